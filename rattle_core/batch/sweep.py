"""Bifurcation sweeps: one parameter over many values, in parallel, in cancellable chunks.

``sweep(base, name, values, ...)`` runs, for every value, ``transient`` periods unrecorded and
``record`` periods recorded, and returns a :class:`SweepResult`: a tidy impact table (value,
impulse, flank, phase) and a per-value summary (classification and rattle metrics).

* ``mode="fresh"``: every value starts from the same state (``x0``, ``v0`` at t = 0); the
  values run in chunks (:func:`~rattle_core.batch.chunks.run_chunk`, parallel across cores), so
  a caller sees progress between chunks and can cancel.
* ``mode="continuation"``: each value starts from the final state of the previous one, in the
  order given (pass descending values to sweep down); this follows one attractor and reveals
  coexisting ones.
* ``executor``: a ``dask.distributed.Client`` runs the chunks on a cluster instead
  (:func:`~rattle_core.batch.executor.run_chunks`).
"""
from __future__ import annotations

import dataclasses
import math
from typing import TYPE_CHECKING, Any, Callable, Sequence

import numpy as np

from ..analysis.vocabulary import STICKING_KINDS, regime_letters
from ..model.params import (RattleParams, check_cancel, check_progress, check_range, check_reals,
                            parse_name)
from ..solver import kernel as solver
from ..solver.trajectory import MAX_PERIODS, SOLVER_VERSION, _check_int
from .chunks import check_start, param_arrays, run_chunk, summary_arrays
from .executor import run_chunks

if TYPE_CHECKING:  # pandas is imported on first use: it costs a quarter second at start-up
    import pandas as pd

#: Largest number of values one sweep may hold.
MAX_VALUES = 1_000_000
#: Most forcing periods one sweep or map may run in all (values × (transient + record)).
#: Two cores run about 1.5e5 (chaotic) to 3.5e5 (periodic) periods a second: minutes, not hours.
PERIOD_BUDGET = 1e8
PERIOD_BUDGET_MINUTES = "5 to 10"
SCHEMA_VERSION = 2
SUMMARY_COLUMNS = ["value", "regime", "period", "n_active", "n_reverse", "active_per_period",
                   "reverse_per_period", "chaotic", "lyapunov", "stick_fraction", "intensity",
                   "sticking", "loop_amplification", "status"]


@dataclasses.dataclass
class SweepResult:
    """A bifurcation sweep: impacts per value and a summary per value.

    Attributes
    ----------
    name : str
        Swept parameter (``lam``, ``r``, ``j``, ``v_stick``, ``hK``, ``phiK``).
    values : ndarray
        Swept values, in the order run.
    params : RattleParams
        Base parameters (the swept one is overridden value by value).
    settings : dict
        transient, record, mode, x0, v0, solver and schema versions.
    table : DataFrame
        One row per recorded impact: value, impulse, flank, phase.
    summary : DataFrame
        One row per value: value, regime, period, n_active, n_reverse, active_per_period,
        reverse_per_period, chaotic, lyapunov, stick_fraction, intensity, sticking,
        loop_amplification, status.  Each value is one run of ``record`` periods: a periodic
        value's numbers are exact, a chaotic value's are one sample, whose 95 % half-width is
        about 2 × 3 % × √(4000/record) of the mean impulse and intensity (measured at the
        paper's Figure 7; docs/model.md, "What the statistics mean").  For intervals use
        :func:`~rattle_core.batch.ensemble.statistics` at the values that matter.
    cancelled : bool
        True when the caller cancelled; then only the values done are present.
    from_cache : bool
        True when the result was read from the disk cache (:mod:`rattle_core.store.cache`).
    """

    name: str
    values: np.ndarray
    params: RattleParams
    settings: dict
    table: pd.DataFrame
    summary: pd.DataFrame
    cancelled: bool = False
    from_cache: bool = False


def _summarise(chunk: dict, record: int) -> pd.DataFrame:
    import pandas as pd
    cl = summary_arrays(chunk, record)
    cols = dict(cl)
    cols["value"] = np.asarray(chunk["values"], dtype=np.float64)
    cols["regime"] = regime_letters(cl["regime_code"])
    cols["sticking"] = np.array(STICKING_KINDS, dtype=object)[cl["sticking"]]
    return pd.DataFrame({k: cols[k] for k in SUMMARY_COLUMNS})


def _table(chunk: dict) -> pd.DataFrame:
    import pandas as pd
    return pd.DataFrame({"value": np.repeat(chunk["values"], chunk["counts"]),
                         "impulse": chunk["impulse"], "flank": chunk["flank"],
                         "phase": chunk["phase"]})


def validate_sweep_args(name: str, values: Sequence[float], transient: int, record: int,
                        mode: str, columns: dict | None = None) -> tuple[np.ndarray, int, int]:
    """Check a sweep request; raises ``ValueError`` naming what is wrong.  With ``columns``
    (name → per-value values of the model), ``name`` only labels ``values``."""
    if columns is None:
        parse_name(name)
    elif not isinstance(name, str) or not name.isidentifier():
        raise ValueError(f"name = {name!r} must be a word labelling the values")
    vals = check_reals("values", values)
    if vals.size == 0:
        raise ValueError("values is empty; give at least one value to sweep")
    if vals.size > MAX_VALUES:
        raise ValueError(f"values has {vals.size} entries; the allowed range is 1 to {MAX_VALUES}")
    transient = _check_int("transient", transient, 0, MAX_PERIODS)
    record = _check_int("record", record, 1, 100_000)
    if mode not in ("fresh", "continuation"):
        raise ValueError(f"mode = {mode!r}; allowed: 'fresh' or 'continuation'")
    check_budget(vals.size * (transient + record), "values × (transient + record)")
    if columns is not None:
        if not columns:
            raise ValueError("columns is empty; give at least one parameter's values")
        for k, v in columns.items():
            parse_name(k)
            if np.shape(v) != vals.shape:
                raise ValueError(f"columns[{k!r}] has {np.size(v)} values but there are "
                                 f"{vals.size}; one per value")
    return vals, transient, record


def _rows(name: str, cols: dict, columns: dict | None, a: int, b: int) -> str | dict:
    """What :func:`run_chunk` takes for values ``a:b``: the swept name, or the columns' rows."""
    return name if columns is None else {k: v[a:b] for k, v in cols.items()}


def check_budget(periods: float, what: str) -> None:
    """Refuse a request of more forcing periods than :data:`PERIOD_BUDGET`, naming ``what``."""
    if periods > PERIOD_BUDGET:
        raise ValueError(f"{what} = {periods:.3g} forcing periods is over the budget of "
                         f"{PERIOD_BUDGET:.0e} per request (about {PERIOD_BUDGET_MINUTES} minutes "
                         "on two cores); ask for fewer values or periods, or split the request")


def sweep(base: RattleParams, name: str, values: Sequence[float], transient: int = 500,
          record: int = 200, mode: str = "fresh", x0: float | None = None, v0: float = 0.0,
          progress: Callable[[int, int], Any] | None = None,
          cancel: Callable[[], bool] | None = None, chunk_size: int | None = None,
          executor: Any = None, columns: dict | None = None) -> SweepResult:
    """Sweep parameter ``name`` over ``values``; record every impact after a transient.

    Parameters
    ----------
    base : RattleParams
        Parameters held fixed.
    name : str
        ``lam``, ``r``, ``j``, ``v_stick``, ``hK`` (amplitude ratio of harmonic K ≥ 2) or
        ``phiK`` (phase of harmonic K, degrees).
    values : sequence of float
        Values, run in this order (matters for ``continuation``).
    transient, record : int
        Unrecorded and recorded forcing periods per value.
    mode : {"fresh", "continuation"}
    x0, v0 : float
        Start state at t = 0 (``x0=None``: mid-backlash) for ``fresh``, and for the first value
        of ``continuation``.
    progress : callable(done, total), optional
        Called after each chunk.
    cancel : callable() -> bool, optional
        Polled between chunks; returning True stops the sweep (``result.cancelled``).
    chunk_size : int, optional
        Values per chunk (default: about 1/20 of the sweep, at least 16).
    executor : dask.distributed.Client, optional
        Run the chunks on this Dask cluster instead of locally.
    columns : dict, optional
        Several parameters at once: name → one value per swept value (for example ``lam``,
        ``j``, ``h2``, ``phi2`` of an engine-speed sweep whose harmonics follow a measurement,
        :meth:`~rattle_core.model.gearbox.Excitation.follow`); ``name`` then only labels
        ``values`` (``"rpm"``).

    Each value runs once, with ``base.noise`` (docs/model.md, "Noise").  Its noise stream
    derives from its own parameters and start state, so a value gives the same numbers in any
    chunk, on any number of threads, and as a :func:`simulate` call from the same start.  A
    chaotic value's statistics are then one run's: their spread over independent runs is
    what :func:`~rattle_core.batch.ensemble.statistics` measures (about 3 % (1 σ) in mean
    impulse for 4000 recorded periods at the paper's Figure 7; shorter windows scatter more,
    as 1/√record).
    """
    if not isinstance(base, RattleParams):
        raise ValueError(f"base must be a RattleParams, got {type(base).__name__}")
    progress = check_progress(progress)
    cancel = check_cancel(cancel)
    vals, transient, record = validate_sweep_args(name, values, transient, record, mode, columns)
    cols = {name: vals} if columns is None else {k: np.asarray(v, dtype=np.float64)
                                                 for k, v in columns.items()}
    param_arrays(base, cols)  # validates the range of the swept values
    x0 = check_start(base, cols, x0)
    v0 = check_range("v0", v0, -1e6, 1e6)
    nv = vals.size
    if chunk_size is None:
        chunk_size = max(16, math.ceil(nv / 20))
    chunk_size = _check_int("chunk_size", chunk_size, 1, MAX_VALUES)
    settings = {"transient": transient, "record": record, "mode": mode, "x0": x0, "v0": v0,
                "noise": base.noise, "solver_version": SOLVER_VERSION,
                "schema_version": SCHEMA_VERSION}
    chunks: list[dict] = []
    cancelled = False
    if mode == "continuation":
        x, v = x0, v0
        for i, val in enumerate(vals):
            if cancel is not None and cancel():
                cancelled = True
                break
            c = run_chunk(base, _rows(name, cols, columns, i, i + 1), vals[i:i + 1], transient,
                          record, x, v)
            chunks.append(c)
            x, v = float(c["final_x"][0]), float(c["final_v"][0])
            if progress is not None and ((i + 1) % chunk_size == 0 or i + 1 == nv):
                progress(i + 1, nv)
    else:
        starts = range(0, nv, chunk_size)
        tasks = [(base, _rows(name, cols, columns, s, s + chunk_size), vals[s:s + chunk_size],
                  transient, record, x0, v0, solver.MAX_IMPACTS_PER_PERIOD) for s in starts]
        chunks, cancelled = run_chunks(run_chunk, tasks, [len(t[2]) for t in tasks],
                                       executor=executor, progress=progress, cancel=cancel)
    import pandas as pd
    if chunks:
        table = pd.concat([_table(c) for c in chunks], ignore_index=True)
        summary = pd.concat([_summarise(c, record) for c in chunks], ignore_index=True)
        done_vals = np.concatenate([c["values"] for c in chunks])
    else:
        table = pd.DataFrame({"value": [], "impulse": [], "flank": np.empty(0, np.int8), "phase": []})
        summary = pd.DataFrame(columns=SUMMARY_COLUMNS)
        done_vals = np.empty(0)
    return SweepResult(name=name, values=done_vals, params=base, settings=settings, table=table,
                       summary=summary, cancelled=cancelled)

