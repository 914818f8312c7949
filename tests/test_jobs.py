"""The job pool: background work in worker processes, bounded in time, killable, shared fairly.

A job that never returns stands in for a solver that hangs (``time.sleep``, run in a worker);
a real diagram sweep checks the results and progress against ``rattle_core.sweep``.
"""
from __future__ import annotations

import gc
import threading
import time
import weakref

import numpy as np
import pytest

from app.work import tasks
from conftest import wait_for
from app.work.jobs import JobPool
from rattle_core import RattleParams, sweep

pytestmark = pytest.mark.timeout(300)


@pytest.fixture(scope="module")
def pool():
    p = JobPool(size=2, grace=1.0)
    yield p
    p.shutdown()


class Outcome:
    def __init__(self):
        self.done = threading.Event()
        self.result = self.error = None
        self.progress: list[float] = []

    def kwargs(self) -> dict:
        return {"on_done": self._done, "on_error": self._error, "on_progress": self.progress.append}

    def _done(self, r):
        self.result = r
        self.done.set()

    def _error(self, m):
        self.error = m
        self.done.set()


def test_a_diagram_job_returns_the_sweep_with_progress(pool):
    """A sweep run in a worker equals rattle_core.sweep, and reports progress up to 1."""
    base = RattleParams(lam=2.0, amplitudes=(1.0, 0.25), phases_deg=(0.0, -135.0))
    values = np.linspace(1.0, 3.0, 40)
    out = Outcome()
    pool.submit(("s", "diagram"), tasks.diagram, (base, "lam", values, 100, 30), {"use_cache": False},
                **out.kwargs())
    assert out.done.wait(120) and out.error is None
    ref = sweep(base, "lam", values, transient=100, record=30)
    np.testing.assert_array_equal(out.result["impulse"], ref.table["impulse"].to_numpy())
    np.testing.assert_array_equal(out.result["regime"], ref.summary["regime"].to_numpy())
    assert out.progress and out.progress[-1] == 1.0



def test_a_finished_jobs_callbacks_are_let_go_by_the_pool(pool):
    """Once a job that reported progress has ended, nothing of the pool holds its callbacks:
    what they reach (a closed page's views, in the server) is collected. A reader thread that
    kept its last progress callback in a local held a page until its worker's next job."""
    class Views:
        pass
    views, done, progress = Views(), threading.Event(), []
    base = RattleParams(lam=2.0, amplitudes=(1.0, 0.25), phases_deg=(0.0, -135.0))
    pool.submit(("freed", "diagram"), tasks.diagram, (base, "lam", np.linspace(1.0, 3.0, 40), 100, 30),
                {"use_cache": False}, on_progress=lambda f, v=views: progress.append(f),
                on_done=lambda r, v=views: done.set(), on_error=lambda m, v=views: done.set())
    freed = weakref.ref(views)
    del views
    assert done.wait(120) and progress
    # the callback that set ``done`` is still returning: wait for the reader to be idle again
    wait_for(lambda: (gc.collect(), freed() is None)[-1], 20, "the pool to let go of the callbacks")


LIMIT = 12.0


def test_a_job_past_its_time_limit_is_killed_and_others_still_run(pool):
    """One session's hung job is killed at its limit; another session's job finishes meanwhile."""
    hung, quick = Outcome(), Outcome()
    t0 = time.monotonic()
    # a limit the quick job stays well inside, even on a loaded machine
    pool.submit(("a", "diagram"), time.sleep, (1000,), time_limit=LIMIT, **hung.kwargs())
    pool.submit(("b", "diagram"), tasks.diagram, (RattleParams(lam=2.0), "lam", np.linspace(1, 2, 10), 50, 20),
                {"use_cache": False}, **quick.kwargs())
    assert quick.done.wait(60) and quick.error is None
    assert not hung.done.is_set()  # finished while the hung job still ran: it did not wait
    assert hung.done.wait(60) and "time limit" in hung.error
    assert LIMIT <= time.monotonic() - t0 < LIMIT + 30.0
    assert len(pool.worker_pids()) == 2


def test_cancel_kills_a_job_that_does_not_stop_and_calls_nothing_back(pool):
    """A cancelled job that ignores its flag is killed after the grace; no callback runs."""
    out = Outcome()
    job = pool.submit(("c", "x"), time.sleep, (1000,), **out.kwargs())
    wait_for(lambda: pool.worker_pids(job), timeout=30, what="the job to start in a worker")
    pid = pool.worker_pids(job)[0]
    job.cancel()
    deadline = time.monotonic() + 15
    while pid in pool.worker_pids() and time.monotonic() < deadline:
        time.sleep(0.1)
    assert pid not in pool.worker_pids()
    assert job.cancelled and not out.done.wait(1.0)


def test_a_new_request_replaces_the_sessions_last_and_session_end_cancels_all(pool):
    """Per session and kind one job: queued ones are replaced; cancel_session cancels them all."""
    blockers = [pool.submit((f"busy{i}", "x"), time.sleep, (1000,)) for i in range(2)]
    first = pool.submit(("d", "diagram"), time.sleep, (0.1,))
    second = pool.submit(("d", "diagram"), time.sleep, (0.1,))
    other = pool.submit(("d", "map"), time.sleep, (0.1,))
    assert first.status == "cancelled" and second.status == "queued" and other.status == "queued"
    pool.cancel_session("d")
    assert second.cancelled and other.cancelled
    assert [j for j in pool.pending("d")] == []
    for b in blockers:
        b.cancel()


def test_a_slow_worker_start_does_not_count_against_a_job_limit():
    """Workers that take 3 s to warm up (a loaded machine) still run a 0.2 s job within a 1 s
    limit: a worker takes jobs only once warm, so its start is not part of the job's time."""
    import functools
    slow = JobPool(size=1, grace=1.0, warm=functools.partial(time.sleep, 3.0))
    try:
        out = Outcome()
        job = slow.submit(("w", "x"), time.sleep, (0.2,), time_limit=1.0, **out.kwargs())
        assert job.status == "queued"  # no worker is warm yet
        assert out.done.wait(60)
        assert out.error is None and job.status == "done", out.error
    finally:
        slow.shutdown()
