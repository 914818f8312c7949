"""Floquet multipliers: the impact map's Jacobian and the stroboscopic monodromy (compiled).

Eliminating ``(t_{i+1}, u_{i+1})`` from one flight's equations gives the local map ``D_i``, and
the impact map's Jacobian is ``M = D_{m−1} ⋯ D_0``.  The tangent dynamics give the same
multipliers as the monodromy ``S``: flight shears and impact saltation matrices, multiplied over
one period from just after the first impact.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from .shooting import _flight_ends


@njit(cache=True, nogil=True)
def _maps(z, fl, n, lam, r, j, h, phi, w_out, M, S):
    """Relative impact velocities, impact-map Jacobian ``M`` and stroboscopic monodromy ``S``.

    ``S`` is the product of flight shears and saltation matrices, for the state just after
    impact 0; ``M`` the product of the local maps ``D_i`` in ``(t, u)``.  Both are 2 × 2.
    """
    m = fl.shape[0]
    cphi = np.cos(phi)
    sphi = np.sin(phi)
    inv_lam = 1.0 / lam
    M[:, :] = 0.0
    M[0, 0] = 1.0
    M[1, 1] = 1.0
    S[:, :] = 0.0
    S[0, 0] = 1.0
    S[1, 1] = 1.0
    for i in range(m):
        ip, ti, ui, tn, s, (a0, a1, a2, a3, a4), (b0, b1, b2, b3, b4) = _flight_ends(
            z, n, m, i, h, cphi, sphi)
        vm = ui - s * inv_lam
        w = vm - b1
        w_out[ip] = w
        # local map (t_i, u_i) -> (t_{i+1}, u_{i+1}) from G_i = H_i = 0
        dt_t = -(a1 - vm) / w
        dt_u = -s / w
        c = -(1.0 + r) * b2 - r * inv_lam
        du_t = -(r * inv_lam + c * dt_t)
        du_u = -(r + c * dt_u)
        m00 = dt_t * M[0, 0] + dt_u * M[1, 0]
        m01 = dt_t * M[0, 1] + dt_u * M[1, 1]
        m10 = du_t * M[0, 0] + du_u * M[1, 0]
        m11 = du_t * M[0, 1] + du_u * M[1, 1]
        M[0, 0] = m00
        M[0, 1] = m01
        M[1, 0] = m10
        M[1, 1] = m11
        # flight shear, then the saltation matrix of the impact at t_{i+1}
        s00 = S[0, 0] + s * S[1, 0]
        s01 = S[0, 1] + s * S[1, 1]
        s10 = S[1, 0]
        s11 = S[1, 1]
        k = -(1.0 + r) * (inv_lam + b2) / w
        S[0, 0] = -r * s00
        S[0, 1] = -r * s01
        S[1, 0] = k * s00 - r * s10
        S[1, 1] = k * s01 - r * s11


@njit(cache=True, nogil=True)
def _local_maps(z, fl, n, lam, r, h, phi, D):
    """The local maps ``D[i] = ∂(t_{i+1}, u_{i+1}) / ∂(t_i, u_i)`` of each flight and impact."""
    m = fl.shape[0]
    cphi = np.cos(phi)
    sphi = np.sin(phi)
    inv_lam = 1.0 / lam
    for i in range(m):
        ip, ti, ui, tn, s, (a0, a1, a2, a3, a4), (b0, b1, b2, b3, b4) = _flight_ends(
            z, n, m, i, h, cphi, sphi)
        vm = ui - s * inv_lam
        w = vm - b1
        D[i, 0, 0] = -(a1 - vm) / w
        D[i, 0, 1] = -s / w
        c = -(1.0 + r) * b2 - r * inv_lam
        D[i, 1, 0] = -(r * inv_lam + c * D[i, 0, 0])
        D[i, 1, 1] = -(r + c * D[i, 0, 1])


def _flip_vectors(z, fl, n, lam, r, h, phi) -> np.ndarray:
    """The eigenvector of the impact map's multiplier nearest −1, carried through the local
    maps: ``(m, 2)``, row ``i`` the shift of impact ``i`` along the critical direction (the
    direction in which a period-doubled orbit leaves)."""
    m = fl.shape[0]
    D = np.empty((m, 2, 2))
    _local_maps(z, fl, n, lam, r, h, phi, D)
    M = np.eye(2)
    for i in range(m):
        M = D[i] @ M
    ev, vec = np.linalg.eig(M)
    delta = np.empty((m, 2))
    delta[0] = np.real(vec[:, int(np.argmin(np.abs(ev + 1.0)))])
    for i in range(m - 1):
        delta[i + 1] = D[i] @ delta[i]
    return delta
