"""Rigorous root-free step lengths: the basis of "no impact is ever missed".

A gap function ``g(s)`` (distance to a wall during flight, or the contact reaction during a
stick phase) is known at the current point together with its first derivatives, and its higher
derivatives are bounded by the excitation bounds ``M_n = Σ k^n h_k`` (see ``excitation._bounds``).
From ``g ≥ 0`` these functions return a step ``d`` such that **g has no root in (0, d)**, proven by
a quadratic lower bound:

    g(s) ≥ g + g' s + c s²/2,   valid on [0, h] when c ≤ min g'' on [0, h].

The curvature bound ``c`` is the better of the global bound ``−M₂`` and the local one
``g''(0) − M₃ h`` over a trial interval ``h`` (the Taylor-predicted root).  Repeated steps
approach the first root from the left and never pass it: quadratically for a transversal
crossing, and still geometrically for a tangency (grazing), where the local bound makes the
convergence superlinear.  Leaving a wall with zero relative velocity (``g = g' = 0``) uses the
cubic or quartic bound instead (``_leave_step``).
"""
from __future__ import annotations

import numpy as np
from numba import njit

#: Longest trial interval for the local curvature bound; beyond it the global bound is used.
HMAX = 2.0
INF = np.inf


@njit(cache=True, nogil=True)
def _root_free(g, g1, c):
    """Smallest positive root of q(s) = g + g1 s + c s²/2 for g ≥ 0 (``inf`` if none)."""
    if c < 0.0:
        disc = g1 * g1 - 2.0 * c * g
        sq = np.sqrt(disc)
        if g1 >= 0.0:
            return (g1 + sq) / (-c)
        return 2.0 * g / (sq - g1)
    if g1 >= 0.0:
        return INF
    if c == 0.0:
        return g / (-g1)
    disc = g1 * g1 - 2.0 * c * g
    if disc < 0.0:
        return INF
    return 2.0 * g / (np.sqrt(disc) - g1)


@njit(cache=True, nogil=True)
def _safe_step(g, g1, g2, m2, m3):
    """Proven root-free distance for g with derivatives (g1, g2), |g''| ≤ m2, |g'''| ≤ m3."""
    d0 = _root_free(g, g1, g2)
    h = d0 if d0 < HMAX else HMAX
    c = g2 - m3 * h
    if c < -m2:
        c = -m2
    d = _root_free(g, g1, c)
    if d < h:
        # c ≥ −m2, so inside [0, h] the local bound is never worse than the global one
        return d
    dg = _root_free(g, g1, -m2)
    return h if h > dg else dg


@njit(cache=True, nogil=True)
def _leave_step(g2, g3, m3, m4):
    """Root-free step from g = g' = 0 with g'' = g2 ≥ 0 and g''' = g3.

    Cubic bound ``g ≥ g2 s²/2 − m3 s³/6`` is positive up to ``3 g2 / m3``; quartic bound
    ``g ≥ g3 s³/6 − m4 s⁴/24`` (for g2 ≥ 0) up to ``4 g3 / m4``.  Half of each keeps a margin.
    Returns 0 when neither applies (the gear cannot leave).
    """
    s = 0.0
    if g2 > 0.0 and m3 > 0.0:
        s = 1.5 * g2 / m3
    if g2 >= 0.0 and g3 > 0.0 and m4 > 0.0:
        s4 = 2.0 * g3 / m4
        if s4 > s:
            s = s4
    return s
