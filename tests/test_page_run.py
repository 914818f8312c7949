"""The page's own run has the limits jobs have: a budget, a worker with a time limit, no lock.

The audit's worst link (32 harmonics of amplitude 100 in a backlash of 0.01) used to simulate
for minutes inside the session's redraw, holding the lock every session's redraw needs.  Now
it is refused within seconds with a message; a heavy run within the budget goes to a worker
process (time limit, superseded by a newer change); and no simulation holds the lock.
"""
from __future__ import annotations

import threading
import time
import types

import pytest
from panel.io.location import Location

from app.main import configure
from app.session import RUNNING, Session
from app.work import page_run
from app.work.threads import HV_LOCK
from conftest import wait_for

configure()
HARMONICS = ",".join(f"{k}:100:0" for k in range(3, 33))
WORST = f"?r=1&j=0.01&h2=100&phi2=0&harmonics={HARMONICS}&periods=1&transient=300&shown=1"
#: Ten small harmonics and the longest run: over the inline limit, within the budget.
HEAVY = {"harmonics": ",".join(f"{k}:0.01:0" for k in range(3, 11)), "periods": 20000,
         "transient": 100000}


@pytest.mark.parametrize("link", [WORST, WORST.replace("transient=300", "transient=100000")])
def test_the_worst_link_is_refused_at_once_with_a_message(link):
    """The audit's worst links draw a page within seconds and say the run is over the budget."""
    t0 = time.monotonic()
    s = Session(location=Location(search=link)).state
    took = time.monotonic() - t0
    assert took < 20, f"{took:.1f} s"
    assert s.result is not None
    text = " ".join(s.messages.values())
    assert "budget" in text and "harmonics" in text, s.messages


def test_the_budget_counts_periods_harmonics_and_impacts():
    """The work estimate is (transient + periods) × harmonics × (1 + impacts per period)."""
    from rattle_core import RattleParams, simulate
    p = RattleParams(lam=3.3, amplitudes=(1.0, 0.25, 0.1), phases_deg=(0.0, 45.0, 0.0))
    kwargs = dict(periods=40, transient=60, x0=None, v0=0.0, t0=0.0, strobe_phase=0.0,
                  lyapunov=True, max_impacts_per_period=page_run.MAX_IMPACTS)
    probe = simulate(p, periods=page_run.PROBE_PERIODS)
    expected = 100 * 3 * (1 + probe.impact_t.size / page_run.PROBE_PERIODS)
    assert page_run.work(p, kwargs) == pytest.approx(expected)


def test_no_simulation_holds_the_lock(monkeypatch):
    """A change arriving under the HoloViews lock simulates with the lock free for others."""
    s = Session()
    seen = []
    real = page_run.simulate

    def watched(*args, **kwargs):
        got = []
        other = threading.Thread(target=lambda: got.append(HV_LOCK.acquire(timeout=5) and
                                                           (HV_LOCK.release() or True)))
        other.start()
        other.join()
        seen.append(bool(got and got[0]))
        return real(*args, **kwargs)
    monkeypatch.setattr(page_run, "simulate", watched)
    with HV_LOCK, HV_LOCK:  # held twice, as a stream callback inside a redraw holds it
        s.state.lam = 2.5
        assert HV_LOCK._is_owned()
    assert seen and all(seen), seen
    assert s.state.result.params.lam == 2.5


def test_a_heavy_run_goes_to_a_worker_and_is_published(job_pool):
    """A run over the inline limit runs in a worker; the page says so, then draws it."""
    s = Session(pool=job_pool)
    first = s.state.result
    s.state.param.update(**HEAVY)
    assert s.page.pending is not None
    assert s.state.messages.get("global") == RUNNING
    assert s.state.result is first
    wait_for(lambda: s.state.result is not first, 120, "the heavy run")
    assert s.state.result.tr.settings["periods"] == 20000
    assert "global" not in s.state.messages
    s.destroy()


def test_a_newer_change_supersedes_a_heavy_run(job_pool):
    """A change made while a heavy run computes cancels it; its result is never shown."""
    s = Session(pool=job_pool)
    s.state.param.update(**HEAVY)
    job = s.page.pending
    assert job is not None
    s.state.param.update(periods=100, transient=100)
    assert s.page.pending is None
    wait_for(lambda: job.finished, 30, "the cancel")
    assert job.status == "cancelled"
    assert s.state.result.tr.settings["periods"] == 100
    assert job.on_done is None and job.on_error is None  # nothing of it can still arrive
    s.destroy()


def test_a_heavy_run_over_its_time_limit_is_stopped(job_pool, monkeypatch):
    """A heavy run that overruns its time limit is killed; the last good values come back."""
    monkeypatch.setattr(page_run, "TIME_LIMIT", 0.05)
    s = Session(pool=job_pool)
    good = s.state.periods
    s.state.param.update(**HEAVY)
    # a worker killed by the test before is replaced, and warms up first: minutes when loaded
    wait_for(lambda: "time limit" in s.state.messages.get("global", ""), 300, "the time limit")
    assert s.state.periods == good
    assert s.state.result.tr.settings["periods"] == good
    s.destroy()


def test_a_worker_failing_during_the_change_keeps_its_message():
    """A heavy run whose worker fails before the change that started it has finished (a loaded
    machine) still leaves its message and the last good values: the callback waits its turn."""

    class FailingAtOnce:
        def submit(self, owner, fn, args=(), kwargs=None, *, time_limit, on_done=None,
                   on_error=None, on_progress=None):
            worker = threading.Thread(target=on_error, args=("stopped after 0.05 s, the time limit",))
            worker.start()
            worker.join(timeout=0.5)  # as long as the refresh lets it
            return types.SimpleNamespace(cancel=lambda: None)

        def cancel_session(self, key):
            pass

    s = Session(pool=FailingAtOnce())
    good = s.state.periods
    s.state.param.update(**HEAVY)
    wait_for(lambda: "time limit" in s.state.messages.get("global", ""), 30, "the time limit")
    assert s.state.periods == good
    assert s.page.pending is None
