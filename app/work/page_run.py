"""The page's own run: a budget before it starts, and a worker process when it is heavy.

Every change of a session's state simulates once (:mod:`app.session`).  That run is on the
page's path, so it gets the limits background jobs have:

* **a budget**: a short probe (:data:`PROBE_PERIODS` periods, the run's own start) measures
  the impacts per period, and the run's work, ``(transient + periods) × harmonics ×
  (1 + impacts per period)``, must stay within :data:`BUDGET` (at most about 25 s on this
  machine); more is refused with a message before it starts.  A period with more than
  :data:`MAX_IMPACTS` impacts stops the run at once (the solver's runaway limit);
* **a worker**: a run whose work is over :data:`INLINE_WORK` goes to the job pool
  (:mod:`app.work.jobs`), where it has a time limit (:data:`TIME_LIMIT`) and is killed if
  it overruns; a newer change of the same session cancels it (it is superseded);
* **no lock**: the probe and an inline run let go of the HoloViews lock
  (:func:`app.work.threads.unlocked`), so other sessions redraw meanwhile; the compiled
  solver releases the GIL.
"""
from __future__ import annotations

import math
import time
from typing import Any, Callable

from rattle_core import SolverError, classify, simulate

from .threads import unlocked

#: Most work one page run may take: periods × harmonics × (1 + impacts per period).  A run
#: with its Lyapunov exponent and classification costs 0.3 to 1.2 µs per unit on one core
#: (more with more harmonics), so this is at most about 25 s, within :data:`TIME_LIMIT`.
BUDGET = 2.0e7
#: Runs estimated above this (0.05 to 0.25 s) run in a worker process.
INLINE_WORK = 2.0e5
#: Seconds a page run may take in a worker before it is killed.
TIME_LIMIT = 30.0
#: The page's runaway limit: impacts within one forcing period.
MAX_IMPACTS = 20_000
#: Periods the probe runs to measure the impacts per period.
PROBE_PERIODS = 4


def run_kwargs(state: Any) -> dict:
    """The keyword arguments of ``simulate`` for the run ``state`` asks for."""
    return dict(periods=state.periods, x0=state.x0, v0=state.v0, t0=state.t0,
                strobe_phase=math.radians(state.strobe), transient=state.transient,
                lyapunov=True, max_impacts_per_period=MAX_IMPACTS)


def work(params: Any, kwargs: dict) -> float:
    """The run's work (see the module docstring), from a probe of its first periods.

    Raises ``ValueError`` for a bad request and ``SolverError`` for a runaway start.
    """
    total = kwargs["periods"] + kwargs["transient"]
    probe = {**kwargs, "periods": max(1, min(PROBE_PERIODS, total)), "transient": 0,
             "lyapunov": False, "record_segments": False}
    try:
        per_period = simulate(params, **probe).impact_t.size / probe["periods"]
    except SolverError as exc:
        if not str(exc).startswith("runaway"):
            raise
        per_period = MAX_IMPACTS  # at least: the probe stopped at the runaway limit
    return float(total) * params.n_harmonics * (1.0 + per_period)


def over_budget(params: Any, kwargs: dict, units: float) -> str:
    """The message for a run over :data:`BUDGET`."""
    total = kwargs["periods"] + kwargs["transient"]
    per_period = units / (total * params.n_harmonics) - 1.0
    return (f"periods + transient = {total} with {params.n_harmonics} harmonics and about "
            f"{per_period:.3g} impacts per period is {units:.2g} units of work, over the page's "
            f"budget of {BUDGET:.0e}; lower the periods, the transient or the harmonics, or "
            "raise the backlash")


def compute(params: Any, kwargs: dict) -> tuple[Any, Any, float]:
    """Simulate and classify; ``(trajectory, classification, milliseconds)``."""
    t0 = time.perf_counter()
    tr = simulate(params, **kwargs)
    cls = classify(tr)
    return tr, cls, 1e3 * (time.perf_counter() - t0)


class PageRun:
    """How one session runs its own simulation: checked, then here or in a worker."""

    def __init__(self, jobs: Any, kind: str = "run"):
        self.jobs = jobs
        #: The job kind its worker runs go under: a session has one job of each kind, so the
        #: pinned run (``"pin"``) and the live run do not cancel each other.
        self.kind = kind
        #: The run in a worker, if any (superseded by the next call of :meth:`run`).
        self.pending: Any = None
        self._token: object | None = None

    def cancel(self) -> None:
        """Drop the run in a worker (a newer change supersedes it)."""
        job, self.pending, self._token = self.pending, None, None
        if job is not None:
            job.cancel()

    def run(self, params: Any, kwargs: dict, on_done: Callable[[tuple], None],
            on_error: Callable[[str], None]) -> tuple | None:
        """``(trajectory, classification, ms)`` of a light run, computed now; None when the
        run went to a worker (then ``on_done`` or ``on_error`` is called later, in the page's
        document).  Raises ``ValueError`` over the budget or for bad input, ``SolverError``
        at the runaway limit."""
        self.cancel()
        with unlocked():
            units = work(params, kwargs)
        if units > BUDGET:
            raise ValueError(over_budget(params, kwargs, units))
        if units <= INLINE_WORK:
            with unlocked():
                return compute(params, kwargs)

        token = self._token = object()  # only the latest run may report

        def done(result: tuple) -> None:
            if self._token is token:
                self.pending = self._token = None
                on_done(result)

        def failed(message: str) -> None:
            if self._token is token:
                self.pending = self._token = None
                on_error(message)
        self.pending = self.jobs.submit(self.kind, compute, (params, kwargs), time_limit=TIME_LIMIT,
                                        on_done=done, on_error=failed)
        return None
