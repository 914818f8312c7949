"""Defining conditions of bifurcations, and the extended systems they make with an orbit.

A bifurcation of codimension one is the orbit's shooting equations ``F(z; q₁, q₂) = 0`` plus
one scalar condition ``g(z; q₁, q₂) = 0``.  With ``z`` of size ``2m`` that is ``2m + 1``
equations in ``2m + 2`` unknowns: a curve in the plane of the two parameters.

* **Period doubling**: ``g = (1 + tr S + det S) / (1 + |tr S| + det S)``, zero where a Floquet
  multiplier is −1 (``S``, the monodromy, is 2 × 2).  **Fold**: the same with ``1 − tr S``
  (multiplier +1).  Their gradients are central differences of the compiled monodromy.
* **Grazing** of flight ``k`` on a wall: ``g = gap(s*)`` at the interior minimum ``s*`` of the
  gap, where its slope is zero; by the envelope theorem ``∂g = ∂gap`` at fixed ``s*``, in
  closed form.  (An impact that slows to zero on a pulling wall is the grazing of the flight
  that replaces it: the orbit without that impact touches the wall there.)
* **Onset of sticking** of impact ``k`` on its pushing flank ``σ``: ``g = σ w_k + v_eff``, zero
  where the impact's speed ``−σ w_k`` has fallen to ``v_eff = max(v_stick, 1e-12)``; ``w_k``
  and its gradient are closed form.

The shooting Jacobian is exact (:mod:`.shooting`), so Newton's method on the extended system
converges quadratically wherever the condition's gradient is exact too.
"""
from __future__ import annotations

import numpy as np

from ...model.excitation import TWO_PI, excitation
from ...solver.kernel import V_FLOOR
from .parameter import _KIND_J, _KIND_LAM
from .plane import _Plane, _dy_dparam
from .shooting import NEWTON_TOL, _scaled_norm
from .stability import _maps

#: Relative step of the central differences of the multiplier conditions.
_FD_STEP = 1e-7


def _monodromy(z, fl, n, lam, r, j, h, phi):
    m = len(fl)
    w = np.empty(m)
    M = np.empty((2, 2))
    S = np.empty((2, 2))
    _maps(z, fl, n, lam, r, j, h, phi, w, M, S)
    return S, w


class _Multiplier:
    """A Floquet multiplier at ``+1`` (fold) or ``−1`` (period doubling)."""

    def __init__(self, sign: float):
        self.sign = sign
        self.kind = "period_doubling" if sign < 0 else "fold"

    def value(self, ext, z, q1, q2) -> float:
        S, _ = _monodromy(z, ext.fl, ext.n, *ext.plane.at(q1, q2))
        tr = S[0, 0] + S[1, 1]
        det = S[0, 0] * S[1, 1] - S[0, 1] * S[1, 0]
        return (1.0 - self.sign * tr + det) / (1.0 + abs(tr) + abs(det))

    def grad(self, ext, z, q1, q2):
        X = np.append(z, [q1, q2])
        g = np.empty(len(X))
        for i in range(len(X)):
            d = _FD_STEP * (1.0 + abs(X[i]))
            a, b = X.copy(), X.copy()
            a[i] += d
            b[i] -= d
            g[i] = (self.value(ext, a[:-2], a[-2], a[-1])
                    - self.value(ext, b[:-2], b[-2], b[-1])) / (2.0 * d)
        return g[:-2], g[-2], g[-1]

    def accept(self, ext, z, q1, q2):
        pass


class _Grazing:
    """Flight ``k`` touches ``wall`` (+1 active, −1 reverse) at an interior minimum of its gap."""

    kind = "grazing"

    def __init__(self, k: int, wall: int, s: float):
        self.k, self.wall, self.s = int(k), int(wall), float(s)

    def _touch(self, ext, z, q1, q2):
        lam, r, j, h, phi = ext.plane.at(q1, q2)
        k, m = self.k, len(ext.fl)
        tk, uk = z[2 * k], z[2 * k + 1]
        kn = k + 1 if k + 1 < m else 0
        s_len = z[2 * kn] + (TWO_PI * ext.n if kn == 0 else 0.0) - tk
        s = min(max(self.s, 0.0), s_len)
        # the gap's stationary point: relative velocity u − s/Λ − ẏ(t_k + s) = 0
        for _ in range(40):
            d = uk - s / lam - float(excitation(tk + s, h, phi, 1))
            dd = -1.0 / lam - float(excitation(tk + s, h, phi, 2))
            if dd == 0.0:
                break
            step = d / dd
            s -= step
            if abs(step) < 1e-15 * (1.0 + abs(s)):
                break
        return lam, r, j, h, phi, tk, uk, s

    def value(self, ext, z, q1, q2) -> float:
        lam, r, j, h, phi, tk, uk, s = self._touch(ext, z, q1, q2)
        xk = float(excitation(tk, h, phi)) + (j if ext.fl[self.k] == -1 else 0.0)
        ga = xk + uk * s - 0.5 * s * s / lam - float(excitation(tk + s, h, phi))
        return ga if self.wall == 1 else j - ga

    def grad(self, ext, z, q1, q2):
        lam, r, j, h, phi, tk, uk, s = self._touch(ext, z, q1, q2)
        sg = float(self.wall)
        gz = np.zeros(len(z))
        gz[2 * self.k] = sg * (float(excitation(tk, h, phi, 1))
                               - float(excitation(tk + s, h, phi, 1)))
        gz[2 * self.k + 1] = sg * s
        on_rev = 1.0 if ext.fl[self.k] == -1 else 0.0
        out = []
        for kind, kidx, scale in ext.plane.kinds(q1, q2):
            if kind == _KIND_LAM:
                d = sg * 0.5 * s * s / (lam * lam)
            elif kind == _KIND_J:
                d = on_rev if self.wall == 1 else 1.0 - on_rev
            else:
                d = sg * (_dy_dparam(kind, kidx, 0, tk, h, phi)
                          - _dy_dparam(kind, kidx, 0, tk + s, h, phi))
            out.append(d * scale)
        return gz, out[0], out[1]

    def curvature(self, ext, z, q1, q2) -> float:
        """The gap's second derivative at the touch, ``σ(−1/Λ − ÿ)``: it vanishes where the
        touched wall stops pulling the gear away (the reaction ``1 + Λÿ`` changes sign)."""
        lam, r, j, h, phi, tk, uk, s = self._touch(ext, z, q1, q2)
        return self.wall * (-1.0 / lam - float(excitation(tk + s, h, phi, 2)))

    def touch_time(self, ext, z, q1, q2) -> float:
        return float(self._touch(ext, z, q1, q2)[5] + self._touch(ext, z, q1, q2)[7])

    def accept(self, ext, z, q1, q2):
        self.s = self._touch(ext, z, q1, q2)[7]


class _StickOnset:
    """Impact ``k`` on its pushing flank slows to ``v_eff``: beyond, the gear sticks."""

    kind = "stick_onset"

    def __init__(self, k: int, v_stick: float):
        self.k = int(k)
        self.v_eff = max(float(v_stick), V_FLOOR)

    def _w(self, ext, z, q1, q2):
        lam, r, j, h, phi = ext.plane.at(q1, q2)
        k, m = self.k, len(ext.fl)
        p = k - 1 if k > 0 else m - 1
        tk = z[2 * k] + (TWO_PI * ext.n if k == 0 else 0.0)
        s = tk - z[2 * p]
        w = z[2 * p + 1] - s / lam - float(excitation(tk, h, phi, 1))
        return lam, h, phi, p, tk, s, w

    def value(self, ext, z, q1, q2) -> float:
        w = self._w(ext, z, q1, q2)[-1]
        return float(ext.fl[self.k]) * w + self.v_eff

    def grad(self, ext, z, q1, q2):
        lam, h, phi, p, tk, s, w = self._w(ext, z, q1, q2)
        sg = float(ext.fl[self.k])
        gz = np.zeros(len(z))
        gz[2 * p + 1] += sg
        gz[2 * p] += sg / lam
        gz[2 * self.k] += sg * (-1.0 / lam - float(excitation(tk, h, phi, 2)))
        out = []
        for kind, kidx, scale in ext.plane.kinds(q1, q2):
            if kind == _KIND_LAM:
                d = sg * s / (lam * lam)
            else:
                d = -sg * _dy_dparam(kind, kidx, 1, tk, h, phi)
            out.append(d * scale)
        return gz, out[0], out[1]

    def reaction(self, ext, z, q1, q2) -> float:
        """``σ(1 + Λÿ)`` at the impact: it vanishes where the flank stops pushing."""
        lam, h, phi, p, tk, s, w = self._w(ext, z, q1, q2)
        return float(ext.fl[self.k]) * (1.0 + lam * float(excitation(tk, h, phi, 2)))

    def accept(self, ext, z, q1, q2):
        pass


class _Extended:
    """One impact sequence ``(flanks, period)`` and one condition, in the plane ``(q₁, q₂)``:
    residual, Jacobian, tangent and Newton's method on ``X = (z, q₁, q₂)``."""

    def __init__(self, plane: _Plane, fl, n: int, cond):
        self.plane = plane
        self.fl = np.ascontiguousarray(fl, dtype=np.int8)
        self.n = int(n)
        self.cond = cond
        self.N = 2 * len(self.fl) + 2

    def residual_jacobian(self, X):
        z, q1, q2 = X[:-2], float(X[-2]), float(X[-1])
        F, J, F1, F2 = self.plane.system(z, self.fl, self.n, q1, q2)
        g = self.cond.value(self, z, q1, q2)
        gz, g1, g2 = self.cond.grad(self, z, q1, q2)
        A = np.empty((self.N - 1, self.N))
        A[:-1, :-2] = J
        A[:-1, -2] = F1
        A[:-1, -1] = F2
        A[-1, :-2] = gz
        A[-1, -2] = g1
        A[-1, -1] = g2
        return np.append(F, g), A

    def residual(self, X) -> float:
        R, _ = self.residual_jacobian(X)
        return max(_scaled_norm(R[:-1], X[:-2]), abs(R[-1]))

    def tangent(self, X, prev=None):
        """Unit null vector of the ``(2m + 1) × (2m + 2)`` Jacobian, oriented along ``prev``."""
        return _null_vector(self.residual_jacobian(X)[1], prev)

    def correct(self, Xp, tau, maxit: int = 12, fix: int | None = None):
        """Newton's method from ``Xp``: on the plane ``τ · (X − Xp) = 0`` or, with ``fix`` = −1
        or −2, with ``q₂`` or ``q₁`` held.  Returns ``(X, iterations)``, ``X`` None on failure."""
        X = Xp.copy()
        for it in range(maxit + 1):
            try:
                R, A = self.residual_jacobian(X)
            except (ZeroDivisionError, FloatingPointError, ValueError):
                return None, it  # an impact at zero speed: no orbit of this sequence here
            if not np.all(np.isfinite(R)) or not np.all(np.isfinite(A)):
                return None, it
            res = max(_scaled_norm(R[:-1], X[:-2]), abs(R[-1]))
            if fix is None:
                extra = float(tau @ (X - Xp))
                res = max(res, abs(extra))
            if res < NEWTON_TOL:
                return X, it
            if it == maxit:
                break
            if fix is None:
                B = np.vstack([A, tau[None, :]])
                d = _solve(B, -np.append(R, extra))
            else:
                d = _solve(np.delete(A, fix, axis=1), -R)
                if d is not None:
                    d = np.insert(d, self.N + fix, 0.0)
            if d is None:
                return None, it
            if not np.all(np.isfinite(d)):
                return None, it
            X = X + d
            if np.max(np.abs(d)) < 1e-15 * (1.0 + np.max(np.abs(X))):
                return X, it + 1
        return None, maxit

    def accept(self, X):
        self.cond.accept(self, X[:-2], float(X[-2]), float(X[-1]))


def _null_vector(A, prev=None):
    """Unit null vector of the ``(N − 1) × N`` matrix ``A``: bordered by ``prev`` when given
    (and oriented along it), else the last right singular vector."""
    t = None
    if prev is not None:
        rhs = np.zeros(A.shape[1])
        rhs[-1] = 1.0
        t = _solve(np.vstack([A, prev[None, :]]), rhs)
    if t is None:
        t = np.linalg.svd(A)[2][-1]
    t = t / np.linalg.norm(t)
    if prev is not None and float(t @ prev) < 0.0:
        t = -t
    return t


def _solve(B, b):
    try:
        d = np.linalg.solve(B, b)
    except np.linalg.LinAlgError:
        return None
    return d if np.all(np.isfinite(d)) else None
