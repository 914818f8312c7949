"""Continuation of periodic impacting orbits, stable and unstable, and their bifurcations.

A brute-force bifurcation diagram shows only the attractors reached from one initial state.
This module follows one periodic orbit as a parameter changes, whether the orbit is stable or
not, and finds where it is born, where it loses stability and why.

**Orbits as fixed points of the impact map.**  Between impacts the gear flies on a parabola,
``x = x_i + u_i s − s²/(2Λ)``, so a periodic orbit with ``m`` impacts in ``n`` forcing periods
is fixed by its impact times ``t_i`` and post-impact velocities ``u_i``.  The position at an
impact is the wall's, ``X_i = y(t_i)`` (active flank) or ``y(t_i) + j`` (reverse flank).  Each
flight gives two equations (multiple shooting over the impacts, with ``t_m = t_0 + 2πn`` and
``u_m = u_0``)::

    G_i = X_i(t_i) + u_i s_i − s_i²/(2Λ) − X_{i+1}(t_{i+1}) = 0        (arrival on the wall)
    H_i = u_{i+1} − ẏ(t_{i+1}) + r w_{i+1} = 0                          (impact law)

with ``s_i = t_{i+1} − t_i`` and the incoming relative velocity ``w_{i+1} = u_i − s_i/Λ −
ẏ(t_{i+1})``.  Everything is closed form, so the ``2m × 2m`` Jacobian is exact; Newton's
method solves the system to machine precision in a few steps.  The equations alone do not
know that the flight must stay between the walls: every solution is checked with the solver's
own rigorous event search (``solver._flight``), which must find the next contact exactly where
the orbit claims it, on the claimed flank.  An orbit that passes this check is an orbit of the
simulator, impact for impact.

**Floquet multipliers.**  Eliminating ``(t_{i+1}, u_{i+1})`` from one flight's equations by the
implicit-function theorem gives the local map ``D_i``; the impact map's Jacobian is
``M = D_{m−1} ⋯ D_0``.  Its eigenvalues are the Floquet multipliers (the stroboscopic map is
conjugate to the impact map).  The same numbers come out of the tangent dynamics: flights
shear ``(δx, δv)`` by ``[[1, s], [0, 1]]`` and each impact applies the saltation matrix
``[[−r, 0], [−(1+r)(1/Λ + ÿ)/w, −r]]`` (as in ``solver``); their product is the monodromy of
the stroboscopic map at the time just after the first impact, which this module reports.
Flights preserve area and each impact multiplies it by ``r²``, so ``det M = r^{2m}``: for
``r < 1`` a complex pair can never reach the unit circle, and a Neimark–Sacker bifurcation
(tested as ``det M = 1`` with ``|tr M| < 2``) cannot happen in this model.  The detector is
there for completeness and reports nothing.

**Stick phases.**  A gear that sticks to a tooth leaves it where the reaction ``R̃ = 1 + Λ ÿ``
changes sign, a phase that depends on the parameters only.  The orbit after a release is
therefore the same whatever happened before: the return map is locally constant, its Jacobian
is zero and both multipliers are exactly 0 (superstable).  Newton's method is not needed
there, nor a fit (the chatter before sticking is an infinite impact sequence): a stick
orbit is computed exactly instead: from a release, ``simulate`` runs until the gear sticks
and releases again, until a release repeats.  Such orbits have no folds and no flip or
torus bifurcations; they are followed in natural-parameter steps, and they end where their
impact pattern changes (a grazing flight) or where the stick phase shrinks to nothing.  As in
the solver, the stick phase starts at the first contact slower than ``v_stick``, which ends
the chatter (the rest of the exact model's chatter would take a time of order ``v_stick``).
How many chatter impacts the solver resolves above ``v_stick`` changes along such a branch;
the chatter before a stick phase counts as one element of the impact pattern.

**Pseudo-arclength continuation.**  With the parameter ``p`` added to the unknowns, the
solutions form curves.  From a point and its unit tangent ``τ`` (the null vector of
``[∂F/∂z | ∂F/∂p]``), a step ``ds`` predicts ``X + ds τ``, and Newton corrects on the plane
orthogonal to ``τ``.  The curve may turn back in ``p`` (a fold) and the method follows it
through.  The step grows when Newton converges quickly and shrinks when it does not, or when
the tangent turns too fast.

**Bifurcations** are zeros of test functions evaluated at every point: a fold where the
tangent's parameter component changes sign (a multiplier crosses +1, ``det(I − M) = 0``),
a period doubling where ``det(I + M)`` changes sign (−1), Neimark–Sacker where ``det M − 1``
does with ``|tr M| < 2``.  The nonsmooth events: **grazing**, where the smallest interior
minimum of a flight's gap to a wall crosses zero (the orbit gains an impact) or where an
impact's relative velocity reaches zero (it loses one); the **onset of sticking**, where an
impact on a pushing wall becomes slower than ``v_stick`` (the model then sticks); the **end
of sticking**, where a stick phase shrinks to zero length.  A sign change between two points
is located by the Illinois variant of regula falsi along the arclength, to about 1e-10 in the
parameter.  At a period doubling the branch of the doubled orbit is tangent to the critical
eigenvector: the doubled system is started there along that direction.  At a grazing the
branch stops, and :func:`continue_orbit` can restart from the reported point with the new
impact sequence (an impact inserted at the touching point, or removed): of the two directions
the new branch can leave in, the one whose orbit the event search accepts.  After the onset or
end of sticking the restart is a simulation from the old orbit, just beyond the event.
"""
from __future__ import annotations

import dataclasses
import inspect
import math
import threading
import time
from typing import TYPE_CHECKING, Any, Callable, Sequence

import numpy as np
from numba import njit

from ..model.excitation import TWO_PI, _bounds, _y_derivs
from ..model.params import RattleParams, check_range, parse_name
from ..solver.kernel import V_FLOOR, _flight
from ..solver.trajectory import SOLVER_VERSION, simulate

if TYPE_CHECKING:
    import pandas as pd

CONTINUATION_VERSION = "1.0.0"
#: Most impacts one orbit may have (over its whole period).
MAX_ORBIT_IMPACTS = 512
#: Longest period (in forcing periods) of an orbit that :func:`find_orbit` looks for.
MAX_ORBIT_PERIOD = 32
#: Most branch points one call may compute.
MAX_POINTS = 100_000
#: Newton stops when the scaled residual is below this.
NEWTON_TOL = 1e-12
#: Bifurcations are located to this distance in the internal parameter.
LOCATE_TOL = 1e-11
#: A flight's contact found by the event search must agree with the orbit's to this (scaled).
CONTACT_MATCH = 1e-8

PARAMETERS = ("lam", "r", "j", "hK", "phiK", "rpm", "drag_torque")

_KIND_LAM, _KIND_R, _KIND_J, _KIND_H, _KIND_PHI = 0, 1, 2, 3, 4

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


# ----- compiled kernels ------------------------------------------------------------------

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
def _system(z, fl, n, lam, r, j, h, phi, kind, kidx, F, J, Fp):
    """Residual ``F``, Jacobian ``J = ∂F/∂z`` and ``Fp = ∂F/∂q`` of the shooting equations."""
    m = fl.shape[0]
    cphi = np.cos(phi)
    sphi = np.sin(phi)
    inv_lam = 1.0 / lam
    J[:, :] = 0.0
    for i in range(m):
        ip = i + 1 if i + 1 < m else 0
        ti = z[2 * i]
        ui = z[2 * i + 1]
        tn = z[2 * ip] + (TWO_PI * n if ip == 0 else 0.0)
        un = z[2 * ip + 1]
        s = tn - ti
        a0, a1, a2, a3, a4 = _y_derivs(ti % TWO_PI, h, cphi, sphi)
        b0, b1, b2, b3, b4 = _y_derivs(tn % TWO_PI, h, cphi, sphi)
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
        ip = i + 1 if i + 1 < m else 0
        ti = z[2 * i]
        ui = z[2 * i + 1]
        tn = z[2 * ip] + (TWO_PI * n if ip == 0 else 0.0)
        s = tn - ti
        a0, a1, a2, a3, a4 = _y_derivs(ti % TWO_PI, h, cphi, sphi)
        b0, b1, b2, b3, b4 = _y_derivs(tn % TWO_PI, h, cphi, sphi)
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
    cphi = np.cos(phi)
    sphi = np.sin(phi)
    mb = _bounds(h)
    inv_lam = 1.0 / lam
    m2 = inv_lam + mb[2]
    m3 = mb[3]
    m4 = mb[4]
    v_eff = v_stick if v_stick > V_FLOOR else V_FLOOR
    code = ADMISSIBLE
    for i in range(m):
        ip = i + 1 if i + 1 < m else 0
        ti = z[2 * i]
        ui = z[2 * i + 1]
        tn = z[2 * ip] + (TWO_PI * n if ip == 0 else 0.0)
        s = tn - ti
        a0, a1, a2, a3, a4 = _y_derivs(ti % TWO_PI, h, cphi, sphi)
        b0, b1, b2, b3, b4 = _y_derivs(tn % TWO_PI, h, cphi, sphi)
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


@njit(cache=True, nogil=True)
def _local_maps(z, fl, n, lam, r, h, phi, D):
    """The local maps ``D[i] = ∂(t_{i+1}, u_{i+1}) / ∂(t_i, u_i)`` of each flight and impact."""
    m = fl.shape[0]
    cphi = np.cos(phi)
    sphi = np.sin(phi)
    inv_lam = 1.0 / lam
    for i in range(m):
        ip = i + 1 if i + 1 < m else 0
        ti = z[2 * i]
        ui = z[2 * i + 1]
        tn = z[2 * ip] + (TWO_PI * n if ip == 0 else 0.0)
        s = tn - ti
        a0, a1, a2, a3, a4 = _y_derivs(ti % TWO_PI, h, cphi, sphi)
        b0, b1, b2, b3, b4 = _y_derivs(tn % TWO_PI, h, cphi, sphi)
        vm = ui - s * inv_lam
        w = vm - b1
        D[i, 0, 0] = -(a1 - vm) / w
        D[i, 0, 1] = -s / w
        c = -(1.0 + r) * b2 - r * inv_lam
        D[i, 1, 0] = -(r * inv_lam + c * D[i, 0, 0])
        D[i, 1, 1] = -(r + c * D[i, 0, 1])


# ----- errors, parameters ----------------------------------------------------------------

class ContinuationError(RuntimeError):
    """No orbit could be found or continued (Newton failed, the orbit is not periodic, ...)."""


def _simulate_strict(params: RattleParams, **kw):
    """``simulate`` without the noise that resolves rounding-decided captures, where it exists.

    Periodic orbits are exact: they need the deterministic solver, whatever its defaults.
    """
    if _SIMULATE_HAS_NOISE:
        kw.setdefault("noise", False)
    return simulate(params, **kw)


_SIMULATE_HAS_NOISE = "noise" in inspect.signature(simulate).parameters


@dataclasses.dataclass(frozen=True)
class _Param:
    """The continued parameter: user units ↔ the internal value ``q`` the equations use.

    ``q`` is Λ, r, j, h_K, or φ_K in radians.  Engine speed and drag torque are
    reparametrisations of Λ (or of j, for engine speed with acceleration amplitudes held).
    """

    name: str
    kind: int
    kidx: int
    base: RattleParams
    physical: Any = None

    @classmethod
    def make(cls, name: str, base: RattleParams, physical=None) -> "_Param":
        if not isinstance(name, str):
            raise ValueError(f"param must be a parameter name, got {name!r}; allowed: "
                             f"{', '.join(PARAMETERS)} (K = 1..32)")
        if name in ("rpm", "drag_torque"):
            from ..model.units import PhysicalParams
            if not isinstance(physical, PhysicalParams):
                raise ValueError(f"param = {name!r} needs physical= a PhysicalParams "
                                 f"(got {type(physical).__name__})")
            base = physical.to_dimensionless()
            if name == "rpm" and physical.excitation == "acceleration":
                return cls(name, _KIND_J, 0, base, physical)
            return cls(name, _KIND_LAM, 0, base, physical)
        if name == "v_stick":
            raise ValueError("param = 'v_stick' cannot be continued: it sets only where chatter "
                             f"ends; allowed: {', '.join(PARAMETERS)} (K = 1..32)")
        try:
            kind, k = parse_name(name)
        except ValueError:
            raise ValueError(f"param = {name!r} is not a continuation parameter; allowed: "
                             f"{', '.join(PARAMETERS)} (K = 1..32)") from None
        if kind in ("h", "phi"):
            base = base.with_value(name, base.get(name))
            if kind == "phi" and base.amplitudes[k - 1] == 0.0:
                raise ValueError(f"param = {name!r} has no effect while h{k} = 0 (harmonic {k} "
                                 f"is absent); give h{k} > 0 first")
            return cls(name, _KIND_H if kind == "h" else _KIND_PHI, k - 1, base, None)
        return cls(name, {"lam": _KIND_LAM, "r": _KIND_R, "j": _KIND_J}[kind], 0, base, None)

    # internal value and user value
    def q_of(self, value: float) -> float:
        value = float(value)
        if self.name == "rpm":
            ph = self.physical
            ref = self.base.lam if self.kind == _KIND_LAM else self.base.j
            return ref * (value / ph.rpm) ** 2
        if self.name == "drag_torque":
            return self.base.lam * self.physical.drag_torque / value
        if self.kind == _KIND_PHI:
            return math.radians(value)
        return value

    def value_of(self, q: float) -> float:
        q = float(q)
        if self.name == "rpm":
            ref = self.base.lam if self.kind == _KIND_LAM else self.base.j
            return self.physical.rpm * math.sqrt(q / ref)
        if self.name == "drag_torque":
            return self.physical.drag_torque * self.base.lam / q
        if self.kind == _KIND_PHI:
            return math.degrees(q)
        return q

    @property
    def q0(self) -> float:
        b = self.base
        if self.kind == _KIND_LAM:
            return b.lam
        if self.kind == _KIND_R:
            return b.r
        if self.kind == _KIND_J:
            return b.j
        return float(b.h[self.kidx] if self.kind == _KIND_H else b.phi[self.kidx])

    def arrays(self):
        b = self.base
        return b.lam, b.r, b.j, b.h, b.phi

    def params(self, q: float) -> RattleParams:
        """The :class:`RattleParams` at internal value ``q`` (validated)."""
        b = self.base
        if self.kind == _KIND_LAM:
            return b.replace(lam=float(q))
        if self.kind == _KIND_R:
            return b.replace(r=float(q))
        if self.kind == _KIND_J:
            return b.replace(j=float(q))
        k = self.kidx + 1
        if self.kind == _KIND_H:
            return b.with_value(f"h{k}", float(q))
        return b.with_value(f"phi{k}", math.degrees(q))

    def q_range(self) -> tuple[float, float]:
        """Allowed internal values (the model's own ranges)."""
        from ..model.params import AMPLITUDE_RANGE, J_RANGE, LAM_RANGE, PHASE_RANGE_DEG, R_RANGE
        if self.kind == _KIND_LAM:
            return LAM_RANGE
        if self.kind == _KIND_R:
            return R_RANGE
        if self.kind == _KIND_J:
            return J_RANGE
        if self.kind == _KIND_H:
            return AMPLITUDE_RANGE
        return tuple(math.radians(v) for v in PHASE_RANGE_DEG)


# ----- orbits ------------------------------------------------------------------------------

@dataclasses.dataclass(frozen=True, eq=False)
class PeriodicOrbit:
    """A periodic orbit of the rattle model, exact to rounding.

    Attributes
    ----------
    params : RattleParams
    period : int
        Period in forcing periods (each 2π long).
    t : ndarray
        Impact times over one period, increasing (``t[0]`` in ``[0, 2π)`` for a new orbit; along
        a branch each impact keeps its place in the list, so ``t[0]`` may drift out of it).
    u : ndarray
        Absolute velocity just after each impact, ``ẋ⁺ = ẏ − r w``.
    flank : ndarray of int8
        +1 active flank, −1 reverse flank.
    w : ndarray
        Incoming relative velocity ``w = ẋ⁻ − ẏ`` of each impact.
    stick : ndarray, shape (k, 3)
        Stick phases: flank, start time, release time (empty for an impact orbit).  The start
        is where the solver ends the chatter (the first contact slower than ``v_stick``).
    monodromy : ndarray, shape (2, 2)
        Jacobian of the stroboscopic map over one period, in ``(x, ẋ)``, at the time just after
        the first impact (zero for an orbit that sticks).
    multipliers : ndarray of complex
        Its eigenvalues, the Floquet multipliers, largest modulus first.
    residual : float
        Largest scaled residual of the shooting equations (0 for an orbit that sticks, which
        is computed by direct simulation).
    reason : str
        Empty when the orbit is an orbit of the simulator; otherwise why not (e.g. a flight
        that meets a wall before its next impact: the orbit exists only as a solution of the
        equations).
    gap_min : float
        Smallest interior minimum of a flight's gap to a wall (``inf`` if none): the grazing
        test function.
    """

    params: RattleParams
    period: int
    t: np.ndarray
    u: np.ndarray
    flank: np.ndarray
    w: np.ndarray
    stick: np.ndarray
    monodromy: np.ndarray
    multipliers: np.ndarray
    residual: float
    reason: str
    gap_min: float
    gap_where: tuple = (-1, math.nan, 0)

    @property
    def kind(self) -> str:
        """``"impact"`` (impacts only, found by Newton) or ``"stick"`` (has a stick phase)."""
        return "stick" if len(self.stick) else "impact"

    @property
    def admissible(self) -> bool:
        return self.reason == ""

    @property
    def impulse(self) -> np.ndarray:
        """Signed impulse of each impact, ``Ĩ = −(1 + r) w``."""
        return -(1.0 + self.params.r) * self.w

    @property
    def phase(self) -> np.ndarray:
        """Impact phases ``t mod 2π``."""
        return np.mod(self.t, TWO_PI)

    @property
    def n_impacts(self) -> int:
        return len(self.t)

    @property
    def stable(self) -> bool:
        """All multipliers inside the unit circle (orbits that stick are superstable)."""
        return bool(np.max(np.abs(self.multipliers)) < 1.0)

    @property
    def stick_time(self) -> float:
        """Total time stuck per period."""
        return float(np.sum(self.stick[:, 2] - self.stick[:, 1])) if len(self.stick) else 0.0

    def state_at(self, t) -> tuple[np.ndarray, np.ndarray]:
        """Exact position and velocity on the orbit at times ``t`` (any, the orbit is periodic)."""
        p = self.params
        t = np.asarray(t, dtype=np.float64)
        shape = t.shape
        t = np.atleast_1d(t)
        T = TWO_PI * self.period
        ev_t, ev_k, ev_x, ev_v = self._events()
        tt = ev_t[0] + np.mod(t - ev_t[0], T)
        idx = np.clip(np.searchsorted(ev_t, tt, side="right") - 1, 0, len(ev_t) - 1)
        s = tt - ev_t[idx]
        x = ev_x[idx] + ev_v[idx] * s - 0.5 * s * s / p.lam
        v = ev_v[idx] - s / p.lam
        kind = ev_k[idx]
        stuck = kind != 0
        if np.any(stuck):
            from ..model.excitation import excitation
            x[stuck] = excitation(tt[stuck], p.h, p.phi) + np.where(kind[stuck] == -1, p.j, 0.0)
            v[stuck] = excitation(tt[stuck], p.h, p.phi, 1)
        return x.reshape(shape), v.reshape(shape)

    def _events(self):
        """Segments over one period: start time, kind (0 flight, ±1 stuck), state at start."""
        from ..model.excitation import excitation
        p = self.params
        y = excitation(self.t, p.h, p.phi)
        ev = [(float(ti), 0, float(yi + (p.j if f == -1 else 0.0)), float(ui))
              for ti, yi, f, ui in zip(self.t, y, self.flank, self.u)]
        for f, ts, tr in self.stick:
            ys = float(excitation(ts, p.h, p.phi))
            yr = float(excitation(tr, p.h, p.phi))
            vs = float(excitation(ts, p.h, p.phi, 1))
            vr = float(excitation(tr, p.h, p.phi, 1))
            off = p.j if f == -1 else 0.0
            ev.append((float(ts), int(f), ys + off, vs))
            ev.append((float(tr), 0, yr + off, vr))
        ev.sort(key=lambda e: e[0])
        t0 = ev[0][0]
        ev.append((t0 + TWO_PI * self.period,) + ev[0][1:])
        a = np.array([e[0] for e in ev]), np.array([e[1] for e in ev], dtype=np.int8), \
            np.array([e[2] for e in ev]), np.array([e[3] for e in ev])
        return a

    def summary(self) -> str:
        """One line: period, impacts per flank, stability."""
        na = int(np.sum(self.flank == 1))
        nr = int(np.sum(self.flank == -1))
        mu = ", ".join(f"{m:.4g}" for m in self.multipliers)
        extra = f", stuck {self.stick_time:.4g} per period" if len(self.stick) else ""
        return (f"period {self.period}, {na} active + {nr} reverse impacts{extra}, "
                f"{'stable' if self.stable else 'unstable'} (multipliers {mu})")


def _arrays(params: RattleParams):
    return (float(params.lam), float(params.r), float(params.j),
            np.ascontiguousarray(params.h), np.ascontiguousarray(params.phi))


def _normalise(t: np.ndarray, u: np.ndarray, fl: np.ndarray, n: int):
    """Rotate the impact list so that it starts with the first impact of [0, 2π)."""
    T = TWO_PI * n
    t = np.asarray(t, dtype=np.float64)
    k = np.floor(t[0] / TWO_PI)
    t = t - k * TWO_PI
    # one period [t0, t0 + T): bring each time into it, then start at the smallest phase
    t = t[0] + np.mod(t - t[0], T)
    order = np.argsort(t, kind="stable")
    t, u, fl = t[order], np.asarray(u, float)[order], np.asarray(fl, np.int8)[order]
    ph = np.mod(t, TWO_PI)
    i0 = int(np.argmin(np.where(t - t[0] < TWO_PI, ph, np.inf)))
    t = np.concatenate([t[i0:], t[:i0] + T])
    u = np.concatenate([u[i0:], u[:i0]])
    fl = np.concatenate([fl[i0:], fl[:i0]])
    t = t - np.floor(t[0] / TWO_PI) * TWO_PI
    return t, u, fl


def _pack(t, u):
    z = np.empty(2 * len(t))
    z[0::2] = t
    z[1::2] = u
    return z


def _impact_orbit(params: RattleParams, z: np.ndarray, fl: np.ndarray, n: int,
                  check: bool = True) -> PeriodicOrbit:
    """A :class:`PeriodicOrbit` from a solution of the shooting equations."""
    lam, r, j, h, phi = _arrays(params)
    m = len(fl)
    w = np.empty(m)
    M = np.empty((2, 2))
    S = np.empty((2, 2))
    _maps(z, fl, n, lam, r, j, h, phi, w, M, S)
    F = np.empty(2 * m)
    J = np.empty((2 * m, 2 * m))
    Fp = np.empty(2 * m)
    _system(z, fl, n, lam, r, j, h, phi, _KIND_LAM, 0, F, J, Fp)
    gmin = np.empty(m)
    gs = np.empty(m)
    gw = np.empty(m, dtype=np.int64)
    contact = np.empty(m)
    code = _inspect(z, fl, n, lam, r, j, h, phi, float(params.v_stick), check, gmin, gs, gw,
                    contact)
    mu = np.linalg.eigvals(S) if np.all(np.isfinite(S)) else np.array([np.nan, np.nan])
    mu = mu[np.argsort(-np.abs(mu), kind="stable")].astype(complex)
    k = int(np.argmin(gmin)) if m else -1
    return PeriodicOrbit(
        params=params, period=int(n), t=z[0::2].copy(), u=z[1::2].copy(), flank=fl.copy(),
        w=w, stick=np.zeros((0, 3)), monodromy=S, multipliers=mu,
        residual=float(_scaled_norm(F, z)), reason=_REASONS.get(int(code), ""),
        gap_min=float(gmin[k]) if m else math.inf,
        gap_where=(k, float(z[2 * k] + gs[k]) if m else math.nan, int(gw[k]) if m else 0))


def solve_orbit(params: RattleParams, t, u, flank, period: int, *, maxit: int = 30
                ) -> PeriodicOrbit:
    """Newton's method on the shooting equations from a guess of the impacts.

    Parameters
    ----------
    params : RattleParams
    t, u : array_like
        Guessed impact times over one period and post-impact velocities.
    flank : array_like of int
        Flank of each impact, +1 or −1.
    period : int
        Period in forcing periods, in [1, 32·16].

    Returns
    -------
    PeriodicOrbit
        Check :attr:`PeriodicOrbit.admissible`: a solution of the equations whose flight
        meets a wall early is not an orbit of the model.

    Raises
    ------
    ContinuationError
        When Newton's method does not converge.
    """
    if not isinstance(params, RattleParams):
        raise ValueError(f"params must be a RattleParams, got {type(params).__name__}")
    period = int(check_range("period", period, 1, 16 * MAX_ORBIT_PERIOD))
    t = np.atleast_1d(np.asarray(t, dtype=np.float64))
    u = np.atleast_1d(np.asarray(u, dtype=np.float64))
    fl = np.atleast_1d(np.asarray(flank)).astype(np.int8)
    if not (len(t) == len(u) == len(fl)) or len(t) == 0:
        raise ValueError(f"t, u and flank must have the same length, at least 1; got "
                         f"{len(t)}, {len(u)}, {len(fl)}")
    if len(t) > MAX_ORBIT_IMPACTS:
        raise ValueError(f"the orbit has {len(t)} impacts; the allowed range is 1 to "
                         f"{MAX_ORBIT_IMPACTS}")
    if not np.all(np.isin(fl, (-1, 1))):
        raise ValueError(f"flank values must be +1 (active) or -1 (reverse), got {flank!r}")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(u))):
        raise ValueError("t and u must be finite")
    t, u, fl = _normalise(t, u, fl, period)
    z = _pack(t, u)
    lam, r, j, h, phi = _arrays(params)
    st, _, it, res = _newton(z, lam, fl, period, lam, r, j, h, phi, _KIND_LAM, 0,
                             np.zeros(1), np.zeros(1), False, NEWTON_TOL, maxit)
    if st != 0:
        raise ContinuationError(f"Newton's method did not converge (residual {res:.3g} after "
                                f"{it} iterations) for the period-{period} orbit with flanks "
                                f"{fl.tolist()} at {params}")
    t, u, fl = _normalise(z[0::2], z[1::2], fl, period)
    return _impact_orbit(params, _pack(t, u), fl, period)


def c_orbit(params: RattleParams, n: int = 1, which: str = "stable") -> PeriodicOrbit:
    """The one-sided period-n orbit in closed form: one active-flank impact every n periods.

    A flight of ``2πn`` on a symmetric parabola gives ``ẋ⁺ = πn/Λ`` and ``Ĩ = 2πn/Λ``; the
    impact phase solves ``ẏ(θ) = (1 − r)πn / ((1 + r)Λ)`` (``classify.one_sided_orbits``).
    ``which`` picks the root with the smaller trace of the impact map (``"stable"``, the
    regime C orbit where it is stable) or the larger (``"unstable"``).  The closed form is then
    polished by Newton's method (it is a solution already, to rounding).

    Raises
    ------
    ContinuationError
        When ``ẏ`` never reaches the required value (no such orbit at these parameters).
    """
    from .overlays import one_sided_orbits
    if which not in ("stable", "unstable"):
        raise ValueError(f"which = {which!r}; allowed: 'stable' or 'unstable'")
    n = int(check_range("n", n, 1, MAX_ORBIT_PERIOD))
    orbits = one_sided_orbits(params, n)
    if not orbits:
        raise ContinuationError(f"no one-sided period-{n} orbit at {params}: ẏ never reaches "
                                f"(1 − r)πn/((1 + r)Λ) = "
                                f"{(1 - params.r) * math.pi * n / ((1 + params.r) * params.lam):.6g}")
    pick = min(orbits, key=lambda o: o.trace) if which == "stable" else max(orbits, key=lambda o: o.trace)
    return solve_orbit(params, [pick.theta], [math.pi * n / params.lam], [1], n)


def _releases(tr) -> list[tuple[float, int, float, float]]:
    """Stick phases of a trajectory: ``(release time, flank, stick start, w at the capture)``."""
    out = []
    lam = tr.params.lam
    from ..model.excitation import excitation
    for k in range(len(tr.seg_t) - 1):
        kind = int(tr.seg_kind[k])
        if kind == 0:
            continue
        ts = float(tr.seg_t[k])
        w = 0.0
        if k > 0 and tr.seg_kind[k - 1] == 0:
            s = ts - float(tr.seg_t[k - 1])
            w = float(tr.seg_v[k - 1]) - s / lam - float(excitation(ts, tr.params.h, tr.params.phi, 1))
        out.append((float(tr.seg_t[k + 1]), kind, ts, w))
    return out


def _same_phase(a: float, b: float, tol: float = 1e-9) -> bool:
    d = (a - b) % TWO_PI
    return min(d, TWO_PI - d) < tol


def stick_orbit(params: RattleParams, t_release: float, flank: int,
                max_period: int = MAX_ORBIT_PERIOD) -> PeriodicOrbit:
    """The periodic orbit through a release from a stick phase, computed exactly.

    From the release at ``t_release`` on ``flank`` (position on the wall, ``ẋ = ẏ``) the solver
    runs until the releases repeat (same phase, same flank): a release depends only on the
    phase, so the motion from then on is periodic, and superstable (multipliers 0).

    Raises
    ------
    ContinuationError
        When the releases do not repeat within ``max_period`` forcing periods.
    """
    from ..model.excitation import excitation
    p = params
    t_release = float(t_release)
    off = p.j if flank == -1 else 0.0
    x0 = float(excitation(t_release, p.h, p.phi)) + off
    v0 = float(excitation(t_release, p.h, p.phi, 1))
    tr = _simulate_strict(p, periods=2 * max_period + 1, t0=t_release, x0=x0, v0=v0)
    rel = [(t_release, int(flank), math.nan, 0.0)] + _releases(tr)
    for b in range(1, len(rel)):
        for a in range(b):
            if rel[a][1] == rel[b][1] and _same_phase(rel[a][0], rel[b][0]):
                n = int(round((rel[b][0] - rel[a][0]) / TWO_PI))
                if n < 1:
                    continue
                return _stick_from(tr, rel[a:b + 1], n)
    raise ContinuationError(f"no release repeats within {2 * max_period + 1} periods from "
                            f"t = {t_release:.10g} on flank {flank:+d} at {params}")


def _stick_from(tr, rel, n: int) -> PeriodicOrbit:
    """The stick orbit between two equal releases ``rel[0]`` and ``rel[-1]`` of ``tr``."""
    p = tr.params
    t0, t1 = rel[0][0], rel[-1][0]
    sel = (tr.impact_t >= t0) & (tr.impact_t < t1)
    t = tr.impact_t[sel]
    flank = tr.impact_flank[sel].astype(np.int8)
    w = tr.impact_w[sel]
    from ..model.excitation import excitation
    u = excitation(t, p.h, p.phi, 1) - p.r * w
    stick = np.array([(f, ts, tre) for tre, f, ts, wc in rel[1:]],
                     dtype=np.float64).reshape(-1, 3)
    shift = math.floor(t0 / TWO_PI) * TWO_PI
    t = t - shift
    stick[:, 1:] -= shift
    # the gap test: smallest interior minimum over the flights between events
    gmin, where = math.inf, (-1, math.nan, 0)
    lam, r, j, h, phi = _arrays(p)
    cphi, sphi = np.cos(phi), np.sin(phi)
    seg_t, seg_k, seg_x, seg_v = tr.seg_t, tr.seg_kind, tr.seg_x, tr.seg_v
    ys = excitation(seg_t, p.h, p.phi)
    yds = excitation(seg_t, p.h, p.phi, 1)
    for k in range(len(seg_t) - 1):
        if seg_k[k] != 0 or seg_t[k] < t0 - 1e-12 or seg_t[k] >= t1:
            continue
        leave = 0
        if abs(seg_v[k] - yds[k]) < 1e-9:
            # leaving a wall at rest: after a release, or a plastic contact that pulls away
            leave = 1 if abs(seg_x[k] - ys[k]) < abs(seg_x[k] - ys[k] - p.j) else -1
        g, s, wall = _gap_minima(float(seg_t[k]), float(seg_x[k]), float(seg_v[k]),
                                 float(seg_t[k + 1] - seg_t[k]), lam, j, h, cphi, sphi, leave)
        if g < gmin:
            gmin, where = g, (k, float(seg_t[k] + s - shift), int(wall))
    return PeriodicOrbit(params=p, period=n, t=t, u=u, flank=flank, w=w.copy(), stick=stick,
                         monodromy=np.zeros((2, 2)), multipliers=np.zeros(2, complex),
                         residual=0.0, reason="", gap_min=float(gmin), gap_where=where)


def find_orbit(params: RattleParams, *, x0: float | None = None, v0: float = 0.0,
               t0: float = 0.0, transient: int = 2000, max_period: int = MAX_ORBIT_PERIOD
               ) -> PeriodicOrbit:
    """The periodic orbit a simulation settles on, polished to machine precision.

    Simulates ``transient`` periods from ``(x0, v0)`` at ``t0``, finds the period of the
    stroboscopic samples, and turns the last period's impacts into a Newton guess (or, when
    the gear sticks, computes the stick orbit through the last release exactly).

    Raises
    ------
    ContinuationError
        When the response is not periodic (period above ``max_period``, chaos, a long
        transient), or Newton's method does not reproduce the simulated orbit.
    """
    from .classify import detect_period
    if not isinstance(params, RattleParams):
        raise ValueError(f"params must be a RattleParams, got {type(params).__name__}")
    max_period = int(check_range("max_period", max_period, 1, MAX_ORBIT_PERIOD))
    transient = int(check_range("transient", transient, 0, 1_000_000))
    rec = 4 * max_period
    tr = _simulate_strict(params, periods=rec, transient=transient, x0=x0, v0=v0, t0=t0)
    n = detect_period(tr.strobe_x, tr.strobe_v, params.j, max_period, 1e-9)
    if n == 0:
        n = detect_period(tr.strobe_x, tr.strobe_v, params.j, max_period, 1e-6)
    if n == 0:
        raise ContinuationError(f"the response at {params} is not periodic with a period up to "
                                f"{max_period} after {transient} periods; try a longer "
                                "transient or another start")
    return orbit_from_trajectory(tr, n)


def orbit_from_trajectory(tr, period: int) -> PeriodicOrbit:
    """The periodic orbit of period ``period`` at the end of a :class:`Trajectory`."""
    p = tr.params
    period = int(check_range("period", period, 1, MAX_ORBIT_PERIOD))
    rel = _releases(tr)
    t_end = tr.t_end
    if rel and rel[-1][0] > t_end - 2 * TWO_PI * period:
        return stick_orbit(p, rel[-1][0], rel[-1][1])
    if len(tr.stick_intervals) and tr.stick_intervals[-1, 1] >= t_end - 1e-9 and \
            tr.stick_intervals[-1, 0] <= t_end - 2 * TWO_PI * period:
        raise ContinuationError(f"the gear stays in contact at {p} (regime A): no orbit with "
                                "impacts to follow")
    sel = tr.impact_t >= t_end - TWO_PI * period
    if not np.any(sel):
        raise ContinuationError(f"no impacts in the last {period} periods at {p}")
    t = tr.impact_t[sel]
    from ..model.excitation import excitation
    u = excitation(t, p.h, p.phi, 1) - p.r * tr.impact_w[sel]
    orb = solve_orbit(p, t, u, tr.impact_flank[sel], period)
    ref = np.sort(np.mod(tr.impact_t[sel], TWO_PI))
    if len(ref) != orb.n_impacts or np.max(np.abs(np.sort(orb.phase) - ref)) > 1e-6:
        raise ContinuationError(f"Newton's method moved away from the simulated orbit at {p} "
                                "(the response may not be settled yet)")
    return orb


# ----- results -------------------------------------------------------------------------------

BIFURCATION_KINDS = {
    "fold": "fold: a multiplier crosses +1 and the branch turns back",
    "period_doubling": "period doubling: a multiplier crosses −1",
    "neimark_sacker": "Neimark–Sacker: a complex pair crosses the unit circle",
    "grazing": "grazing: a flight touches a wall, the orbit gains or loses an impact",
    "stick_onset": "onset of sticking: an impact on a pushing wall becomes slower than v_stick",
    "stick_end": "end of sticking: the stick phase shrinks to nothing",
    "sequence_change": "the impact sequence of an orbit that sticks changes",
    "permanent_contact": "the reaction never changes sign: the gear stays on the tooth (A)",
}
#: Bifurcations after which the branch cannot go on with the same impact sequence.
TERMINAL = ("grazing", "stick_onset", "stick_end", "sequence_change", "permanent_contact")


@dataclasses.dataclass(frozen=True, eq=False)
class Bifurcation:
    """A bifurcation located on a branch.

    Attributes
    ----------
    kind : str
        One of :data:`BIFURCATION_KINDS`.
    param : str
        The continued parameter.
    value : float
        Where, in the parameter's units (degrees for phases, rpm, N·m).
    point : int
        Index of the last branch point before it.
    orbit : PeriodicOrbit
        The orbit at the bifurcation.
    detail : dict
        Kind-specific facts: the flight and wall of a grazing, the critical multiplier, ...
    message : str
        One line for people.
    """

    kind: str
    param: str
    value: float
    point: int
    orbit: PeriodicOrbit
    detail: dict
    message: str
    q: float = math.nan
    _restart: Any = None
    _spec: Any = None

    @property
    def multipliers(self) -> np.ndarray:
        return self.orbit.multipliers

    @property
    def can_restart(self) -> bool:
        """Whether :func:`continue_orbit` can start a new branch here (``start=bifurcation``)."""
        return self._restart is not None

    def as_dict(self) -> dict:
        mu = self.orbit.multipliers
        d = {"kind": self.kind, "param": self.param, "value": self.value, "point": self.point,
             "period": self.orbit.period, "n_impacts": self.orbit.n_impacts,
             "mu1_re": float(mu[0].real), "mu1_im": float(mu[0].imag),
             "mu2_re": float(mu[1].real) if len(mu) > 1 else math.nan,
             "mu2_im": float(mu[1].imag) if len(mu) > 1 else math.nan,
             "message": self.message}
        for k, v in self.detail.items():
            if isinstance(v, (int, float, str, bool, np.integer, np.floating)):
                d[k] = v
        return d


@dataclasses.dataclass(eq=False)
class ContinuationResult:
    """A continued branch.

    Attributes
    ----------
    param : str
        The continued parameter.
    points : DataFrame
        One row per branch point: ``point``, ``value`` (the parameter, in its units), ``q``
        (the dimensionless value the equations use: Λ, r, j, h_K, φ_K in radians), ``kind``
        (``impact`` or ``stick``), ``period``, ``n_impacts``, ``n_active``, ``n_reverse``,
        ``stable``, the multipliers ``mu1_re, mu1_im, mu2_re, mu2_im`` and ``mu_max`` (largest
        modulus), ``impulse_max``/``impulse_min`` (signed extremes), ``stick_time``,
        ``gap_min`` (grazing test), ``w_min`` (slowest impact), ``event`` (the bifurcation at
        that point, if any).
    impacts : DataFrame
        One row per impact per point: ``point``, ``value``, ``impact``, ``t``, ``phase``,
        ``u``, ``w``, ``impulse``, ``flank``, ``stable``: the branch drawn on a bifurcation
        diagram.
    bifurcations : list of Bifurcation
    status : str
        Why it stopped: ``bound``, ``max_points``, ``grazing``, ``stick_onset``, ``stick_end``,
        ``sequence_change``, ``step_too_small``, ``cancelled``, ``closed`` (the branch came
        back to its start).
    message : str
    provenance : dict
        Parameters, start, settings, versions: everything the result depends on (JSON-ready;
        :meth:`cache_key` hashes it).
    orbits : list of PeriodicOrbit
        The orbit at each point (:meth:`orbit`, :meth:`orbit_at`).
    seconds : float
        Wall time of the run.
    """

    param: str
    points: "pd.DataFrame"
    impacts: "pd.DataFrame"
    bifurcations: list
    status: str
    message: str
    provenance: dict
    orbits: list = dataclasses.field(default_factory=list, repr=False)
    _spec: Any = dataclasses.field(default=None, repr=False)
    seconds: float = math.nan

    @property
    def bifurcation_table(self) -> "pd.DataFrame":
        import pandas as pd
        cols = ["kind", "param", "value", "point", "period", "n_impacts", "mu1_re", "mu1_im",
                "mu2_re", "mu2_im", "message"]
        rows = [b.as_dict() for b in self.bifurcations]
        df = pd.DataFrame(rows) if rows else pd.DataFrame(columns=cols)
        return df[cols + [c for c in df.columns if c not in cols]]

    @property
    def cancelled(self) -> bool:
        return self.status == "cancelled"

    def orbit(self, i: int) -> PeriodicOrbit:
        """The orbit at branch point ``i``."""
        return self.orbits[int(i)]

    def orbit_at(self, value: float) -> list:
        """The orbits of the branch at exactly ``value`` of the parameter (one per crossing:
        a branch that folds crosses a value more than once), solved there from the two branch
        points around it."""
        spec = self._spec
        value = float(value)
        q = spec.q_of(value)
        vals = self.points["value"].to_numpy()
        out = []
        for i in range(len(vals) - 1):
            a, b = self.orbits[i], self.orbits[i + 1]
            if (vals[i] - value) * (vals[i + 1] - value) > 0 or vals[i] == vals[i + 1]:
                continue
            if (vals[i + 1] == value and i + 2 < len(vals)
                    and (vals[i + 2] - value) * (vals[i] - value) < 0):
                continue  # counted with the next interval
            if a.kind != b.kind or a.period != b.period or a.n_impacts != b.n_impacts:
                continue
            if a.kind == "stick":
                o = _stick_at(spec, q, _handle(a))
                if o is not None:
                    out.append(o)
                continue
            f = (value - vals[i]) / (vals[i + 1] - vals[i])
            t = a.t + f * (b.t - a.t)
            u = a.u + f * (b.u - a.u)
            out.append(solve_orbit(spec.params(q), t, u, a.flank, a.period))
        return out

    def cache_key(self) -> str:
        """SHA-256 of the provenance: equal keys, equal results."""
        from ..model.params import canonical_hash
        return canonical_hash(self.provenance)

    def arrays(self) -> dict:
        """Plain arrays of the points, impacts and bifurcations, keyed ``table/column``: numbers
        and fixed-width strings only, so ``np.savez`` stores them and ``np.load`` reads them
        back with ``allow_pickle=False`` (see :meth:`tables`)."""
        out = {}
        for name, df in (("points", self.points), ("impacts", self.impacts),
                         ("bifurcations", self.bifurcation_table)):
            for c in df.columns:
                col = df[c].to_numpy()
                if col.dtype == object:
                    col = np.array(["" if v is None or (isinstance(v, float) and math.isnan(v))
                                    else str(v) for v in col], dtype=str)
                out[f"{name}/{c}"] = col
        return out

    @staticmethod
    def tables(arrays) -> dict:
        """The DataFrames ``points``, ``impacts`` and ``bifurcations`` back from :meth:`arrays`
        (or from an ``np.load`` of them)."""
        import pandas as pd
        out: dict = {"points": {}, "impacts": {}, "bifurcations": {}}
        for key in arrays.keys():
            name, col = key.split("/", 1)
            out[name][col] = arrays[key]
        return {name: pd.DataFrame(cols) for name, cols in out.items()}


POINT_COLUMNS = ["point", "value", "q", "kind", "period", "n_impacts", "n_active", "n_reverse",
                 "stable", "mu1_re", "mu1_im", "mu2_re", "mu2_im", "mu_max", "impulse_max",
                 "impulse_min", "stick_time", "gap_min", "w_min", "event"]
IMPACT_COLUMNS = ["point", "value", "impact", "t", "phase", "u", "w", "impulse", "flank",
                  "stable"]


def _w_min(orb: PeriodicOrbit) -> float:
    """Slowest impact, signed: negative when an impact points out of its wall."""
    if orb.n_impacts == 0:
        return math.inf
    if orb.kind == "stick":
        keep = ~_tail_mask(orb)
        if not np.any(keep):
            return math.inf
        return float(np.min(-orb.flank[keep] * orb.w[keep]))
    return float(np.min(-orb.flank * orb.w))


def _tail_mask(orb: PeriodicOrbit) -> np.ndarray:
    """Impacts of the chatter before each stick phase: the run of ever slower impacts on the
    sticking flank that ends in it (how many the solver resolves depends on ``v_stick``)."""
    mask = np.zeros(orb.n_impacts, dtype=bool)
    T = TWO_PI * orb.period
    for f, ts, _ in orb.stick:
        before = np.nonzero(orb.t <= ts + 1e-12)[0]
        if not len(before):
            before = np.nonzero(orb.t - T <= ts)[0]
        k = before[-1] if len(before) else -1
        prev = 0.0
        while k >= 0 and orb.flank[k] == f and abs(orb.w[k]) > prev and not mask[k]:
            mask[k] = True
            prev = abs(orb.w[k])
            k -= 1
    return mask


def _signature(orb: PeriodicOrbit) -> tuple:
    """What must stay the same along a branch: period, flanks of the impacts (the chatter
    tails of stick phases counted as one), stick flanks."""
    if orb.kind == "impact":
        return ("impact", orb.period, tuple(int(f) for f in orb.flank))
    tail = _tail_mask(orb)
    return ("stick", orb.period, tuple(int(f) for f in orb.flank[~tail]),
            tuple(int(f) for f in orb.stick[:, 0]))


def _stick_margin(orb: PeriodicOrbit) -> float:
    if not len(orb.stick):
        return math.inf
    return float(np.min(orb.stick[:, 2] - orb.stick[:, 1]))


# ----- the continuation engine ----------------------------------------------------------------

def _is_cancelled(cancel) -> bool:
    if cancel is None:
        return False
    if isinstance(cancel, threading.Event) or hasattr(cancel, "is_set"):
        return bool(cancel.is_set())
    return bool(cancel())


class _Branch:
    """One impact sequence ``(flanks, period)`` under one continued parameter."""

    def __init__(self, spec: _Param, fl: np.ndarray, n: int):
        self.spec = spec
        self.fl = np.ascontiguousarray(fl, dtype=np.int8)
        self.n = int(n)
        self.lam, self.r, self.j, self.h, self.phi = spec.arrays()
        self.m2 = 2 * len(self.fl)

    def system(self, z, q):
        lam, r, j, h, phi = self._at(q)
        F = np.empty(self.m2)
        J = np.empty((self.m2, self.m2))
        Fp = np.empty(self.m2)
        _system(z, self.fl, self.n, lam, r, j, h, phi, self.spec.kind, self.spec.kidx, F, J, Fp)
        return F, J, Fp

    def _at(self, q):
        return _set_params(float(q), self.spec.kind, self.spec.kidx, self.lam, self.r, self.j,
                           self.h, self.phi)

    def tangent(self, z, q, prev: np.ndarray | None):
        """Unit null vector of ``[∂F/∂z | ∂F/∂q]``, oriented along ``prev``."""
        F, J, Fp = self.system(z, q)
        A = np.hstack([J, Fp[:, None]])
        t = None
        if prev is not None:
            B = np.vstack([A, prev[None, :]])
            rhs = np.zeros(self.m2 + 1)
            rhs[-1] = 1.0
            try:
                t = np.linalg.solve(B, rhs)
                if not np.all(np.isfinite(t)):
                    t = None
            except np.linalg.LinAlgError:
                t = None
        if t is None:
            t = np.linalg.svd(A)[2][-1]
        t = t / np.linalg.norm(t)
        if prev is not None and float(t @ prev) < 0.0:
            t = -t
        return t

    def correct(self, X_pred, tau, maxit=12):
        z = X_pred[:-1].copy()
        lam, r, j, h, phi = self.lam, self.r, self.j, self.h, self.phi
        st, q, it, res = _newton(z, float(X_pred[-1]), self.fl, self.n, lam, r, j, h, phi,
                                 self.spec.kind, self.spec.kidx, tau, X_pred, True, NEWTON_TOL,
                                 maxit)
        if st != 0:
            return None, it
        return np.append(z, q), it

    def solve_at(self, z, q, maxit=30):
        z = z.copy()
        st, _, it, res = _newton(z, float(q), self.fl, self.n, self.lam, self.r, self.j, self.h,
                                 self.phi, self.spec.kind, self.spec.kidx, np.zeros(1),
                                 np.zeros(1), False, NEWTON_TOL, maxit)
        return (z if st == 0 else None), it

    def orbit(self, X) -> PeriodicOrbit:
        return _impact_orbit(self.spec.params(X[-1]), X[:-1].copy(), self.fl, self.n)


class _Run:
    """State of one :func:`continue_orbit` call: the points so far and what was found."""

    def __init__(self, spec, q_lo, q_hi, max_points, progress, cancel, v_stick):
        self.spec = spec
        self.q_lo, self.q_hi = q_lo, q_hi
        self.max_points = max_points
        self.progress = progress
        self.cancel = cancel
        self.v_stick = v_stick
        self.rows: list[dict] = []
        self.impact_rows: list[tuple] = []
        self.orbits: list[PeriodicOrbit] = []
        self.bifs: list[Bifurcation] = []
        self.status = ""
        self.message = ""

    def add(self, orb: PeriodicOrbit, q: float, event: str = "") -> int:
        i = len(self.rows)
        mu = orb.multipliers
        imp = orb.impulse
        value = self.spec.value_of(q)
        stable = orb.stable
        self.rows.append({
            "point": i, "value": value, "q": float(q), "kind": orb.kind, "period": orb.period,
            "n_impacts": orb.n_impacts, "n_active": int(np.sum(orb.flank == 1)),
            "n_reverse": int(np.sum(orb.flank == -1)), "stable": stable,
            "mu1_re": float(mu[0].real), "mu1_im": float(mu[0].imag),
            "mu2_re": float(mu[1].real), "mu2_im": float(mu[1].imag),
            "mu_max": float(np.max(np.abs(mu))),
            "impulse_max": float(np.max(imp)) if len(imp) else math.nan,
            "impulse_min": float(np.min(imp)) if len(imp) else math.nan,
            "stick_time": orb.stick_time, "gap_min": orb.gap_min, "w_min": _w_min(orb),
            "event": event})
        ph = orb.phase
        for k in range(orb.n_impacts):
            self.impact_rows.append((i, value, k, float(orb.t[k]), float(ph[k]), float(orb.u[k]),
                                     float(orb.w[k]), float(imp[k]), int(orb.flank[k]), stable))
        self.orbits.append(orb)
        if self.progress is not None:
            self.progress(len(self.rows), self.max_points)
        return i

    def full(self) -> bool:
        if len(self.rows) >= self.max_points:
            self.status = "max_points"
            self.message = (f"stopped at the limit of max_points = {self.max_points} branch points; "
                            "raise it to go on")
            return True
        if _is_cancelled(self.cancel):
            self.status = "cancelled"
            self.message = f"cancelled after {len(self.rows)} points"
            return True
        return False

    def bifurcation(self, kind, q, orb, detail, message, restart=None) -> Bifurcation:
        b = Bifurcation(kind=kind, param=self.spec.name, value=self.spec.value_of(q),
                        point=max(len(self.rows) - 1, 0), orbit=orb, detail=detail,
                        message=message, q=float(q), _restart=restart, _spec=self.spec)
        self.bifs.append(b)
        return b


def _light(br: _Branch, X, v_stick: float) -> dict:
    """Test functions at X without the event search (for locating a sign change)."""
    lam, r, j, h, phi = br._at(X[-1])
    z = X[:-1]
    m = len(br.fl)
    w = np.empty(m)
    M = np.empty((2, 2))
    S = np.empty((2, 2))
    _maps(z, br.fl, br.n, lam, r, j, h, phi, w, M, S)
    gmin = np.empty(m)
    gs = np.empty(m)
    gw = np.empty(m, dtype=np.int64)
    contact = np.empty(m)
    _inspect(z, br.fl, br.n, lam, r, j, h, phi, v_stick, False, gmin, gs, gw, contact)
    tests = _slow_tests(z[0::2], br.fl, w, lam, h, phi, v_stick)
    tr = S[0, 0] + S[1, 1]
    det = S[0, 0] * S[1, 1] - S[0, 1] * S[1, 0]
    tests.update(pd=1.0 + tr + det, ns=det - 1.0, fold=1.0 - tr + det, tr=tr,
                 gap=float(np.min(gmin)))
    return tests


def _slow_tests(t, fl, w, lam, h, phi, v_stick) -> dict:
    """Grazing impact (``w``: slowest impact, zero when an impact grazes); for the onset of
    sticking, each impact's speed ``−σw`` and the reaction ``σR̃`` of its wall."""
    from ..model.excitation import excitation
    speed = -fl * w
    react = fl * (1.0 + lam * excitation(t, h, phi, 2))
    return {"w": float(np.min(speed)), "speed": speed, "react": react}


def _tests_of(orb: PeriodicOrbit, v_stick: float) -> dict:
    """The test functions of :func:`_light`, from an orbit already built."""
    S = orb.monodromy
    tr = S[0, 0] + S[1, 1]
    det = S[0, 0] * S[1, 1] - S[0, 1] * S[1, 0]
    p = orb.params
    tests = _slow_tests(orb.t, orb.flank, orb.w, p.lam, p.h, p.phi, v_stick)
    tests.update(pd=1.0 + tr + det, ns=det - 1.0, fold=1.0 - tr + det, tr=tr, gap=orb.gap_min)
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
    ``(None, nan)`` if a correction fails.
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


def _follow(run: _Run, br: _Branch, X, tau, ds, ds_min, ds_max, first_event: str = ""):
    """Pseudo-arclength continuation of an impact orbit from ``X`` along ``tau``."""
    spec = run.spec
    vs = run.v_stick
    orb = br.orbit(X)
    run.add(orb, X[-1], first_event)
    tests = _tests_of(orb, vs)
    X_start = X.copy()
    tol = LOCATE_TOL
    while not run.full():
        X_new, it = br.correct(X + ds * tau, tau)
        if X_new is not None and np.linalg.norm(X_new - X) > 2.0 * ds:
            X_new = None
        at_bound = False
        if X_new is not None and not run.q_lo <= X_new[-1] <= run.q_hi:
            # land on the bound instead: the point there, by Newton at the bound's value
            qb = run.q_hi if X_new[-1] > run.q_hi else run.q_lo
            frac = (qb - X[-1]) / (X_new[-1] - X[-1])
            zb, _ = br.solve_at(X[:-1] + frac * (X_new[:-1] - X[:-1]), qb)
            X_new = None if zb is None else np.append(zb, qb)
            at_bound = X_new is not None
        tau_new = None
        if X_new is not None:
            tau_new = br.tangent(X_new[:-1], X_new[-1], tau)
            if float(tau_new @ tau) < 0.95 and ds > 4.0 * ds_min:
                X_new = None
        if X_new is None:
            ds *= 0.5
            if ds < ds_min:
                run.status = "step_too_small"
                run.message = (f"the corrector failed with steps down to ds_min = {ds_min:g} near "
                               f"{spec.name} = {spec.value_of(X[-1]):.10g}")
                return
            continue
        orb_new = br.orbit(X_new)
        t_new = _tests_of(orb_new, vs)
        ok = orb_new.admissible
        # events between X and X_new, located along the arclength
        found = []
        if tau[-1] * tau_new[-1] < 0.0:
            found.append("fold")
        for key in ("pd", "gap", "w"):
            if np.isfinite(tests[key]) and np.isfinite(t_new[key]) and \
                    (tests[key] > 0) != (t_new[key] > 0):
                found.append(key)
        # an impact slowing through v_stick: the onset of sticking if its wall pushes there
        v_eff = max(vs, V_FLOOR)
        for k in np.nonzero((tests["speed"] >= v_eff) != (t_new["speed"] >= v_eff))[0]:
            found.append(("st", int(k)))
        # (at r = 1 every orbit has det M = 1: only rounding would change the sign)
        if (tests["ns"] > 0) != (t_new["ns"] > 0) and abs(tests["tr"]) < 2.0 and \
                abs(t_new["tr"]) < 2.0 and min(abs(tests["ns"]), abs(t_new["ns"])) > 1e-9:
            found.append("ns")
        located = []
        h_new = float(tau @ (X_new - X))
        for key in found:
            fn = (lambda Y, k=key: _light(br, Y, vs)[k])
            if key == "fold":
                def fn(Y):
                    return br.tangent(Y[:-1], Y[-1], tau)[-1]
                f0, f1 = tau[-1], tau_new[-1]
            elif isinstance(key, tuple):
                k = key[1]

                def fn(Y, k=k):
                    return _light(br, Y, vs)["speed"][k] - v_eff
                f0, f1 = tests["speed"][k] - v_eff, t_new["speed"][k] - v_eff
            else:
                f0, f1 = tests[key], t_new[key]
            Xe, fe = _locate(br, X, tau, h_new, f0, f1, fn, tol)
            if Xe is None:
                continue
            if isinstance(key, tuple):
                if _light(br, Xe, vs)["react"][key[1]] <= 0.0:
                    continue  # a pulling wall: the gear leaves at once, no sticking
                key = "st"
            located.append((float(np.linalg.norm(Xe - X)), key, Xe))
        if not ok and not any(k in ("gap", "w", "st") for _, k, _ in located):
            Xe, _ = _locate(br, X, tau, h_new, 1.0, -1.0, lambda Y: _admissible_sign(br, Y, vs),
                            tol)
            if Xe is not None:
                located.append((float(np.linalg.norm(Xe - X)), "contact", Xe))
        located.sort(key=lambda e: e[0])
        stop = False
        for _, key, Xe in located:
            if not (run.q_lo <= Xe[-1] <= run.q_hi):
                continue
            if _event(run, br, key, Xe, tau):
                stop = True
                break
        if stop:
            return
        if not ok:
            # inadmissible without a located event: stop rather than follow a virtual orbit
            run.add(orb_new, X_new[-1])
            run.status = "inadmissible"
            run.message = (f"the orbit stopped being an orbit of the model near {spec.name} = "
                           f"{spec.value_of(X_new[-1]):.10g}: {orb_new.reason}")
            return
        X, tau, tests, orb = X_new, tau_new, t_new, orb_new
        run.add(orb, X[-1])
        if at_bound:
            run.status = "bound"
            run.message = f"reached the bound {spec.name} = {spec.value_of(X[-1]):.10g}"
            return
        if len(run.rows) > 10 and np.linalg.norm(X - X_start) < 0.5 * ds:
            run.status = "closed"
            run.message = "the branch came back to its first point (a closed curve)"
            return
        ds = min(ds * (1.5 if it <= 3 else (1.0 if it <= 6 else 0.5)), ds_max)
    return


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
    from ..model.excitation import excitation
    p = orb.params
    speed = -orb.flank * orb.w
    react = orb.flank * (1.0 + p.lam * excitation(orb.t, p.h, p.phi, 2))
    if key == "st":
        k = int(np.argmin(np.where(react > 0.0, speed, np.inf)))
    else:
        k = int(np.argmin(speed))
    side = "active" if orb.flank[k] == 1 else "reverse"
    if key == "st":
        run.add(orb, q, "stick_onset")
        run.status = "stick_onset"
        run.message = (f"onset of sticking at {where}: impact {k} on the pushing {side} flank "
                       f"at t = {orb.t[k]:.10g} slows to v_stick; beyond, the gear sticks "
                       "(continue_orbit(start=this) restarts on the orbit that sticks)")
        run.bifurcation("stick_onset", q, orb, {"type": "impact", "impact": k,
                                                "flank": int(orb.flank[k]),
                                                "time": float(orb.t[k])},
                        run.message, restart=("simulate", br, Xe, tau))
    else:
        run.add(orb, q, "grazing")
        run.status = "grazing"
        run.message = (f"grazing at {where}: impact {k} on the {side} flank at "
                       f"t = {orb.t[k]:.10g} reaches zero relative velocity; beyond, the orbit "
                       "loses it (continue_orbit(start=this) restarts without it)")
        run.bifurcation("grazing", q, orb, {"type": "impact", "impact": k,
                                            "wall": int(orb.flank[k]), "time": float(orb.t[k]),
                                            "w": float(orb.w[k])},
                        run.message, restart=("remove", br, Xe, tau))
    return True


def _release_roots(params: RattleParams, flank: int) -> np.ndarray:
    """Phases in [0, 2π) where the reaction ``σ(1 + Λÿ)`` falls through zero: the releases."""
    from scipy.optimize import brentq

    from ..model.excitation import excitation
    p = params
    t = np.linspace(0.0, TWO_PI, 4097)
    f = flank * (1.0 + p.lam * excitation(t, p.h, p.phi, 2))
    out = []
    for i in np.nonzero((f[:-1] > 0) & (f[1:] <= 0))[0]:
        if f[i + 1] == 0.0:
            out.append(t[i + 1])
            continue
        out.append(brentq(lambda s: flank * (1.0 + p.lam * float(excitation(s, p.h, p.phi, 2))),
                          t[i], t[i + 1], xtol=1e-15, rtol=1e-15))
    return np.mod(np.array(out), TWO_PI)


def _stick_at(spec: _Param, q: float, handle: tuple[float, int]) -> PeriodicOrbit | None:
    """The stick orbit at ``q`` through the release nearest to ``handle = (phase, flank)``."""
    try:
        params = spec.params(q)
    except ValueError:
        return None
    roots = _release_roots(params, handle[1])
    if not len(roots):
        return None
    d = np.abs((roots - handle[0] + math.pi) % TWO_PI - math.pi)
    k = int(np.argmin(d))
    if d[k] > 0.2:
        return None
    try:
        return stick_orbit(params, float(roots[k]), handle[1])
    except ContinuationError:
        return None


def _handle(orb: PeriodicOrbit) -> tuple[float, int]:
    f, _, tr = orb.stick[-1]
    return float(tr % TWO_PI), int(f)


def _follow_stick(run: _Run, orb: PeriodicOrbit, q: float, dq: float, dq_min: float,
                  dq_max: float, first_event: str = ""):
    """Natural-parameter continuation of an orbit that sticks (superstable, no folds)."""
    spec = run.spec
    run.add(orb, q, first_event)
    sig = _signature(orb)
    while not run.full():
        q_new = q + dq
        at_bound = False
        if not run.q_lo <= q_new <= run.q_hi:
            q_new = run.q_hi if q_new > run.q_hi else run.q_lo
            at_bound = True
        new = _stick_at(spec, q_new, _handle(orb))
        if new is not None and _signature(new) == sig:
            q, orb = q_new, new
            run.add(orb, q)
            if at_bound:
                run.status = "bound"
                run.message = f"reached the bound {spec.name} = {spec.value_of(q):.10g}"
                return
            dq = math.copysign(min(abs(dq) * 1.5, dq_max), dq)
            continue
        if abs(dq) > 8 * dq_min and (new is None or abs(dq) > 4 * dq_min):
            # bisect the change of the impact pattern down to the locating tolerance
            lo, hi, o_lo = q, q_new, orb
            while abs(hi - lo) > LOCATE_TOL * (1.0 + abs(lo)):
                mid = 0.5 * (lo + hi)
                o = _stick_at(spec, mid, _handle(o_lo))
                if o is not None and _signature(o) == sig:
                    lo, o_lo = mid, o
                else:
                    hi = mid
            o_hi = _stick_at(spec, hi, _handle(o_lo))
            _stick_event(run, o_lo, lo, o_hi, hi)
            return
        run.status = "step_too_small"
        run.message = f"no stick orbit beyond {spec.name} = {spec.value_of(q):.10g}"
        return


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


# ----- starting and restarting ----------------------------------------------------------------

def _pd_switch(run: _Run, br: _Branch, Xe, ds, ds_min, ds_max):
    """Start the doubled orbit's branch at a period doubling, along the critical eigenvector."""
    m = len(br.fl)
    z = Xe[:-1]
    lam, r, j, h, phi = br._at(Xe[-1])
    D = np.empty((m, 2, 2))
    _local_maps(z, br.fl, br.n, lam, r, h, phi, D)
    M = np.eye(2)
    for i in range(m):
        M = D[i] @ M
    ev, vec = np.linalg.eig(M)
    e = np.real(vec[:, int(np.argmin(np.abs(ev + 1.0)))])
    delta = np.empty((m, 2))
    delta[0] = e
    for i in range(m - 1):
        delta[i + 1] = D[i] @ delta[i]
    br2 = _Branch(br.spec, np.concatenate([br.fl, br.fl]), 2 * br.n)
    shift = np.zeros(2 * m)
    shift[0::2] = TWO_PI * br.n
    X2 = np.concatenate([z, z + shift, [Xe[-1]]])
    tau = np.concatenate([delta.ravel(), -delta.ravel(), [0.0]])
    tau /= np.linalg.norm(tau)
    h_step = ds
    while h_step >= ds_min:
        X1, _ = br2.correct(X2 + h_step * tau, tau)
        if X1 is not None:
            gap = np.max(np.abs(X1[2 * m:-1] - X1[:2 * m] - shift))
            if gap > 1e-8 and _admissible_sign(br2, X1, run.v_stick) > 0:
                t1 = br2.tangent(X1[:-1], X1[-1], (X1 - X2) / np.linalg.norm(X1 - X2))
                run.add(br2.orbit(X2), X2[-1], "period_doubling")
                _follow(run, br2, X1, t1, ds, ds_min, ds_max)
                return
        h_step *= 0.5
    raise ContinuationError(f"could not switch onto the period-{2 * br.n} branch at "
                            f"{br.spec.name} = {br.spec.value_of(Xe[-1]):.10g}")


def _surgery_start(run: _Run, br: _Branch, Xe, mode: str, ds, ds_min, ds_max):
    """Restart past a grazing with one impact more (``insert``) or fewer (``remove``)."""
    spec = br.spec
    q = float(Xe[-1])
    orb = br.orbit(Xe)
    z = Xe[:-1]
    fl = br.fl
    if mode == "insert":
        k, tg, wall = orb.gap_where
        from ..model.excitation import excitation
        p = orb.params
        ug = float(excitation(tg, p.h, p.phi, 1))
        z_new = np.concatenate([z[:2 * k + 2], [tg, ug], z[2 * k + 2:]])
        fl_new = np.concatenate([fl[:k + 1], [wall], fl[k + 1:]]).astype(np.int8)
    else:
        k = int(np.argmin(-orb.flank * orb.w))
        z_new = np.concatenate([z[:2 * k], z[2 * k + 2:]])
        fl_new = np.concatenate([fl[:k], fl[k + 1:]]).astype(np.int8)
        if len(fl_new) == 0:
            raise ContinuationError("the orbit loses its only impact: nothing left to follow")
        if k == 0:
            # the period must start at its first impact: rotate the removed one's period away
            t_new, u_new, fl_new = _normalise(z_new[0::2], z_new[1::2], fl_new, br.n)
            z_new = _pack(t_new, u_new)
    br2 = _Branch(spec, fl_new, br.n)
    X0 = np.append(z_new, q)
    if mode == "remove":
        z_fix, _ = br2.solve_at(z_new, q)
        if z_fix is not None:
            X0 = np.append(z_fix, q)
    tau = br2.tangent(X0[:-1], q, None)
    h_step = ds
    while h_step >= ds_min:
        for sgn in (1.0, -1.0):
            X1, _ = br2.correct(X0 + sgn * h_step * tau, sgn * tau)
            if X1 is not None and _admissible_sign(br2, X1, run.v_stick) > 0:
                t1 = br2.tangent(X1[:-1], X1[-1], sgn * tau)
                _follow(run, br2, X1, t1, ds, ds_min, ds_max)
                return
        h_step *= 0.5
    raise ContinuationError(f"no orbit with the new impact sequence (flanks {fl_new.tolist()}) "
                            f"near {spec.name} = {spec.value_of(q):.10g}")


def _simulate_start(run: _Run, spec: _Param, orb: PeriodicOrbit, q: float, sgn: float,
                    ds, ds_min, ds_max):
    """Restart past an event by simulation from the old orbit, just beyond it."""
    last = None
    for step in (1e-7, 1e-6, 1e-5, 1e-4):
        q1 = q + sgn * step * (1.0 + abs(q))
        try:
            params = spec.params(q1)
        except ValueError:
            break
        t0 = float(orb.t[0]) if orb.n_impacts else 0.0
        x0, v0 = orb.state_at(t0 - 1e-3)
        try:
            new = find_orbit(params, x0=float(x0), v0=float(v0), t0=t0 - 1e-3, transient=400)
        except (ContinuationError, ValueError) as exc:
            last = exc
            continue
        _start(run, spec, new, q1, sgn, ds, ds_min, ds_max)
        return
    raise ContinuationError(f"no periodic attractor found just beyond {spec.name} = "
                            f"{spec.value_of(q):.10g} by simulation from the old orbit"
                            + (f" ({last})" if last else ""))


def _start(run: _Run, spec: _Param, orb: PeriodicOrbit, q: float, sgn: float, ds, ds_min,
           ds_max, event: str = ""):
    """Continue from a solved orbit at ``q`` towards increasing ``q`` (sgn > 0) or decreasing."""
    if orb.kind == "stick":
        _follow_stick(run, orb, q, sgn * ds, ds_min, ds_max, event)
        return
    br = _Branch(spec, orb.flank, orb.period)
    X = np.append(_pack(orb.t, orb.u), q)
    prev = np.zeros(len(X))
    prev[-1] = sgn
    tau = br.tangent(X[:-1], q, prev)
    if tau[-1] * sgn < 0:
        tau = -tau
    _follow(run, br, X, tau, ds, ds_min, ds_max, event)


def continue_orbit(start, param: str | None = None, *, bounds: Sequence[float] | None = None,
                   direction: int = 1, ds: float = 0.01, ds_min: float = 1e-9,
                   ds_max: float = 0.1, max_points: int = 1000, physical=None,
                   progress: Callable[[int, int], Any] | None = None,
                   cancel: threading.Event | Callable[[], bool] | None = None
                   ) -> ContinuationResult:
    """Follow a periodic orbit as one parameter changes; locate its bifurcations.

    Pseudo-arclength continuation of the shooting equations for orbits with impacts only
    (through folds, stable and unstable alike); natural-parameter steps for orbits that stick
    (superstable).  See the module docstring for the method.

    Parameters
    ----------
    start : PeriodicOrbit, RattleParams or Bifurcation
        The first orbit (from :func:`find_orbit`, :func:`c_orbit`, :func:`solve_orbit`,
        :func:`stick_orbit`); parameters, to start from the orbit a simulation settles on; or a
        bifurcation of an earlier result: a period doubling starts the doubled orbit's branch,
        a grazing restarts with the impact gained or lost, an onset or end of sticking restarts
        from a simulation just beyond, a fold goes on through it.
    param : str
        ``lam``, ``r``, ``j``, ``hK`` (H_K/H1), ``phiK`` (degrees), or with ``physical``
        ``rpm`` (engine speed) or ``drag_torque`` [N·m].  Default: the bifurcation's
        parameter, else ``lam``.
    bounds : (float, float), optional
        Stop when the parameter leaves this interval (its units).  Default: the model's range.
    direction : {1, -1}
        Start towards increasing (1) or decreasing (−1) values.
    ds, ds_min, ds_max : float
        First, smallest and largest arclength step, in the dimensionless unknowns (impact
        times, velocities and Λ, r, j, h_K, or φ_K in radians).
    max_points : int
        Most branch points, in [1, 100000]; the run stops there with a message.
    physical : PhysicalParams, optional
        The gear in physical units, for ``rpm`` and ``drag_torque``; ``start`` must then be
        an orbit at ``physical.to_dimensionless()``.
    progress : callable(done, max_points), optional
        Called after every point.
    cancel : threading.Event or callable() -> bool, optional
        Polled after every point; when set the run stops (``status == "cancelled"``) and
        returns the points so far.

    Returns
    -------
    ContinuationResult
        Branch points, impacts per point, bifurcations, why it stopped, provenance.
    """
    import pandas as pd

    t_start = time.perf_counter()
    if param is None:
        param = start.param if isinstance(start, Bifurcation) else "lam"
    if isinstance(start, Bifurcation):
        if param != start.param:
            raise ValueError(f"param = {param!r}, but the bifurcation was found in "
                             f"{start.param!r}; restart in the same parameter")
        if start._restart is None:
            raise ValueError(f"a {start.kind} bifurcation offers no restart")
        params0 = start.orbit.params
    elif isinstance(start, PeriodicOrbit):
        params0 = start.params
    elif isinstance(start, RattleParams):
        params0 = start
    else:
        raise ValueError(f"start must be a PeriodicOrbit, a RattleParams or a Bifurcation, got "
                         f"{type(start).__name__}")
    if direction not in (1, -1):
        raise ValueError(f"direction = {direction!r}; allowed: 1 (increasing) or -1 (decreasing)")
    ds = check_range("ds", ds, 0.0, 1.0, lo_open=True)
    ds_max = check_range("ds_max", ds_max, ds, 10.0)
    ds_min = check_range("ds_min", ds_min, 0.0, ds, lo_open=True)
    max_points = int(check_range("max_points", max_points, 1, MAX_POINTS))
    if isinstance(start, Bifurcation):
        spec = start._spec
        physical = spec.physical
    else:
        spec = _Param.make(param, params0, physical)
        if physical is not None and param in ("rpm", "drag_torque"):
            a, b = spec.base.canonical(), params0.canonical()
            if a != b and not _close_params(spec.base, params0):
                raise ValueError("start is not at the parameters of physical "
                                 f"(physical.to_dimensionless() = {spec.base}, start at {params0})")
    # the internal range, and the user's bounds in it
    lo_q, hi_q = spec.q_range()
    if bounds is not None:
        try:
            b0, b1 = (float(v) for v in bounds)
        except (TypeError, ValueError):
            raise ValueError(f"bounds must be two numbers (low, high), got {bounds!r}") from None
        if not (math.isfinite(b0) and math.isfinite(b1)) or b0 >= b1:
            raise ValueError(f"bounds = {bounds!r} must be two finite numbers, low < high")
        qa, qb = sorted((spec.q_of(b0), spec.q_of(b1)))
        for v, qv in ((b0, qa), (b1, qb)):
            try:
                spec.params(qv)
            except ValueError as exc:
                raise ValueError(f"bounds: {param} = {v!r} is outside the model's range ({exc})") \
                    from None
        lo_q, hi_q = max(lo_q, qa), min(hi_q, qb)
    eps = 1e-12 * (1.0 + abs(hi_q - lo_q))
    if spec.kind in (_KIND_LAM, _KIND_J):
        lo_q = max(lo_q, 1e-9)
    q_start = spec.q0 if not isinstance(start, Bifurcation) else start.q
    if not lo_q - eps <= q_start <= hi_q + eps:
        raise ValueError(f"the start, {param} = {spec.value_of(q_start):.10g}, lies outside "
                         f"bounds [{spec.value_of(lo_q):.10g}, {spec.value_of(hi_q):.10g}]")
    sgn = float(direction)
    if param == "drag_torque":
        sgn = -sgn  # Λ falls as the drag torque grows
    run = _Run(spec, lo_q, hi_q, max_points, progress, cancel, float(params0.v_stick))

    if isinstance(start, RattleParams):
        start = find_orbit(start)
    if isinstance(start, PeriodicOrbit):
        _start(run, spec, start, spec.q0, sgn, ds, ds_min, ds_max)
    else:
        how = start._restart
        if how[0] == "pd":
            _pd_switch(run, how[1], how[2], ds, ds_min, ds_max)
        elif how[0] in ("insert", "remove"):
            _surgery_start(run, how[1], how[2], how[0], ds, ds_min, ds_max)
        elif how[0] == "fold":
            _follow(run, how[1], how[2], how[3], ds, ds_min, ds_max, "fold")
        else:
            beyond = float(np.sign(how[3][-1])) if how[1] is not None else \
                float(np.sign(how[3] - how[2]))
            _simulate_start(run, spec, start.orbit, start.q, beyond or sgn, ds, ds_min, ds_max)
    if not run.status:
        run.status = "done"
    points = pd.DataFrame(run.rows, columns=POINT_COLUMNS)
    impacts = pd.DataFrame(run.impact_rows, columns=IMPACT_COLUMNS)
    impacts["flank"] = impacts["flank"].astype(np.int8)
    provenance = {
        "param": param, "params": params0.to_dict(),
        "physical": dataclasses.asdict(physical) if physical is not None else None,
        "start": _start_provenance(start),
        "settings": {"bounds": [spec.value_of(lo_q), spec.value_of(hi_q)],
                     "direction": direction, "ds": ds, "ds_min": ds_min, "ds_max": ds_max,
                     "max_points": max_points},
        "solver_version": SOLVER_VERSION, "continuation_version": CONTINUATION_VERSION,
    }
    return ContinuationResult(param=param, points=points, impacts=impacts,
                              bifurcations=run.bifs, status=run.status, message=run.message,
                              provenance=provenance, orbits=run.orbits, _spec=spec,
                              seconds=time.perf_counter() - t_start)


def _close_params(a: RattleParams, b: RattleParams) -> bool:
    da, db = a.to_dict(), b.to_dict()
    return all(np.allclose(np.atleast_1d(da[k]), np.atleast_1d(db[k]), rtol=1e-12, atol=1e-12)
               if len(np.atleast_1d(da[k])) == len(np.atleast_1d(db[k])) else False for k in da)


def _start_provenance(start) -> dict:
    if isinstance(start, Bifurcation):
        return {"bifurcation": start.kind, "value": start.value, "param": start.param,
                "orbit": _start_provenance(start.orbit)}
    if isinstance(start, PeriodicOrbit):
        return {"period": start.period, "t": start.t.tolist(), "u": start.u.tolist(),
                "flank": start.flank.tolist(), "stick": start.stick.tolist(),
                "params": start.params.to_dict()}
    return {}
