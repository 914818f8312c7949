"""Bifurcations and nonsmooth events: test functions, location along the arclength, records.

A fold, a period doubling or a Neimark–Sacker point is a zero of a function of the monodromy;
a grazing, of the smallest gap or the slowest impact; the onset of sticking, of an impact's
speed minus ``v_stick`` on a pushing wall.  A sign change between two branch points is located
by the Illinois variant of regula falsi, then recorded with what a restart needs.
"""
from __future__ import annotations

import math

import numpy as np

from .admissibility import ADMISSIBLE, _inspect
from .branch import _Branch
from .orbits import PeriodicOrbit
from .results import _Run
from .stability import _maps, _velocities
from .sticking import _release_roots, _stick_margin, _w_min

#: Bifurcations are located to this distance in the internal parameter.
LOCATE_TOL = 1e-11


def _light(br: _Branch, X, v_stick: float, monodromy: bool = True) -> dict:
    """Test functions at X without the event search (for locating a sign change).

    With ``monodromy`` False only the finite ones are computed: ``w``, ``speed``, ``react``
    and ``gap``, none of which divides by an impact's velocity, so a grazing (``w = 0``) is
    located on values that exist there.  The multiplier tests need the monodromy, which has
    a factor ``1/w``: at a grazing impact they are NaN.
    """
    lam, r, j, h, phi = br._at(X[-1])
    z = X[:-1]
    m = len(br.fl)
    w = np.empty(m)
    if monodromy:
        M = np.empty((2, 2))
        S = np.empty((2, 2))
        _maps(z, br.fl, br.n, lam, r, j, h, phi, w, M, S)
    else:
        _velocities(z, br.fl, br.n, lam, h, phi, w)
    gmin = np.empty(m)
    gs = np.empty(m)
    gw = np.empty(m, dtype=np.int64)
    contact = np.empty(m)
    _inspect(z, br.fl, br.n, lam, r, j, h, phi, v_stick, False, gmin, gs, gw, contact)
    tests = _slow_tests(z[0::2], br.fl, w, lam, h, phi, v_stick)
    tests["gap"] = float(np.min(gmin))
    if monodromy:
        tests.update(_multiplier_tests(S))
    return tests


def _multiplier_tests(S) -> dict:
    """Fold (``1 − tr + det``), period doubling (``1 + tr + det``) and Neimark–Sacker
    (``det − 1``) tests of the monodromy ``S``; NaN when ``S`` is (an impact grazes).

    The period-doubling test is divided by ``1 + |tr| + |det|``: it stays in [−1, 1] where
    ``tr`` grows like ``1/w`` near a grazing impact, so a sign change through that pole
    (where the test is ±1) is told from a multiplier at −1 (where it is 0).
    """
    tr = S[0, 0] + S[1, 1]
    det = S[0, 0] * S[1, 1] - S[0, 1] * S[1, 0]
    return dict(pd=(1.0 + tr + det) / (1.0 + abs(tr) + abs(det)), ns=det - 1.0,
                fold=1.0 - tr + det, tr=tr)


def _slow_tests(t, fl, w, lam, h, phi, v_stick) -> dict:
    """Grazing impact (``w``: slowest impact, zero when an impact grazes); for the onset of
    sticking, each impact's speed ``−σw`` and the reaction ``σR̃`` of its wall."""
    from ...model.excitation import excitation
    speed = -fl * w
    react = fl * (1.0 + lam * excitation(t, h, phi, 2))
    return {"w": float(np.min(speed)), "speed": speed, "react": react}


def _tests_of(orb: PeriodicOrbit, v_stick: float) -> dict:
    """The test functions of :func:`_light`, from an orbit already built."""
    p = orb.params
    tests = _slow_tests(orb.t, orb.flank, orb.w, p.lam, p.h, p.phi, v_stick)
    tests.update(_multiplier_tests(orb.monodromy), gap=orb.gap_min)
    return tests


def _admissible_sign(br: _Branch, X, v_stick: float) -> float:
    lam, r, j, h, phi = br._at(X[-1])
    m = len(br.fl)
    gmin, gs, contact = np.empty(m), np.empty(m), np.empty(m)
    gw = np.empty(m, dtype=np.int64)
    code = _inspect(X[:-1], br.fl, br.n, lam, r, j, h, phi, v_stick, True, gmin, gs, gw, contact)
    return 1.0 if code == ADMISSIBLE else -1.0


def _locate(br: _Branch, X0, tau0, h_hi, f0, f1, fn, tol):
    """Zero of ``fn`` along the arclength from ``X0`` (value ``f0``) to ``h_hi`` (value ``f1``).

    Illinois regula falsi; each trial point is corrected onto the branch on the plane
    ``τ0 · (X − X0 − h τ0) = 0``.  Returns ``(X, f)`` at the end nearer the zero, or
    ``(None, nan)`` if a correction fails or ``fn`` does not exist at a trial point.
    """
    lo, hi = 0.0, h_hi
    X_lo, X_hi = X0, None
    side = 0
    X_best, f_best = X0, f0
    for _ in range(200):
        if f1 != f0 and np.isfinite(f0) and np.isfinite(f1):
            h = (lo * f1 - hi * f0) / (f1 - f0)
            if not lo < h < hi:
                h = 0.5 * (lo + hi)
        else:
            h = 0.5 * (lo + hi)
        X, _ = br.correct(X0 + h * tau0, tau0, maxit=20)
        if X is None:
            return None, math.nan
        f = fn(X)
        if not math.isfinite(f):
            return None, math.nan
        if abs(f) < abs(f_best) or X_best is X0:
            X_best, f_best = X, f
        if (f > 0) == (f0 > 0):
            lo, f0, X_lo = h, f, X
            if side == -1:
                f1 *= 0.5
            side = -1
        else:
            hi, f1, X_hi = h, f, X
            if side == 1:
                f0 *= 0.5
            side = 1
        if X_hi is not None and abs(X_hi[-1] - X_lo[-1]) < tol * (1.0 + abs(X_lo[-1])) and \
                hi - lo < 1e-5:
            break
        if f == 0.0 or hi - lo < 1e-15:
            break
    return X_best, f_best


def _event(run: _Run, br: _Branch, key: str, Xe, tau) -> bool:
    """Record the event ``key`` located at ``Xe``; True when the branch stops there."""
    spec = run.spec
    q = float(Xe[-1])
    orb = br.orbit(Xe)
    value = spec.value_of(q)
    where = f"{spec.name} = {value:.10g}"
    if key == "fold":
        run.add(orb, q, "fold")
        run.bifurcation("fold", q, orb, {"multiplier": 1.0},
                        f"fold at {where}: the branch turns back (multiplier +1)",
                        restart=("fold", br, Xe, tau))
        return False
    if key == "pd":
        run.add(orb, q, "period_doubling")
        run.bifurcation("period_doubling", q, orb, {"multiplier": -1.0},
                        f"period doubling at {where} (multiplier −1); a period-{2 * br.n} orbit "
                        "branches off (continue_orbit(start=this) follows it)",
                        restart=("pd", br, Xe, tau))
        return False
    if key == "ns":
        run.add(orb, q, "neimark_sacker")
        run.bifurcation("neimark_sacker", q, orb, {}, f"Neimark–Sacker at {where}")
        return False
    if key == "gap" or key == "contact":
        k, tg, wall = orb.gap_where
        run.add(orb, q, "grazing")
        run.status = "grazing"
        run.message = (f"grazing at {where}: flight {k} touches the "
                       f"{'active' if wall == 1 else 'reverse'} flank at t = {tg:.10g}; "
                       "beyond, the orbit gains an impact (continue_orbit(start=this) restarts "
                       "with it)")
        run.bifurcation("grazing", q, orb, {"type": "flight", "flight": int(k), "wall": int(wall),
                                            "time": float(tg), "gap": float(orb.gap_min)},
                        run.message, restart=("insert", br, Xe, tau))
        return True
    # an impact slows to zero (grazing), or on a pushing wall to v_stick (sticking)
    from ...model.excitation import excitation
    p = orb.params
    speed = -orb.flank * orb.w
    react = orb.flank * (1.0 + p.lam * excitation(orb.t, p.h, p.phi, 2))
    if key == "st":
        k = int(np.argmin(np.where(react > 0.0, speed, np.inf)))
    else:
        k = int(np.argmin(speed))
    side = "active" if orb.flank[k] == 1 else "reverse"
    data = {"type": "impact", "impact": k}
    if key == "st":
        kind, restart = "stick_onset", "simulate"
        data.update(flank=int(orb.flank[k]), time=float(orb.t[k]))
        message = (f"onset of sticking at {where}: impact {k} on the pushing {side} flank "
                   f"at t = {orb.t[k]:.10g} slows to v_stick; beyond, the gear sticks "
                   "(continue_orbit(start=this) restarts on the orbit that sticks)")
    else:
        kind, restart = "grazing", "remove"
        data.update(wall=int(orb.flank[k]), time=float(orb.t[k]), w=float(orb.w[k]))
        message = (f"grazing at {where}: impact {k} on the {side} flank at "
                   f"t = {orb.t[k]:.10g} reaches zero relative velocity; beyond, the orbit "
                   "loses it (continue_orbit(start=this) restarts without it)")
    run.add(orb, q, kind)
    run.status, run.message = kind, message
    run.bifurcation(kind, q, orb, data, message, restart=(restart, br, Xe, tau))
    return True


def _stick_event(run: _Run, o_lo: PeriodicOrbit, q_lo: float, o_hi, q_hi: float):
    spec = run.spec
    where = f"{spec.name} = {spec.value_of(q_lo):.10g}"
    margin = _stick_margin(o_lo)
    scale = 1e-6
    if margin < scale:
        kind = "stick_end"
        msg = (f"end of sticking at {where}: the stick phase shrinks to nothing (left "
               f"{margin:.3g}); beyond, the gear no longer sticks (continue_orbit(start=this) "
               "restarts by simulation)")
        detail = {"stick_time": margin}
    elif o_lo.gap_min < scale or (o_hi is not None and o_hi.n_impacts != o_lo.n_impacts
                                  and _w_min(o_lo) > scale):
        kind = "grazing"
        k, tg, wall = o_lo.gap_where
        msg = (f"grazing at {where}: a flight touches the "
               f"{'active' if wall == 1 else 'reverse'} flank at t = {tg:.10g}; beyond, the "
               "impact pattern changes (continue_orbit(start=this) restarts by simulation)")
        detail = {"type": "flight", "wall": int(wall), "time": float(tg),
                  "gap": float(o_lo.gap_min)}
    elif _w_min(o_lo) < scale:
        kind = "grazing"
        msg = (f"grazing at {where}: an impact reaches zero relative velocity; beyond, the "
               "orbit loses it (continue_orbit(start=this) restarts by simulation)")
        detail = {"type": "impact", "w": _w_min(o_lo)}
    elif o_hi is None and not len(_release_roots(spec.params(q_hi), int(o_lo.stick[-1, 0]))):
        kind = "permanent_contact"
        msg = (f"permanent contact beyond {where}: the reaction no longer changes sign, the "
               "gear stays on the tooth (regime A)")
        detail = {}
    else:
        kind = "sequence_change"
        msg = (f"the orbit that sticks changes at {where}"
               + (": its release disappears" if o_hi is None else
                  f": {o_lo.summary()} becomes {o_hi.summary()}"))
        detail = {}
    run.add(o_lo, q_lo, kind)
    run.status = kind
    run.message = msg
    run.bifurcation(kind, q_lo, o_lo, detail, msg,
                    restart=None if kind == "permanent_contact" else ("simulate", None, q_lo, q_hi))
