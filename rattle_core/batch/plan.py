"""Maps over any two axes: which dimensionless parameters a grid drives, worked out first.

A map's axes may be dimensionless names (``lam``, ``r``, ``j``, ``v_stick``, ``hK``,
``phiK``), physical ones (:data:`PHYSICAL_AXES`: engine speed, drag torque, inertia, backlash,
through :mod:`rattle_core.model.units`) or the start state (``x0`` × ``v0``: basins).
:func:`plan_map` checks the request and says how to run it before anything runs;
:func:`point_params` gives the model at one grid point.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..model.params import RattleParams, iter_names, parse_name
from .maps import _grid_args, check_basin_axes

#: Physical map axes: axis name → (PhysicalParams field, factor from the axis unit to SI).
PHYSICAL_AXES = {"rpm": ("rpm", 1.0), "drag_torque": ("drag_torque", 1.0),
                 "inertia": ("inertia", 1.0), "backlash_um": ("backlash", 1e-6)}
#: Names of the start-state axes of a basin map.
BASIN_AXES = ("x0", "v0")


def point_params(params: RattleParams, phys: Any, names: tuple[str, ...],
                 point: tuple[float, ...], follow: Any = None) -> RattleParams:
    """The dimensionless parameters at one grid point: physical axes first, then the others.

    ``phys`` (a :class:`~rattle_core.model.units.PhysicalParams`, or None) holds the physical
    values not swept; a physical axis replaces its field (``rpm``, ``drag_torque``, ...) and
    the point's ``RattleParams`` follows from :meth:`PhysicalParams.to_dimensionless`.
    ``follow`` (an :class:`~rattle_core.model.gearbox.Excitation`) takes the harmonics at the
    point's engine speed from a measurement instead of holding ``phys``'s.
    """
    if phys is not None:
        changes = {PHYSICAL_AXES[n][0]: v * PHYSICAL_AXES[n][1]
                   for n, v in zip(names, point) if n in PHYSICAL_AXES}
        if follow is not None:
            moved = phys.replace(**changes) if changes else phys
            params = follow.follow(moved, moved.rpm).to_dimensionless().replace(noise=params.noise)
        elif changes:
            # the physical set knows nothing of the model's noise: it keeps the caller's
            params = phys.replace(**changes).to_dimensionless().replace(noise=params.noise)
    for n, v in zip(names, point):
        if n not in PHYSICAL_AXES:
            parse_name(n)
            params = params.with_value(n, v)
    return params


def plan_map(params: RattleParams, phys: Any, x_name: str, x_values, y_name: str, y_values,
             labels: tuple[str, str] = ("x axis", "y axis"), follow: Any = None) -> tuple:
    """How a grid over two axes maps onto the dimensionless model; checks it before any run.

    Returns ``("basin",)`` for ``x0`` × ``v0``; ``("map", a, a_values, b, b_values)`` when
    the x axis drives one dimensionless parameter ``a`` and the y axis another ``b`` (a
    regime map over them); or ``("flat", name, values)`` when both axes drive the same one
    (``values`` per grid point, rows following y: a 1-D sweep reshaped).  Only physical axes
    can drive the same parameter, and they act on Λ and j as products of powers
    (``Λ = m H₁ ω² / F``, ``j = b / H₁``), so that grid is ``v(x, y₀) v(x₀, y) / v(x₀, y₀)``;
    the far corner is evaluated directly to check it.  With ``follow`` (harmonics that follow
    engine speed, :meth:`~rattle_core.model.gearbox.Excitation.follow`) and physical axes, every
    point's numbers are worked out: ``("rows", columns)``, columns of name → one value per
    grid point (rows following y).

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
        # the start states are checked here too, so a bad one stops the request before any
        # worker or progress bar starts
        x_axis = 0 if x_name == "x0" else 1
        check_basin_axes(params, (xv, yv)[x_axis], (yv, xv)[x_axis],
                         (f"{labels[x_axis]} x0 values", f"{labels[1 - x_axis]} v0 values"))
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
    if follow is not None:
        if phys is None or not set(names) <= set(PHYSICAL_AXES):
            raise ValueError(f"harmonics that follow engine speed need two physical axes "
                             f"({', '.join(PHYSICAL_AXES)}); got {x_name!r} and {y_name!r}")
        from ..model.gearbox import model_columns
        grid = [point_params(params, phys, names, (x, y), follow) for y in yv for x in xv]
        return ("rows", model_columns(grid))
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
