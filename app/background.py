"""Cancellable background sweeps for the bifurcation diagram.

A sweep takes seconds; a slider move must take milliseconds. Sweeps therefore run on one
process-wide worker thread, never on the server's event loop:

* one worker for all sessions, because the sweep kernel already uses every core
  (``numba`` ``prange``) and the default threading layer must not be entered from two
  threads at once;
* every :class:`Job` carries a cancel flag, polled by the sweep between chunks; a session
  cancels its running job whenever the parameters move on, and a job cancelled before it
  starts never runs;
* results, progress and errors come back through callbacks that the session schedules on its
  own document (see ``app.dashboard``), so one session's failure stays in that session.

Shipped diagrams (``assets/paper``) and the disk cache answer first when they fit.
"""
from __future__ import annotations

import dataclasses
import logging
import threading
from concurrent.futures import ThreadPoolExecutor
from typing import Any, Callable

import numpy as np

from rattle_core import RattleParams
from rattle_core.store import assets
from rattle_core.store.cache import cached_sweep

log = logging.getLogger(__name__)

_EXECUTOR = ThreadPoolExecutor(max_workers=1, thread_name_prefix="rattle-sweep")


@dataclasses.dataclass(frozen=True)
class SweepRequest:
    """One diagram to compute: parameter ``name`` over ``values`` with the rest fixed."""

    params: RattleParams
    name: str
    values: tuple[float, ...]
    transient: int = 300
    record: int = 100

    def as_array(self) -> np.ndarray:
        return np.asarray(self.values, dtype=np.float64)


@dataclasses.dataclass
class Diagram:
    """Impulses against a swept value, ready to plot; ``source`` says where they came from."""

    name: str
    value: np.ndarray
    impulse: np.ndarray
    flank: np.ndarray
    source: str
    cancelled: bool = False

    @property
    def span(self) -> tuple[float, float]:
        return float(np.min(self.value)), float(np.max(self.value))


def diagram_from_result(result: Any, source: str) -> Diagram:
    """Flatten a ``SweepResult`` into plotting arrays."""
    t = result.table
    return Diagram(name=result.name, value=np.asarray(t["value"], dtype=np.float64),
                   impulse=np.asarray(t["impulse"], dtype=np.float64),
                   flank=np.asarray(t["flank"], dtype=np.int8), source=source,
                   cancelled=bool(getattr(result, "cancelled", False)))


def find_shipped(params: RattleParams, name: str) -> Diagram | None:
    """A shipped diagram sweeping ``name`` with every other parameter equal to ``params``."""
    found = assets.find_asset(params, name)
    return None if found is None else diagram_from_result(found[1], f"shipped diagram {found[0]}")


def run_sweep(req: SweepRequest, progress: Callable[[int, int], Any] | None = None,
              cancel: Callable[[], bool] | None = None) -> Diagram:
    """Compute (or fetch from the disk cache) one diagram, in the calling thread."""
    res = cached_sweep(req.params, req.name, req.as_array(), transient=req.transient,
                       record=req.record, mode="fresh", progress=progress, cancel=cancel)
    return diagram_from_result(res, "computed (disk cache)")


class CancellableJob:
    """Background work that its session can cancel at any time; subclasses define ``run``.

    The work polls :attr:`cancelled` (or passes ``self._cancel.is_set`` on) between chunks;
    progress is reported as a fraction, and never after a cancel.
    """

    def __init__(self, request: Any, on_progress: Callable[[float], None],
                 on_done: Callable[..., None], on_error: Callable[..., None]):
        self.request = request
        self._cancel = threading.Event()
        self._on_progress = on_progress
        self._on_done = on_done
        self._on_error = on_error
        self.future = None

    def cancel(self) -> None:
        self._cancel.set()

    @property
    def cancelled(self) -> bool:
        return self._cancel.is_set()

    def _progress(self, done: int, total: int) -> None:
        if not self.cancelled:
            self._on_progress(done / max(total, 1))

    def run(self) -> None:
        raise NotImplementedError


class Job(CancellableJob):
    """A queued or running bifurcation sweep."""

    def run(self) -> None:
        if self.cancelled:
            return
        try:
            diagram = run_sweep(self.request, self._progress, self._cancel.is_set)
        except Exception as exc:  # reported to its own session only, as a message
            if not self.cancelled:
                log.warning("background sweep failed: %s", exc)
                self._on_error(f"{type(exc).__name__}: {exc}")
            return
        if not self.cancelled and not diagram.cancelled:
            self._on_done(diagram)


def submit(req: SweepRequest, on_progress: Callable[[float], None],
           on_done: Callable[[Diagram], None], on_error: Callable[[str], None]) -> Job:
    """Queue a sweep on the shared worker; the callbacks run on the worker thread."""
    job = Job(req, on_progress, on_done, on_error)
    job.future = _EXECUTOR.submit(job.run)
    return job


def warm_up() -> None:
    """Compile the sweep kernel (numba) and load the shipped diagrams before the first visitor."""
    for name in assets.list_assets():
        assets.load_asset(name)
    try:
        run_sweep(SweepRequest(RattleParams(lam=2.0), "lam", (2.0, 2.5), transient=2, record=2))
    except Exception as exc:
        log.warning("sweep warm-up failed: %s", exc)
