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
is zero and both multipliers are exactly 0 (superstable).  Newton's method is neither needed
nor possible there (the chatter before sticking is an infinite impact sequence).  A stick
orbit is computed exactly instead: from a release, ``simulate`` runs until the gear sticks
and releases again, until a release repeats.  Such orbits have no folds and no flip or
torus bifurcations; they are followed in natural-parameter steps, and they end where their
impact pattern changes (a grazing flight) or where the stick phase shrinks to nothing.  The
stick phase starts at the accumulation point of the chatter, estimated from the last impact
faster than ``v_stick`` by the geometric series ``t∞ ≈ t_k + 2r|w_k| / ((1 − r)|g''|)``.

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
impact sequence (an impact inserted at the touching point, or removed).
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

from .excitation import TWO_PI, _bounds, _y_derivs
from .params import RattleParams, check_range, parse_name
from .solver import V_FLOOR, _flight
from .trajectory import SOLVER_VERSION, simulate

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
            "an impact is slower than v_stick", _MISSED_CONTACT:
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
        if abs(w) < v_eff:
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
            from .units import PhysicalParams
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

    def with_base(self, params: RattleParams) -> "_Param":
        return dataclasses.replace(self, base=params)

    def q_range(self) -> tuple[float, float]:
        """Allowed internal values (the model's own ranges)."""
        from .params import AMPLITUDE_RANGE, J_RANGE, LAM_RANGE, PHASE_RANGE_DEG, R_RANGE
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
        Impact times over one period, increasing, ``t[0]`` in ``[0, 2π)``.
    u : ndarray
        Absolute velocity just after each impact, ``ẋ⁺ = ẏ − r w``.
    flank : ndarray of int8
        +1 active flank, −1 reverse flank.
    w : ndarray
        Incoming relative velocity ``w = ẋ⁻ − ẏ`` of each impact.
    stick : ndarray, shape (k, 3)
        Stick phases: flank, start time, release time (empty for an impact orbit).  The start
        is the accumulation point of the chatter (see the module docstring).
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
            from .excitation import excitation
            x[stuck] = excitation(tt[stuck], p.h, p.phi) + np.where(kind[stuck] == -1, p.j, 0.0)
            v[stuck] = excitation(tt[stuck], p.h, p.phi, 1)
        return x, v

    def _events(self):
        """Segments over one period: start time, kind (0 flight, ±1 stuck), state at start."""
        from .excitation import excitation
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


def _arrays(params: RattleParams, kind: int = _KIND_LAM, kidx: int = 0):
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
    from .classify import one_sided_orbits
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


def _stick_start(params: RattleParams, t_s: float, w: float, sigma: int) -> float:
    """Accumulation point of the chatter that the solver ended at ``t_s`` with velocity ``w``.

    The remaining bounces take ``2r|w|/|g''|`` times ``1 + r + r² + ⋯``; ``|g''| = |R̃|/Λ``.
    """
    from .excitation import excitation
    react = abs(1.0 + params.lam * float(excitation(t_s, params.h, params.phi, 2)))
    if params.r == 0.0 or react == 0.0 or params.r >= 1.0:
        return t_s
    return t_s + 2.0 * params.r * abs(w) * params.lam / ((1.0 - params.r) * react)


def _releases(tr) -> list[tuple[float, int, float, float]]:
    """Stick phases of a trajectory: ``(release time, flank, stick start, w at the capture)``."""
    out = []
    lam = tr.params.lam
    from .excitation import excitation
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
    from .excitation import excitation
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
    from .excitation import excitation
    u = excitation(t, p.h, p.phi, 1) - p.r * w
    stick = np.array([(f, _stick_start(p, ts, wc, f), tre) for tre, f, ts, wc in rel[1:]],
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
    from .excitation import excitation
    u = excitation(t, p.h, p.phi, 1) - p.r * tr.impact_w[sel]
    orb = solve_orbit(p, t, u, tr.impact_flank[sel], period)
    ref = np.sort(np.mod(tr.impact_t[sel], TWO_PI))
    if len(ref) != orb.n_impacts or np.max(np.abs(np.sort(orb.phase) - ref)) > 1e-6:
        raise ContinuationError(f"Newton's method moved away from the simulated orbit at {p} "
                                "(the response may not be settled yet)")
    return orb
