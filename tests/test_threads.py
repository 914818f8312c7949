"""The HoloViews lock goes to its waiters in turn, and a page is built one view at a time.

* :class:`app.work.threads.FairRLock`: a thread that releases the lock and asks for it again
  at once comes after a thread that was already waiting (``threading.RLock`` lets it straight
  back in); it is reentrant, and a timed-out wait leaves no trace.
* A dashboard's build lets go of the lock between its views: another session's redraw,
  waiting for the lock, gets it before the page is finished.
* The app's configuration lets a waiting thread take the interpreter sooner than CPython's
  default (``benchmarks/bench_isolation.py`` measures what that does to a redraw).
"""
from __future__ import annotations

import sys
import threading

import pytest

from app.work.threads import SWITCH_INTERVAL_S, FairRLock, HV_LOCK, unlocked
from conftest import wait_for


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


def test_a_page_build_lets_another_session_in_between_its_views(job_pool, monkeypatch):
    """While a page is built, a waiting thread gets the lock before the last view is built."""
    from app import dashboard as dashboard_module
    from app.main import configure, warm_up

    configure()
    warm_up(pool=False)
    built: list[str] = []
    got_in_at: list[int] = []
    real = dashboard_module._built
    started = threading.Event()

    def watched(view, **kwargs):
        with HV_LOCK:
            if view.__name__ == "TimeHistoryView":
                started.set()
                # Other threads left by earlier tests may be queued too: wait for this one.
                wait_for(lambda: any(owner == t.ident for owner, _ in list(HV_LOCK._waiters)),
                         60, "the other session to wait")
            out = real(view, **kwargs)
            built.append(view.__name__)
        return out
    monkeypatch.setattr(dashboard_module, "_built", watched)

    def other() -> None:
        started.wait(120)
        with HV_LOCK:
            got_in_at.append(len(built))
    t = threading.Thread(target=other)
    t.start()
    d = dashboard_module.Dashboard(pool=job_pool)
    t.join(30)
    try:
        assert got_in_at == [built.index("TimeHistoryView") + 1], (got_in_at, built)
        assert got_in_at[0] < len(built)
    finally:
        d.destroy()


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
