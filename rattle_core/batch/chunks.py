"""The chunk runner: many runs of the compiled solver in one call, and their classification.

Sweeps and maps both hand their values to :func:`run_chunk` a chunk at a time (through
:func:`~rattle_core.batch.executor.run_chunks`, locally or as Dask tasks):

* every value gets its own parameter row (:func:`param_arrays` validates them all);
* the values run in parallel across cores in one ``numba.prange`` kernel, or on one thread when
  the chunk is a task on a Dask worker (the cluster already shares the cores out);
* :func:`summary_arrays` classifies a chunk in one compiled pass
  (:func:`~rattle_core.analysis.classify.classify_batch`), with the same numbers as classifying
  each value on its own.

Everything returned is plain arrays, so a chunk pickles cheaply to and from a Dask worker.
"""
from __future__ import annotations

import sys
import threading

import numba
import numpy as np
from numba import njit, prange

from ..analysis.classify import classify_batch
from ..analysis.vocabulary import REGIME_CODES
from ..model.excitation import excitation
from ..model.params import RattleParams, check_range, parse_name
from ..solver import kernel as solver
from ..solver.noise import _seed, user_seed

# Numba's workqueue threading layer aborts the whole process when two threads launch a parallel
# kernel at once (Dask worker threads, dashboard jobs); launches are therefore serialised.
_KERNEL_LOCK = threading.Lock()


@njit(cache=True, nogil=True)
def _sweep_one(i, lam, r, j, h, phi, vs, x0, v0, n_tr, n_rec, max_imp, cap,
               imp_t, imp_tau, imp_I, imp_flank, counts, status, str_x, str_v, lyap, stick,
               final_x, final_v, eps, seeds, rounding, loop_amp, kicks):
    imp_w = np.empty(cap)
    seg_t = np.empty(0)
    seg_k = np.empty(0, dtype=np.int8)
    seg_x = np.empty(0)
    seg_v = np.empty(0)
    # seed 0 asks for the stream derived from the inputs, as simulate(seed=None) does
    seed = seeds[i]
    if seed == 0:
        seed = _seed(lam[i], r[i], j[i], h[i], phi[i], vs[i], 0, 0.0, x0[i], v0[i], eps[i])
    out = solver._integrate(lam[i], r[i], j[i], h[i], phi[i], vs[i], 0, 0.0, x0[i], v0[i],
                            n_tr + n_rec, n_tr, 0.0, max_imp, True, eps[i], seed,
                            imp_t[i], imp_tau[i], imp_I[i], imp_w, imp_flank[i],
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
                  imp_t, imp_tau, imp_I, imp_flank, counts, status, str_x, str_v, lyap, stick,
                  final_x, final_v, eps, seeds, rounding, loop_amp, kicks):
    for i in prange(lam.shape[0]):
        _sweep_one(i, lam, r, j, h, phi, vs, x0, v0, n_tr, n_rec, max_imp, cap,
                   imp_t, imp_tau, imp_I, imp_flank, counts, status, str_x, str_v, lyap, stick,
                   final_x, final_v, eps, seeds, rounding, loop_amp, kicks)


# The same loop on one thread, for a chunk running as a Dask task: the cluster's workers
# already share the cores out, and a parallel kernel per task would put workers × cores
# threads on them.  It needs no launch lock either, so a worker's threads run side by side.
@njit(cache=True, nogil=True)
def _sweep_kernel_serial(lam, r, j, h, phi, vs, x0, v0, n_tr, n_rec, max_imp, cap,
                         imp_t, imp_tau, imp_I, imp_flank, counts, status, str_x, str_v, lyap,
                         stick, final_x, final_v, eps, seeds, rounding, loop_amp, kicks):
    for i in range(lam.shape[0]):
        _sweep_one(i, lam, r, j, h, phi, vs, x0, v0, n_tr, n_rec, max_imp, cap,
                   imp_t, imp_tau, imp_I, imp_flank, counts, status, str_x, str_v, lyap, stick,
                   final_x, final_v, eps, seeds, rounding, loop_amp, kicks)


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


def param_arrays(base: RattleParams, columns: dict[str, np.ndarray]):
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
            "v_stick": np.full(nv, base.v_stick), "noise": np.full(nv, base.noise)}
    for name, values in columns.items():
        kind, k = parse_name(name)
        if kind == "h":
            h[:, k - 1] = values
        elif kind == "phi":
            phi[:, k - 1] = np.deg2rad(values)
        else:
            cols[kind] = np.asarray(values, dtype=np.float64)
    return cols["lam"], cols["r"], cols["j"], h, phi, cols["v_stick"], cols["noise"]


def check_start(base: RattleParams, columns: dict[str, np.ndarray], x0) -> float | None:
    """A common start position ``x0`` at t = 0 checked against every value's backlash.

    ``x0`` must lie in ``[y(0), y(0) + j]`` for each value, as :func:`simulate` demands of a
    single run: a value outside is refused, not clipped.  Returns ``x0`` as a float (or None).
    """
    if x0 is None:
        return None
    x0 = check_range("x0", x0, -1e6, 1e6)
    _, _, j, h, phi, *_ = param_arrays(base, columns)
    y0 = np.sum(h * np.cos(phi), axis=1)  # y(0) = Σ h_k cos(−φ_k)
    bad = (x0 < y0 - 1e-12) | (x0 > y0 + j + 1e-12)
    if np.any(bad):
        i = int(np.argmax(bad))
        raise ValueError(f"x0 = {x0!r} is outside the backlash at t = 0, [{y0[i]:g}, "
                         f"{y0[i] + j[i]:g}], for the value at row {i}; every value must start "
                         "between its teeth")
    return x0


def run_chunk(base: RattleParams, name: str | dict, values: np.ndarray, transient: int,
               record: int, x0: float | np.ndarray | None, v0: float | np.ndarray,
              max_impacts_per_period: int = solver.MAX_IMPACTS_PER_PERIOD,
              seeds: np.ndarray | None = None, times: bool = False) -> dict:
    """Run one chunk of values in parallel; returns plain arrays (picklable, for Dask too).

    ``name`` is one swept name (``values`` its values) or a dict of name → per-value arrays
    (then ``values`` labels the rows).  ``x0``/``v0`` may be per-value arrays of absolute
    start states; positions are clipped into each value's backlash.  ``seeds`` (per-value
    ints, as ``simulate(seed=...)``) picks each row's noise stream; ``None`` derives every
    stream from its row's inputs.  With ``times`` the result also holds ``time``: each impact's
    dimensionless time from the start of the run (transient included), for a sound.
    """
    values = np.asarray(values, dtype=np.float64)
    columns = name if isinstance(name, dict) else {name: values}
    lam, r, j, h, phi, vs, eps = param_arrays(base, columns)
    nv = len(values)
    streams = np.zeros(nv, np.uint64)
    if seeds is not None:
        streams = np.array([user_seed(int(s)) for s in np.broadcast_to(seeds, (nv,))],
                           dtype=np.uint64)
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
        imp_t = np.empty((m, cap))
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
                imp_t, imp_tau, imp_I, imp_fl, counts, status, str_x, str_v, lyap, stick, fx, fv,
                eps[todo], streams[todo], rnd, lamp, kk)
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
            impacts[i] = (imp_I[a, :c].copy(), imp_fl[a, :c].copy(), imp_tau[a, :c].copy(),
                          imp_t[a, :c].copy() if times else None)
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
    if times:
        res["time"] = np.concatenate([imp[3] for imp in impacts]) if nv else np.empty(0)
    res["values"] = values
    res["j"] = j
    return res


def summary_arrays(chunk: dict, record: int, period_tol: float | None = None) -> dict:
    """Per-value classification of a chunk, as arrays (one compiled pass over all values).

    ``regime_code`` is the regime's code (:data:`~rattle_core.analysis.vocabulary.REGIME_CODES`):
    a run that did not finish (status ≠ 0) is ``"error"`` whatever its partial window looks like.
    ``period_tol`` overrides the classification's period tolerance.
    """
    extra = {} if period_tol is None else {"period_tol": period_tol}
    cl = classify_batch(chunk["counts"], chunk["impulse"], chunk["flank"], chunk["str_x"],
                        chunk["str_v"], record, chunk["stick"], chunk["lyap"], chunk["j"],
                        chunk.get("rounding"), chunk.get("loop_amp"), chunk.get("kicks"),
                        **extra)
    status = np.asarray(chunk["status"], dtype=np.int64)
    cl["regime_code"] = np.where(status == 0, cl["regime"], REGIME_CODES["error"]).astype(np.int8)
    cl["status"] = status
    return cl
