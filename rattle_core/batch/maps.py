"""2-D maps: regimes and rattle intensity over two parameters, and basins of attraction.

* :func:`regime_map` runs every point of a grid over two parameters (``lam × phi2``,
  ``lam × h2``, ...) and classifies it (``classify``): regime, period, Lyapunov exponent,
  impacts per period, stick fraction and rattle intensity, each as a 2-D array.
* :func:`basin_map` fixes the parameters and runs a grid of initial states ``(x0, ẋ0)`` at
  t = 0; each point is coloured by the attractor it reaches.  Attractors are told apart by
  their regime and a fingerprint of their stroboscopic section (the periodic orbit's smallest
  section point, rounded), so two coexisting period-1 orbits get two colours.

* :func:`run_map` is the entry point of the CLI and the dashboard: its axes may also be
  physical (``rpm``, ``drag_torque``, ``inertia``, ``backlash_um``, through
  :mod:`rattle_core.units`) or the start state (``x0`` × ``v0``: basins).  :func:`plan_map`
  works out, and checks, which dimensionless parameters the two axes drive before anything runs.

The grid is flattened into per-point parameter arrays and run in chunks through the sweep
kernel: in parallel on local cores, or on a Dask cluster when ``executor`` is a
``dask.distributed.Client`` (results are identical, point for point).  Each chunk is classified
where it runs and reduced to what the map keeps of a point (its fields and, for basins, its
attractor fingerprint), so a Dask task sends back a few numbers per point, not its impacts.
"""
from __future__ import annotations

import dataclasses
import math
from typing import Any, Callable

import numpy as np

from ..analysis.classify import MAX_PERIOD, detect_period
from ..model.excitation import excitation
from ..model.params import RattleParams, check_range, iter_names, parse_name
from .sweep import REGIME_ORDER, SCHEMA_VERSION, _run_chunk, _summary_arrays
from ..solver.trajectory import MAX_PERIODS, SOLVER_VERSION, _check_int

#: Regime letters and their integer codes in map arrays.
REGIME_CODES = {"A": 0, "B": 1, "C": 2, "D": 3, "E": 4, "P": 5, "Q": 6, "error": 7}
#: Colour of each regime in map pictures (the CLI's PNG, the dashboard's map).
REGIME_COLOURS = {"A": "#9e9e9e", "B": "#ff9800", "C": "#2e7d32", "D": "#d32f2f",
                  "E": "#1565c0", "P": "#7b1fa2", "Q": "#795548", "error": "#000000"}
#: Physical map axes: axis name → (PhysicalParams field, factor from the axis unit to SI).
PHYSICAL_AXES = {"rpm": ("rpm", 1.0), "drag_torque": ("drag_torque", 1.0),
                 "inertia": ("inertia", 1.0), "backlash_um": ("backlash", 1e-6)}
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
    #: Set by :func:`run_map`: the map was read from the disk cache, not computed.
    from_cache: bool = False

    def table(self):
        """One row per grid point (a DataFrame): the two axes, then every field (regime as its
        letter)."""
        import pandas as pd
        letters = {v: k for k, v in REGIME_CODES.items()}
        gx, gy = np.meshgrid(self.x_values, self.y_values)
        df = pd.DataFrame({self.x_name: gx.ravel(), self.y_name: gy.ravel()})
        for k in sorted(self.fields, key=lambda k: (k != "regime", k != "attractor")):
            v = self.fields[k]
            df[k] = [letters.get(int(c), "") for c in v.ravel()] if k == "regime" else v.ravel()
        return df


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


#: Per-point fields of a regime map besides ``regime``, as floats (NaN where not run).
_FLOAT_FIELDS = ("period", "lyapunov", "active_per_period", "reverse_per_period",
                 "stick_fraction", "intensity")
# the summary's regime codes (index into REGIME_ORDER) as codes of REGIME_CODES
_MAP_CODE = np.array([REGIME_CODES[r] for r in REGIME_ORDER], dtype=np.int8)


def _map_chunk(base: RattleParams, columns: dict, rows: np.ndarray, transient: int,
               record: int, x0: np.ndarray | float | None, v0: np.ndarray | float,
               decimals: int | None = None) -> dict:
    """Run one chunk of grid points and reduce it to what a map keeps of each point.

    Returns ``rows`` (the points' flat indices), ``regime`` (codes of :data:`REGIME_CODES`),
    the :data:`_FLOAT_FIELDS` and, when ``decimals`` is given (basins), ``fingerprint``: each
    point's attractor fingerprint.  On a Dask cluster this is the task itself, so a few numbers
    per point travel back instead of every impact and stroboscopic sample.
    """
    chunk = _run_chunk(base, columns, rows, transient, record, x0, v0)
    cl = _summary_arrays(chunk, record)
    out = {"rows": np.asarray(rows, dtype=np.int64), "regime": _MAP_CODE[cl["regime_code"]]}
    for k in _FLOAT_FIELDS:
        out[k] = np.asarray(cl[k], dtype=np.float64)
    if decimals is not None:
        out["fingerprint"] = [
            _fingerprint(sx, sv, detect_period(sx, sv, base.j), REGIME_ORDER[code], decimals)
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

    args = [(base, {k: v[s:s + chunk_size] for k, v in columns.items()}, idx[s:s + chunk_size],
             transient, record, part(x0, s), part(v0, s), decimals) for s in range(0, n, chunk_size)]
    parts: list = []
    done = 0
    if executor is not None:
        from dask.distributed import as_completed
        futures = [executor.submit(_map_chunk, *a, pure=False) for a in args]
        order = {f.key: i for i, f in enumerate(futures)}
        found: dict = {}
        for fut, res in as_completed(futures, with_results=True):
            found[order[fut.key]] = res
            done += len(res["rows"])
            if progress is not None:
                progress(done, n)
            if cancel is not None and cancel() and len(found) < len(futures):
                for f in futures:
                    f.cancel()
                return [found[i] for i in sorted(found)], True
        return [found[i] for i in sorted(found)], False
    for a in args:
        if cancel is not None and cancel():
            return parts, True
        parts.append(_map_chunk(*a))
        done += len(parts[-1]["rows"])
        if progress is not None:
            progress(done, n)
    return parts, False


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


# ----- maps over any two axes: dimensionless, physical or the start state -----------------

#: Names of the start-state axes of a basin map.
BASIN_AXES = ("x0", "v0")


def point_params(params: RattleParams, phys: Any, names: tuple[str, ...],
                 point: tuple[float, ...]) -> RattleParams:
    """The dimensionless parameters at one grid point: physical axes first, then the others.

    ``phys`` (a :class:`~rattle_core.units.PhysicalParams`, or None) holds the physical
    values not swept; a physical axis replaces its field (``rpm``, ``drag_torque``, ...) and
    the point's ``RattleParams`` follows from :meth:`PhysicalParams.to_dimensionless`.
    """
    if phys is not None:
        changes = {PHYSICAL_AXES[n][0]: v * PHYSICAL_AXES[n][1]
                   for n, v in zip(names, point) if n in PHYSICAL_AXES}
        if changes:
            params = phys.replace(**changes).to_dimensionless()
    for n, v in zip(names, point):
        if n not in PHYSICAL_AXES:
            parse_name(n)
            params = params.with_value(n, v)
    return params


def plan_map(params: RattleParams, phys: Any, x_name: str, x_values, y_name: str, y_values,
             labels: tuple[str, str] = ("x axis", "y axis")) -> tuple:
    """How a grid over two axes maps onto the dimensionless model; checks it before any run.

    Returns ``("basin",)`` for ``x0`` × ``v0``; ``("map", a, a_values, b, b_values)`` when
    the x axis drives one dimensionless parameter ``a`` and the y axis another ``b`` (a
    regime map over them); or ``("flat", name, values)`` when both axes drive the same one
    (``values`` per grid point, rows following y: a 1-D sweep reshaped).  Only physical axes
    can drive the same parameter, and they act on Λ and j as products of powers
    (``Λ = m H₁ ω² / F``, ``j = b / H₁``), so that grid is ``v(x, y₀) v(x₀, y) / v(x₀, y₀)``;
    the far corner is evaluated directly to check it.

    Raises ``ValueError`` naming the axis (``labels`` say how: ``"x axis"``, ``"--param"``).
    """
    names = (x_name, y_name)
    if not isinstance(params, RattleParams):
        raise ValueError(f"params must be a RattleParams, got {type(params).__name__}")
    if x_name == y_name:
        raise ValueError(f"{labels[0]} and {labels[1]} must differ, both are {x_name!r}")
    xv = _grid_args(x_name, x_values, f"{labels[0]} {x_name} values")
    yv = _grid_args(y_name, y_values, f"{labels[1]} {y_name} values")
    if set(names) & set(BASIN_AXES):
        if set(names) != set(BASIN_AXES):
            raise ValueError(f"basins of attraction need {labels[0]} x0 {labels[1]} v0 together; "
                             f"got {x_name!r} and {y_name!r}")
        return ("basin",)
    for axis, (n, vals) in enumerate(zip(names, (xv, yv))):
        if n in PHYSICAL_AXES:
            if phys is None:
                raise ValueError(f"{labels[axis]} {n!r} is physical: give physical units (inertia, "
                                 "radius, drag torque, backlash, rpm, excitation amplitudes)")
        else:
            try:
                parse_name(n)
            except ValueError as exc:
                raise ValueError(f"{labels[axis]}: {exc}") from None
        # every check is a range check, so the extreme values settle the whole axis
        for v in (float(vals.min()), float(vals.max())):
            try:
                point_params(params, phys, (n,), (v,))
            except ValueError as exc:
                raise ValueError(f"{labels[axis]} {n}: {exc}") from None
    along_x = [point_params(params, phys, names, (x, yv[0])) for x in xv]
    along_y = [point_params(params, phys, names, (xv[0], y)) for y in yv]
    corner = point_params(params, phys, names, (xv[-1], yv[-1]))
    kmax = max(p.n_harmonics for p in along_x + along_y + [corner])
    wide = params.with_value(f"phi{kmax}", params.get(f"phi{kmax}")) if kmax > 1 else params
    vx, vy = {}, {}

    def varies(v: np.ndarray) -> bool:
        # physical units reach Λ and j through products that cancel only up to rounding
        return bool(np.ptp(v) > 1e-12 * np.max(np.abs(v)))
    for n in iter_names(wide):
        lx = np.array([p.get(n) for p in along_x])
        ly = np.array([p.get(n) for p in along_y])
        if varies(lx):
            vx[n] = lx
        if varies(ly):
            vy[n] = ly
    varying = sorted(set(vx) | set(vy))
    if not varying:
        raise ValueError(f"{labels[0]} {x_name} and {labels[1]} {y_name} leave the dimensionless "
                         "model unchanged over the grid; choose parameters that change it")
    for axis, found in ((0, vx), (1, vy)):
        if not found:
            raise ValueError(f"{labels[axis]} {names[axis]} leaves the dimensionless model "
                             f"unchanged with {names[1 - axis]} also swept; choose parameters "
                             "that each change it")
    if len(vx) == 1 and len(vy) == 1:
        (a, av), = vx.items()
        (b, bv), = vy.items()
        if a != b:
            if (math.isclose(corner.get(a), av[-1], rel_tol=1e-12)
                    and math.isclose(corner.get(b), bv[-1], rel_tol=1e-12)):
                return ("map", a, av, b, bv)
        elif a in ("lam", "j"):
            grid = np.outer(bv, av) / av[0]
            if math.isclose(grid[-1, -1], corner.get(a), rel_tol=1e-9):
                return ("flat", a, grid.ravel())
    raise ValueError(f"{labels[0]} {x_name} × {labels[1]} {y_name} changes {', '.join(varying)} "
                     "together; a map needs each axis to drive its own dimensionless parameter, "
                     "or both the same one")


def _flat_map(params: RattleParams, name: str, flat: np.ndarray, shape: tuple[int, int],
              use_cache: bool, common: dict) -> MapResult:
    """A map whose two axes drive one parameter: a 1-D sweep over every grid point, reshaped."""
    if use_cache:
        from ..store.cache import cached_sweep as run
    else:
        from .sweep import sweep as run
    res = run(params, name, flat, **common)
    summ = res.summary
    fields = _fields([], flat.size)
    m = len(summ)
    fields["regime"][:m] = summ["regime"].map(REGIME_CODES).to_numpy(dtype=np.int8)
    for k in _FLOAT_FIELDS:
        fields[k][:m] = summ[k].to_numpy(dtype=np.float64)
    return MapResult(kind="regime", x_name=name, y_name=name, x_values=flat, y_values=flat,
                     params=params, settings=dict(res.settings),
                     fields={k: v.reshape(shape) for k, v in fields.items()},
                     cancelled=res.cancelled)


def run_map(params: RattleParams, phys: Any, x_name: str, x_values, y_name: str, y_values, *,
            use_cache: bool = True, labels: tuple[str, str] = ("x axis", "y axis"),
            **common: Any) -> MapResult:
    """A regime/intensity map or basins of attraction over any two axes, labelled as asked.

    Parameters
    ----------
    params : RattleParams
        Parameters held fixed (for physical axes, those of ``phys`` at its own values).
    phys : PhysicalParams or None
        The same model in physical units; needed for physical axes.
    x_name, y_name : str
        Dimensionless names (``lam``, ``r``, ``j``, ``v_stick``, ``hK``, ``phiK``), physical
        ones (:data:`PHYSICAL_AXES`: ``rpm``, ``drag_torque`` [N·m], ``inertia`` [kg·m²],
        ``backlash_um`` [µm]), or ``x0`` and ``v0`` for basins of attraction.
    x_values, y_values : sequence of float
    use_cache : bool
        Serve a map that ran before from the disk cache (:mod:`rattle_core.cache`), and store
        this one; ``result.from_cache`` tells which happened.
    labels : (str, str)
        How error messages name the two axes.
    **common
        ``transient``, ``record``, ``x0``, ``v0`` (regime maps), ``progress``, ``cancel``,
        ``executor``, ``chunk_size``, as for :func:`regime_map` and :func:`basin_map`.

    Returns
    -------
    MapResult
        ``x_name``, ``y_name``, ``x_values``, ``y_values`` are the caller's; ``settings``
        adds ``model_axes`` (the dimensionless parameters the axes drive) and, in physical
        units, ``physical``.
    """
    plan = plan_map(params, phys, x_name, x_values, y_name, y_values, labels)
    xv = _grid_args(x_name, x_values, "x_values")
    yv = _grid_args(y_name, y_values, "y_values")
    progress = common.get("progress")
    reported = []

    def track(done: int, total: int) -> None:
        reported.append(done)
        if progress is not None:
            progress(done, total)
    common = dict(common, progress=track)
    if plan[0] == "basin":
        if "x0" in common or "v0" in common:
            raise ValueError("x0 and v0 are the axes of a basin map; do not give them as settings")
        xs, vs = (xv, yv) if x_name == "x0" else (yv, xv)
        if use_cache:
            from ..store.cache import cached_map
            result = cached_map("basin", params, "x0", xs, "v0", vs, **common)
        else:
            result = basin_map(params, xs, vs, **common)
        if x_name != "x0":
            result = dataclasses.replace(result, fields={k: v.T for k, v in result.fields.items()})
        axes: Any = list(BASIN_AXES)
    elif plan[0] == "map":
        _, a, av, b, bv = plan
        if use_cache:
            from ..store.cache import cached_map
            result = cached_map("regime", params, a, av, b, bv, **common)
        else:
            result = regime_map(params, a, av, b, bv, **common)
        axes = [a, b]
    else:
        _, name, flat = plan
        result = _flat_map(params, name, flat, (yv.size, xv.size), use_cache, common)
        axes = name
    settings = dict(result.settings, model_axes=axes)
    if phys is not None:
        settings["physical"] = dataclasses.asdict(phys)
    return dataclasses.replace(result, x_name=x_name, y_name=y_name, x_values=xv, y_values=yv,
                               settings=settings,
                               from_cache=use_cache and not reported and not result.cancelled)
