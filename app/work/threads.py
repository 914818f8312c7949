"""How the app's code meets the server's threads.

Bokeh applies each session's browser events in a worker thread of its own, holding that
session's document lock; the tornado loop runs the sessions' timers and next-tick callbacks.
Two sessions can therefore run Python at once, and HoloViews keeps process-wide registries
(streams, links, options) that are not safe against that. So:

* :data:`HV_LOCK` is held while a session changes or redraws its views (one session at a
  time); :data:`BUILD_LOCK` while a new page is built (one page at a time). A page build
  and another session's redraw run side by side: the registries they both touch are made
  safe for it (:mod:`app.work.registries`), and a redraw never waits for a page build;
* :func:`plot_lock` is what building one HoloViews plot holds: within a redraw, the redraw's
  lock; within a page build, the build's; elsewhere (a tab first shown) both;
* :func:`building` marks the thread that builds a page, and :func:`give_way` lets it pause
  while a redraw runs, so that a redraw has the interpreter to itself (for at most
  :data:`GIVE_WAY_BUDGET_S` per page: a stream of redraws does not stall a page); it pauses
  before each view, each plot and each Bokeh model (:func:`give_way_at_each_model`);
* :func:`unlocked` lets go of :data:`HV_LOCK` around computation (a simulation never holds it);
* :func:`later` runs a state change that comes from a HoloViews stream callback (a click, a
  zoom, which HoloViews runs outside the document's lock) on the session's next tick, where
  Bokeh holds the lock;
* :func:`share_the_interpreter` shortens the time a thread runs Python before a waiting one
  gets the interpreter, so a session's short redraw is not held back by another's long build;
* :func:`writes_bokeh` marks a view's method that sets Bokeh models itself. Panel runs some
  widget callbacks on the event loop without the document's lock (a click that arrives while
  a debounced change is pending), and a Bokeh change made there raises in the server's
  session; Panel's ``unlocked()``, which HoloViews uses for the same reason, collects the
  changes and sends them to the page, held or not.

The locks are always taken in the order :data:`BUILD_LOCK`, then :data:`HV_LOCK`; a thread
that holds :data:`HV_LOCK` never asks for :data:`BUILD_LOCK`, so the two cannot deadlock.
"""
from __future__ import annotations

import collections
import contextlib
import functools
import logging
import sys
import threading
import time
from typing import Any, Iterator

import panel as pn

log = logging.getLogger(__name__)

class FairRLock:
    """A reentrant lock handed to its waiters first come, first served.

    ``threading.RLock`` lets the thread that releases it take it straight back: a page built
    plot after plot, releasing between plots, would keep it while another session's redraw
    waited for the whole page. Here a release with waiters hands the lock to the one that
    waited longest.
    """

    def __init__(self) -> None:
        self._mutex = threading.Lock()
        self._owner: int | None = None
        self._count = 0
        self._waiters: collections.deque[tuple[int, threading.Lock]] = collections.deque()

    def acquire(self, blocking: bool = True, timeout: float = -1) -> bool:
        me = threading.get_ident()
        with self._mutex:
            if self._owner == me:
                self._count += 1
                return True
            if self._owner is None and not self._waiters:
                self._owner, self._count = me, 1
                return True
            if not blocking:
                return False
            gate = threading.Lock()
            gate.acquire()
            entry = (me, gate)
            self._waiters.append(entry)
        if gate.acquire(timeout=timeout):
            return True  # handed over by release(), which made this thread the owner
        with self._mutex:
            if self._owner == me:  # handed over just as the wait timed out
                return True
            self._waiters.remove(entry)
            return False

    def release(self) -> None:
        with self._mutex:
            if self._owner != threading.get_ident():
                raise RuntimeError("cannot release an un-acquired lock")
            self._count -= 1
            if self._count:
                return
            if self._waiters:
                owner, gate = self._waiters.popleft()
                self._owner, self._count = owner, 1
                gate.release()
            else:
                self._owner = None

    def _is_owned(self) -> bool:
        return self._owner == threading.get_ident()

    def __enter__(self) -> bool:
        return self.acquire()

    def __exit__(self, *exc: Any) -> None:
        self.release()


#: Held while a session changes or redraws its views, and while a plot is built outside a
#: page build. Bokeh applies each session's browser events in a worker thread, so two
#: sessions could draw at once, and a session's background results must not land in the
#: middle of its own redraw.
HV_LOCK = FairRLock()

#: Held while a new page builds its views and plots: page builds take turns, and a redraw
#: never waits for one (see the module docstring).
BUILD_LOCK = FairRLock()

#: Seconds a page build spends, in all, paused for other sessions' redraws (:func:`give_way`).
GIVE_WAY_BUDGET_S = 5.0

_local = threading.local()
_drawing = threading.Condition()
_redraws = 0


@contextlib.contextmanager
def drawing() -> Iterator[None]:
    """A session redraws during the block: page builds pause at their next step."""
    global _redraws
    with _drawing:
        _redraws += 1
    try:
        yield
    finally:
        with _drawing:
            _redraws -= 1
            _drawing.notify_all()


@contextlib.contextmanager
def building() -> Iterator[None]:
    """This thread builds a page during the block (:func:`plot_lock`, :func:`give_way`)."""
    outer = getattr(_local, "budget", None)
    if outer is None:
        _local.budget = GIVE_WAY_BUDGET_S
    try:
        yield
    finally:
        if outer is None:
            _local.budget = None


def is_building() -> bool:
    return getattr(_local, "budget", None) is not None


def give_way() -> None:
    """In a page build, wait while another session redraws (within the page's budget).

    The interpreter runs one thread at a time: a build that went on meanwhile would take half
    of it, and a redraw would take about twice as long as alone.
    """
    budget = getattr(_local, "budget", None)
    if not budget or not _redraws or HV_LOCK._is_owned():
        return
    start = time.monotonic()
    with _drawing:
        _drawing.wait_for(lambda: _redraws == 0, timeout=budget)
    _local.budget = max(0.0, budget - (time.monotonic() - start))


@contextlib.contextmanager
def plot_lock() -> Iterator[None]:
    """What building one HoloViews plot holds; see the module docstring."""
    if HV_LOCK._is_owned():
        with HV_LOCK:
            yield
    elif is_building():
        give_way()
        with BUILD_LOCK:
            yield
    else:
        with BUILD_LOCK, HV_LOCK:
            yield


#: Seconds a thread runs Python before a thread waiting for the interpreter takes it over
#: (CPython's default is 5 ms). A session's redraw is short bursts of Python between waits (for
#: its run in a worker process, for :data:`HV_LOCK`, for the socket), and while another session
#: builds a page, which is Python without a wait for seconds, each burst waited up to the whole
#: interval to run: at 5 ms a redraw took 4 to 6 times as long as alone, at 0.5 ms about 2.5
#: times (``benchmarks/bench_isolation.py`` measures both in one run).
SWITCH_INTERVAL_S = 0.0005


def share_the_interpreter(interval: float = SWITCH_INTERVAL_S) -> None:
    """Let a thread that waits for the interpreter take it after ``interval`` seconds."""
    sys.setswitchinterval(interval)


@contextlib.contextmanager
def unlocked() -> Iterator[None]:
    """:data:`HV_LOCK` let go by this thread for the block, however deeply it holds it.

    Computation never holds the lock: a session that simulates inside a redraw (a change
    arrives under the lock) lets the other sessions draw meanwhile, and takes it back after.
    """
    depth = 0
    while HV_LOCK._is_owned():
        HV_LOCK.release()
        depth += 1
    try:
        yield
    finally:
        for _ in range(depth):
            HV_LOCK.acquire()


def writes_bokeh(method: Any) -> Any:
    """``method`` runs inside Panel's ``unlocked()``: its Bokeh changes reach the page whether
    or not the caller holds the document's lock (without a server it runs as it is)."""
    @functools.wraps(method)
    def held(*args: Any, **kwargs: Any) -> Any:
        with pn.io.unlocked():
            return method(*args, **kwargs)
    return held


def later(fn: Any, *args: Any) -> None:
    """Run ``fn(*args)`` on the session's next tick (at once without a server).

    HoloViews runs its stream callbacks (a click, a zoom) outside the document's lock; a
    state change from there must wait for a tick of its own, where Bokeh holds the lock.
    """
    doc = pn.state.curdoc
    if doc is None or doc.session_context is None:
        fn(*args)
        return

    def tick() -> None:
        try:
            with HV_LOCK:
                fn(*args)
        except Exception as exc:  # a callback never raises into the page
            log.warning("deferred update failed: %s: %s", type(exc).__name__, exc)
    doc.add_next_tick_callback(tick)


_paused_models = False


def give_way_at_each_model() -> None:
    """Make each Bokeh model a page build creates a point where it gives way (:func:`give_way`).

    A plot's build is some 0.3 s of Python with a few hundred models made along the way; a
    redraw that starts meanwhile would otherwise share the interpreter with it to its end.
    Outside a page build the check costs a thread-local read.
    """
    global _paused_models
    if _paused_models:
        return
    from bokeh.model import Model

    made = Model.__init__

    @functools.wraps(made)
    def init(self, *args: Any, **kwargs: Any) -> None:
        if _redraws and getattr(_local, "budget", None):
            give_way()
        made(self, *args, **kwargs)
    Model.__init__ = init
    _paused_models = True
