"""2-D maps: regimes and rattle intensity over two parameters, and basins of attraction.

* :func:`regime_map` runs every point of a grid over two parameters (``lam × phi2``,
  ``lam × h2``, ...) and classifies it (``classify``): regime, period, Lyapunov exponent,
  impacts per period, stick fraction and rattle intensity, each as a 2-D array.
* :func:`basin_map` fixes the parameters and runs a grid of initial states ``(x0, ẋ0)`` at
  t = 0; each point is coloured by the attractor it reaches.  Attractors are told apart by
  their regime and a fingerprint of their stroboscopic section (the periodic orbit's smallest
  section point, rounded), so two coexisting period-1 orbits get two colours.

The grid is flattened into per-point parameter arrays and run in chunks through the sweep
kernel: in parallel on local cores, or on a Dask cluster when ``executor`` is a
``dask.distributed.Client`` (results are identical, point for point).  Physical sweeps
(engine speed, drag torque) map onto these names through :mod:`rattle_core.units`.
"""
from __future__ import annotations

import dataclasses
import math
from typing import Any, Callable

import numpy as np
import pandas as pd

from .classify import MAX_PERIOD, detect_period
from .excitation import excitation
from .params import RattleParams, check_range, parse_name
from .sweep import SCHEMA_VERSION, _run_chunk, _summarise
from .trajectory import MAX_PERIODS, SOLVER_VERSION, _check_int

#: Regime letters and their integer codes in map arrays.
REGIME_CODES = {"A": 0, "B": 1, "C": 2, "D": 3, "E": 4, "P": 5, "Q": 6, "error": 7}
MAX_GRID = 4_000_000


@dataclasses.dataclass
class MapResult:
    """A 2-D map. Arrays have shape ``(len(y_values), len(x_values))`` (rows follow y).

    ``fields`` holds ``regime`` (codes of :data:`REGIME_CODES`), ``period``, ``lyapunov``,
    ``active_per_period``, ``reverse_per_period``, ``stick_fraction``, ``intensity``, and for
    basins ``attractor`` (index into ``attractors``).  Points not run (cancelled) are NaN or −1.
    """

    kind: str
    x_name: str
    y_name: str
    x_values: np.ndarray
    y_values: np.ndarray
    params: RattleParams
    settings: dict
    fields: dict
    attractors: list = dataclasses.field(default_factory=list)
    cancelled: bool = False


def _grid_args(name: str, values, label: str) -> np.ndarray:
    try:
        vals = np.asarray(values, dtype=np.float64).ravel()
    except (TypeError, ValueError):
        raise ValueError(f"{label} must be numbers, got {values!r}") from None
    if vals.size == 0:
        raise ValueError(f"{label} is empty; give at least one value")
    if not np.all(np.isfinite(vals)):
        raise ValueError(f"{label} must all be finite, got {vals[~np.isfinite(vals)][0]!r}")
    return vals


def _check_size(nx: int, ny: int, transient: int, record: int) -> tuple[int, int]:
    transient = _check_int("transient", transient, 0, MAX_PERIODS)
    record = _check_int("record", record, 1, 100_000)
    if nx * ny > MAX_GRID:
        raise ValueError(f"the grid has {nx}×{ny} = {nx * ny} points; the allowed range is "
                         f"up to {MAX_GRID}")
    if nx * ny * (transient + record) > 5e10:
        raise ValueError(f"points × (transient + record) = {nx * ny * (transient + record):.3g} "
                         "periods; the allowed range is up to 5e10")
    return transient, record


def _run_grid(base: RattleParams, columns: dict, x0: np.ndarray | float | None,
              v0: np.ndarray | float, transient: int, record: int, progress, cancel,
              executor, chunk_size: int | None) -> tuple[list, bool]:
    n = len(next(iter(columns.values())))
    if chunk_size is None:
        chunk_size = max(64, math.ceil(n / 40))
    idx = np.arange(n, dtype=np.float64)

    def part(a, s):
        return a[s:s + chunk_size] if isinstance(a, np.ndarray) else a

    starts = list(range(0, n, chunk_size))
    args = [({k: v[s:s + chunk_size] for k, v in columns.items()}, idx[s:s + chunk_size],
             part(x0, s), part(v0, s)) for s in starts]
    results: list = []
    cancelled = False
    if executor is not None:
        from dask.distributed import as_completed
        futures = [executor.submit(_run_chunk, base, cols, rows, transient, record, xs, vs,
                                   pure=False) for cols, rows, xs, vs in args]
        done = 0
        for _ in as_completed(futures):
            if cancel is not None and cancel():
                for f in futures:
                    f.cancel()
                return [], True
            done += 1
            if progress is not None:
                progress(min(done * chunk_size, n), n)
        results = [f.result() for f in futures]
    else:
        for cols, rows, xs, vs in args:
            if cancel is not None and cancel():
                cancelled = True
                break
            results.append(_run_chunk(base, cols, rows, transient, record, xs, vs))
            if progress is not None:
                progress(min(int(rows[-1]) + 1, n), n)
    return results, cancelled


def _fields(results: list, record: int, n: int) -> tuple[dict, pd.DataFrame]:
    keys = ["period", "lyapunov", "active_per_period", "reverse_per_period", "stick_fraction",
            "intensity"]
    out = {k: np.full(n, np.nan) for k in keys}
    out["regime"] = np.full(n, -1, dtype=np.int8)
    frames = []
    for c in results:
        summ = _summarise(c, record)
        rows = c["values"].astype(np.int64)
        for k in keys:
            out[k][rows] = summ[k].to_numpy(dtype=np.float64)
        out["regime"][rows] = summ["regime"].map(REGIME_CODES).to_numpy(dtype=np.int8)
        summ["row"] = rows
        frames.append(summ)
    return out, (pd.concat(frames, ignore_index=True) if frames else pd.DataFrame())


def regime_map(base: RattleParams, x_name: str, x_values, y_name: str, y_values,
               transient: int = 300, record: int = 100, x0: float | None = None, v0: float = 0.0,
               progress: Callable[[int, int], Any] | None = None,
               cancel: Callable[[], bool] | None = None, executor: Any = None,
               chunk_size: int | None = None) -> MapResult:
    """Regime and rattle-intensity map over two parameters.

    Parameters
    ----------
    base : RattleParams
        Parameters held fixed.
    x_name, y_name : str
        Swept names (``lam``, ``r``, ``j``, ``v_stick``, ``hK``, ``phiK``); must differ.
    x_values, y_values : sequence of float
    transient, record : int
        Unrecorded and recorded periods per point.
    x0, v0 : float
        Common start state at t = 0 (``x0=None``: mid-backlash).
    progress, cancel, executor, chunk_size
        As for :func:`~rattle_core.sweep.sweep`.
    """
    parse_name(x_name)
    parse_name(y_name)
    if x_name == y_name:
        raise ValueError(f"x_name and y_name must differ, both are {x_name!r}")
    xv = _grid_args(x_name, x_values, "x_values")
    yv = _grid_args(y_name, y_values, "y_values")
    transient, record = _check_size(len(xv), len(yv), transient, record)
    if x0 is not None:
        x0 = check_range("x0", x0, -1e6, 1e6)
    v0 = check_range("v0", v0, -1e6, 1e6)
    gx, gy = np.meshgrid(xv, yv)
    columns = {x_name: gx.ravel(), y_name: gy.ravel()}
    results, cancelled = _run_grid(base, columns, x0, v0, transient, record, progress, cancel,
                                   executor, chunk_size)
    flat, _ = _fields(results, record, gx.size)
    fields = {k: v.reshape(gx.shape) for k, v in flat.items()}
    settings = {"transient": transient, "record": record, "x0": x0, "v0": v0,
                "solver_version": SOLVER_VERSION, "schema_version": SCHEMA_VERSION}
    return MapResult(kind="regime", x_name=x_name, y_name=y_name, x_values=xv, y_values=yv,
                     params=base, settings=settings, fields=fields, cancelled=cancelled)


def _fingerprint(sx: np.ndarray, sv: np.ndarray, period: int, regime: str, decimals: int) -> tuple:
    if regime in ("A", "D", "Q", "error") or period <= 0:
        return (regime,)
    last_x = sx[-period:]
    last_v = sv[-period:]
    k = int(np.lexsort((last_v, last_x))[0])
    return (regime, period, round(float(last_x[k]), decimals), round(float(last_v[k]), decimals))


def basin_map(params: RattleParams, x0_values, v0_values, transient: int = 300,
              record: int = 64, progress: Callable[[int, int], Any] | None = None,
              cancel: Callable[[], bool] | None = None, executor: Any = None,
              chunk_size: int | None = None, decimals: int = 4) -> MapResult:
    """Basins of attraction over initial states ``(x0, ẋ0)`` at t = 0.

    ``x0_values`` are absolute positions in ``[y(0), y(0) + j]``.  The ``attractor`` field
    indexes :attr:`MapResult.attractors`, a list of dicts (regime, period, a section point,
    share of the grid), most common first.
    """
    if not isinstance(params, RattleParams):
        raise ValueError(f"params must be a RattleParams, got {type(params).__name__}")
    xv = _grid_args("x0", x0_values, "x0_values")
    vv = _grid_args("v0", v0_values, "v0_values")
    y0 = float(excitation(0.0, params.h, params.phi))
    lo, hi = y0, y0 + params.j
    if xv.min() < lo - 1e-12 or xv.max() > hi + 1e-12:
        raise ValueError(f"x0_values must lie in the backlash at t = 0, [{lo:g}, {hi:g}]; got "
                         f"[{xv.min():g}, {xv.max():g}]")
    if np.max(np.abs(vv)) > 1e6:
        raise ValueError("v0_values must lie in [-1e6, 1e6]")
    transient, record = _check_size(len(xv), len(vv), transient, record)
    record = max(record, 2 * MAX_PERIOD + 2)
    gx, gv = np.meshgrid(xv, vv)
    n = gx.size
    columns = {"lam": np.full(n, params.lam)}
    results, cancelled = _run_grid(params, columns, np.clip(gx.ravel(), lo, hi), gv.ravel(),
                                   transient, record, progress, cancel, executor, chunk_size)
    flat, summ = _fields(results, record, n)
    labels = np.full(n, -1, dtype=np.int32)
    keys: dict = {}
    codes = {c: k for k, c in REGIME_CODES.items()}
    for c in results:
        rows = c["values"].astype(np.int64)
        for a, row in enumerate(rows):
            reg = codes[int(flat["regime"][row])]
            per = detect_period(c["str_x"][a], c["str_v"][a], params.j)
            fp = _fingerprint(c["str_x"][a], c["str_v"][a], per, reg, decimals)
            labels[row] = keys.setdefault(fp, len(keys))
    counts = np.bincount(labels[labels >= 0], minlength=len(keys))
    order = np.argsort(-counts, kind="stable")
    remap = np.full(len(keys), -1, dtype=np.int32)
    remap[order] = np.arange(len(keys))
    labels = np.where(labels >= 0, remap[np.maximum(labels, 0)], -1)
    inv = {v: k for k, v in keys.items()}
    attractors = []
    for new, old in enumerate(order):
        fp = inv[int(old)]
        attractors.append({"regime": fp[0], "period": fp[1] if len(fp) > 1 else 0,
                           "section_point": fp[2:] if len(fp) > 2 else (),
                           "share": float(counts[old] / max(1, (labels >= 0).sum()))})
    fields = {k: v.reshape(gx.shape) for k, v in flat.items()}
    fields["attractor"] = labels.reshape(gx.shape)
    settings = {"transient": transient, "record": record, "solver_version": SOLVER_VERSION,
                "schema_version": SCHEMA_VERSION}
    return MapResult(kind="basin", x_name="x0", y_name="v0", x_values=xv, y_values=vv,
                     params=params, settings=settings, fields=fields, attractors=attractors,
                     cancelled=cancelled)
