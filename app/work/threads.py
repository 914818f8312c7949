"""How the app's code meets the server's threads.

Bokeh applies each session's browser events in a worker thread of its own, holding that
session's document lock; the tornado loop runs the sessions' timers and next-tick callbacks.
Two sessions can therefore run Python at once, and HoloViews keeps process-wide registries
(streams, options) that are not safe against that. So:

* :data:`HV_LOCK` is held while HoloViews builds streams or plots and while a session redraws;
* :func:`unlocked` lets go of it around computation (a simulation never holds it);
* :func:`later` runs a state change that comes from a HoloViews stream callback (a click, a
  zoom, which HoloViews runs outside the document's lock) on the session's next tick, where
  Bokeh holds the lock.
"""
from __future__ import annotations

import contextlib
import logging
import threading
from typing import Any, Iterator

import panel as pn

log = logging.getLogger(__name__)

#: Held while HoloViews builds streams or plots, and while a session redraws. Bokeh applies
#: each session's browser events in a worker thread, so two sessions can draw at once, and
#: HoloViews keeps process-wide registries (streams, options): a stream added by one session
#: while another builds a plot breaks the walk of the stream registry ("dictionary changed
#: size during iteration").
HV_LOCK = threading.RLock()


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
