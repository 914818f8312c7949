"""Codimension-two points: where two defining conditions hold at once, found along a curve.

Along each curve the other conditions are test functions; a sign change between two curve
points is located by the Illinois variant of regula falsi along the arclength (each trial
point corrected onto the curve), recorded, and offered as the start of the other curve.

* **grazing meets period doubling** (``grazing_period_doubling``): on a period-doubling curve
  the orbit's smallest gap reaches zero (or an impact's speed does); on a grazing curve the
  test ``1 + tr S + det S`` changes sign.  Beyond it on the period-doubling curve the orbit is
  no longer an orbit of the model: the curve ends there.
* **fold meets period doubling** (``fold_period_doubling``, a degenerate flip): the period-2n
  orbits born at the period doubling change side.  The test is the signed distance ``δq₁`` at
  which the doubled orbit of a small amplitude ``a`` lives, ``δq₁ ≈ c a²`` (two amplitudes,
  Richardson-extrapolated), times the side on which the period-n orbit is unstable: positive
  when the doubling is supercritical, negative when subcritical.  Where it changes sign the
  fold curve of the period-2n orbits begins.
* **grazing meets fold** (``grazing_fold``): as for period doubling, with ``1 − tr S + det S``.
* **grazing meets the onset of sticking** (``grazing_sticking``): the touched wall's reaction
  ``σ(1 + Λÿ)`` at the touching point changes sign, which is the gap's curvature there; the
  grazing curve ends (the gap's minimum merges with a maximum) and the onset-of-sticking curve
  of the orbit with that impact begins.  Found on either curve.
* **the curve turns** (``turn``): its tangent's component along the second parameter changes
  sign; there two bifurcations of the same kind, seen by one-parameter continuation in the
  first parameter, meet and vanish.
"""
from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from ...model.excitation import TWO_PI, excitation
from .curvepoint import _admissible, _orbit, _where
from .defining import _Extended, _Grazing, _Multiplier, _StickOnset, _monodromy
from .orbits import PeriodicOrbit
from .sticking import _w_min

CODIM2_KINDS = {
    "grazing_period_doubling": "grazing meets period doubling",
    "fold_period_doubling": "fold meets period doubling (the doubling changes from super- to "
                            "subcritical)",
    "grazing_fold": "grazing meets fold",
    "grazing_sticking": "grazing meets the onset of sticking (the touched wall stops pulling)",
    "turn": "the curve turns back in its second parameter",
}

#: Amplitude of the doubled orbit used by the criticality test.
_GPD_AMPLITUDE = 2e-3


@dataclasses.dataclass(eq=False)
class Codim2Point:
    """A codimension-two point on a bifurcation curve.

    Attributes
    ----------
    kind : str
        One of :data:`CODIM2_KINDS`.
    curve : str
        The kind of curve it was found on.
    other : str
        The kind of curve that starts here (empty for a turn); ``continue_bifurcation(this,
        param2)`` follows it.
    param1, param2 : str
    value1, value2 : float
        Where, in the parameters' units.
    orbit : PeriodicOrbit
    message : str
    terminal : bool
        Whether the curve ends here.
    point : int
        Index of the point in the curve's table.
    """

    kind: str
    curve: str
    other: str
    param1: str
    param2: str
    value1: float
    value2: float
    orbit: PeriodicOrbit
    message: str
    terminal: bool = False
    point: int = -1
    _X: Any = dataclasses.field(default=None, repr=False)
    _restart: Any = dataclasses.field(default=None, repr=False)

    @property
    def can_restart(self) -> bool:
        """Whether :func:`continue_bifurcation` can follow the other curve from here."""
        return self._restart is not None

    def as_dict(self) -> dict:
        return {"kind": self.kind, "curve": self.curve, "other": self.other,
                self.param1: self.value1, self.param2: self.value2, "point": self.point,
                "message": self.message}


def _pd_test(ext: _Extended, X, sign: float) -> float:
    lam, r, j, h, phi = ext.plane.at(X[-2], X[-1])
    S, _ = _monodromy(X[:-2], ext.fl, ext.n, lam, r, j, h, phi)
    tr = S[0, 0] + S[1, 1]
    det = S[0, 0] * S[1, 1] - S[0, 1] * S[1, 0]
    return (1.0 - sign * tr + det) / (1.0 + abs(tr) + abs(det))


def _codim2_tests(ext: _Extended, X, orb: PeriodicOrbit, tau) -> dict:
    """The codimension-two test functions at a curve point (keys as in :func:`_record`)."""
    kind = ext.cond.kind
    tests = {"turn": float(tau[-1])}
    if kind in ("period_doubling", "fold"):
        tests["gap"] = orb.gap_min if math.isfinite(orb.gap_min) else math.nan
        tests["w"] = _w_min(orb)
        if kind == "period_doubling":
            tests["gpd"] = _criticality(ext, X)
    elif kind == "grazing":
        tests["pd"] = _pd_test(ext, X, -1.0)
        tests["fold"] = _pd_test(ext, X, 1.0)
        tests["curv"] = ext.cond.curvature(ext, X[:-2], X[-2], X[-1])
    elif kind == "stick_onset":
        tests["react"] = ext.cond.reaction(ext, X[:-2], X[-2], X[-1])
    return tests


def _test_at(ext: _Extended, key: str, X, tau) -> float:
    """Test ``key`` at ``X``: finite, or NaN where it does not exist (an impact grazes)."""
    if key == "turn":
        return float(ext.tangent(X, tau)[-1])
    if key in ("pd", "fold"):
        return _pd_test(ext, X, -1.0 if key == "pd" else 1.0)
    if key == "curv":
        return ext.cond.curvature(ext, X[:-2], X[-2], X[-1])
    if key == "react":
        return ext.cond.reaction(ext, X[:-2], X[-2], X[-1])
    if key == "gpd":
        return _criticality(ext, X)
    orb = _orbit(ext, X)
    if key == "adm":
        return 1.0 if _admissible(ext, orb) else -1.0
    return orb.gap_min if key == "gap" else _w_min(orb)


def _locate_on_curve(ext: _Extended, X0, tau0, h_hi, f0, f1, key, tol=1e-11):
    """Zero of test ``key`` along the curve between ``X0`` (value ``f0``) and the point at
    arclength ``h_hi`` (value ``f1``): Illinois regula falsi, each trial point corrected onto
    the curve on the plane ``τ₀ · (X − X₀ − h τ₀) = 0``.  None when a correction fails."""
    lo, hi = 0.0, h_hi
    fa, fb = f0, f1
    side = 0
    best, f_best = None, math.inf
    X_lo, X_hi = X0, None
    for _ in range(100):
        h = (lo * fb - hi * fa) / (fb - fa) if fb != fa else 0.5 * (lo + hi)
        if not lo < h < hi:
            h = 0.5 * (lo + hi)
        X, _ = ext.correct(X0 + h * tau0, tau0, maxit=20)
        if X is None:
            return best
        f = _test_at(ext, key, X, tau0)
        if not np.isfinite(f):
            return best
        if abs(f) < f_best:
            best, f_best = X, abs(f)
        if (f > 0) == (fa > 0):
            lo, fa, X_lo = h, f, X
            if side == -1:
                fb *= 0.5
            side = -1
        else:
            hi, fb, X_hi = h, f, X
            if side == 1:
                fa *= 0.5
            side = 1
        if f == 0.0 or hi - lo < 1e-14:
            break
        if X_hi is not None and np.max(np.abs(X_hi[-2:] - X_lo[-2:])) < tol * (
                1.0 + np.max(np.abs(X_lo[-2:]))):
            break
    return best


_LABELS = {
    ("period_doubling", "gap"): ("grazing_period_doubling", "grazing", True),
    ("period_doubling", "w"): ("grazing_period_doubling", "grazing", True),
    ("period_doubling", "gpd"): ("fold_period_doubling", "fold", False),
    ("fold", "gap"): ("grazing_fold", "grazing", True),
    ("fold", "w"): ("grazing_fold", "grazing", True),
    ("period_doubling", "adm"): ("grazing_period_doubling", "grazing", True),
    ("fold", "adm"): ("grazing_fold", "grazing", True),
    ("grazing", "pd"): ("grazing_period_doubling", "period_doubling", False),
    ("grazing", "fold"): ("grazing_fold", "fold", False),
    ("grazing", "curv"): ("grazing_sticking", "stick_onset", True),
    ("stick_onset", "react"): ("grazing_sticking", "grazing", True),
}


def _record(run, ext: _Extended, key: str, Xe, tau, side: int, idx: int):
    """Record the codimension-two point of test ``key`` at ``Xe`` (None if it is not one)."""
    kind = ext.cond.kind
    if key == "turn":
        label, other, terminal = "turn", "", False
    else:
        label, other, terminal = _LABELS[(kind, key)]
    orb = _orbit(ext, Xe)
    v1, v2 = ext.plane.value_of(Xe[-2], Xe[-1])
    where = _where(ext, Xe)
    restart = None
    try:
        restart = _restart_data(ext, key, Xe, run.v_stick)
    except (ValueError, IndexError, np.linalg.LinAlgError):
        restart = None
    text = {"turn": f"the {kind.replace('_', ' ')} curve turns back in "
                    f"{ext.plane.spec2.name} at {where}"}.get(
        label, f"{CODIM2_KINDS[label]} at {where}"
               + (f"; the {other.replace('_', ' ')} curve starts here" if restart else "")
               + ("; the curve ends here" if terminal else ""))
    point = Codim2Point(kind=label, curve=kind, other=other if restart else "",
                        param1=ext.plane.spec1.name, param2=ext.plane.spec2.name, value1=v1,
                        value2=v2, orbit=orb, message=text, terminal=terminal, point=idx,
                        _X=Xe, _restart=restart)
    run.codim2.append(point)
    return point


def _reduced(ext: _Extended, X, k: int):
    """The orbit without impact ``k`` (which has slowed to zero): flanks, unknowns, and the
    grazing condition of the flight that replaces it."""
    fl, n = ext.fl, ext.n
    m = len(fl)
    if m < 2:
        raise ValueError("the orbit loses its only impact: there is no grazing orbit left")
    z = X[:-2]
    tk = z[2 * k] + (TWO_PI * n if k == 0 else 0.0)
    p = k - 1 if k > 0 else m - 1
    z_new = np.delete(z, [2 * k, 2 * k + 1])
    fl_new = np.delete(fl, k)
    flight = p if k > 0 else m - 2
    s = tk - z[2 * p]
    return fl_new, np.append(z_new, X[-2:]), _Grazing(flight, int(fl[k]), s)


def _inserted(ext: _Extended, X, cond: _Grazing, v_stick: float):
    """The orbit with an impact inserted where flight ``cond.k`` touches its wall."""
    z = X[:-2]
    lam, r, j, h, phi = ext.plane.at(X[-2], X[-1])
    k = cond.k
    tg = z[2 * k] + cond._touch(ext, z, X[-2], X[-1])[7]
    ug = float(excitation(tg, h, phi, 1))
    z_new = np.concatenate([z[:2 * k + 2], [tg, ug], z[2 * k + 2:]])
    fl_new = np.concatenate([ext.fl[:k + 1], [cond.wall], ext.fl[k + 1:]]).astype(np.int8)
    return fl_new, np.append(z_new, X[-2:]), _StickOnset(k + 1, v_stick)


def _restart_data(ext: _Extended, key: str, Xe, v_stick: float):
    """``(extended system, first point, how)`` of the other curve at a codimension-two point."""
    kind = ext.cond.kind
    plane = ext.plane
    if key == "turn":
        return None
    if kind in ("period_doubling", "fold") and key == "adm":
        orb = _orbit(ext, Xe)
        key = "gap" if abs(orb.gap_min) < 1e-6 else ("w" if abs(_w_min(orb)) < 1e-6 else "")
    if kind in ("period_doubling", "fold") and key == "gap":
        orb = _orbit(ext, Xe)
        k, tg, wall = orb.gap_where
        cond = _Grazing(k, wall, tg - Xe[2 * k])
        return _Extended(plane, ext.fl, ext.n, cond), Xe.copy(), "same"
    if kind in ("period_doubling", "fold") and key == "w":
        orb = _orbit(ext, Xe)
        k = int(np.argmin(-orb.flank * orb.w))
        fl, X, cond = _reduced(ext, Xe, k)
        return _Extended(plane, fl, ext.n, cond), X, "same"
    if kind == "grazing" and key in ("pd", "fold"):
        cond = _Multiplier(-1.0 if key == "pd" else 1.0)
        return _Extended(plane, ext.fl, ext.n, cond), Xe.copy(), "same"
    if kind == "grazing" and key == "curv":
        fl, X, cond = _inserted(ext, Xe, ext.cond, v_stick)
        return _Extended(plane, fl, ext.n, cond), X, "degenerate"
    if kind == "stick_onset" and key == "react":
        fl, X, cond = _reduced(ext, Xe, ext.cond.k)
        return _Extended(plane, fl, ext.n, cond), X, "degenerate"
    if kind == "period_doubling" and key == "gpd":
        return _doubled(ext, Xe, _Multiplier(1.0)) + ("doubled",)
    return None


def _doubled(ext: _Extended, Xe, cond):
    """The period-2n extended system at a period-doubling point, with the doubled orbit."""
    m = len(ext.fl)
    z = Xe[:-2]
    shift = np.zeros(2 * m)
    shift[0::2] = TWO_PI * ext.n
    ext2 = _Extended(ext.plane, np.concatenate([ext.fl, ext.fl]), 2 * ext.n, cond)
    return ext2, np.concatenate([z, z + shift, Xe[-2:]])


def _pd_direction(ext: _Extended, Xe):
    """The doubled orbit's unknowns moved along the critical eigenvector (multiplier −1): the
    direction in which the period-2n orbits leave the doubled period-n one."""
    from .stability import _flip_vectors
    lam, r, j, h, phi = ext.plane.at(Xe[-2], Xe[-1])
    delta = _flip_vectors(Xe[:-2], ext.fl, ext.n, lam, r, h, phi)
    tau = np.concatenate([delta.ravel(), -delta.ravel(), [0.0, 0.0]])
    return tau / np.linalg.norm(tau)


def _criticality(ext: _Extended, Xe) -> float:
    """Signed criticality of the period doubling at ``Xe``: the side ``δq₁`` of the doubled
    orbits of small amplitude, times the side where the period-n orbit is unstable."""
    from .shooting import NEWTON_TOL, _scaled_norm
    m = len(ext.fl)
    q2 = float(Xe[-1])
    _, X2 = _doubled(ext, Xe, None)
    e = _pd_direction(ext, Xe)[:-1]       # unknowns (z2, q1), q2 held
    if not np.all(np.isfinite(e)):
        return math.nan  # an impact grazes: the local maps, and the flip direction, do not exist
    fl2 = np.concatenate([ext.fl, ext.fl])
    Y0 = X2[:-1]
    dq = []
    for a in (_GPD_AMPLITUDE, 0.5 * _GPD_AMPLITUDE):
        Y = Y0 + a * e
        ok = False
        for _ in range(30):
            F, J, F1, _F2 = ext.plane.system(Y[:-1], fl2, 2 * ext.n, Y[-1], q2)
            g = float(e @ (Y - Y0)) - a
            if max(_scaled_norm(F, Y[:-1]), abs(g)) < NEWTON_TOL:
                ok = True
                break
            A = np.zeros((4 * m + 1, 4 * m + 1))
            A[:-1, :-1] = J
            A[:-1, -1] = F1
            A[-1] = e
            try:
                d = np.linalg.solve(A, -np.append(F, g))
            except np.linalg.LinAlgError:
                return math.nan
            Y = Y + d
            if np.max(np.abs(d)) < 1e-15 * (1.0 + np.max(np.abs(Y))):
                ok = True
                break
        if not ok:
            return math.nan
        dq.append(float(Y[-1] - Xe[-2]))
    c = (16.0 * dq[1] - dq[0]) / (3.0 * _GPD_AMPLITUDE ** 2)
    # the side where the period-n orbit is unstable: where the PD test falls (total derivative
    # along the one-parameter branch at fixed q₂)
    F, J, F1, _F2 = ext.plane.system(Xe[:-2], ext.fl, ext.n, Xe[-2], q2)
    try:
        dz = np.linalg.solve(J, -F1)
    except np.linalg.LinAlgError:
        return math.nan
    gz, g1, _g2 = ext.cond.grad(ext, Xe[:-2], Xe[-2], q2)
    dg = float(g1 + gz @ dz)
    return -c * dg
