"""How the app's code meets the server's threads.

Bokeh applies each session's browser events in a worker thread of its own, holding that
session's document lock; the tornado loop runs the sessions' timers and next-tick callbacks.
Two sessions can therefore run Python at once, and HoloViews keeps process-wide registries
(streams, options) that are not safe against that. So:

* :data:`HV_LOCK` is held while HoloViews builds streams or plots and while a session redraws;
  a page is built one view and one plot at a time, each under the lock on its own, and the
  lock passes to its waiters in turn (:class:`FairRLock`): another session's redraw waits for
  one plot of a heavy page, never for the whole page;
* :func:`unlocked` lets go of it around computation (a simulation never holds it);
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
"""
from __future__ import annotations

import collections
import contextlib
import functools
import logging
import sys
import threading
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


#: Held while HoloViews builds streams or plots, and while a session redraws. Bokeh applies
#: each session's browser events in a worker thread, so two sessions can draw at once, and
#: HoloViews keeps process-wide registries (streams, options): a stream added by one session
#: while another builds a plot breaks the walk of the stream registry ("dictionary changed
#: size during iteration").
HV_LOCK = FairRLock()


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
