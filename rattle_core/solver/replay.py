"""The gear between the teeth of a measured wall: flight, impact, chatter, stick and release,
exactly, piece by piece (docs/model.md, "A run-up in physical time").

The rules are the core's (:mod:`rattle_core.solver.kernel`), and so are the step lengths: the
same proven root-free steps (:mod:`rattle_core.solver.events`) find every contact and every
release, grazing ones included.  What changes is the wall and the flight:

* the wall is a :class:`~rattle_core.solver.wall.PiecewiseWall`, whose derivative bounds hold
  per piece, so a search never steps across a piece's end: it stops there, and the next piece
  continues the same flight (or stick phase) with that piece's bounds;
* the flight deceleration is ``q(s) = q₀ + q₁ s`` on a piece (drag over inertia and the mean
  rotation's acceleration, in reference units), so a flight is the closed-form cubic
  ``x = x₀ + v₀ s − q s²/2 − q₁ s³/6`` (``q`` at the flight's start), with gap bounds
  ``|g''| ≤ max|q| + M₂`` and ``|g'''| ≤ |q₁| + M₃``;
* the contact reaction is ``σ (q + ÿ)`` (the core's ``R̃ = 1 + Λ ÿ`` divided by ``Λ``).

With one piece per forcing period, ``q = 1/Λ`` and ``A_k``, ``Φ_k`` those of a harmonic
excitation, this is the core's model term for term; ``tests/test_runup.py`` checks that both
give the same impacts.
"""
from __future__ import annotations

import dataclasses

import numpy as np
from numba import njit

from .events import _leave_step, _root_free, _safe_step
from .kernel import (CONTACT_TOL, FLIGHT, MIN_STEP, OK, OVERFLOW_IMPACTS, OVERFLOW_SEGMENTS,
                     RUNAWAY, STALL, STICK_ACTIVE, V_FLOOR, MAX_IMPACTS_PER_PERIOD)
from .wall import PiecewiseWall, _wall_derivs

_FLIGHT_MAX_IT = 100_000
TWO_PI = 2.0 * np.pi


@njit(cache=True, nogil=True)
def _pflight(j, amp, phase, p, s0, qa, q1, m2, m3, m4, x0, v0, dmax, leave, moved):
    """First contact of a flight from local time ``s0`` of piece ``p``, up to ``dmax`` later.

    As ``kernel._flight``, with the cubic flight of a linear deceleration ``qa + q1 d``.
    ``moved`` says the flight began on an earlier piece (so a gap at rest on a wall here is a
    contact, as after the start of a flight in the core).  Returns ``(d, hit, y0..y4)``.
    """
    d = 0.0
    d_prev = 0.0
    if leave != 0:
        y0, y1, y2, y3, y4 = _wall_derivs(amp, phase, p, s0)
        g2 = leave * (-qa - y2)
        g3 = leave * (-q1 - y3)
        if g2 < 0.0:
            g2 = 0.0
        d = _leave_step(g2, g3, m3, m4)
        if d <= 0.0:
            d = 1e-12
        d_other = _safe_step(j, 0.0, -g2, m2, m3)
        if d_other < d:
            d = d_other
        if d >= dmax:
            return dmax, 0, 0.0, 0.0, 0.0, 0.0, 0.0
    for _ in range(_FLIGHT_MAX_IT):
        x = x0 + v0 * d - 0.5 * d * d * qa - d * d * d * q1 / 6.0
        vv = v0 - d * qa - 0.5 * q1 * d * d
        y0, y1, y2, y3, y4 = _wall_derivs(amp, phase, p, s0 + d)
        ga = x - y0
        ga1 = vv - y1
        ga2 = -(qa + q1 * d) - y2
        gr = j - ga
        hit = 0
        slow = V_FLOOR if (d > 0.0 or moved) else 0.0
        delta = 0.0
        if ga <= CONTACT_TOL and ga1 <= slow:
            hit = 1
            delta = ga / (-ga1) if ga1 < -1e-7 else 0.0
        elif gr <= CONTACT_TOL and ga1 >= -slow:
            hit = -1
            delta = gr / ga1 if ga1 > 1e-7 else 0.0
        if hit != 0:
            if (ga1 + ga2 * delta) * hit > 0.0 or d + delta < d_prev or d + delta > dmax:
                delta = 0.0
            return (d + delta, hit, y0 + y1 * delta, y1 + y2 * delta, y2 + y3 * delta,
                    y3 + y4 * delta, y4)
        gap_a = ga if ga > 0.0 else 0.0
        gap_r = gr if gr > 0.0 else 0.0
        ga_glob = _root_free(gap_a, ga1, -m2)
        gr_glob = _root_free(gap_r, -ga1, -m2)
        if ga_glob <= gr_glob:
            st = _safe_step(gap_a, ga1, ga2, m2, m3)
            if st > gr_glob:
                dr = _safe_step(gap_r, -ga1, -ga2, m2, m3)
                st = st if st < dr else dr
        else:
            st = _safe_step(gap_r, -ga1, -ga2, m2, m3)
            if st > ga_glob:
                da = _safe_step(gap_a, ga1, ga2, m2, m3)
                st = st if st < da else da
        if st < MIN_STEP:
            st = MIN_STEP
        if d + st >= dmax:
            return dmax, 0, 0.0, 0.0, 0.0, 0.0, 0.0
        d_prev = d
        d += st
    return d, 2, 0.0, 0.0, 0.0, 0.0, 0.0


@njit(cache=True, nogil=True)
def _prelease(amp, phase, p, s0, q0, q1, f_m2, f_m3, tol, dmax, sigma):
    """First time the reaction σ(q + ÿ) stops being positive, up to ``dmax`` after ``s0``.

    As ``kernel._release``; returns ``(d, released)`` with released 1, 0 (still stuck at
    ``dmax``) or 2 (iteration budget exceeded).
    """
    max_it = 10_000 + int(200.0 * dmax / TWO_PI)
    d = 0.0
    for _ in range(max_it):
        y0, y1, y2, y3, y4 = _wall_derivs(amp, phase, p, s0 + d)
        f = sigma * (q0 + q1 * (s0 + d) + y2)
        f1 = sigma * (q1 + y3)
        f2 = sigma * y4
        if f < -tol:
            # a reaction that turned at a joint of the pieces: the contact ends here
            return d, 1
        if f <= tol and f1 < 0.0:
            if f2 > 0.0 and f - 0.5 * f1 * f1 / f2 > -tol:
                d += -f1 / f2 + 2.0 * np.sqrt(2.0 * tol / f2)
                if d >= dmax:
                    return dmax, 0
                continue
            if f1 < -1e-7:
                d += f / (-f1)
            if d < 0.0:
                d = 0.0
            if d > dmax:
                d = dmax
            return d, 1
        st = _safe_step(f if f > 0.0 else 0.0, f1, f2, f_m2, f_m3)
        if st < 1e-12:
            st = 1e-12
        if d + st >= dmax:
            return dmax, 0
        d += st
    return d, 2


@njit(cache=True, nogil=True)
def _replay(t0, length, amp, phase, decel, bnd, qmax, r, j, v_stick, p0, s0, x0, v0, mode0,
            p_end, max_imp_per_piece,
            imp_p, imp_s, imp_I, imp_w, imp_flank, seg_p, seg_s, seg_kind, seg_x, seg_v):
    """Run from local time ``s0`` of piece ``p0`` to the start of piece ``p_end``.

    State ``(x, v)`` relative to the mean rotation, in reference units; ``mode0`` is 0 (flight)
    or ±1 (stuck on that flank, where ``x, v`` are then taken from the wall).  Returns
    ``(status, n_imp, n_seg, p, s, x, v, mode)``.  Impacts are recorded as piece and local time.
    """
    v_eff = v_stick if v_stick > V_FLOOR else V_FLOOR
    p = p0
    s = s0
    x = x0
    v = v0
    mode = mode0
    leave = 0
    moved = False
    cap_imp = imp_p.shape[0]
    cap_seg = seg_p.shape[0]
    n_imp = 0
    n_seg = 0
    status = OK
    imp_piece = p
    imp_count = 0
    loop_piece = p
    loops = 0
    max_loops = 8 * max_imp_per_piece + 100_000

    pending = 0
    c0, c1, c2, c3, c4 = 0.0, 0.0, 0.0, 0.0, 0.0
    if p < p_end:
        c0, c1, c2, c3, c4 = _wall_derivs(amp, phase, p, s)
        if mode != FLIGHT:
            x = c0 if mode == STICK_ACTIVE else c0 + j
            v = c1
        elif x - c0 <= CONTACT_TOL and v - c1 <= 0.0:
            pending = 1
        elif c0 + j - x <= CONTACT_TOL and v - c1 >= 0.0:
            pending = -1

    while p < p_end:
        if p != loop_piece:
            loop_piece = p
            loops = 0
        loops += 1
        if loops > max_loops:
            status = STALL
            break
        q0 = decel[p, 0]
        q1 = decel[p, 1]
        if pending != 0:
            sigma = pending
            pending = 0
            y0, y1, y2, y3, y4 = c0, c1, c2, c3, c4
            w = v - y1
            x = y0 if sigma == 1 else y0 + j
            zero_rel = False
            if abs(w) >= v_eff:
                vplus = y1 - r * w
                if n_imp >= cap_imp:
                    status = OVERFLOW_IMPACTS
                    break
                imp_p[n_imp] = p
                imp_s[n_imp] = s
                imp_I[n_imp] = vplus - v
                imp_w[n_imp] = w
                imp_flank[n_imp] = sigma
                n_imp += 1
                if p != imp_piece:
                    imp_piece = p
                    imp_count = 0
                imp_count += 1
                if imp_count > max_imp_per_piece:
                    status = RUNAWAY
                    break
                v = vplus
                zero_rel = r == 0.0
            else:
                v = y1
                zero_rel = True
            mode = FLIGHT
            leave = 0
            moved = False
            if zero_rel:
                f = sigma * (q0 + q1 * s + y2)
                f1 = sigma * (q1 + y3)
                f2 = sigma * y4
                tol = CONTACT_TOL * (qmax[p] + bnd[p, 2])
                if f > tol or (f > -tol and (f1 > 0.0 or (f2 > 0.0 and
                                                        f - 0.5 * f1 * f1 / f2 > -tol))):
                    mode = sigma
                else:
                    leave = sigma
            continue

        dmax = length[p] - s
        if dmax < 0.0:
            dmax = 0.0
        if cap_seg > 0:
            if n_seg >= cap_seg:
                status = OVERFLOW_SEGMENTS
                break
            seg_p[n_seg] = p
            seg_s[n_seg] = s
            seg_kind[n_seg] = mode
            seg_x[n_seg] = x
            seg_v[n_seg] = v
            n_seg += 1
        if mode == FLIGHT:
            qa = q0 + q1 * s
            m2 = qmax[p] + bnd[p, 2]
            m3 = abs(q1) + bnd[p, 3]
            m4 = bnd[p, 4]
            d, hit, c0, c1, c2, c3, c4 = _pflight(j, amp, phase, p, s, qa, q1, m2, m3, m4, x, v,
                                                  dmax, leave, moved)
            leave = 0
            if hit == 2:
                status = STALL
                break
            x = x + v * d - 0.5 * d * d * qa - d * d * d * q1 / 6.0
            v = v - d * qa - 0.5 * q1 * d * d
            if hit != 0:
                pending = hit
                s = s + d
            else:
                # the flight goes on into the next piece
                p += 1
                s = 0.0
                moved = True
                if p < p_end:
                    c0, c1, c2, c3, c4 = _wall_derivs(amp, phase, p, 0.0)
                    if x - c0 < 0.0:
                        x = c0
                    elif x > c0 + j:
                        x = c0 + j
        else:
            tol = CONTACT_TOL * (qmax[p] + bnd[p, 2])
            d, rel = _prelease(amp, phase, p, s, q0, q1, bnd[p, 4], bnd[p, 5], tol, dmax, mode)
            if rel == 2:
                status = STALL
                break
            if rel == 1:
                s = s + d
                y0, y1, y2, y3, y4 = _wall_derivs(amp, phase, p, s)
                x = y0 if mode == STICK_ACTIVE else y0 + j
                v = y1
                leave = mode
                mode = FLIGHT
                moved = False
            else:
                # still stuck at the piece's end: carried on the wall into the next piece
                y0, y1, y2, y3, y4 = _wall_derivs(amp, phase, p, length[p])
                x = y0 if mode == STICK_ACTIVE else y0 + j
                v = y1
                p += 1
                s = 0.0
    return status, n_imp, n_seg, p, s, x, v, mode


@dataclasses.dataclass(frozen=True)
class WallRun:
    """A gear's motion against a :class:`PiecewiseWall`, in the wall's reference units.

    Attributes
    ----------
    impact_t, impact_impulse, impact_w : ndarray
        Impact times, signed impulses ``ẋ⁺ − ẋ⁻`` and incoming relative velocities.
    impact_flank : ndarray of int8
        +1 active flank, −1 reverse flank.
    seg_t, seg_kind, seg_x, seg_v : ndarray
        Segments (each inside one piece): start time, kind (0 flight, ±1 stuck), state.
    t, x, v, mode : float, float, float, int
        The gear's state at the end of the run.
    """

    impact_t: np.ndarray
    impact_impulse: np.ndarray
    impact_w: np.ndarray
    impact_flank: np.ndarray
    seg_t: np.ndarray
    seg_kind: np.ndarray
    seg_x: np.ndarray
    seg_v: np.ndarray
    t: float
    x: float
    v: float
    mode: int
    wall: PiecewiseWall
    j: float

    def sample(self, t) -> tuple[np.ndarray, np.ndarray]:
        """Exact position and velocity at times ``t`` inside the run (needs its segments)."""
        if self.seg_t.size == 0:
            raise ValueError("the run kept no segments; replay with segments=True to sample it")
        t = np.atleast_1d(np.asarray(t, dtype=np.float64))
        i = np.clip(np.searchsorted(self.seg_t, t, side="right") - 1, 0, self.seg_t.size - 1)
        w = self.wall
        p, _ = w.piece_of(self.seg_t[i])
        s_start = self.seg_t[i] - w.t0[p]
        d = t - self.seg_t[i]
        qa = w.decel[p, 0] + w.decel[p, 1] * s_start
        q1 = w.decel[p, 1]
        x = self.seg_x[i] + self.seg_v[i] * d - 0.5 * d * d * qa - d * d * d * q1 / 6.0
        v = self.seg_v[i] - d * qa - 0.5 * q1 * d * d
        kind = self.seg_kind[i]
        stuck = kind != 0
        if np.any(stuck):
            y = w.values(t[stuck])
            yd = w.values(t[stuck], 1)
            x[stuck] = np.where(kind[stuck] == 1, y, y + self.j)
            v[stuck] = yd
        return x, v


class ReplayError(RuntimeError):
    """A replay stopped at a limit (runaway chatter, root-search budget, capacity)."""


_MESSAGES = {STALL: "an event search exceeded its iteration budget",
             RUNAWAY: "impacts within one piece exceeded the runaway limit",
             OVERFLOW_IMPACTS: "impacts exceeded the capacity", OVERFLOW_SEGMENTS:
             "segments exceeded the capacity"}


def run_wall(wall: PiecewiseWall, r: float, j: float, v_stick: float = 1e-6, *, x0: float | None = None,
             v0: float = 0.0, mode: int = FLIGHT, segments: bool = False,
             max_impacts_per_piece: int = MAX_IMPACTS_PER_PERIOD) -> WallRun:
    """The gear's exact motion against ``wall`` from its start to its end.

    Parameters
    ----------
    wall : PiecewiseWall
    r, j, v_stick : float
        Restitution in [0, 1], backlash > 0 and limit impact velocity ≥ 0, in the wall's units.
    x0, v0 : float
        Start state (position relative to the mean rotation and velocity); ``x0=None`` starts
        mid-backlash.  Ignored for a start stuck on a flank (``mode`` ±1).
    segments : bool
        Keep the segments, for :meth:`WallRun.sample`.
    """
    if not 0.0 <= r <= 1.0:
        raise ValueError(f"r = {r!r} is outside the allowed range [0, 1]")
    if not j > 0.0 or not np.isfinite(j):
        raise ValueError(f"j = {j!r} must be a finite number > 0")
    if not 0.0 <= v_stick <= 10.0:
        raise ValueError(f"v_stick = {v_stick!r} is outside the allowed range [0, 10]")
    if mode not in (-1, 0, 1):
        raise ValueError(f"mode = {mode!r} must be 0 (flight), 1 or -1 (stuck on that flank)")
    y_start = float(wall.values(wall.t0[0])[0])
    if x0 is None:
        x0 = y_start + 0.5 * j
    if mode == FLIGHT and not y_start - 1e-12 * max(1.0, j) <= x0 <= y_start + j + 1e-12 * max(1.0, j):
        raise ValueError(f"x0 = {x0!r} is outside the backlash [{y_start:g}, {y_start + j:g}]")
    x0 = min(max(float(x0), y_start), y_start + j)
    n_p = wall.t0.size
    cap_imp = 64 * n_p + 10_000
    cap_seg = (4 * n_p + 20_000) if segments else 0
    while True:
        ip = np.empty(cap_imp, np.int64)
        is_ = np.empty(cap_imp)
        iI = np.empty(cap_imp)
        iw = np.empty(cap_imp)
        ifl = np.empty(cap_imp, np.int8)
        sp = np.empty(cap_seg, np.int64)
        ss = np.empty(cap_seg)
        sk = np.empty(cap_seg, np.int8)
        sx = np.empty(cap_seg)
        sv = np.empty(cap_seg)
        out = _replay(wall.t0, wall.length, wall.amp, wall.phase, wall.decel, wall.bounds,
                      wall.qmax, float(r), float(j), float(v_stick), 0, 0.0, x0, float(v0),
                      int(mode), n_p, int(max_impacts_per_piece),
                      ip, is_, iI, iw, ifl, sp, ss, sk, sx, sv)
        status, n_imp, n_seg, p, s, x, v, md = out
        if status == OVERFLOW_IMPACTS:
            cap_imp *= 8
            continue
        if status == OVERFLOW_SEGMENTS:
            cap_seg *= 8
            continue
        if status != OK:
            raise ReplayError(f"replay stopped at t = {wall.t0[min(p, n_p - 1)] + s:.6g}: "
                              f"{_MESSAGES.get(status, status)}")
        break
    t_end = wall.t_end
    return WallRun(impact_t=wall.t0[ip[:n_imp]] + is_[:n_imp], impact_impulse=iI[:n_imp].copy(),
                   impact_w=iw[:n_imp].copy(), impact_flank=ifl[:n_imp].copy(),
                   seg_t=wall.t0[sp[:n_seg]] + ss[:n_seg], seg_kind=sk[:n_seg].copy(),
                   seg_x=sx[:n_seg].copy(), seg_v=sv[:n_seg].copy(),
                   t=t_end, x=float(x), v=float(v), mode=int(md), wall=wall, j=float(j))


__all__ = ["WallRun", "ReplayError", "run_wall"]
