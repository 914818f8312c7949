"""Bifurcation curves in two parameters: the loop that follows an extended system.

A located bifurcation (a fold, a period doubling, a grazing, an onset of sticking) satisfies
the orbit's shooting equations plus one defining condition (:mod:`.defining`).  In the plane
of two parameters the solutions form a curve, followed here by pseudo-arclength steps: predict
along the unit tangent, correct by Newton's method on the plane orthogonal to it, grow the step
when Newton converges fast and shrink it when it does not or the tangent turns.  At every point
the codimension-two test functions (:mod:`.codim2`) are evaluated; their zeros are located
along the arclength, labelled, and offered as starts of the other curve.
"""
from __future__ import annotations

import dataclasses
import math
import threading
import time
from typing import Any, Callable

import numpy as np

from .codim2 import _LABELS, Codim2Point, _codim2_tests, _locate_on_curve, _record
from .curvepoint import _admissible, _orbit, _where
from .defining import _Extended
from .orbits import PeriodicOrbit
from .results import _limit
from .sticking import _w_min

#: Most points one curve may have.
MAX_CURVE_POINTS = 20_000

CURVE_KINDS = {
    "fold": "fold curve: a multiplier is +1",
    "period_doubling": "period-doubling curve: a multiplier is −1",
    "grazing": "grazing curve: a flight touches a wall",
    "stick_onset": "onset-of-sticking curve: an impact on a pushing wall slows to v_stick",
    "stick_end": "end-of-sticking curve: the stick phase shrinks to nothing",
    "contact": "contact boundary Λ_c = 1/max(−ÿ): below it the gear never leaves the tooth",
}


@dataclasses.dataclass(eq=False)
class BifurcationCurve:
    """A bifurcation followed in two parameters.

    Attributes
    ----------
    kind : str
        One of :data:`CURVE_KINDS`.
    param1, param2 : str
        The bifurcation's own parameter and the second one.
    points : DataFrame
        One row per curve point: a column named after each parameter (its units: degrees,
        rpm, N·m), ``q1`` and ``q2`` (the values the equations use), ``period``,
        ``n_impacts``, ``impulse_1`` … ``impulse_m`` (signed, per impact), ``mu1_re``,
        ``mu1_im``, ``mu2_re``, ``mu2_im`` (Floquet multipliers), ``gap_min``, ``w_min``,
        ``event`` (the codimension-two point there, if any).  The contact boundary has
        ``t_star`` (where ``−ÿ`` is largest) instead of impulses and multipliers.
    codim2 : list of Codim2Point
        Codimension-two points on the curve, in curve order.
    status, message : str
        Why the curve ended at each side (``bound``, ``max_points``, ``closed``,
        ``step_too_small``, ``inadmissible``, ``cancelled``, or a codimension-two point that
        ends it).
    provenance : dict
        Parameters, start and settings (JSON-ready).
    orbits : list of PeriodicOrbit
        The orbit at each point.
    seconds : float
        Wall time of the run.
    """

    kind: str
    param1: str
    param2: str
    points: Any
    codim2: list
    status: str
    message: str
    provenance: dict
    orbits: list = dataclasses.field(default_factory=list, repr=False)
    seconds: float = math.nan
    _ext: Any = dataclasses.field(default=None, repr=False)
    _X: list = dataclasses.field(default_factory=list, repr=False)

    @property
    def cancelled(self) -> bool:
        return self.status == "cancelled"

    def orbit(self, i: int) -> PeriodicOrbit:
        """The orbit at curve point ``i``."""
        return self.orbits[int(i)]

    def at(self, value2: float) -> list:
        """The curve's points at exactly ``value2`` of the second parameter, one per crossing:
        ``(value1, orbit)`` solved there from the two points around it."""
        ext = self._ext
        if ext is None:
            raise ValueError("this curve has no extended system to solve")
        q2 = ext.plane.spec2.q_of(float(value2))
        Q = np.array([X[-1] for X in self._X])
        out = []
        for i in range(len(Q) - 1):
            if (Q[i] - q2) * (Q[i + 1] - q2) > 0 or Q[i] == Q[i + 1]:
                continue
            f = (q2 - Q[i]) / (Q[i + 1] - Q[i])
            Xg = self._X[i] + f * (self._X[i + 1] - self._X[i])
            Xg[-1] = q2
            X, _ = ext.correct(Xg, None, maxit=30, fix=-1)
            if X is None:
                continue
            orb = _orbit(ext, X)
            out.append((ext.plane.spec1.value_of(X[-2]), orb))
        return out

    def codim2_table(self):
        import pandas as pd
        rows = [c.as_dict() for c in self.codim2]
        return pd.DataFrame(rows, columns=["kind", "curve", "other", self.param1, self.param2,
                                           "point", "message"])


class _CurveRun:
    """The points of one curve as they are found, in both directions from the start."""

    def __init__(self, ext, bounds_q, max_points, progress, cancel, v_stick):
        self.ext = ext
        self.bounds_q = bounds_q  # ((lo1, hi1), (lo2, hi2))
        self.max_points = max_points
        self.progress = progress
        self.cancel = cancel
        self.v_stick = v_stick
        self.sides: list[list] = []
        self.codim2: list[Codim2Point] = []
        self.status: list[str] = []
        self.message: list[str] = []
        self.count = 0


    def inside(self, X) -> bool:
        (a1, b1), (a2, b2) = self.bounds_q
        return a1 <= X[-2] <= b1 and a2 <= X[-1] <= b2


def _side(run: _CurveRun, X, tau, ds, ds_min, ds_max):
    """Follow the curve from ``X`` along ``tau`` until it stops; returns its points."""
    ext = run.ext
    pts = [(X, _orbit(ext, X), "")]
    run.count += 1
    tests = _codim2_tests(ext, X, pts[0][1], tau)
    X_start = X.copy()
    status, message = "", ""
    while True:
        status, message = _limit(run.count, run.max_points, run.cancel)
        if status:
            break
        X_new, it = ext.correct(X + ds * tau, tau)
        if X_new is not None and np.linalg.norm(X_new - X) > 2.0 * ds:
            X_new = None
        at_bound = False
        if X_new is not None and not run.inside(X_new):
            X_new, at_bound = _land(run, X, X_new), True
        tau_new = None
        if X_new is not None:
            tau_new = ext.tangent(X_new, tau)
            if float(tau_new @ tau) < 0.95 and ds > 4.0 * ds_min:
                X_new = None
        if X_new is None:
            ds *= 0.5
            if ds < ds_min:
                status = "step_too_small"
                message = (f"the corrector failed with steps down to ds_min = {ds_min:g} near "
                           f"{_where(ext, X)}")
                break
            continue
        orb_new = _orbit(ext, X_new)
        t_new = _codim2_tests(ext, X_new, orb_new, tau_new)
        ok = _admissible(ext, orb_new)
        found = []
        for key, f0 in tests.items():
            f1 = t_new.get(key, math.nan)
            if np.isfinite(f0) and np.isfinite(f1) and (f0 > 0) != (f1 > 0):
                found.append((key, f0, f1))
        located = []
        for key, f0, f1 in found:
            Xe = _locate_on_curve(ext, X, tau, float(tau @ (X_new - X)), f0, f1, key)
            if Xe is not None:
                located.append((float(np.linalg.norm(Xe - X)), key, Xe))
        located.sort(key=lambda e: e[0])
        stop = None
        for _, key, Xe in located:
            if not run.inside(Xe):
                continue
            point = _record(run, ext, key, Xe, tau, len(run.sides), len(pts))
            if point is None:
                continue
            pts.append((Xe, point.orbit, point.kind))
            if point.terminal:
                stop = point
                break
        if stop is not None:
            status, message = stop.kind, stop.message
            break
        if not ok and (ext.cond.kind, "adm") in _LABELS:
            Xe = _locate_on_curve(ext, X, tau, float(tau @ (X_new - X)), 1.0, -1.0, "adm")
            point = None if Xe is None else _record(run, ext, "adm", Xe, tau, len(run.sides),
                                                    len(pts))
            if point is not None:
                pts.append((Xe, point.orbit, point.kind))
                status, message = point.kind, point.message
                break
        if not ok:
            status = "inadmissible"
            message = (f"the orbit stopped being an orbit of the model near {_where(ext, X_new)}: "
                       f"{orb_new.reason or 'a flight meets a wall'}")
            break
        ext.accept(X_new)
        X, tau, tests = X_new, tau_new, t_new
        pts.append((X, orb_new, ""))
        run.count += 1
        if run.progress is not None:
            run.progress(run.count, run.max_points)
        if at_bound:
            status, message = "bound", f"reached the bound at {_where(ext, X)}"
            break
        if len(pts) > 10 and np.linalg.norm(X - X_start) < 0.5 * ds:
            status, message = "closed", "the curve came back to its first point (a closed curve)"
            break
        ds = min(ds * (1.5 if it <= 3 else (1.0 if it <= 6 else 0.5)), ds_max)
    run.status.append(status)
    run.message.append(message)
    return pts


def _land(run: _CurveRun, X, X_new):
    """The point where the step from ``X`` to ``X_new`` leaves the bounds, solved there."""
    ext = run.ext
    (a1, b1), (a2, b2) = run.bounds_q
    best = None
    for idx, lo, hi in ((-2, a1, b1), (-1, a2, b2)):
        if lo <= X_new[idx] <= hi:
            continue
        qb = hi if X_new[idx] > hi else lo
        frac = (qb - X[idx]) / (X_new[idx] - X[idx])
        if best is None or frac < best[0]:
            best = (frac, idx, qb)
    frac, idx, qb = best
    Xg = X + frac * (X_new - X)
    Xg[idx] = qb
    Xb, _ = ext.correct(Xg, None, maxit=30, fix=idx)
    return Xb


def _trace(ext: _Extended, X0, direction: int, ds, ds_min, ds_max, bounds_q, max_points,
           progress, cancel, v_stick, kind: str, start_event: str = ""):
    """Both sides of the curve through ``X0`` (or one, ``direction`` = ±1 along increasing or
    decreasing ``q₂``), joined into one run of points."""
    run = _CurveRun(ext, bounds_q, max_points, progress, cancel, v_stick)
    tau0 = ext.tangent(X0)
    if tau0[-1] < 0 or (tau0[-1] == 0 and tau0[-2] < 0):
        tau0 = -tau0
    sides = [1, -1] if direction == 0 else [direction]
    halves = []
    for sgn in sides:
        run.sides.append(sgn)
        ext.accept(X0)
        halves.append(_side(run, X0.copy(), sgn * tau0, ds, ds_min, ds_max))
    if len(halves) == 2:
        back = halves[1][::-1]
        points = back[:-1] + [(back[-1][0], back[-1][1], start_event)] + halves[0][1:]
    else:
        points = halves[0]
        points[0] = (points[0][0], points[0][1], start_event)
    return run, points


def _table(ext: _Extended, points, names) -> "Any":
    import pandas as pd
    rows = []
    m = len(ext.fl)
    for i, (X, orb, event) in enumerate(points):
        v1, v2 = ext.plane.value_of(X[-2], X[-1])
        mu = orb.multipliers
        row = {"point": i, names[0]: v1, names[1]: v2, "q1": float(X[-2]), "q2": float(X[-1]),
               "period": orb.period, "n_impacts": orb.n_impacts}
        imp = orb.impulse
        for k in range(m):
            row[f"impulse_{k + 1}"] = float(imp[k])
        row.update(mu1_re=float(mu[0].real), mu1_im=float(mu[0].imag),
                   mu2_re=float(mu[1].real), mu2_im=float(mu[1].imag),
                   stable=orb.stable, gap_min=orb.gap_min, w_min=_w_min(orb), event=event)
        rows.append(row)
    return pd.DataFrame(rows)


def _finish(kind, ext, run, points, names, provenance, t_start) -> BifurcationCurve:
    st = [s for s in run.status]
    msg = "; ".join(f"{'up' if sgn > 0 else 'down'}: {m}" for sgn, m in zip(run.sides,
                                                                          run.message))
    status = st[0] if len(set(st)) == 1 else "+".join(st)
    # codimension-two points in curve order
    order = {id(X): i for i, (X, _, _) in enumerate(points)}
    for c in run.codim2:
        c.point = order.get(id(c._X), -1)
    codim2 = sorted(run.codim2, key=lambda c: c.point)
    return BifurcationCurve(kind=kind, param1=names[0], param2=names[1],
                            points=_table(ext, points, names), codim2=codim2, status=status,
                            message=msg, provenance=provenance,
                            orbits=[o for _, o, _ in points], seconds=time.perf_counter() - t_start,
                            _ext=ext, _X=[X for X, _, _ in points])


def _check_cancel(cancel: threading.Event | Callable[[], bool] | None):
    if cancel is not None and not (hasattr(cancel, "is_set") or callable(cancel)):
        raise ValueError(f"cancel must be a threading.Event or a callable, got "
                         f"{type(cancel).__name__}")
