"""The rattle atlas: every bifurcation curve of a plane that continuation finds from a few seeds.

A regime map shows pixels; the atlas draws the boundaries between them exactly.  For a window
``x_range × y_range`` of two parameters it

1. draws the contact boundary ``Λ_c = 1/max(−ÿ)`` when one axis sets Λ (below it: regime A;
   over r or j it is a straight line);
2. takes a few rows ``y = const`` of the window and, on each, the periodic orbits that
   simulations from a few values of ``x`` settle on; follows each in ``x`` across the window
   (:func:`continue_orbit`), and the period-doubled branches born on the way;
3. follows every fold, period doubling, grazing, onset and end of sticking found in ``y``
   (:func:`continue_bifurcation`), unless a curve already drawn passes through it.

What the seeds never reach (an orbit no simulation from them settles on) is not drawn; more
rows and columns of seeds find more.
"""
from __future__ import annotations

import re
import threading
from typing import Any, Callable, Sequence

import numpy as np

from ...model.params import RattleParams, check_cancel, check_progress, check_range
from .bifcurve import _low_high, contact_bifurcation, continue_bifurcation
from .driver import continue_orbit
from .orbits import ContinuationError
from .parameter import _KIND_LAM, _Param
from .results import Bifurcation, _is_cancelled
from .simulated import find_orbit
from .twoparam import BifurcationCurve

#: Kinds of one-parameter bifurcations the atlas follows in the second parameter.
ATLAS_KINDS = ("fold", "period_doubling", "grazing", "stick_onset", "stick_end")
# what ends one seed or one curve of the atlas without ending the atlas: no orbit there, a
# branch that cannot be followed, an impact reaching zero speed inside the shooting equations
_FAILURES = (ValueError, ContinuationError, ZeroDivisionError, FloatingPointError,
             np.linalg.LinAlgError)
#: Axes continuation understands.
ATLAS_AXES = ("lam", "r", "j", "hK", "phiK", "rpm", "drag_torque")


def atlas(params: RattleParams, x_name: str, x_range: Sequence[float], y_name: str,
          y_range: Sequence[float], *, physical=None, rows: int = 3, columns: int = 3,
          max_curves: int = 24, max_points: int = 400,
          progress: Callable[[int, int], Any] | None = None,
          cancel: threading.Event | Callable[[], bool] | None = None) -> list[BifurcationCurve]:
    """Bifurcation curves over the window ``x_range × y_range`` of two parameters.

    Parameters
    ----------
    params : RattleParams
        The model at the window's reference point (the other parameters).
    x_name, y_name : str
        The axes: ``lam``, ``r``, ``j``, ``hK``, ``phiK`` (degrees), ``rpm``, ``drag_torque``
        (these two with ``physical``).
    x_range, y_range : (float, float)
        The window, in the axes' units.
    physical : PhysicalParams, optional
        The gear in physical units, for ``rpm`` and ``drag_torque``.
    rows, columns : int
        Seeds: rows of constant ``y`` (in [1, 9]) and starting values of ``x`` on each (in
        [1, 9]).
    max_curves : int
        Most curves, in [1, 200].
    max_points : int
        Most points per curve, in [10, 20000].
    progress : callable(done, total), optional
        Called after each seed row and each curve.
    cancel : threading.Event or callable() -> bool, optional
        Stops between curves; the curves so far are returned.

    Returns
    -------
    list of BifurcationCurve
        The contact boundary first (when an axis sets Λ), then the curves in the order found;
        each curve's ``points`` has a column per axis.
    """
    if not isinstance(params, RattleParams):
        raise ValueError(f"params must be a RattleParams, got {type(params).__name__}")
    progress = check_progress(progress)
    cancel = check_cancel(cancel)
    rows = int(check_range("rows", rows, 1, 9))
    columns = int(check_range("columns", columns, 1, 9))
    max_curves = int(check_range("max_curves", max_curves, 1, 200))
    max_points = int(check_range("max_points", max_points, 10, 20000))
    if x_name == y_name:
        raise ValueError(f"x_name and y_name are both {x_name!r}; choose two parameters")
    specs = []
    for name, rng, label in ((x_name, x_range, "x_range"), (y_name, y_range, "y_range")):
        try:
            spec = _Param.make(name, params, physical if name in ("rpm", "drag_torque") else None)
        except ValueError as exc:
            raise ValueError(f"the atlas has no curves over {name!r}: {exc}") from None
        lo, hi = _low_high(rng, label)
        specs.append((spec, lo, hi))
    (sx, x0, x1), (sy, y0, y1) = specs
    done = [0]
    total = rows + max_curves
    curves: list[BifurcationCurve] = []

    def tick():
        done[0] += 1
        if progress is not None:
            progress(min(done[0], total), total)

    def phys_for(name, ph):
        return ph if name in ("rpm", "drag_torque") else None

    # 1. the contact boundary, when an axis is a value of Λ
    for s, (lo, hi), other, (olo, ohi) in (((sx, (x0, x1), sy, (y0, y1)),
                                            (sy, (y0, y1), sx, (x0, x1)))):
        if s.kind != _KIND_LAM:
            continue
        try:
            ref, ph = _seed(params, physical, {other.name: 0.5 * (olo + ohi)})
            b = contact_bifurcation(ref, s.name, physical=phys_for(s.name, ph))
            curve = continue_bifurcation(b, other.name, bounds=(olo, ohi), bounds1=(lo, hi),
                                         max_points=max_points, cancel=cancel,
                                         physical=phys_for(other.name, ph))
            if len(curve.points) > 1:
                curves.append(curve)
        except (ValueError, ContinuationError):
            pass
        break
    # 2. seeds: orbits on rows of constant y, followed across the window in x
    found = []
    for yv in _grid(y0, y1, rows):
        for xv in _grid(x0, x1, columns):
            if _is_cancelled(cancel):
                return curves
            try:
                p, ph = _seed(params, physical, {x_name: xv, y_name: yv})
                orb = find_orbit(p, transient=600)
            except _FAILURES:
                continue
            found.extend((b, ph) for b in _bifurcations_across(
                orb, x_name, (x0, x1), phys_for(x_name, ph), cancel))
        tick()
    # 3. each bifurcation followed in y, unless a curve already passes through it
    for b, ph in found:
        if len(curves) >= max_curves or _is_cancelled(cancel):
            break
        if any(_passes(c, b, (x0, x1), (y0, y1), y_name, ph) for c in curves):
            continue
        try:
            curve = continue_bifurcation(b, y_name, bounds=(y0, y1), bounds1=(x0, x1),
                                         max_points=max_points, cancel=cancel,
                                         physical=phys_for(y_name, ph))
        except _FAILURES:
            continue
        if len(curve.points) > 1 and not any(_same_curve(c, curve, (x0, x1), (y0, y1))
                                             for c in curves):
            curves.append(curve)
        tick()
    return curves


def _same_curve(a: BifurcationCurve, b: BifurcationCurve, xw, yw) -> bool:
    """Whether curve ``b`` runs along ``a`` (three of its points lie on it)."""
    if a.kind != b.kind or a.param1 != b.param1:
        return False
    pts = b.points
    for i in (len(pts) // 4, len(pts) // 2, 3 * len(pts) // 4):
        if not _near(a, float(pts[b.param1].iloc[i]), float(pts[b.param2].iloc[i]),
                     int(pts["period"].iloc[i]), xw, yw):
            return False
    return True


def _seed(params: RattleParams, physical, values: dict):
    """The model at a point of the window, and the gear in physical units that gives it."""
    phys_fields = {n: v for n, v in values.items() if n in ("rpm", "drag_torque")}
    if not phys_fields:
        p = params
        for n, v in values.items():
            p = p.with_value(n, v)
        return p, None
    held = physical.replace(**phys_fields)
    p = held.to_dimensionless()
    for n, v in values.items():
        if n not in phys_fields:
            p = p.with_value(n, v)
    return p, type(physical).from_dimensionless(p, held, solve_for="drag_torque")


def _grid(lo: float, hi: float, n: int) -> np.ndarray:
    return lo + (hi - lo) * (np.arange(n) + 0.5) / n


def _bifurcations_across(orb, x_name: str, x_window, physical, cancel) -> list:
    """Bifurcations of ``orb``'s branch, both ways in x, and of the doubled branches born on
    it (up to period 4)."""
    out = []
    todo: list = [(orb, 1), (orb, -1)]
    branches = 0
    while todo and branches < 6:
        start, d = todo.pop(0)
        try:
            if isinstance(start, Bifurcation):
                res = continue_orbit(start, bounds=x_window, max_points=300, cancel=cancel)
            else:
                res = continue_orbit(start, x_name, bounds=x_window, direction=d,
                                     max_points=300, cancel=cancel, physical=physical)
        except _FAILURES:
            continue
        branches += 1
        for b in res.bifurcations:
            if b.kind == "stick_end" or (b.kind in ATLAS_KINDS and b._restart is not None
                                         and b._restart[1] is not None):
                out.append(b)
            if b.kind == "period_doubling" and b.orbit.period <= 2:
                todo.append((b, 0))
    return out


def _passes(curve: BifurcationCurve, b, xw, yw, y_name: str, physical) -> bool:
    """Whether ``curve`` goes through the bifurcation ``b`` (same kind and orbit shape)."""
    if curve.kind != b.kind or not len(curve.points) or curve.param1 != b.param:
        return False
    o = b.orbit
    # (a grazing is the same curve seen from the orbit with the impact and from the one
    # without it: the number of impacts may differ, the period does not)
    return _near(curve, b.value, _value_in(o.params, y_name, physical), o.period, xw, yw)


def _near(curve: BifurcationCurve, xv: float, yv: float, period: int, xw, yw) -> bool:
    """Whether the point ``(xv, yv)`` lies on ``curve``'s points of that period."""
    pts = curve.points
    same = (pts["period"] == period).to_numpy()
    if not same.any():
        return False
    x = pts[curve.param1].to_numpy()[same]
    y = pts[curve.param2].to_numpy()[same]
    dx = (x - xv) / (xw[1] - xw[0])
    dy = (y - yv) / (yw[1] - yw[0])
    if len(x) < 2:
        return bool(np.min(np.hypot(dx, dy)) < 2e-3)
    # distance to the polyline, in window units
    vx, vy = np.diff(dx), np.diff(dy)
    L = vx * vx + vy * vy
    t = np.clip(-(dx[:-1] * vx + dy[:-1] * vy) / np.where(L > 0, L, 1.0), 0.0, 1.0)
    return bool(np.min(np.hypot(dx[:-1] + t * vx, dy[:-1] + t * vy)) < 2e-3)


def _value_in(p: RattleParams, name: str, physical) -> float:
    """The axis ``name``'s value at the parameters ``p`` (``physical`` gave ``p``)."""
    if name in ("rpm", "drag_torque"):
        return float(getattr(physical, name))
    return float(p.get(name))


def axes_supported(x_name: str, y_name: str) -> str:
    """Empty when the atlas can draw over these axes; otherwise why not."""
    for name in (x_name, y_name):
        if name not in ("lam", "r", "j", "rpm", "drag_torque") and \
                not re.fullmatch(r"(h|phi)([2-9]|[12][0-9]|3[0-2])", str(name)):
            return (f"the atlas draws no curves over {name!r}; its axes are "
                    f"{', '.join(ATLAS_AXES)}")
    return ""
