"""Ctrl-C around the server: held back, noted or ignored while it starts, and while it waits.

Ctrl-C in a terminal signals the whole process group, and Python raises it wherever the main
thread stands, including inside a callback Python calls on its own (a weak reference's, or
one numba's compiled code calls while loading kernels), where it is printed as "Exception
ignored in …" and dropped. These blocks decide where it lands instead. The module imports
nothing heavy: ``rattle serve`` uses :func:`sigint_noted` around the import of the server
itself.
"""
from __future__ import annotations

import contextlib
import signal
import threading
from typing import Iterator


@contextlib.contextmanager
def no_sigint() -> Iterator[None]:
    """SIGINT held back in this thread, and blocked for good in the processes it starts.

    Ctrl-C in a terminal signals the whole process group; the server stops its workers
    itself, so they must not die half-way with a traceback of their own.  An interrupt held
    back here arrives once the block ends, where the server is ready to stop cleanly.
    """
    mask = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, mask)


@contextlib.contextmanager
def sigint_noted() -> Iterator[threading.Event]:
    """A Ctrl-C during the block sets the event yielded, and raises nothing.

    Python drops an exception raised inside a callback it calls on its own (a weak
    reference's, or one numba's compiled code calls while loading kernels) with "Exception
    ignored in …": a KeyboardInterrupt landing there was lost, and the server went on to
    serve.  Here the handler only takes note.
    """
    noted = threading.Event()
    if threading.current_thread() is not threading.main_thread():
        yield noted
        return
    old = signal.signal(signal.SIGINT, lambda signum, frame: noted.set())
    try:
        yield noted
    finally:
        signal.signal(signal.SIGINT, old)


@contextlib.contextmanager
def sigint_deferred() -> Iterator[None]:
    """A Ctrl-C during the block is noted (:func:`sigint_noted`), and raised as
    KeyboardInterrupt once it ends."""
    with sigint_noted() as noted:
        yield
    if noted.is_set():
        raise KeyboardInterrupt


@contextlib.contextmanager
def sigint_ignored() -> Iterator[None]:
    """SIGINT ignored while Dask starts its worker processes, which keep ignoring it.

    Dask starts them from threads of its own, so :func:`no_sigint`'s mask does not reach
    them; an ignored signal does.  A Ctrl-C in these few seconds is lost, not half-handled.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    old = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, old)
