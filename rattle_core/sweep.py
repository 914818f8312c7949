"""Bifurcation sweeps: one parameter over many values, in parallel, in cancellable chunks.

``sweep(base, name, values, ...)`` runs, for every value, ``transient`` periods unrecorded and
``record`` periods recorded, and returns a :class:`SweepResult`: a tidy impact table (value,
impulse, flank, phase) and a per-value summary (classification and rattle metrics).

* ``mode="fresh"``: every value starts from the same state (``x0``, ``v0`` at t = 0); values
  run in parallel across cores (``numba.prange``) in chunks, so a caller sees progress between
  chunks and can cancel.
* ``mode="continuation"``: each value starts from the final state of the previous one, in the
  order given (pass descending values to sweep down); this follows one attractor and reveals
  coexisting ones.
* ``executor``: a ``dask.distributed.Client`` runs the chunks on a cluster instead; there each
  chunk runs on one thread, since the workers already share the cores.

Each chunk is classified in one compiled pass (:func:`~rattle_core.classify.classify_batch`),
with the same numbers as classifying each value on its own.
"""
from __future__ import annotations

import dataclasses
import math
import os
import sys
import threading
from typing import TYPE_CHECKING, Any, Callable, Sequence

import numba
import numpy as np
from numba import njit, prange

from . import solver
from .classify import REGIME_LETTERS, STICKING_KINDS, classify_batch
from .excitation import excitation
from .params import RattleParams, check_bool, check_range, parse_name
from .trajectory import MAX_PERIODS, SOLVER_VERSION, _check_int

if TYPE_CHECKING:  # pandas is imported on first use: it costs a quarter second at start-up
    import pandas as pd

#: Largest number of values one sweep may hold.
MAX_VALUES = 1_000_000
SCHEMA_VERSION = 2
# Numba's workqueue threading layer aborts the whole process when two threads launch a parallel
# kernel at once (Dask worker threads, dashboard jobs); launches are therefore serialised.
_KERNEL_LOCK = threading.Lock()


@njit(cache=True, nogil=True)
def _sweep_one(i, lam, r, j, h, phi, vs, x0, v0, n_tr, n_rec, max_imp, cap,
               imp_tau, imp_I, imp_flank, counts, status, str_x, str_v, lyap, stick,
               final_x, final_v, noise, rounding, loop_amp, kicks):
    imp_t = np.empty(cap)
    imp_w = np.empty(cap)
    seg_t = np.empty(0)
    seg_k = np.empty(0, dtype=np.int8)
    seg_x = np.empty(0)
    seg_v = np.empty(0)
    out = solver._integrate(lam[i], r[i], j[i], h[i], phi[i], vs[i], 0, 0.0, x0[i], v0[i],
                            n_tr + n_rec, n_tr, 0.0, max_imp, True, noise,
                            imp_t, imp_tau[i], imp_I[i], imp_w, imp_flank[i],
                            seg_t, seg_k, seg_x, seg_v, str_x[i], str_v[i])
    status[i] = out[0]
    counts[i] = out[1]
    final_x[i] = out[6]
    final_v[i] = out[7]
    lt = out[10]
    lyap[i] = out[9] / lt if lt > 0 else np.nan
    stick[i] = out[11]
    rounding[i] = out[13]
    loop_amp[i] = out[14]
    kicks[i] = out[15]


@njit(parallel=True, cache=True, nogil=True)
def _sweep_kernel(lam, r, j, h, phi, vs, x0, v0, n_tr, n_rec, max_imp, cap,
                  imp_tau, imp_I, imp_flank, counts, status, str_x, str_v, lyap, stick,
                  final_x, final_v, noise, rounding, loop_amp, kicks):
    for i in prange(lam.shape[0]):
        _sweep_one(i, lam, r, j, h, phi, vs, x0, v0, n_tr, n_rec, max_imp, cap,
                   imp_tau, imp_I, imp_flank, counts, status, str_x, str_v, lyap, stick,
                   final_x, final_v, noise, rounding, loop_amp, kicks)


# The same loop on one thread, for a chunk running as a Dask task: the cluster's workers
# already share the cores out, and a parallel kernel per task would put workers × cores
# threads on them.  It needs no launch lock either, so a worker's threads run side by side.
@njit(cache=True, nogil=True)
def _sweep_kernel_serial(lam, r, j, h, phi, vs, x0, v0, n_tr, n_rec, max_imp, cap,
                         imp_tau, imp_I, imp_flank, counts, status, str_x, str_v, lyap, stick,
                         final_x, final_v, noise, rounding, loop_amp, kicks):
    for i in range(lam.shape[0]):
        _sweep_one(i, lam, r, j, h, phi, vs, x0, v0, n_tr, n_rec, max_imp, cap,
                   imp_tau, imp_I, imp_flank, counts, status, str_x, str_v, lyap, stick,
                   final_x, final_v, noise, rounding, loop_amp, kicks)


def _in_dask_worker() -> bool:
    """True when called from a task on a Dask worker (distributed is then already imported)."""
    distributed = sys.modules.get("distributed")
    if distributed is None:
        return False
    try:
        distributed.get_worker()
    except ValueError:
        return False
    return True


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
        reverse_per_period, chaotic, lyapunov, stick_fraction, intensity, status.
    cancelled : bool
        True when the caller cancelled; then only the values done are present.
    """

    name: str
    values: np.ndarray
    params: RattleParams
    settings: dict
    table: pd.DataFrame
    summary: pd.DataFrame
    cancelled: bool = False


def _param_arrays(base: RattleParams, columns: dict[str, np.ndarray]):
    """Per-value parameter arrays for one or more swept names; validates every value range."""
    nv = len(next(iter(columns.values())))
    kmax = base.n_harmonics
    for name in columns:
        kind, k = parse_name(name)
        kmax = max(kmax, k)
    for name, values in columns.items():
        # every check is a range check, so the extreme values settle the whole column
        for v in (float(np.min(values)), float(np.max(values))):
            base.with_value(name, v)
    h = np.zeros((nv, kmax))
    phi = np.zeros((nv, kmax))
    h[:, :base.n_harmonics] = base.h
    phi[:, :base.n_harmonics] = base.phi
    cols = {"lam": np.full(nv, base.lam), "r": np.full(nv, base.r), "j": np.full(nv, base.j),
            "v_stick": np.full(nv, base.v_stick)}
    for name, values in columns.items():
        kind, k = parse_name(name)
        if kind == "h":
            h[:, k - 1] = values
        elif kind == "phi":
            phi[:, k - 1] = np.deg2rad(values)
        else:
            cols[kind] = np.asarray(values, dtype=np.float64)
    return cols["lam"], cols["r"], cols["j"], h, phi, cols["v_stick"]


def _run_chunk(base: RattleParams, name: str | dict, values: np.ndarray, transient: int,
               record: int, x0: float | np.ndarray | None, v0: float | np.ndarray,
               max_impacts_per_period: int = solver.MAX_IMPACTS_PER_PERIOD,
               noise: bool = True) -> dict:
    """Run one chunk of values in parallel; returns plain arrays (picklable, for Dask too).

    ``name`` is one swept name (``values`` its values) or a dict of name → per-value arrays
    (then ``values`` labels the rows).  ``x0``/``v0`` may be per-value arrays of absolute
    start states; positions are clipped into each value's backlash.
    """
    values = np.asarray(values, dtype=np.float64)
    columns = name if isinstance(name, dict) else {name: values}
    lam, r, j, h, phi, vs = _param_arrays(base, columns)
    nv = len(values)
    # a grid repeats each excitation many times: evaluate y(0) once per distinct one
    hp, inverse = np.unique(np.hstack([h, phi]), axis=0, return_inverse=True)
    kh = h.shape[1]
    y0 = np.array([float(excitation(0.0, row[:kh], row[kh:])) for row in hp])[inverse.ravel()]
    if x0 is None:
        xs = y0 + 0.5 * j
    else:
        xs = np.clip(np.broadcast_to(np.asarray(x0, dtype=np.float64), (nv,)), y0, y0 + j)
    vs0 = np.broadcast_to(np.asarray(v0, dtype=np.float64), (nv,)).copy()
    cap = 8 * record + 64
    on_worker = _in_dask_worker()
    todo = np.arange(nv)
    if not on_worker:
        # the parallel kernel hands each thread one contiguous block of values; neighbouring
        # values cost alike, so dealing them out in turn evens out the threads' shares
        nt = numba.get_num_threads()
        todo = np.concatenate([todo[t::nt] for t in range(nt)])
    res = {"counts": np.zeros(nv, np.int64), "status": np.zeros(nv, np.int64),
           "lyap": np.full(nv, np.nan), "stick": np.zeros(nv), "final_x": np.zeros(nv),
           "final_v": np.zeros(nv), "str_x": np.zeros((nv, record)), "str_v": np.zeros((nv, record)),
           "rounding": np.zeros(nv, np.bool_), "loop_amp": np.full(nv, -np.inf),
           "kicks": np.zeros(nv, np.int64)}
    impacts: list = [None] * nv
    while len(todo):
        m = len(todo)
        imp_tau = np.empty((m, cap))
        imp_I = np.empty((m, cap))
        imp_fl = np.empty((m, cap), dtype=np.int8)
        counts = np.zeros(m, np.int64)
        status = np.zeros(m, np.int64)
        str_x = np.zeros((m, record))
        str_v = np.zeros((m, record))
        lyap = np.zeros(m)
        stick = np.zeros(m)
        fx = np.zeros(m)
        fv = np.zeros(m)
        rnd = np.zeros(m, np.bool_)
        lamp = np.zeros(m)
        kk = np.zeros(m, np.int64)
        args = (lam[todo], r[todo], j[todo], np.ascontiguousarray(h[todo]),
                np.ascontiguousarray(phi[todo]), vs[todo], np.ascontiguousarray(xs[todo]),
                vs0[todo], transient, record, max_impacts_per_period, cap,
                imp_tau, imp_I, imp_fl, counts, status, str_x, str_v, lyap, stick, fx, fv,
                bool(noise), rnd, lamp, kk)
        if on_worker:
            _sweep_kernel_serial(*args)
        else:
            with _KERNEL_LOCK:
                _sweep_kernel(*args)
        again = []
        for a, i in enumerate(todo):
            if status[a] == solver.OVERFLOW_IMPACTS:
                again.append(i)
                continue
            c = counts[a]
            impacts[i] = (imp_I[a, :c].copy(), imp_fl[a, :c].copy(), imp_tau[a, :c].copy())
            res["counts"][i] = c
            res["status"][i] = status[a]
            res["lyap"][i] = lyap[a]
            res["stick"][i] = stick[a]
            res["final_x"][i] = fx[a]
            res["final_v"][i] = fv[a]
            res["str_x"][i] = str_x[a]
            res["str_v"][i] = str_v[a]
            res["rounding"][i] = rnd[a]
            res["loop_amp"][i] = lamp[a] / np.log(10.0)
            res["kicks"][i] = kk[a]
        todo = np.array(again, dtype=np.int64)
        cap *= 8
    res["impulse"] = np.concatenate([imp[0] for imp in impacts]) if nv else np.empty(0)
    res["flank"] = np.concatenate([imp[1] for imp in impacts]) if nv else np.empty(0, np.int8)
    res["phase"] = np.concatenate([imp[2] for imp in impacts]) if nv else np.empty(0)
    res["values"] = values
    res["j"] = j
    return res


#: Regime letters of the summary, indexed by :func:`_summary_arrays`' ``regime_code``.
REGIME_ORDER = REGIME_LETTERS + ("error",)
_REGIME_OBJ = np.array(REGIME_ORDER, dtype=object)
SUMMARY_COLUMNS = ["value", "regime", "period", "n_active", "n_reverse", "active_per_period",
                   "reverse_per_period", "chaotic", "lyapunov", "stick_fraction", "intensity",
                   "sticking", "loop_amplification", "status"]
_STICKING_OBJ = np.array(STICKING_KINDS, dtype=object)


def _summary_arrays(chunk: dict, record: int) -> dict:
    """Per-value classification of a chunk, as arrays (one compiled pass over all values).

    ``regime_code`` indexes :data:`REGIME_ORDER`: a run that did not finish (status ≠ 0) is
    ``"error"`` whatever its partial window looks like.
    """
    cl = classify_batch(chunk["counts"], chunk["impulse"], chunk["flank"], chunk["str_x"],
                        chunk["str_v"], record, chunk["stick"], chunk["lyap"], chunk["j"],
                        chunk.get("rounding"), chunk.get("loop_amp"), chunk.get("kicks"))
    status = np.asarray(chunk["status"], dtype=np.int64)
    cl["regime_code"] = np.where(status == 0, cl["regime"], len(REGIME_ORDER) - 1).astype(np.int8)
    cl["status"] = status
    return cl


def _summarise(chunk: dict, record: int) -> pd.DataFrame:
    import pandas as pd
    cl = _summary_arrays(chunk, record)
    cols = dict(cl)
    cols["value"] = np.asarray(chunk["values"], dtype=np.float64)
    cols["regime"] = _REGIME_OBJ[cl["regime_code"]]
    cols["sticking"] = _STICKING_OBJ[cl["sticking"]]
    return pd.DataFrame({k: cols[k] for k in SUMMARY_COLUMNS})


def _table(chunk: dict) -> pd.DataFrame:
    import pandas as pd
    return pd.DataFrame({"value": np.repeat(chunk["values"], chunk["counts"]),
                         "impulse": chunk["impulse"], "flank": chunk["flank"],
                         "phase": chunk["phase"]})


def validate_sweep_args(name: str, values: Sequence[float], transient: int, record: int,
                        mode: str) -> tuple[np.ndarray, int, int]:
    """Check a sweep request; raises ``ValueError`` naming what is wrong."""
    parse_name(name)
    try:
        vals = np.asarray(values, dtype=np.float64).ravel()
    except (TypeError, ValueError):
        raise ValueError(f"values must be numbers, got {values!r}") from None
    if vals.size == 0:
        raise ValueError("values is empty; give at least one value to sweep")
    if vals.size > MAX_VALUES:
        raise ValueError(f"values has {vals.size} entries; the allowed range is 1 to {MAX_VALUES}")
    if not np.all(np.isfinite(vals)):
        bad = vals[~np.isfinite(vals)][0]
        raise ValueError(f"values must all be finite, got {bad!r}")
    transient = _check_int("transient", transient, 0, MAX_PERIODS)
    record = _check_int("record", record, 1, 100_000)
    if mode not in ("fresh", "continuation"):
        raise ValueError(f"mode = {mode!r}; allowed: 'fresh' or 'continuation'")
    if vals.size * (transient + record) > 5e9:
        raise ValueError(f"values × (transient + record) = {vals.size * (transient + record):.3g} "
                         "periods; the allowed range is up to 5e9")
    return vals, transient, record


def sweep(base: RattleParams, name: str, values: Sequence[float], transient: int = 500,
          record: int = 200, mode: str = "fresh", x0: float | None = None, v0: float = 0.0,
          progress: Callable[[int, int], Any] | None = None,
          cancel: Callable[[], bool] | None = None, chunk_size: int | None = None,
          executor: Any = None, noise: bool = True) -> SweepResult:
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
    noise : bool
        The attractor under vanishing noise (default) or the strict model; see
        :func:`~rattle_core.trajectory.simulate`.  Each value's seed derives from its own
        parameters and start state, so a value gives the same numbers in any chunk, on any
        number of threads, and as a :func:`simulate` call from the same start.
    """
    if not isinstance(base, RattleParams):
        raise ValueError(f"base must be a RattleParams, got {type(base).__name__}")
    vals, transient, record = validate_sweep_args(name, values, transient, record, mode)
    _param_arrays(base, {name: vals})  # validates the range of the swept values
    if x0 is not None:
        x0 = check_range("x0", x0, -1e6, 1e6)
    v0 = check_range("v0", v0, -1e6, 1e6)
    nv = vals.size
    if chunk_size is None:
        chunk_size = max(16, math.ceil(nv / 20))
    chunk_size = _check_int("chunk_size", chunk_size, 1, MAX_VALUES)
    noise = check_bool("noise", noise)
    settings = {"transient": transient, "record": record, "mode": mode, "x0": x0, "v0": v0,
                "noise": noise, "solver_version": SOLVER_VERSION,
                "schema_version": SCHEMA_VERSION}
    chunks: list[dict] = []
    cancelled = False
    if mode == "continuation":
        x, v = x0, v0
        for i, val in enumerate(vals):
            if cancel is not None and cancel():
                cancelled = True
                break
            c = _run_chunk(base, name, vals[i:i + 1], transient, record, x, v, noise=noise)
            chunks.append(c)
            x, v = float(c["final_x"][0]), float(c["final_v"][0])
            if progress is not None and ((i + 1) % chunk_size == 0 or i + 1 == nv):
                progress(i + 1, nv)
    elif executor is not None:
        futures = [executor.submit(_run_chunk, base, name, vals[s:s + chunk_size], transient,
                                   record, x0, v0, noise=noise, pure=False)
                   for s in range(0, nv, chunk_size)]
        from dask.distributed import as_completed
        done = 0
        for fut in as_completed(futures):
            if cancel is not None and cancel():
                for f in futures:
                    f.cancel()
                cancelled = True
                break
            done += 1
            if progress is not None:
                progress(min(done * chunk_size, nv), nv)
        if not cancelled:
            chunks = [f.result() for f in futures]
    else:
        for s in range(0, nv, chunk_size):
            if cancel is not None and cancel():
                cancelled = True
                break
            chunks.append(_run_chunk(base, name, vals[s:s + chunk_size], transient, record, x0, v0,
                                     noise=noise))
            if progress is not None:
                progress(min(s + chunk_size, nv), nv)
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


def default_threads() -> int:
    """Threads numba uses for sweeps (``NUMBA_NUM_THREADS`` or the core count)."""
    return int(os.environ.get("NUMBA_NUM_THREADS", os.cpu_count() or 1))
