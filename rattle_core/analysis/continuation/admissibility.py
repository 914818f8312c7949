"""Whether a solution of the shooting equations is an orbit of the simulator (compiled).

The equations do not know that a flight must stay between the walls.  Each flight of a
solution is searched again with the solver's own rigorous event search (``solver._flight``),
which must find the next contact where the orbit claims it, on the claimed flank; impacts must
point into their walls and, on a pushing wall, be faster than ``v_stick``.  The smallest
interior minimum of each flight's gap to a wall is the grazing test function.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from ...model.excitation import TWO_PI, _y_derivs
from ...solver.kernel import _flight, _setup
from .shooting import _flight_ends

#: A flight's contact found by the event search must agree with the orbit's to this (scaled).
CONTACT_MATCH = 1e-8

# reasons an orbit is not an orbit of the simulator (admissibility codes)
ADMISSIBLE = 0
_BAD_ORDER = 1       # a flight of zero or negative length
_BAD_DIRECTION = 2   # an impact velocity points out of the wall
_TOO_SLOW = 3        # an impact slower than v_stick (the model makes it plastic)
_MISSED_CONTACT = 4  # the event search finds another contact first
_STICKS = 5          # r = 0 on a pushing wall: the gear would stick
_REASONS = {_BAD_ORDER: "impact times out of order", _BAD_DIRECTION:
            "an impact velocity points out of its wall", _TOO_SLOW:
            "an impact on a pushing wall is slower than v_stick (the gear sticks)", _MISSED_CONTACT:
            "a flight meets a wall before its next impact", _STICKS:
            "a plastic impact on a pushing wall sticks"}


@njit(cache=True, nogil=True)
def _gap_minima(tau0, x0, u, s_len, lam, j, h, cphi, sphi, leave):
    """Smallest interior local minimum of the two gaps over a flight of length ``s_len``.

    The extrema of the gaps are the roots of the relative velocity ``d(s) = u − s/Λ − ẏ``;
    a root where ``d' > 0`` is a minimum of the active gap, one where ``d' < 0`` a minimum of
    the reverse gap.  Roots are bracketed on a grid and polished by bisection.  Returns
    ``(gap, s, wall)``, wall ±1, or ``(inf, nan, 0)`` when the flight has no interior minimum.
    ``leave`` = ±1 when the flight leaves that wall with zero relative velocity (a release):
    the relative velocity then starts at zero and its sign is known, so the rounding noise
    near the start is not mistaken for a root.
    """
    inv_lam = 1.0 / lam
    nstep = int(s_len / 0.02) + 8
    hs = s_len / nstep
    best = np.inf
    best_s = np.nan
    best_wall = 0
    edge = 1e-9 * (1.0 + s_len)
    y0, y1, y2, y3, y4 = _y_derivs(tau0 % TWO_PI, h, cphi, sphi)
    d_prev = u - y1
    if leave != 0:
        d_prev = float(leave)
    s_prev = 0.0
    starting = leave != 0
    for kk in range(1, nstep + 1):
        s = kk * hs
        y0, y1, y2, y3, y4 = _y_derivs((tau0 + s) % TWO_PI, h, cphi, sphi)
        d = u - s * inv_lam - y1
        if starting:
            if leave * d > 1e-12:
                starting = False
            else:
                s_prev = s
                continue
        if (d_prev < 0.0) != (d < 0.0) or d == 0.0:
            lo = s_prev
            hi = s
            dlo = d_prev
            for _ in range(80):
                mid = 0.5 * (lo + hi)
                if mid <= lo or mid >= hi:
                    break
                z0, z1, z2, z3, z4 = _y_derivs((tau0 + mid) % TWO_PI, h, cphi, sphi)
                dm = u - mid * inv_lam - z1
                if (dm < 0.0) == (dlo < 0.0) and dm != 0.0:
                    lo = mid
                    dlo = dm
                else:
                    hi = mid
            sr = 0.5 * (lo + hi)
            if edge < sr < s_len - edge:
                z0, z1, z2, z3, z4 = _y_derivs((tau0 + sr) % TWO_PI, h, cphi, sphi)
                ga = x0 + u * sr - 0.5 * sr * sr * inv_lam - z0
                curv = -inv_lam - z2
                if curv > 0.0:
                    gap = ga
                    wall = 1
                else:
                    gap = j - ga
                    wall = -1
                if gap < best:
                    best = gap
                    best_s = sr
                    best_wall = wall
        d_prev = d
        s_prev = s
    return best, best_s, best_wall


@njit(cache=True, nogil=True)
def _inspect(z, fl, n, lam, r, j, h, phi, v_stick, check, gmin, gs, gwall, contact):
    """Admissibility and the grazing test data of an impact orbit.

    Fills per flight ``i`` (from impact i to i+1): ``gmin`` smallest interior gap minimum,
    ``gs`` where, ``gwall`` which wall; ``contact`` the event search's first contact minus
    the orbit's (nan when not checked).  Returns the admissibility code (0 admissible).
    """
    m = fl.shape[0]
    cphi, sphi, mb, inv_lam, m2, m3, m4, v_eff = _setup(lam, h, phi, v_stick)
    code = ADMISSIBLE
    for i in range(m):
        ip, ti, ui, tn, s, (a0, a1, a2, a3, a4), (b0, b1, b2, b3, b4) = _flight_ends(
            z, n, m, i, h, cphi, sphi)
        xi = a0 + (j if fl[i] == -1 else 0.0)
        w = ui - s * inv_lam - b1
        contact[i] = np.nan
        gmin[i], gs[i], gwall[i] = _gap_minima(ti, xi, ui, max(s, 0.0), lam, j, h, cphi, sphi,
                                               fl[i] if r == 0.0 else 0)
        if not s > 0.0:
            code = code if code != ADMISSIBLE else _BAD_ORDER
            continue
        if not fl[ip] * w < 0.0:
            code = code if code != ADMISSIBLE else _BAD_DIRECTION
            continue
        if abs(w) < v_eff and fl[ip] * (1.0 + lam * b2) > 0.0:
            # on a pushing wall the model ends the rebounds there: the gear sticks (on a
            # pulling wall it leaves at once, within r·v_stick of the bounce)
            code = code if code != ADMISSIBLE else _TOO_SLOW
        leave = 0
        if r == 0.0:
            react = fl[i] * (1.0 + lam * a2)
            if react > 0.0:
                code = code if code != ADMISSIBLE else _STICKS
            leave = fl[i]
        if check:
            slack = CONTACT_MATCH * (1.0 + s) + 1e-12 / abs(w)
            sc, hit, c0, c1, c2, c3, c4 = _flight(lam, j, h, cphi, sphi, m2, m3, m4,
                                                  ti % TWO_PI, xi, ui, s + 2.0 * slack, leave)
            contact[i] = sc - s if hit == fl[ip] else -s
            if hit != fl[ip] or abs(sc - s) > slack:
                code = code if code != ADMISSIBLE else _MISSED_CONTACT
    return code
