"""The shooting equations of an impacting orbit and Newton's method on them (compiled).

An orbit with ``m`` impacts is the vector ``z = (t_0, u_0, …, t_{m−1}, u_{m−1})``.  Each flight
gives two equations, the arrival on the next wall and the impact law there, with their exact
Jacobian in ``z`` and derivative in the continued parameter ``q``.  Newton's method solves them
at a fixed ``q``, or with ``q`` unknown and the pseudo-arclength row added.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from ...model.excitation import TWO_PI, _y_derivs
from .parameter import _KIND_H, _KIND_J, _KIND_LAM, _KIND_R

#: Newton stops when the scaled residual is below this.
NEWTON_TOL = 1e-12


@njit(cache=True, nogil=True)
def _set_params(q, kind, kidx, lam, r, j, h, phi):
    """The model's numbers with the continued parameter set to ``q`` (phases in radians)."""
    hh = h.copy()
    pp = phi.copy()
    if kind == _KIND_LAM:
        lam = q
    elif kind == _KIND_R:
        r = q
    elif kind == _KIND_J:
        j = q
    elif kind == _KIND_H:
        hh[kidx] = q
    else:
        pp[kidx] = q
    return lam, r, j, hh, pp


@njit(cache=True, nogil=True)
def _flight_ends(z, n, m, i, h, cphi, sphi):
    """Flight ``i`` of the orbit ``z``, from impact ``i`` to the next (the last flight ends at
    ``t_0 + 2πn``): ``(ip, t_i, u_i, t_{i+1}, s, y-derivatives at t_i, y-derivatives at t_{i+1})``
    with ``ip`` the next impact's index and ``s = t_{i+1} − t_i``."""
    ip = i + 1 if i + 1 < m else 0
    ti = z[2 * i]
    tn = z[2 * ip] + (TWO_PI * n if ip == 0 else 0.0)
    return (ip, ti, z[2 * i + 1], tn, tn - ti, _y_derivs(ti % TWO_PI, h, cphi, sphi),
            _y_derivs(tn % TWO_PI, h, cphi, sphi))


@njit(cache=True, nogil=True)
def _system(z, fl, n, lam, r, j, h, phi, kind, kidx, F, J, Fp):
    """Residual ``F``, Jacobian ``J = ∂F/∂z`` and ``Fp = ∂F/∂q`` of the shooting equations."""
    m = fl.shape[0]
    cphi = np.cos(phi)
    sphi = np.sin(phi)
    inv_lam = 1.0 / lam
    J[:, :] = 0.0
    for i in range(m):
        ip, ti, ui, tn, s, (a0, a1, a2, a3, a4), (b0, b1, b2, b3, b4) = _flight_ends(
            z, n, m, i, h, cphi, sphi)
        un = z[2 * ip + 1]
        xi = a0 + (j if fl[i] == -1 else 0.0)
        xn = b0 + (j if fl[ip] == -1 else 0.0)
        vm = ui - s * inv_lam
        w = vm - b1
        F[2 * i] = xi + ui * s - 0.5 * s * s * inv_lam - xn
        F[2 * i + 1] = un - b1 + r * w
        J[2 * i, 2 * i] += a1 - vm
        J[2 * i, 2 * i + 1] += s
        J[2 * i, 2 * ip] += w
        J[2 * i + 1, 2 * i] += r * inv_lam
        J[2 * i + 1, 2 * i + 1] += r
        J[2 * i + 1, 2 * ip] += -(1.0 + r) * b2 - r * inv_lam
        J[2 * i + 1, 2 * ip + 1] += 1.0
        if kind == _KIND_LAM:
            Fp[2 * i] = 0.5 * s * s * inv_lam * inv_lam
            Fp[2 * i + 1] = r * s * inv_lam * inv_lam
        elif kind == _KIND_R:
            Fp[2 * i] = 0.0
            Fp[2 * i + 1] = w
        elif kind == _KIND_J:
            Fp[2 * i] = (1.0 if fl[i] == -1 else 0.0) - (1.0 if fl[ip] == -1 else 0.0)
            Fp[2 * i + 1] = 0.0
        else:
            k = kidx + 1.0
            ai = k * (ti % TWO_PI) - phi[kidx]
            an = k * (tn % TWO_PI) - phi[kidx]
            if kind == _KIND_H:
                Fp[2 * i] = np.cos(ai) - np.cos(an)
                Fp[2 * i + 1] = (1.0 + r) * k * np.sin(an)
            else:
                hk = h[kidx]
                Fp[2 * i] = hk * (np.sin(ai) - np.sin(an))
                Fp[2 * i + 1] = -(1.0 + r) * k * hk * np.cos(an)


@njit(cache=True, nogil=True)
def _scaled_norm(F, z):
    e = 0.0
    for i in range(F.shape[0]):
        a = abs(F[i]) / (1.0 + abs(z[i]))
        if a > e:
            e = a
    return e


@njit(cache=True, nogil=True)
def _newton(z, q, fl, n, lam, r, j, h, phi, kind, kidx, tau, xpred, arclength, tol, maxit):
    """Newton's method on the shooting equations, in place on ``z`` (and ``q``).

    ``arclength`` adds the pseudo-arclength row ``τ · (X − X_pred) = 0`` with ``q`` unknown;
    otherwise ``q`` is held.  Returns ``(status, q, iterations, residual)``: status 0
    converged, 1 no convergence, 2 singular or non-finite.
    """
    m2 = z.shape[0]
    F = np.empty(m2)
    J = np.empty((m2, m2))
    Fp = np.empty(m2)
    A = np.zeros((m2 + 1, m2 + 1))
    b = np.empty(m2 + 1)
    res = np.inf
    for it in range(maxit + 1):
        lam_, r_, j_, h_, phi_ = _set_params(q, kind, kidx, lam, r, j, h, phi)
        _system(z, fl, n, lam_, r_, j_, h_, phi_, kind, kidx, F, J, Fp)
        res = _scaled_norm(F, z)
        g = 0.0
        if arclength:
            for i in range(m2):
                g += tau[i] * (z[i] - xpred[i])
            g += tau[m2] * (q - xpred[m2])
            if abs(g) > res:
                res = abs(g)
        if not np.isfinite(res):
            return 2, q, it, res
        if res < tol:
            return 0, q, it, res
        if it == maxit:
            break
        if arclength:
            A[:m2, :m2] = J
            A[:m2, m2] = Fp
            A[m2, :] = tau
            b[:m2] = -F
            b[m2] = -g
            if abs(np.linalg.det(A)) == 0.0:
                return 2, q, it, res
            d = np.linalg.solve(A, b)
            for i in range(m2):
                z[i] += d[i]
            q += d[m2]
        else:
            if abs(np.linalg.det(J)) == 0.0:
                return 2, q, it, res
            d = np.linalg.solve(J, -F)
            for i in range(m2):
                z[i] += d[i]
        step = 0.0
        for i in range(d.shape[0]):
            step = max(step, abs(d[i]))
        if not np.isfinite(step):
            return 2, q, it, res
        if step < 1e-15 * (1.0 + np.abs(z).max()):
            # converged to rounding: the residual cannot fall further
            return 0, q, it + 1, res
    return 1, q, maxit, res
