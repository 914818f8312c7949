"""continue_bifurcation(): the request checked, the curve started, the result assembled."""
from __future__ import annotations

import dataclasses
import math
import threading
import time
from typing import Any, Callable, Sequence

import numpy as np

from ...model.params import RattleParams, check_cancel, check_progress, check_range
from ...solver.trajectory import SOLVER_VERSION
from .codim2 import Codim2Point, _pd_direction, _reduced
from .contact import _ContactSystem, _contact_side, _global_start, _polish_t
from .curvepoint import _admissible, _orbit
from .stickend import _stick_end_side
from .defining import _Extended, _Grazing, _Multiplier, _StickOnset
from .driver import CONTINUATION_VERSION
from .orbits import ContinuationError
from .parameter import _KIND_J, _KIND_LAM, _KIND_R, _Param  # noqa: F401
from .plane import _Plane
from .results import Bifurcation
from .twoparam import MAX_CURVE_POINTS, BifurcationCurve, _finish, _trace

#: Bifurcation kinds that :func:`continue_bifurcation` follows in a second parameter.
CURVE_STARTS = ("fold", "period_doubling", "grazing", "stick_onset", "stick_end",
                "permanent_contact")


def continue_bifurcation(bifurcation, param2: str | None = None, *,
                         bounds: Sequence[float] | None = None,
                         bounds1: Sequence[float] | None = None, direction: int = 0,
                         ds: float = 0.02, ds_min: float = 1e-8, ds_max: float = 0.1,
                         max_points: int = 1000, physical=None,
                         progress: Callable[[int, int], Any] | None = None,
                         cancel: threading.Event | Callable[[], bool] | None = None
                         ) -> BifurcationCurve:
    """Follow a bifurcation in a second parameter: its curve in the plane of two parameters.

    The orbit's shooting equations plus the bifurcation's defining condition form an extended
    system (:mod:`rattle_core.analysis.continuation.defining`), solved by Newton's method with
    exact Jacobians and followed by pseudo-arclength steps with adaptive length.
    Codimension-two points on the way are located and labelled
    (:mod:`~rattle_core.analysis.continuation.codim2`).

    Parameters
    ----------
    bifurcation : Bifurcation or Codim2Point
        From :attr:`ContinuationResult.bifurcations`: a ``fold``, ``period_doubling``,
        ``grazing``, ``stick_onset``, or ``permanent_contact`` (the contact boundary
        ``Λ_c = 1/max(−ÿ)``, where rattle starts; :func:`contact_bifurcation` makes one
        directly).  Or a codimension-two point of an earlier curve: the other curve through it
        is followed.
    param2 : str
        The second parameter: ``lam``, ``r``, ``j``, ``hK``, ``phiK`` (degrees), or ``rpm``,
        ``drag_torque`` with ``physical`` (or when the bifurcation was found in physical
        units).  It must change another model number than the first.
    bounds : (float, float), optional
        The curve stops where ``param2`` leaves this interval (its units).  Default: the
        model's range.
    bounds1 : (float, float), optional
        The same for the bifurcation's own parameter.
    direction : {0, 1, -1}
        Both ways from the start (0), or only towards increasing (1) or decreasing (−1)
        internal ``param2``.
    ds, ds_min, ds_max : float
        First, smallest and largest arclength step.
    max_points : int
        Most curve points, in [1, 20000].
    physical : PhysicalParams, optional
        The gear in physical units, for ``param2`` in ``rpm`` or ``drag_torque``.
    progress : callable(done, max_points), optional
    cancel : threading.Event or callable() -> bool, optional

    Returns
    -------
    BifurcationCurve
        ``points`` (a DataFrame with a column per parameter, the impulses and multipliers),
        ``codim2``, ``status``.

    Raises
    ------
    ValueError
        For a kind that has no curve, an unknown or conflicting ``param2``, bad bounds.
    ContinuationError
        When the extended system cannot be solved at the start.
    """
    t_start = time.perf_counter()
    progress = check_progress(progress)
    cancel = check_cancel(cancel)
    if (isinstance(direction, (bool, np.bool_)) or not isinstance(direction, (int, np.integer))
            or direction not in (0, 1, -1)):
        raise ValueError(f"direction = {direction!r}; allowed: the int 0 (both), 1 or -1")
    ds = check_range("ds", ds, 0.0, 1.0, lo_open=True)
    ds_max = check_range("ds_max", ds_max, ds, 10.0)
    ds_min = check_range("ds_min", ds_min, 0.0, ds, lo_open=True)
    max_points = int(check_range("max_points", max_points, 1, MAX_CURVE_POINTS))
    if isinstance(bifurcation, Codim2Point):
        if not bifurcation.can_restart:
            raise ValueError(f"the {bifurcation.kind} point offers no other curve to follow")
        if param2 is not None and param2 != bifurcation.param2:
            raise ValueError(f"param2 = {param2!r}, but the point lies in the plane "
                             f"({bifurcation.param1}, {bifurcation.param2}); restart in it")
        ext, X0, how = bifurcation._restart
        plane = ext.plane
        kind = ext.cond.kind
        X0 = _first_point(ext, X0, how, bifurcation,
                          (_bounds_q(plane.spec1, bounds1, "bounds1"),
                           _bounds_q(plane.spec2, bounds, "bounds")))
        start = {"codim2": bifurcation.kind, "value1": bifurcation.value1,
                 "value2": bifurcation.value2}
        v_stick = float(bifurcation.orbit.params.v_stick)
        event = bifurcation.kind
    elif isinstance(bifurcation, Bifurcation):
        if bifurcation.kind not in CURVE_STARTS:
            raise ValueError(f"bifurcation kind {bifurcation.kind!r} has no curve to follow; "
                             f"allowed: {', '.join(CURVE_STARTS)}")
        if param2 is None:
            raise ValueError("param2 must name the second parameter (lam, r, j, hK, phiK, rpm "
                             "or drag_torque)")
        spec1 = bifurcation._spec
        base = bifurcation.orbit.params
        phys = spec1.physical if spec1.physical is not None else physical
        spec2 = _Param.make(param2, base, phys if param2 in ("rpm", "drag_torque") else None)
        if param2 == spec1.name:
            raise ValueError(f"param2 = {param2!r} is the bifurcation's own parameter; choose "
                             "another")
        plane = _Plane(spec1, spec2, base)
        q1, q2 = float(bifurcation.q), float(spec2.q0)
        if spec2.physical is not None and not _same(plane.params(q1, q2), base):
            raise ValueError("physical does not describe the bifurcation's gear "
                             f"(physical.to_dimensionless() = {spec2.base}, bifurcation at "
                             f"{base})")
        v_stick = float(base.v_stick)
        kind, ext, X0 = _from_bifurcation(plane, bifurcation, q1, q2, v_stick)
        start = {"bifurcation": bifurcation.kind, "param": bifurcation.param,
                 "value": bifurcation.value}
        event = ""
    else:
        raise ValueError(f"bifurcation must be a Bifurcation or a Codim2Point, got "
                         f"{type(bifurcation).__name__}")
    bounds_q = (_bounds_q(plane.spec1, bounds1, "bounds1"),
                _bounds_q(plane.spec2, bounds, "bounds"))
    for i, (lo, hi) in zip((-2, -1) if kind != "contact" else (1, 2), bounds_q):
        if not lo - 1e-9 * (1 + abs(lo)) <= X0[i] <= hi + 1e-9 * (1 + abs(hi)):
            name = plane.spec1.name if i in (-2, 1) else plane.spec2.name
            spec = plane.spec1 if i in (-2, 1) else plane.spec2
            raise ValueError(f"the start, {name} = {spec.value_of(X0[i]):.10g}, lies outside "
                             f"its bounds [{spec.value_of(lo):.10g}, {spec.value_of(hi):.10g}]")
    names = plane.names
    provenance = {
        "kind": kind, "param1": names[0], "param2": names[1], "start": start,
        "params": plane.base.to_dict(),
        "physical": dataclasses.asdict(plane.spec1.physical or plane.spec2.physical)
        if (plane.spec1.physical or plane.spec2.physical) is not None else None,
        "settings": {"bounds": [plane.spec2.value_of(v) for v in bounds_q[1]],
                     "bounds1": [plane.spec1.value_of(v) for v in bounds_q[0]],
                     "direction": direction, "ds": ds, "ds_min": ds_min, "ds_max": ds_max,
                     "max_points": max_points},
        "solver_version": SOLVER_VERSION, "continuation_version": CONTINUATION_VERSION,
    }
    if kind == "stick_end":
        return _stick_end_curve(ext, X0, direction, ds, ds_min, ds_max, bounds_q, max_points,
                                cancel, names, provenance, t_start)
    if kind == "contact":
        return _contact_curve(ext, X0, direction, ds, ds_min, ds_max, bounds_q, max_points,
                              cancel, names, provenance, t_start)
    run, points = _trace(ext, X0, direction, ds, ds_min, ds_max, bounds_q, max_points,
                         progress, cancel, v_stick, kind, event)
    return _finish(kind, ext, run, points, names, provenance, t_start)


def contact_bifurcation(params: RattleParams, param: str = "lam", physical=None) -> Bifurcation:
    """The contact boundary ``Λ_c = 1/max(−ÿ)`` as a bifurcation in ``param`` (``lam``, or
    ``rpm``/``drag_torque`` with ``physical``), ready for :func:`continue_bifurcation`."""
    from ..overlays import contact_boundary
    from .orbits import PeriodicOrbit
    if not isinstance(params, RattleParams):
        raise ValueError(f"params must be a RattleParams, got {type(params).__name__}")
    spec = _Param.make(param, params, physical)
    if spec.kind != _KIND_LAM:
        raise ValueError(f"param = {param!r}: the contact boundary is a value of Λ; allowed: "
                         "lam, or rpm/drag_torque with displacement excitation")
    lam_c = contact_boundary(spec.base)
    q = lam_c
    p = spec.base.replace(lam=lam_c)
    orb = PeriodicOrbit(params=p, period=1, t=np.zeros(0), u=np.zeros(0),
                        flank=np.zeros(0, np.int8), w=np.zeros(0), stick=np.zeros((0, 3)),
                        monodromy=np.zeros((2, 2)), multipliers=np.zeros(2, complex),
                        residual=0.0, reason="", gap_min=math.inf)
    return Bifurcation(kind="permanent_contact", param=param, value=spec.value_of(q), point=0,
                       orbit=orb, detail={}, message=f"contact boundary at {param} = "
                       f"{spec.value_of(q):.10g}", q=q, _spec=spec)


def _same(a: RattleParams, b: RattleParams) -> bool:
    da, db = a.to_dict(), b.to_dict()
    for k in da:
        x, y = np.atleast_1d(da[k]), np.atleast_1d(db[k])
        n = max(len(x), len(y))
        x = np.pad(np.asarray(x, float), (0, n - len(x)))
        y = np.pad(np.asarray(y, float), (0, n - len(y)))
        if not np.allclose(x, y, rtol=1e-9, atol=1e-12):
            return False
    return True


def _low_high(pair, label: str) -> tuple[float, float]:
    """Two finite numbers, low < high, or ValueError naming ``label``."""
    try:
        lo, hi = (float(v) for v in pair)
    except (TypeError, ValueError):
        raise ValueError(f"{label} must be two numbers (low, high), got {pair!r}") from None
    if not (math.isfinite(lo) and math.isfinite(hi)) or lo >= hi:
        raise ValueError(f"{label} = {pair!r} must be two finite numbers, low < high")
    return lo, hi


def _bounds_q(spec: _Param, bounds, label: str) -> tuple[float, float]:
    lo_q, hi_q = spec.q_range()
    if spec.kind in (_KIND_LAM, _KIND_J):
        lo_q = max(lo_q, 1e-9)
    if spec.kind == _KIND_R:
        hi_q = min(hi_q, 1.0)
    if bounds is None:
        return lo_q, hi_q
    b0, b1 = _low_high(bounds, label)
    qa, qb = sorted((spec.q_of(b0), spec.q_of(b1)))
    for v, qv in ((b0, qa), (b1, qb)):
        try:
            spec.params(qv)
        except ValueError as exc:
            raise ValueError(f"{label}: {spec.name} = {v!r} is outside the model's range "
                             f"({exc})") from None
    return max(lo_q, qa), min(hi_q, qb)


def _from_bifurcation(plane: _Plane, b: Bifurcation, q1: float, q2: float, v_stick: float):
    """The extended system of a one-parameter bifurcation, and its first point solved."""
    if b.kind == "permanent_contact":
        sys_ = _ContactSystem(plane)
        X = _global_start(plane, q1, q2)
        X[0] = _polish_t(sys_, X)
        Xc, _ = sys_.correct(X, None, maxit=40, fix=-1)
        if Xc is None:
            raise ContinuationError(f"no contact boundary near {b.param} = {b.value:.10g}")
        return "contact", sys_, Xc
    orb = b.orbit
    if b.kind == "stick_end":
        # no extended system: the orbit sticks; ``ext`` carries what the natural steps need
        q_lo, q_hi = b._restart[2], b._restart[3]
        return "stick_end", (plane, orb, float(np.sign(q_lo - q_hi)) or 1.0), \
            np.array([q1, q2])
    if orb.kind != "impact" or b._restart is None or b._restart[1] is None:
        raise ValueError(f"the {b.kind} at {b.param} = {b.value:.10g} is on an orbit that "
                         "sticks; only bifurcations of impact orbits have curves here")
    br = b._restart[1]
    fl, n = br.fl, br.n
    z = np.asarray(b._restart[2][:-1], dtype=float)
    X = np.append(z, [q1, q2])
    if b.kind == "period_doubling":
        ext = _Extended(plane, fl, n, _Multiplier(-1.0))
    elif b.kind == "fold":
        ext = _Extended(plane, fl, n, _Multiplier(1.0))
    elif b.kind == "grazing" and b.detail.get("type") == "flight":
        k, tg, wall = orb.gap_where
        ext = _Extended(plane, fl, n, _Grazing(k, wall, tg - z[2 * k]))
    elif b.kind == "grazing":
        probe = _Extended(plane, fl, n, None)
        k = int(b.detail.get("impact", int(np.argmin(-orb.flank * orb.w))))
        fl, X, cond = _reduced(probe, X, k)
        ext = _Extended(plane, fl, n, cond)
    else:
        ext = _Extended(plane, fl, n, _StickOnset(int(b.detail["impact"]), v_stick))
    Xc, _ = ext.correct(X, None, maxit=40, fix=-1)
    if Xc is None:
        raise ContinuationError(f"the {b.kind} at {b.param} = {b.value:.10g} could not be "
                                "solved as an extended system (its defining condition does "
                                "not hold nearby)")
    ext.accept(Xc)
    return b.kind, ext, Xc


def _first_point(ext, X0, how: str, point: Codim2Point, bounds_q):
    """Solve the other curve's first point at a codimension-two point, inside ``bounds_q``."""
    if how == "doubled":
        # the fold of the doubled orbits starts at zero amplitude; begin a little way along it
        e = _pd_direction(_Extended(ext.plane, ext.fl[:len(ext.fl) // 2], ext.n // 2, None),
                          np.append(X0[:len(X0) // 2 - 1], X0[-2:]))
        for a in (2e-2, 1e-2, 5e-3):
            X, _ = ext.correct(X0 + a * e, e, maxit=30)
            if X is not None:
                m = (len(X) - 2) // 2
                if np.max(np.abs(X[m:2 * m] - X[:m] - _shift(m, ext.n // 2))) > 1e-8:
                    ext.accept(X)
                    return X
        raise ContinuationError(f"could not start the fold curve of the period-{ext.n} orbits "
                                f"at {point.kind} ({point.param1} = {point.value1:.10g})")
    X = None
    if how == "degenerate":
        X = _degenerate_start(ext, X0, bounds_q)
    else:
        X, _ = ext.correct(X0, None, maxit=40, fix=-1)
    if X is None:
        raise ContinuationError(f"could not start the {ext.cond.kind} curve at the "
                                f"{point.kind} point ({point.param1} = {point.value1:.10g}, "
                                f"{point.param2} = {point.value2:.10g})")
    ext.accept(X)
    return X


#: Offsets (relative to 1 + |q|) at which :func:`_degenerate_start` holds one parameter.
_START_OFFSETS = (0.0, 1e-6, 1e-5, 1e-4, 1e-3, 1e-2)
#: Farthest (relative to 1 + |q|) a degenerate start may lie from the point in each parameter.
_START_RADIUS = 5e-2


def _degenerate_start(ext, X0, bounds_q):
    """The other curve's point nearest ``X0`` where its condition holds non-degenerately.

    At a codimension-two point where a gap's minimum merges with a maximum (or a wall stops
    pushing), the other curve's condition is singular, and ``X0`` (the orbit with an impact
    removed or inserted) is only a guess.  Newton's method is started with one parameter held
    at small offsets from ``X0`` each way, and a solution counts only if it lies within the
    bounds, near ``X0``, and is a start of that curve: a true gap minimum (grazing) or a
    pushing wall (onset of sticking), on an orbit of the model.  The one nearest ``X0`` in the
    parameters wins.  None when there is none.
    """
    (a1, b1), (a2, b2) = bounds_q
    q0 = X0[-2:]
    radius = _START_RADIUS * (1.0 + np.abs(q0))
    best, best_d = None, math.inf
    s0 = getattr(ext.cond, "s", None)
    for off in _START_OFFSETS:
        for fix in (-1, -2):
            for sgn in ((1.0,) if off == 0.0 else (1.0, -1.0)):
                Xg = X0.copy()
                Xg[fix] += sgn * off * (1.0 + abs(X0[fix]))
                if s0 is not None:
                    ext.cond.s = s0
                _aim_touch(ext, Xg)
                X, _ = ext.correct(Xg, None, maxit=40, fix=fix)
                if X is None or not (a1 <= X[-2] <= b1 and a2 <= X[-1] <= b2):
                    continue
                d = np.abs(X[-2:] - q0)
                if np.any(d > radius) or float(np.max(d / radius)) >= best_d:
                    continue
                if _nondegenerate(ext, X) and _admissible(ext, _orbit(ext, X)):
                    best, best_d = X, float(np.max(d / radius))
        if best is not None:
            break
    if best is not None:
        _aim_touch(ext, best)
    return best


def _aim_touch(ext, X) -> None:
    """Point a grazing condition at the interior gap minimum of its flight at ``X``, when the
    flight has one on that wall: Newton's method on the gap's slope then starts at a minimum,
    not at the inflection where a minimum and a maximum have merged."""
    cond = ext.cond
    if not isinstance(cond, _Grazing):
        return
    from .admissibility import _inspect
    lam, r, j, h, phi = ext.plane.at(X[-2], X[-1])
    m = len(ext.fl)
    gmin, gs, contact = np.empty(m), np.empty(m), np.empty(m)
    gw = np.empty(m, dtype=np.int64)
    _inspect(X[:-2], ext.fl, ext.n, lam, r, j, h, phi, 0.0, False, gmin, gs, gw, contact)
    if gw[cond.k] == cond.wall and np.isfinite(gs[cond.k]):
        cond.s = float(gs[cond.k])


def _nondegenerate(ext, X) -> bool:
    """Whether the condition at ``X`` is the start of its curve: a grazing flight touches at a
    minimum of its gap (positive curvature), an onset of sticking is on a pushing wall."""
    z, q1, q2 = X[:-2], float(X[-2]), float(X[-1])
    cond = ext.cond
    if isinstance(cond, _Grazing):
        return cond.curvature(ext, z, q1, q2) > 0.0
    if isinstance(cond, _StickOnset):
        return cond.reaction(ext, z, q1, q2) > 0.0
    return True


def _shift(m: int, n: int):
    s = np.zeros(m)
    s[0::2] = 2.0 * np.pi * n
    return s


def _contact_curve(sys_, X0, direction, ds, ds_min, ds_max, bounds_q, max_points, cancel,
                   names, provenance, t_start) -> BifurcationCurve:
    import pandas as pd
    tau0 = sys_.tangent(X0)
    if tau0[-1] < 0:
        tau0 = -tau0
    count = [1]
    pts, status, msg = _both_ways(direction, lambda sgn: _contact_side(
        sys_, X0.copy(), sgn * tau0, ds, ds_min, ds_max, bounds_q, max_points, count, cancel))
    rows = []
    for i, (X, ev) in enumerate(pts):
        v1, v2 = sys_.plane.value_of(X[1], X[2])
        rows.append({"point": i, names[0]: v1, names[1]: v2, "q1": float(X[1]),
                     "q2": float(X[2]), "t_star": float(X[0] % (2 * np.pi)), "event": ev})
    return BifurcationCurve(kind="contact", param1=names[0], param2=names[1],
                            points=pd.DataFrame(rows), codim2=[], status=status, message=msg,
                            provenance=provenance, seconds=time.perf_counter() - t_start,
                            _ext=None, _X=[X for X, _ in pts])


def _stick_end_curve(ext, X0, direction, ds, ds_min, ds_max, bounds_q, max_points, cancel,
                     names, provenance, t_start) -> BifurcationCurve:
    import pandas as pd
    plane, orb0, inside = ext
    count = [1]
    span = bounds_q[1][1] - bounds_q[1][0]
    dq = min(ds, 0.05) * (span if math.isfinite(span) and span < 1e3 else 1.0)
    pts, status, msg = _both_ways(direction, lambda sgn: _stick_end_side(
        plane, X0, orb0, inside, sgn, bounds_q, dq, ds_min * max(span, 1.0), 2 * dq, count,
        max_points, cancel))
    rows = []
    for i, (X, orb) in enumerate(pts):
        v1, v2 = plane.value_of(X[0], X[1])
        row = {"point": i, names[0]: v1, names[1]: v2, "q1": float(X[0]), "q2": float(X[1]),
               "period": orb.period, "n_impacts": orb.n_impacts}
        for k, imp in enumerate(orb.impulse):
            row[f"impulse_{k + 1}"] = float(imp)
        row.update(mu1_re=0.0, mu1_im=0.0, mu2_re=0.0, mu2_im=0.0, stable=True,
                   stick_time=orb.stick_time, gap_min=orb.gap_min, event="")
        rows.append(row)
    return BifurcationCurve(kind="stick_end", param1=names[0], param2=names[1],
                            points=pd.DataFrame(rows), codim2=[], status=status, message=msg,
                            provenance=provenance, orbits=[o for _, o in pts],
                            seconds=time.perf_counter() - t_start, _ext=None,
                            _X=[X for X, _ in pts])


def _both_ways(direction: int, side):
    """``side(±1)`` → ``(points, status, message)`` run both ways (or one), joined into one
    run of points in curve order, with a status and message per side."""
    sides = [1, -1] if direction == 0 else [direction]
    runs = [side(sgn) for sgn in sides]
    pts = runs[1][0][::-1] + runs[0][0][1:] if len(runs) == 2 else runs[0][0]
    statuses = [r[1] for r in runs]
    status = statuses[0] if len(set(statuses)) == 1 else "+".join(statuses)
    msg = "; ".join(f"{'up' if sgn > 0 else 'down'}: {r[2]}" for sgn, r in zip(sides, runs))
    return pts, status, msg
