"""The imposed motion of the driving tooth, ``y(t) = Σ_k h_k cos(k t − φ_k)``, and its derivatives.

Two forms of the same formula:

* ``_y_derivs`` (compiled) returns ``y, ẏ, ÿ, y⁽³⁾, y⁽⁴⁾`` at one phase, using the angle-addition
  recurrence so that any number of harmonics costs a single ``sin``/``cos`` pair.
* :func:`excitation` (numpy) evaluates the m-th derivative on arrays, using
  ``dᵐ/dtᵐ cos(kt − φ) = kᵐ cos(kt − φ + mπ/2)``.

Times are reduced modulo 2π before evaluation: the excitation is 2π-periodic, and the reduction
keeps phases exact at late times (t ~ 1e6 would otherwise cost ~1e-10 in absolute accuracy).

``_bounds`` gives ``M_n = Σ k^n h_k``, the rigorous bounds ``|y⁽ⁿ⁾| ≤ M_n`` the event finders use.
"""
from __future__ import annotations

import numpy as np
from numba import njit

TWO_PI = 2.0 * np.pi


@njit(cache=True, nogil=True)
def _y_derivs(tau, h, cphi, sphi):
    c1 = np.cos(tau)
    s1 = np.sin(tau)
    ck = c1
    sk = s1
    y0 = 0.0
    y1 = 0.0
    y2 = 0.0
    y3 = 0.0
    y4 = 0.0
    for i in range(h.shape[0]):
        k = i + 1.0
        hk = h[i]
        if hk != 0.0:
            cc = ck * cphi[i] + sk * sphi[i]  # cos(k tau - phi_k)
            ss = sk * cphi[i] - ck * sphi[i]  # sin(k tau - phi_k)
            k2 = k * k
            y0 += hk * cc
            y1 -= k * hk * ss
            y2 -= k2 * hk * cc
            y3 += k2 * k * hk * ss
            y4 += k2 * k2 * hk * cc
        cn = ck * c1 - sk * s1
        sk = sk * c1 + ck * s1
        ck = cn
    return y0, y1, y2, y3, y4


@njit(cache=True, nogil=True)
def _bounds(h):
    """M[n] = Σ k^n |h_k| for n = 0..5: rigorous bounds on |y^(n)|."""
    m = np.zeros(6)
    for i in range(h.shape[0]):
        k = i + 1.0
        p = abs(h[i])
        for n in range(6):
            m[n] += p
            p *= k
    return m


def excitation(t, h, phi, order: int = 0) -> np.ndarray:
    """m-th time derivative of the excitation at times ``t``.

    Implements ``y⁽ᵐ⁾(t) = Σ_k h_k kᵐ cos(k t − φ_k + m π/2)``.

    Parameters
    ----------
    t : array_like
        Dimensionless times ``ω t``.
    h, phi : array_like
        Amplitudes ``h_k`` and phases ``φ_k`` (radians), k = 1..K.
    order : int
        Derivative order m ≥ 0.
    """
    t = np.asarray(t, dtype=np.float64)
    tau = np.mod(t, TWO_PI)
    h = np.asarray(h, dtype=np.float64)
    phi = np.asarray(phi, dtype=np.float64)
    out = np.zeros_like(tau)
    for i, (hk, pk) in enumerate(zip(h, phi)):
        k = i + 1
        if hk != 0.0:
            out += hk * k**order * np.cos(k * tau - pk + order * np.pi / 2)
    return out


def params_excitation(params, t, order: int = 0) -> np.ndarray:
    """:func:`excitation` for a :class:`~rattle_core.model.params.RattleParams`."""
    return excitation(t, params.h, params.phi, order)
