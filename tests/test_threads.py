"""The app's locks go to their waiters in turn, and a redraw never waits for a page build.

* :class:`app.work.threads.FairRLock`: a thread that releases the lock and asks for it again
  at once comes after a thread that was already waiting (``threading.RLock`` lets it straight
  back in); it is reentrant, and a timed-out wait leaves no trace.
* A dashboard's build lets go of the build lock between its views: another page's build,
  waiting for it, gets it before the page is finished.
* Another session's redraw goes on while a page build holds the build lock, and the build
  pauses while a redraw runs (within its budget).
* :func:`app.work.threads.plot_lock` takes the lock of the work it is in, in the one order.
* HoloViews' stream and link registries are locked ones (:mod:`app.work.registries`).
* The app's configuration lets a waiting thread take the interpreter sooner than CPython's
  default (``benchmarks/bench_isolation.py`` measures what that does to a redraw).
"""
from __future__ import annotations

import sys
import threading
import time

import pytest

from app.work import threads
from app.work.threads import (BUILD_LOCK, HV_LOCK, SWITCH_INTERVAL_S, FairRLock, building,
                               drawing, give_way, plot_lock, unlocked)
from conftest import new_dashboard, wait_for


def test_a_waiting_thread_gets_the_lock_before_the_releaser_takes_it_back():
    """A holds, B waits, A releases and asks again: B goes first, then A."""
    lock = FairRLock()
    order: list[str] = []

    def b() -> None:
        with lock:
            order.append("B")
    lock.acquire()
    other = threading.Thread(target=b)
    other.start()
    wait_for(lambda: len(lock._waiters) == 1, 10, "B to wait for the lock")
    lock.release()
    with lock:
        order.append("A")
    other.join(10)
    assert order == ["B", "A"]


def test_the_lock_is_reentrant_and_refuses_a_stranger_release():
    """Held twice by one thread, it is free only after two releases; another thread cannot
    release it, and a timed-out wait leaves the queue empty."""
    lock = FairRLock()
    with lock, lock:
        assert lock._is_owned()
        got: list[bool] = []
        t = threading.Thread(target=lambda: got.append(lock.acquire(timeout=0.2)))
        t.start()
        t.join(10)
        assert got == [False] and not lock._waiters
        errors: list[Exception] = []

        def stranger() -> None:
            try:
                lock.release()
            except RuntimeError as exc:
                errors.append(exc)
        t = threading.Thread(target=stranger)
        t.start()
        t.join(10)
        assert len(errors) == 1
    assert not lock._is_owned()
    assert lock.acquire(blocking=False)
    lock.release()


def test_unlocked_lets_go_however_deeply_held():
    """``unlocked()`` frees the lock for another thread and takes it back as deeply."""
    with HV_LOCK, HV_LOCK:
        with unlocked():
            got: list[bool] = []
            t = threading.Thread(target=lambda: got.append(HV_LOCK.acquire(timeout=5)
                                                           and (HV_LOCK.release() or True)))
            t.start()
            t.join(10)
            assert got == [True]
        assert HV_LOCK._count == 2


def test_a_page_build_lets_another_build_in_between_its_views(job_pool, monkeypatch):
    """While a page is built, a thread waiting for the build lock gets it before the last view
    is built."""
    from app import dashboard as dashboard_module

    built: list[str] = []
    got_in_at: list[int] = []
    real = dashboard_module._built
    started = threading.Event()

    def watched(view, **kwargs):
        with BUILD_LOCK:
            if view.__name__ == "TimeHistoryView":
                started.set()
                # Other threads left by earlier tests may be queued too: wait for this one.
                wait_for(lambda: any(owner == t.ident for owner, _ in list(BUILD_LOCK._waiters)),
                         60, "the other build to wait")
            out = real(view, **kwargs)
            built.append(view.__name__)
        return out
    monkeypatch.setattr(dashboard_module, "_built", watched)

    def other() -> None:
        started.wait(120)
        with BUILD_LOCK:
            got_in_at.append(len(built))
    t = threading.Thread(target=other)
    t.start()
    d = new_dashboard(job_pool)
    t.join(30)
    try:
        assert got_in_at == [built.index("TimeHistoryView") + 1], (got_in_at, built)
        assert got_in_at[0] < len(built)
    finally:
        d.destroy()


def test_a_redraw_goes_on_while_another_page_is_built(dash, job_pool, monkeypatch):
    """A page build stopped inside its diagram view, holding the build lock: another session
    takes a new Λ and redraws meanwhile. (With the build under the redraws' lock, as it was,
    the redraw waited for the whole view.)"""
    from app import dashboard as dashboard_module

    real = dashboard_module._built
    inside, go_on = threading.Event(), threading.Event()

    def held(view, **kwargs):
        if view.__name__ != "DiagramView":
            return real(view, **kwargs)
        with BUILD_LOCK:
            inside.set()
            go_on.wait(120)
            return real(view, **kwargs)
    monkeypatch.setattr(dashboard_module, "_built", held)
    other: list = []
    builder = threading.Thread(target=lambda: other.append(
        dashboard_module.Dashboard(pool=job_pool)))
    builder.start()
    try:
        wait_for(inside.is_set, 120, "the other page to reach its diagram")
        old, lam = dash.state.result, dash.state.lam + 0.05
        redraw = threading.Thread(target=lambda: setattr(dash.state, "lam", lam))
        redraw.start()
        redraw.join(60)
        assert not redraw.is_alive(), "the redraw waited for the other page's build"
        assert dash.state.result is not None and dash.state.result is not old
        assert dash.state.lam == pytest.approx(lam)
        assert builder.is_alive()  # the other page was still being built all along
    finally:
        go_on.set()
        builder.join(120)
        for d in other:
            d.destroy()


def test_a_page_build_gives_way_to_a_redraw_within_its_budget(monkeypatch):
    """In a page build, ``give_way`` waits while a redraw runs, up to the page's budget in
    all; outside a build it never waits."""
    done_drawing, order = threading.Event(), []

    def redraw() -> None:
        with drawing():
            order.append("redraw starts")
            done_drawing.wait(30)
            order.append("redraw ends")
    r = threading.Thread(target=redraw)
    r.start()
    wait_for(lambda: order, 30, "the redraw to start")
    give_way()  # not in a build: at once
    order.append("not a build")

    def build() -> None:
        with building():
            give_way()
            order.append("build goes on")
    b = threading.Thread(target=build)
    b.start()
    wait_for(lambda: len(threads._drawing._waiters) > 0, 30, "the build to pause")
    assert "build goes on" not in order
    done_drawing.set()
    r.join(30)
    b.join(30)
    assert order == ["redraw starts", "not a build", "redraw ends", "build goes on"]

    # a redraw that does not end: the build waits for its budget, and then no more
    monkeypatch.setattr(threads, "GIVE_WAY_BUDGET_S", 0.3)
    with drawing():
        waits: list[float] = []
        with building():
            for _ in range(3):
                t = time.monotonic()
                give_way()
                waits.append(time.monotonic() - t)
    assert waits[0] >= 0.25 and sum(waits[1:]) < 0.1, waits


def test_a_page_build_pauses_at_the_next_bokeh_model_while_a_redraw_runs():
    """After ``configure()`` a Bokeh model made in a page build waits for a running redraw;
    made outside a build, or with no redraw running, it does not."""
    from bokeh.models import Range1d

    from app.main import configure

    configure()
    made: list[str] = []

    def build() -> None:
        with building():
            Range1d()
            made.append("in a build")
    with drawing():
        Range1d()  # not in a build: at once
        made.append("outside a build")
        b = threading.Thread(target=build)
        b.start()
        wait_for(lambda: len(threads._drawing._waiters) > 0, 30, "the build to pause")
        assert made == ["outside a build"]
    b.join(30)
    assert made == ["outside a build", "in a build"]
    with building():
        t = time.monotonic()
        Range1d()  # no redraw running
        assert time.monotonic() - t < 0.5


def _holds_within(lock: FairRLock, seconds: float = 10.0) -> bool:
    """Whether another thread can take ``lock`` within ``seconds``."""
    got: list[bool] = []
    t = threading.Thread(target=lambda: got.append(lock.acquire(timeout=seconds)
                                                   and (lock.release() or True)))
    t.start()
    t.join(seconds + 30)
    return got == [True]


def test_plot_lock_takes_the_lock_of_the_work_it_is_in():
    """In a redraw (the redraws' lock held) it takes no build lock; in a page build, the build
    lock only; elsewhere both, build lock first."""
    with HV_LOCK:
        with plot_lock():
            assert HV_LOCK._count == 2 and not BUILD_LOCK._is_owned()
            assert _holds_within(BUILD_LOCK)
    with building():
        with plot_lock():
            assert BUILD_LOCK._is_owned() and not HV_LOCK._is_owned()
            assert _holds_within(HV_LOCK)
    with plot_lock():
        assert BUILD_LOCK._is_owned() and HV_LOCK._is_owned()
        assert not _holds_within(BUILD_LOCK, 0.2) and not _holds_within(HV_LOCK, 0.2)
    assert not BUILD_LOCK._is_owned() and not HV_LOCK._is_owned()


def test_the_holoviews_registries_are_walked_and_changed_under_a_lock():
    """After ``configure()``, HoloViews' stream and link registries are locked ones: a change
    waits while another thread holds the registry's lock, a walk is a list, and streams made
    and walked by two threads at once raise nothing."""
    import holoviews as hv
    from holoviews.plotting.links import Link
    from holoviews.streams import Stream

    from app.main import configure
    from app.work import registries

    configure()
    assert registries.installed()
    reg = Stream.registry
    assert type(reg).__name__.startswith("Locked") and type(Link.registry).__name__.startswith("Locked")
    curve = hv.Curve([1, 2, 3])
    stream = hv.streams.Tap(source=curve)
    assert reg.get(curve) == [stream] and isinstance(reg.items(), list)

    added = threading.Event()
    other = hv.Curve([3, 2, 1])
    with reg._lock:
        t = threading.Thread(target=lambda: (hv.streams.Tap(source=other), added.set()))
        t.start()
        assert not added.wait(0.3)  # the change waits for the lock
    t.join(30)
    assert added.is_set() and len(reg.get(other, [])) == 1

    errors: list[Exception] = []
    keep: list = []
    stop = threading.Event()

    def make() -> None:
        try:
            while not stop.is_set():
                c = hv.Curve([0, 1])
                keep.append((c, hv.streams.Tap(source=c)))
                if len(keep) > 400:
                    del keep[:200]
        except Exception as exc:
            errors.append(exc)
    before = sys.getswitchinterval()
    sys.setswitchinterval(1e-6)
    try:
        maker = threading.Thread(target=make)
        maker.start()
        walks = 0
        deadline = time.monotonic() + 2.0
        while time.monotonic() < deadline:
            walks += len(reg.items()) > 0
        stop.set()
        maker.join(30)
    finally:
        sys.setswitchinterval(before)
    assert not errors and walks > 10, (errors, walks)


def test_views_built_without_the_lock_make_no_holoviews_object(dash, monkeypatch):
    """Each view of ``PLAIN_VIEWS`` (built without the lock) makes no HoloViews element, map
    or stream; a view that does is counted (the check can fail)."""
    import holoviews as hv
    from app import dashboard as dashboard_module

    made: list[str] = []
    for cls in (hv.core.dimension.Dimensioned, hv.streams.Stream):
        real = cls.__init__

        def counted(self, *args, _real=real, **kwargs):
            made.append(type(self).__name__)
            _real(self, *args, **kwargs)
        monkeypatch.setattr(cls, "__init__", counted)
    extra = {"NoiseView": {"jobs": dash.session.jobs},
             "RunupView": {"jobs": dash.session.jobs, "gearbox": dash.gearbox},
             "PresentView": {"header": dash.shell.header}}
    for view in dashboard_module.PLAIN_VIEWS:
        made.clear()
        view(state=dash.state, **extra.get(view.__name__, {}))
        assert made == [], (view.__name__, made)
    dashboard_module.SectionView(state=dash.state)
    assert made  # a view with HoloViews plots is seen to make them


def test_the_app_hands_the_interpreter_on_sooner_than_cpython_does():
    """``configure()`` (the server's and every session's setup) sets the switch interval to
    :data:`SWITCH_INTERVAL_S`, a tenth of CPython's 5 ms."""
    from app.main import configure

    before = sys.getswitchinterval()
    sys.setswitchinterval(0.005)
    try:
        configure()
        assert sys.getswitchinterval() == pytest.approx(SWITCH_INTERVAL_S, rel=1e-3)
        assert SWITCH_INTERVAL_S <= 0.0005
    finally:
        sys.setswitchinterval(before)
