"""Floquet multipliers: the impact map's Jacobian and the stroboscopic monodromy (compiled).

Eliminating ``(t_{i+1}, u_{i+1})`` from one flight's equations gives the local map ``D_i``, and
the impact map's Jacobian is ``M = D_{m−1} ⋯ D_0``.  The tangent dynamics give the same
multipliers as the monodromy ``S``: flight shears and impact saltation matrices, multiplied over
one period from just after the first impact.

Both have a factor ``1/w`` per impact, ``w`` its relative velocity: at a grazing impact
(``w = 0``) they do not exist.  The kernels then return the number of such impacts and fill
the matrices with NaN rather than divide; the grazing itself is located on ``w``, which
:func:`_velocities` computes without any division but by ``Λ > 0``.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from .shooting import _flight_ends


@njit(cache=True, nogil=True, error_model="numpy")
def _velocities(z, fl, n, lam, h, phi, w_out):
    """Relative velocity ``w = ẋ⁻ − ẏ`` of each impact: the grazing test functions, finite
    wherever the orbit is (zero exactly at a grazing impact)."""
    m = fl.shape[0]
    cphi = np.cos(phi)
    sphi = np.sin(phi)
    inv_lam = 1.0 / lam
    for i in range(m):
        ip, ti, ui, tn, s, (a0, a1, a2, a3, a4), (b0, b1, b2, b3, b4) = _flight_ends(
            z, n, m, i, h, cphi, sphi)
        w_out[ip] = ui - s * inv_lam - b1


@njit(cache=True, nogil=True, error_model="numpy")
def _maps(z, fl, n, lam, r, j, h, phi, w_out, M, S):
    """Relative impact velocities, impact-map Jacobian ``M`` and stroboscopic monodromy ``S``.

    ``S`` is the product of flight shears and saltation matrices, for the state just after
    impact 0; ``M`` the product of the local maps ``D_i`` in ``(t, u)``.  Both are 2 × 2.
    Returns the number of impacts whose ``w`` is zero or not finite: when it is not 0,
    ``M`` and ``S`` are NaN (``w_out`` is filled all the same).
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
    singular = 0
    for i in range(m):
        ip, ti, ui, tn, s, (a0, a1, a2, a3, a4), (b0, b1, b2, b3, b4) = _flight_ends(
            z, n, m, i, h, cphi, sphi)
        vm = ui - s * inv_lam
        w = vm - b1
        w_out[ip] = w
        if w == 0.0 or not np.isfinite(w):
            singular += 1
            continue
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
    if singular:
        M[:, :] = np.nan
        S[:, :] = np.nan
    return singular


@njit(cache=True, nogil=True, error_model="numpy")
def _local_maps(z, fl, n, lam, r, h, phi, D):
    """The local maps ``D[i] = ∂(t_{i+1}, u_{i+1}) / ∂(t_i, u_i)`` of each flight and impact.

    Returns the number of impacts whose ``w`` is zero or not finite; their ``D[i]`` is NaN.
    """
    m = fl.shape[0]
    cphi = np.cos(phi)
    sphi = np.sin(phi)
    inv_lam = 1.0 / lam
    singular = 0
    for i in range(m):
        ip, ti, ui, tn, s, (a0, a1, a2, a3, a4), (b0, b1, b2, b3, b4) = _flight_ends(
            z, n, m, i, h, cphi, sphi)
        vm = ui - s * inv_lam
        w = vm - b1
        if w == 0.0 or not np.isfinite(w):
            singular += 1
            D[i, :, :] = np.nan
            continue
        D[i, 0, 0] = -(a1 - vm) / w
        D[i, 0, 1] = -s / w
        c = -(1.0 + r) * b2 - r * inv_lam
        D[i, 1, 0] = -(r * inv_lam + c * D[i, 0, 0])
        D[i, 1, 1] = -(r + c * D[i, 0, 1])
    return singular


def _flip_vectors(z, fl, n, lam, r, h, phi) -> np.ndarray:
    """The eigenvector of the impact map's multiplier nearest −1, carried through the local
    maps: ``(m, 2)``, row ``i`` the shift of impact ``i`` along the critical direction (the
    direction in which a period-doubled orbit leaves); NaN when an impact grazes, where the
    maps do not exist."""
    m = fl.shape[0]
    D = np.empty((m, 2, 2))
    if _local_maps(z, fl, n, lam, r, h, phi, D):
        return np.full((m, 2), np.nan)
    M = np.eye(2)
    for i in range(m):
        M = D[i] @ M
    ev, vec = np.linalg.eig(M)
    delta = np.empty((m, 2))
    delta[0] = np.real(vec[:, int(np.argmin(np.abs(ev + 1.0)))])
    for i in range(m - 1):
        delta[i + 1] = D[i] @ delta[i]
    return delta
