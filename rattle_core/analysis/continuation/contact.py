"""The contact boundary in two parameters: where rattle starts, ``Λ_c = 1 / max_t(−ÿ)``.

Below ``Λ_c`` the reaction ``R̃ = 1 + Λÿ`` never changes sign and a gear resting on the active
flank stays there (regime A).  At the boundary the reaction's minimum just touches zero:
``1 + Λ ÿ(t*) = 0`` and ``y⁽³⁾(t*) = 0``, two equations in ``(t*, q₁, q₂)``, a curve, with
an exact Jacobian.  The tracked maximum of ``−ÿ`` must stay the largest one; where another
takes over, the boundary has a corner, and the curve goes on from the new maximum.
"""
from __future__ import annotations

import numpy as np

from ...model.excitation import TWO_PI, excitation
from ..overlays import _max_neg_ydd
from .defining import _null_vector
from .parameter import _KIND_LAM
from .plane import _Plane, _dy_dparam
from .results import _limit
from .shooting import NEWTON_TOL


class _ContactCond:
    kind = "contact"


class _ContactSystem:
    """``(1 + Λÿ(t*), y⁽³⁾(t*)) = 0`` on ``X = (t*, q₁, q₂)``, with the pseudo-arclength
    machinery's interface (:class:`~.defining._Extended`)."""

    def __init__(self, plane: _Plane):
        self.plane = plane
        self.N = 3
        self.cond = _ContactCond()
        self.fl = np.zeros(0, dtype=np.int8)
        self.n = 1

    def residual_jacobian(self, X):
        t, q1, q2 = float(X[0]), float(X[1]), float(X[2])
        lam, r, j, h, phi = self.plane.at(q1, q2)
        y2, y3, y4 = (float(excitation(t, h, phi, k)) for k in (2, 3, 4))
        R = np.array([1.0 + lam * y2, y3])
        A = np.zeros((2, 3))
        A[0, 0] = lam * y3
        A[1, 0] = y4
        for col, (kind, kidx, scale) in zip((1, 2), self.plane.kinds(q1, q2)):
            if kind == _KIND_LAM:
                A[0, col] = y2 * scale
            else:
                A[0, col] = lam * _dy_dparam(kind, kidx, 2, t, h, phi) * scale
                A[1, col] = _dy_dparam(kind, kidx, 3, t, h, phi) * scale
        return R, A

    def tangent(self, X, prev=None):
        return _null_vector(self.residual_jacobian(X)[1], prev)

    def correct(self, Xp, tau, maxit: int = 12, fix: int | None = None):
        X = Xp.copy()
        for it in range(maxit + 1):
            R, A = self.residual_jacobian(X)
            if fix is None:
                extra = float(tau @ (X - Xp))
                B, b = np.vstack([A, tau[None, :]]), -np.append(R, extra)
                res = max(np.max(np.abs(R)), abs(extra))
            else:
                B, b = np.delete(A, fix, axis=1), -R
                res = float(np.max(np.abs(R)))
            if res < NEWTON_TOL:
                return X, it
            if it == maxit:
                break
            try:
                d = np.linalg.solve(B, b)
            except np.linalg.LinAlgError:
                return None, it
            if fix is not None:
                d = np.insert(d, 3 + fix, 0.0)
            if not np.all(np.isfinite(d)):
                return None, it
            X = X + d
        return None, maxit

    def accept(self, X):
        pass

    def is_global(self, X) -> float:
        """Largest ``−ÿ`` minus the tracked one (zero while the tracked maximum is global)."""
        lam, r, j, h, phi = self.plane.at(X[1], X[2])
        p = self.plane.params(X[1], X[2])
        return float(_max_neg_ydd(p) + excitation(X[0], h, phi, 2))


def _global_start(plane: _Plane, q1: float, q2: float):
    """``(t*, q₁, q₂)`` on the boundary near ``q₁``: ``t*`` the global maximum of ``−ÿ``."""
    p = plane.params(q1, q2)
    t = np.linspace(0.0, TWO_PI, 4096, endpoint=False)
    f = -excitation(t, p.h, p.phi, 2)
    return np.array([float(t[int(np.argmax(f))]), q1, q2])


def _contact_side(sys_: _ContactSystem, X, tau, ds, ds_min, ds_max, bounds_q, max_points,
                  count, cancel):
    """One side of the contact boundary; corners where another maximum of ``−ÿ`` takes over."""
    (a1, b1), (a2, b2) = bounds_q
    pts = [(X, "")]
    status = message = ""
    while True:
        status, message = _limit(count[0], max_points, cancel)
        if status:
            break
        X_new, it = sys_.correct(X + ds * tau, tau)
        at_bound = False
        if X_new is not None and not (a1 <= X_new[1] <= b1 and a2 <= X_new[2] <= b2):
            idx, qb = (1, (b1 if X_new[1] > b1 else a1)) if not a1 <= X_new[1] <= b1 else \
                (2, (b2 if X_new[2] > b2 else a2))
            frac = (qb - X[idx]) / (X_new[idx] - X[idx])
            Xg = X + frac * (X_new - X)
            Xg[idx] = qb
            X_new, _ = sys_.correct(Xg, None, maxit=30, fix=idx - 3)
            at_bound = True
        tau_new = None if X_new is None else sys_.tangent(X_new, tau)
        if tau_new is not None and float(tau_new @ tau) < 0.95 and ds > 4 * ds_min:
            X_new = None
        if X_new is None:
            ds *= 0.5
            if ds < ds_min:
                status, message = "step_too_small", "the corrector failed"
                break
            continue
        if sys_.is_global(X_new) > 1e-12:
            # another maximum of −ÿ overtook the tracked one: locate the corner, jump to it
            lo, hi = 0.0, 1.0
            for _ in range(60):
                mid = 0.5 * (lo + hi)
                Xm, _ = sys_.correct(X + mid * (X_new - X), tau, maxit=20)
                if Xm is None or sys_.is_global(Xm) > 1e-13:
                    hi = mid
                else:
                    lo = mid
            Xc, _ = sys_.correct(X + lo * (X_new - X), tau, maxit=20)
            if Xc is None:
                status, message = "step_too_small", "could not locate a corner of the boundary"
                break
            pts.append((Xc, "corner"))
            X_new = _global_start(sys_.plane, Xc[1], Xc[2])
            X_new[0] = _polish_t(sys_, X_new)
            tau_new = sys_.tangent(X_new, tau)
        X, tau = X_new, tau_new
        pts.append((X, ""))
        count[0] += 1
        if at_bound:
            status, message = "bound", "reached the bound"
            break
        ds = min(ds * (1.5 if it <= 3 else 1.0), ds_max)
    return pts, status, message


def _polish_t(sys_: _ContactSystem, X) -> float:
    lam, r, j, h, phi = sys_.plane.at(X[1], X[2])
    t = float(X[0])
    for _ in range(50):
        y3 = float(excitation(t, h, phi, 3))
        y4 = float(excitation(t, h, phi, 4))
        if y4 == 0.0:
            break
        step = y3 / y4
        t -= step
        if abs(step) < 1e-15:
            break
    return t
