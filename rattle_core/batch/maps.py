"""2-D maps: regimes and rattle intensity over two parameters, and basins of attraction.

* :func:`regime_map` runs every point of a grid over two parameters (``lam × phi2``,
  ``lam × h2``, ...) and classifies it (``classify``): regime, period, Lyapunov exponent,
  impacts per period, stick fraction and rattle intensity, each as a 2-D array.
* :func:`basin_map` fixes the parameters and runs a grid of initial states ``(x0, ẋ0)`` at
  t = 0; each point is coloured by the attractor it reaches.  Attractors are told apart by
  their regime and a fingerprint of their stroboscopic section (the periodic orbit's smallest
  section point, rounded), so two coexisting period-1 orbits get two colours.

Maps over physical axes are planned in :mod:`rattle_core.batch.plan`, and served from the disk
cache by :func:`rattle_core.store.requests.run_map`.

The grid is flattened into per-point parameter arrays and run in chunks
(:func:`~rattle_core.batch.chunks.run_chunk` through
:func:`~rattle_core.batch.executor.run_chunks`): in parallel on local cores, or on a Dask
cluster when ``executor`` is a ``dask.distributed.Client`` (results are identical, point for
point).  Each chunk is classified
where it runs and reduced to what the map keeps of a point (its fields and, for basins, its
attractor fingerprint), so a Dask task sends back a few numbers per point, not its impacts.
"""
from __future__ import annotations

import dataclasses
import math
from typing import Any, Callable

import numpy as np

from ..analysis.classify import MAX_PERIOD, detect_period
from ..analysis.vocabulary import LETTERS, regime_letters
from ..model.excitation import excitation
from ..model.params import (RattleParams, check_cancel, check_int, check_progress, check_range,
                            check_reals, parse_name)
from ..solver.trajectory import MAX_PERIODS, SOLVER_VERSION, _check_int
from .chunks import check_start, run_chunk, summary_arrays
from .executor import run_chunks
from .sweep import SCHEMA_VERSION, check_budget

MAX_GRID = 4_000_000


@dataclasses.dataclass
class MapResult:
    """A 2-D map. Arrays have shape ``(len(y_values), len(x_values))`` (rows follow y).

    ``fields`` holds ``regime`` (codes of :data:`~rattle_core.analysis.vocabulary.REGIME_CODES`), ``period``, ``lyapunov``,
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
    #: The map was read from the disk cache (:mod:`rattle_core.store.cache`), not computed.
    from_cache: bool = False

    def table(self):
        """One row per grid point (a DataFrame): the two axes, then every field (regime as its
        letter)."""
        import pandas as pd
        gx, gy = np.meshgrid(self.x_values, self.y_values)
        df = pd.DataFrame({self.x_name: gx.ravel(), self.y_name: gy.ravel()})
        for k in sorted(self.fields, key=lambda k: (k != "regime", k != "attractor")):
            v = self.fields[k]
            df[k] = regime_letters(v.ravel()) if k == "regime" else v.ravel()
        return df


def _grid_args(name: str, values, label: str) -> np.ndarray:
    vals = check_reals(label, values)
    if vals.size == 0:
        raise ValueError(f"{label} is empty; give at least one value")
    return vals


def check_basin_axes(params: RattleParams, x0_values, v0_values,
                     labels: tuple[str, str] = ("x0_values", "v0_values")) -> tuple:
    """The start states of a basin map, checked: ``(x0 values, v0 values, y(0), y(0) + j)``.

    Every ``x0`` must lie in the backlash at t = 0, ``[y(0), y(0) + j]``, and every ``v0`` in
    ``[-1e6, 1e6]``; ``labels`` say how messages name the two axes.
    """
    xv = _grid_args("x0", x0_values, labels[0])
    vv = _grid_args("v0", v0_values, labels[1])
    y0 = float(excitation(0.0, params.h, params.phi))
    lo, hi = y0, y0 + params.j
    if xv.min() < lo - 1e-12 or xv.max() > hi + 1e-12:
        raise ValueError(f"{labels[0]} must lie in the backlash at t = 0, [{lo:g}, {hi:g}]; got "
                         f"[{xv.min():g}, {xv.max():g}]")
    if np.max(np.abs(vv)) > 1e6:
        raise ValueError(f"{labels[1]} must lie in [-1e6, 1e6]; got [{vv.min():g}, {vv.max():g}]")
    return xv, vv, lo, hi


def _check_size(nx: int, ny: int, transient: int, record: int) -> tuple[int, int]:
    transient = _check_int("transient", transient, 0, MAX_PERIODS)
    record = _check_int("record", record, 1, 100_000)
    if nx * ny > MAX_GRID:
        raise ValueError(f"the grid has {nx}×{ny} = {nx * ny} points; the allowed range is "
                         f"up to {MAX_GRID}")
    check_budget(nx * ny * (transient + record), "points × (transient + record)")
    return transient, record


#: Per-point fields of a regime map besides ``regime``, as floats (NaN where not run).
_FLOAT_FIELDS = ("period", "lyapunov", "active_per_period", "reverse_per_period",
                 "stick_fraction", "intensity")


def _map_chunk(base: RattleParams, columns: dict, rows: np.ndarray, transient: int,
               record: int, x0: np.ndarray | float | None, v0: np.ndarray | float,
               decimals: int | None = None) -> dict:
    """Run one chunk of grid points and reduce it to what a map keeps of each point.

    Returns ``rows`` (the points' flat indices), ``regime`` (regime codes),
    the :data:`_FLOAT_FIELDS` and, when ``decimals`` is given (basins), ``fingerprint``: each
    point's attractor fingerprint.  On a Dask cluster this is the task itself, so a few numbers
    per point travel back instead of every impact and stroboscopic sample.
    """
    chunk = run_chunk(base, columns, rows, transient, record, x0, v0)
    cl = summary_arrays(chunk, record)
    out = {"rows": np.asarray(rows, dtype=np.int64), "regime": cl["regime_code"]}
    for k in _FLOAT_FIELDS:
        out[k] = np.asarray(cl[k], dtype=np.float64)
    if decimals is not None:
        out["fingerprint"] = [
            _fingerprint(sx, sv, detect_period(sx, sv, base.j), LETTERS[code], decimals)
            for sx, sv, code in zip(chunk["str_x"], chunk["str_v"], cl["regime_code"])]
    return out


def _run_grid(base: RattleParams, columns: dict, x0: np.ndarray | float | None,
              v0: np.ndarray | float, transient: int, record: int, progress, cancel,
              executor, chunk_size: int | None, decimals: int | None = None
              ) -> tuple[list, bool]:
    """Run the grid in chunks (:func:`_map_chunk`); returns the chunks done, in grid order.

    ``cancel`` is polled and ``progress`` called each time a chunk is done; once cancelled,
    the chunks already done are kept, and on Dask the others are cancelled.
    """
    n = len(next(iter(columns.values())))
    if chunk_size is None:
        chunk_size = max(64, math.ceil(n / 40))
    chunk_size = _check_int("chunk_size", chunk_size, 1, MAX_GRID)
    idx = np.arange(n, dtype=np.float64)

    def part(a, s):
        return a[s:s + chunk_size] if isinstance(a, np.ndarray) else a

    tasks = [(base, {k: v[s:s + chunk_size] for k, v in columns.items()}, idx[s:s + chunk_size],
              transient, record, part(x0, s), part(v0, s), decimals) for s in range(0, n, chunk_size)]
    return run_chunks(_map_chunk, tasks, [len(t[2]) for t in tasks], executor=executor,
                      progress=progress, cancel=cancel)


def _fields(parts: list, n: int) -> dict:
    """The flat per-point fields of a map from its chunks; points not run are NaN or -1."""
    out = {k: np.full(n, np.nan) for k in _FLOAT_FIELDS}
    out["regime"] = np.full(n, -1, dtype=np.int8)
    for p in parts:
        for k in out:
            out[k][p["rows"]] = p[k]
    return out


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
        As for :func:`~rattle_core.batch.sweep.sweep`.
    """
    if not isinstance(base, RattleParams):
        raise ValueError(f"base must be a RattleParams, got {type(base).__name__}")
    progress = check_progress(progress)
    cancel = check_cancel(cancel)
    parse_name(x_name)
    parse_name(y_name)
    if x_name == y_name:
        raise ValueError(f"x_name and y_name must differ, both are {x_name!r}")
    xv = _grid_args(x_name, x_values, "x_values")
    yv = _grid_args(y_name, y_values, "y_values")
    transient, record = _check_size(len(xv), len(yv), transient, record)
    gx, gy = np.meshgrid(xv, yv)
    x0 = check_start(base, {x_name: gx.ravel(), y_name: gy.ravel()}, x0)
    v0 = check_range("v0", v0, -1e6, 1e6)
    columns = {x_name: gx.ravel(), y_name: gy.ravel()}
    results, cancelled = _run_grid(base, columns, x0, v0, transient, record, progress, cancel,
                                   executor, chunk_size)
    flat = _fields(results, gx.size)
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
    progress = check_progress(progress)
    cancel = check_cancel(cancel)
    decimals = check_int("decimals", decimals, 0, 15)
    xv, vv, lo, hi = check_basin_axes(params, x0_values, v0_values)
    transient, record = _check_size(len(xv), len(vv), transient, record)
    record = max(record, 2 * MAX_PERIOD + 2)
    gx, gv = np.meshgrid(xv, vv)
    n = gx.size
    columns = {"lam": np.full(n, params.lam)}
    results, cancelled = _run_grid(params, columns, np.clip(gx.ravel(), lo, hi), gv.ravel(),
                                   transient, record, progress, cancel, executor, chunk_size,
                                   decimals)
    flat = _fields(results, n)
    labels = np.full(n, -1, dtype=np.int32)
    keys: dict = {}
    for part in results:
        for row, fp in zip(part["rows"], part["fingerprint"]):
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
