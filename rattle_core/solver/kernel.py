"""The compiled event loop: flight, impact, chatter, stick and release, exactly.

State: time as (period index ``n``, phase ``tau`` ∈ [0, 2π)) so that phases stay exact at late
times; position ``x``; velocity ``v``; mode (flight, stuck on the active flank, stuck on the
reverse flank).

* **Flight** is closed form: ``x = x0 + v0 s − s²/(2Λ)``, ``v = v0 − s/Λ``.  The next contact is
  the first root of the gaps ``g_a = x − y`` and ``g_r = y + j − x``, found by proven root-free
  steps (``events._safe_step``); a contact is declared when a gap is ≤ ``CONTACT_TOL`` while
  closing (``g' ≤ 0``), then polished by one Newton step.
* **Impact**: ``ẋ⁺ = ẏ − r w`` with ``w = ẋ⁻ − ẏ``; impulse ``Ĩ = ẋ⁺ − ẋ⁻ = −(1 + r) w``.
* **Chatter** ends by the limit impact velocity: an impact with ``|w| < max(v_stick, V_FLOOR)``
  is plastic (``ẋ⁺ = ẏ``, not recorded as an impact).  The gear then sticks while the reaction
  ``R̃ = 1 + Λ ÿ`` keeps its sign (> 0 active flank, < 0 reverse flank), or leaves at once.
  ``V_FLOOR`` is the numerical resolution of relative velocity, so ``v_stick = 0`` still ends.
* **Release**: the first sign change of ``R̃``, found with the same rigorous steps on ``R̃``.
* **Tangent dynamics** (optional): ``(δx, δv)`` through flight (shear), impacts (saltation
  matrix ``[[−r, 0], [−(1+r)(1/Λ + ÿ)/w, −r]]``) and sticking (collapse to zero), for the
  largest Lyapunov exponent.

Runaways stop with a status code, never a hang: impacts per period above a limit
(``RUNAWAY``) or a root search that exceeds its iteration budget (``STALL``).
"""
from __future__ import annotations

import numpy as np
from numba import njit

from .events import _leave_step, _root_free, _safe_step
from .noise import _uniform
from ..model.excitation import TWO_PI, _bounds, _y_derivs

CONTACT_TOL = 1e-13
V_FLOOR = 1e-12
MIN_STEP = 1e-15
#: Default limit on impacts within one forcing period before a run is declared a runaway.
MAX_IMPACTS_PER_PERIOD = 100_000

FLIGHT = 0
STICK_ACTIVE = 1
STICK_REVERSE = -1

OK = 0
OVERFLOW_IMPACTS = 1
OVERFLOW_SEGMENTS = 2
RUNAWAY = 3
STALL = 4

_FLIGHT_MAX_IT = 100_000
#: Shortest excursion between stick phases that contributes to the Lyapunov exponent.
MIN_EXCURSION_PERIODS = 20
#: A capture whose excursion amplified perturbations beyond this (natural log of 1e10) was
#: decided by rounding: double precision no longer resolves the loop (docs/model.md).
LOG_ROUNDING = 23.025850929940457


@njit(cache=True, nogil=True)
def _flight(lam, j, h, cphi, sphi, m2, m3, m4, tau0, x0, v0, smax, leave):
    """First contact of a flight from (tau0, x0, v0), up to ``smax``.

    Returns ``(s, hit, y0, y1, y2, y3, y4)``: hit = +1 active flank, −1 reverse flank, 0 none
    before smax, 2 iteration budget exceeded; ``y0..y4`` are the excitation and its first four
    derivatives at the contact, carried to the polished time to first order (the polishing step
    is ≤ 1e-6, so the error is below 1e-12) to spare the caller an evaluation.  ``leave`` = ±1 when the flight starts on that wall with zero
    relative velocity (after a stick phase or a plastic contact).
    """
    inv_lam = 1.0 / lam
    s = 0.0
    s_prev = 0.0
    if leave != 0:
        y0, y1, y2, y3, y4 = _y_derivs(tau0, h, cphi, sphi)
        g2 = leave * (-inv_lam - y2)
        g3 = -leave * y3
        if g2 < 0.0:
            g2 = 0.0
        s = _leave_step(g2, g3, m3, m4)
        if s <= 0.0:
            s = 1e-12
        # the opposite wall, a full backlash away, must stay clear over the same step
        d_other = _safe_step(j, 0.0, -g2, m2, m3)
        if d_other < s:
            s = d_other
        if s >= smax:
            return smax, 0, 0.0, 0.0, 0.0, 0.0, 0.0
    for _ in range(_FLIGHT_MAX_IT):
        x = x0 + v0 * s - 0.5 * s * s * inv_lam
        vv = v0 - s * inv_lam
        y0, y1, y2, y3, y4 = _y_derivs(tau0 + s, h, cphi, sphi)
        ga = x - y0
        ga1 = vv - y1
        ga2 = -inv_lam - y2
        gr = j - ga
        hit = 0
        # on a wall (after the start) and moving off it slower than the resolution V_FLOOR,
        # the gear is at rest there: a contact (the reaction then decides), or the search
        # would crawl in steps of rounding size (Λ ≈ 1, where R̃ touches zero)
        slow = V_FLOOR if s > 0.0 else 0.0
        if ga <= CONTACT_TOL and ga1 <= slow:
            hit = 1
            delta = ga / (-ga1) if ga1 < -1e-7 else 0.0
        elif gr <= CONTACT_TOL and ga1 >= -slow:
            hit = -1
            delta = gr / ga1 if ga1 > 1e-7 else 0.0
        if hit != 0:
            if (ga1 + ga2 * delta) * hit > 0.0 or s + delta < s_prev:
                # the one-step polish is kept only if the gear still moves into the wall at
                # the polished time and that time is not before the last point known clear of
                # the wall (a gap curving away, a start a rounding inside the wall): otherwise
                # the contact stays where the gap was found closed, and time never runs back
                delta = 0.0
            return (s + delta, hit, y0 + y1 * delta, y1 + y2 * delta, y2 + y3 * delta,
                    y3 + y4 * delta, y4)
        gap_a = ga if ga > 0.0 else 0.0
        gap_r = gr if gr > 0.0 else 0.0
        # the local bound only lengthens a wall's step beyond its global one, so the far wall
        # needs the local refinement only when its global step is the shorter
        ga_glob = _root_free(gap_a, ga1, -m2)
        gr_glob = _root_free(gap_r, -ga1, -m2)
        if ga_glob <= gr_glob:
            d = _safe_step(gap_a, ga1, ga2, m2, m3)
            if d > gr_glob:
                dr = _safe_step(gap_r, -ga1, -ga2, m2, m3)
                d = d if d < dr else dr
        else:
            d = _safe_step(gap_r, -ga1, -ga2, m2, m3)
            if d > ga_glob:
                da = _safe_step(gap_a, ga1, ga2, m2, m3)
                d = d if d < da else da
        if d < MIN_STEP:
            d = MIN_STEP
        if s + d >= smax:
            return smax, 0, 0.0, 0.0, 0.0, 0.0, 0.0
        s_prev = s
        s += d
    return s, 2, 0.0, 0.0, 0.0, 0.0, 0.0


@njit(cache=True, nogil=True)
def _release(lam, h, cphi, sphi, mb, tau0, smax, sigma):
    """First time the contact reaction σ(1 + Λ ÿ) stops being positive, up to ``smax``.

    Returns ``(s, released)``; released = 1 at a release, 0 if still stuck at smax,
    2 iteration budget exceeded.
    """
    f_m2 = lam * mb[4]
    f_m3 = lam * mb[5]
    tol = CONTACT_TOL * (1.0 + lam * mb[2])
    max_it = 10_000 + int(200.0 * smax / TWO_PI)
    s = 0.0
    for _ in range(max_it):
        y0, y1, y2, y3, y4 = _y_derivs(tau0 + s, h, cphi, sphi)
        f = sigma * (1.0 + lam * y2)
        f1 = sigma * lam * y3
        f2 = sigma * lam * y4
        if f <= tol and f1 < 0.0:
            if f2 > 0.0 and f - 0.5 * f1 * f1 / f2 > -tol:
                # a tangential zero: R̃ touches 0 and turns back, so the contact holds; jump
                # past the touching point, where the search resumes with R̃ rising
                s += -f1 / f2 + 2.0 * np.sqrt(2.0 * tol / f2)
                if s >= smax:
                    return smax, 0
                continue
            if f1 < -1e-7:
                s += f / (-f1)
            if s < 0.0:
                s = 0.0
            return s, 1
        d = _safe_step(f if f > 0.0 else 0.0, f1, f2, f_m2, f_m3)
        if d < 1e-12:
            # a tangential zero of the reaction (R̃ touches 0 and turns back): the gear stays
            d = 1e-12
        if s + d >= smax:
            return smax, 0
        s += d
    return s, 2


@njit(cache=True, nogil=True)
def _setup(lam, h, phi, v_stick):
    """What every event search of one parameter set needs: ``cos φ_k``, ``sin φ_k``, the
    excitation bounds, ``1/Λ``, the gap bounds ``M₂ = 1/Λ + Σ k² h_k``, ``M₃``, ``M₄`` and the
    plastic-impact threshold ``max(v_stick, V_FLOOR)``."""
    mb = _bounds(h)
    inv_lam = 1.0 / lam
    v_eff = v_stick if v_stick > V_FLOOR else V_FLOOR
    return np.cos(phi), np.sin(phi), mb, inv_lam, inv_lam + mb[2], mb[3], mb[4], v_eff


@njit(cache=True, nogil=True)
def _later_or_equal(n, tau, n_ref, tau_ref):
    return n > n_ref or (n == n_ref and tau >= tau_ref)


@njit(cache=True, nogil=True)
def _integrate(lam, r, j, h, phi, v_stick, n0, tau0, x0, v0, n_periods, rec_from, theta,
               max_imp_per_period, tangent, eps, seed,
               imp_t, imp_tau, imp_I, imp_w, imp_flank,
               seg_t, seg_kind, seg_x, seg_v,
               str_x, str_v):
    """Run ``n_periods`` forcing periods from t0 = 2π n0 + tau0.

    Impacts, segments and stroboscopic samples are recorded from ``t0 + 2π rec_from`` on, into
    the given arrays (their lengths are the capacities; a zero-length segment array records
    none).  Returns ``(status, n_imp, n_seg, n_str, n, tau, x, v, mode, lyap_sum, lyap_time,
    stick_time, n_stick, rounding, loop_amp, kicks)``; lyap_sum to n_stick, ``rounding`` (a
    capture decided by rounding) and ``loop_amp`` (the largest release-to-capture
    amplification, natural log) refer to the recording window; ``kicks`` counts the rebounds
    of the whole run whose restitution was scattered (``eps > 0``).  ``eps`` is the relative
    scatter of the restitution coefficient, drawn uniformly in ±eps at every rebound from the
    stream ``seed`` (docs/model.md, "Noise").
    """
    cphi, sphi, mb, inv_lam, m2, m3, m4, v_eff = _setup(lam, h, phi, v_stick)

    n = n0
    tau = tau0
    x = x0
    v = v0
    mode = FLIGHT
    leave = 0
    n_end = n0 + n_periods
    n_rec = n0 + rec_from
    tau_rec = tau0
    ns = n_rec if theta >= tau_rec else n_rec + 1
    cap_imp = imp_t.shape[0]
    cap_seg = seg_t.shape[0]
    cap_str = str_x.shape[0]
    n_imp = 0
    n_seg = 0
    n_str = 0
    status = OK
    imp_period = n
    imp_count = 0
    dx = 0.7071067811865476
    dv = 0.7071067811865476
    # Lyapunov bookkeeping: growth is buffered and moved into the current excursion (the
    # motion between two stick phases) at the first impact of each new period; a stick phase
    # discards the buffer (its chatter saltations are meaningless once the perturbation
    # collapses).  An excursion counts only if it lasts MIN_EXCURSION_PERIODS: after a release
    # the perturbation is exactly zero, and a short excursion's growth is not an exponent.
    lyap_sum = 0.0
    lyap_time = 0.0
    exc_sum = 0.0
    exc_time = 0.0
    min_exc = MIN_EXCURSION_PERIODS * TWO_PI
    buf = 0.0
    n_commit = n_rec
    t_commit = n_rec * TWO_PI + tau_rec
    committing = True
    stuck_in_window = False
    stick_time = 0.0
    n_stick = 0
    # Release-to-capture amplification (docs/model.md, "Sticking erases the past"): a tangent
    # vector restarted at each release (and at t0), read at each impact in impact-map
    # coordinates (shifts of the impact time and of the impact velocity), which stay bounded
    # through chatter, where the fixed-time tangent grows without meaning.
    ex_dx = 0.0
    ex_dv = 1.0
    ex_log = 0.0
    ex_a2 = 0.0
    ex_a2_log = 0.0
    loop_max = -np.inf
    rounding = False
    rounding_rec = False
    kicks = 0

    # a start on a wall, at rest on it or moving into it, is a contact at t0
    y0, y1, y2, y3, y4 = _y_derivs(tau, h, cphi, sphi)
    pending = 0
    c0, c1, c2, c3, c4 = y0, y1, y2, y3, y4
    if x - y0 <= CONTACT_TOL and v - y1 <= 0.0:
        pending = 1
    elif y0 + j - x <= CONTACT_TOL and v - y1 >= 0.0:
        pending = -1

    # events of any kind (impacts, zero-velocity contacts, releases) within one period are
    # bounded too, so no pathological sequence can loop for ever
    loop_period = n
    loops = 0
    max_loops = 8 * max_imp_per_period + 100_000
    while True:
        if n != loop_period:
            loop_period = n
            loops = 0
        loops += 1
        if loops > max_loops:
            status = STALL
            break
        rem = (n_end - n) * TWO_PI + (tau0 - tau)
        if rem <= 0.0 and pending == 0:
            break
        recording = _later_or_equal(n, tau, n_rec, tau_rec)

        if pending != 0:
            sigma = pending
            pending = 0
            y0, y1, y2, y3, y4c = c0, c1, c2, c3, c4
            w = v - y1
            x = y0 if sigma == 1 else y0 + j
            zero_rel = False
            if abs(w) >= v_eff:
                # δt = −δx/w and δw = δv − (1/Λ + ÿ) δt; the logarithm waits for a capture
                et = ex_dx / w
                q = (inv_lam + y2) * et
                ew = ex_dv + q
                ex_a2 = et * et + ew * ew
                ex_a2_log = ex_log
                rk = r
                if eps > 0.0 and r > 0.0:
                    # the restitution of this rebound, r (1 + eps ξ), kept physical (≤ 1)
                    u = _uniform(seed, kicks)
                    rk = r * (1.0 + eps * (2.0 * u - 1.0))
                    if rk > 1.0:
                        rk = 1.0
                    kicks += 1
                vplus = y1 - rk * w
                ex_dv = -rk * ex_dv - (1.0 + rk) * q
                ex_dx = -rk * ex_dx
                if recording:
                    if n_imp >= cap_imp:
                        status = OVERFLOW_IMPACTS
                        break
                    imp_t[n_imp] = n * TWO_PI + tau
                    imp_tau[n_imp] = tau
                    imp_I[n_imp] = vplus - v
                    imp_w[n_imp] = w
                    imp_flank[n_imp] = sigma
                    n_imp += 1
                if n != imp_period:
                    imp_period = n
                    imp_count = 0
                imp_count += 1
                if imp_count > max_imp_per_period:
                    status = RUNAWAY
                    break
                if tangent:
                    ddv = -rk * dv - (1.0 + rk) * (inv_lam + y2) / w * dx
                    dx = -rk * dx
                    dv = ddv
                v = vplus
                zero_rel = r == 0.0
            else:
                if tangent:
                    ww = w
                    if abs(ww) < V_FLOOR:
                        ww = V_FLOOR if ww >= 0.0 else -V_FLOOR
                    dv = -(inv_lam + y2) / ww * dx
                    dx = 0.0
                ww = w
                if abs(ww) < V_FLOOR:
                    ww = V_FLOOR if ww >= 0.0 else -V_FLOOR
                ex_dv = -(inv_lam + y2) / ww * ex_dx
                ex_dx = 0.0
                v = y1
                zero_rel = True
            nrm = abs(ex_dx) + abs(ex_dv)
            if nrm > 1e100 or (nrm < 1e-100 and nrm > 0.0):
                ex_log += np.log(nrm)
                ex_dx /= nrm
                ex_dv /= nrm
            mode = FLIGHT
            leave = 0
            if zero_rel:
                f = sigma * (1.0 + lam * y2)
                f1 = sigma * lam * y3
                tol = CONTACT_TOL * (1.0 + lam * mb[2])
                f2 = sigma * lam * y4c
                if f > tol or (f > -tol and (f1 > 0.0 or (f2 > 0.0 and
                                                        f - 0.5 * f1 * f1 / f2 > -tol))):
                    mode = sigma
                    ex_amp = ex_a2_log + 0.5 * np.log(ex_a2) if ex_a2 > 0.0 else -np.inf
                    if ex_amp > LOG_ROUNDING:
                        rounding = True
                        rounding_rec = rounding_rec or recording
                    if recording and ex_amp > loop_max:
                        loop_max = ex_amp
                    if tangent:
                        dx = 0.0
                        dv = 0.0
                else:
                    leave = sigma
            if tangent:
                nrm = np.sqrt(dx * dx + dv * dv)
                if nrm > 0.0:
                    if recording:
                        buf += np.log(nrm)
                    dx /= nrm
                    dv /= nrm
                if mode != FLIGHT:
                    buf = 0.0
                    committing = False
                    if exc_time >= min_exc:
                        lyap_sum += exc_sum
                        lyap_time += exc_time
                    exc_sum = 0.0
                    exc_time = 0.0
                elif recording and committing and n > n_commit:
                    t_now = n * TWO_PI + tau
                    exc_sum += buf
                    exc_time += t_now - t_commit
                    buf = 0.0
                    t_commit = t_now
                    n_commit = n
            continue

        seg_start_t = n * TWO_PI + tau
        if mode == FLIGHT:
            s, hit, c0, c1, c2, c3, c4 = _flight(lam, j, h, cphi, sphi, m2, m3, m4, tau, x, v, rem,
                                             leave)
            leave = 0
            if hit == 2:
                status = STALL
                break
        else:
            s, rel = _release(lam, h, cphi, sphi, mb, tau, rem, mode)
            if rel == 2:
                status = STALL
                break
            hit = 0

        # record the segment, if any part of it lies in the window
        tau_end_seg = tau + s
        k = np.floor(tau_end_seg / TWO_PI)
        n_after = n + int(k)
        tau_after = tau_end_seg - k * TWO_PI
        if tau_after < 0.0:
            tau_after = 0.0
        in_window = _later_or_equal(n_after, tau_after, n_rec, tau_rec)
        if in_window and cap_seg > 0:
            if n_seg >= cap_seg:
                status = OVERFLOW_SEGMENTS
                break
            seg_t[n_seg] = seg_start_t
            seg_kind[n_seg] = mode
            seg_x[n_seg] = x
            seg_v[n_seg] = v
            n_seg += 1

        # stroboscopic samples inside this segment
        while n_str < cap_str:
            o = (ns - n) * TWO_PI + (theta - tau)
            if o >= s:
                break
            if o < 0.0:
                o = 0.0
            if mode == FLIGHT:
                str_x[n_str] = x + v * o - 0.5 * o * o * inv_lam
                str_v[n_str] = v - o * inv_lam
            else:
                yy0, yy1, yy2, yy3, yy4 = _y_derivs(theta, h, cphi, sphi)
                str_x[n_str] = yy0 if mode == STICK_ACTIVE else yy0 + j
                str_v[n_str] = yy1
            n_str += 1
            ns += 1

        if in_window:
            if mode != FLIGHT:
                # only the part of the stick phase inside the window counts
                t_rec = n_rec * TWO_PI + tau_rec
                stick_time += min(s, n_after * TWO_PI + tau_after - t_rec)
                n_stick += 1
                stuck_in_window = True

        if mode == FLIGHT:
            x = x + v * s - 0.5 * s * s * inv_lam
            v = v - s * inv_lam
            ex_dx += ex_dv * s
            if tangent:
                dx += dv * s
        n = n_after
        tau = tau_after
        if mode == FLIGHT:
            if hit != 0:
                pending = hit
        else:
            y0, y1, y2, y3, y4 = _y_derivs(tau, h, cphi, sphi)
            x = y0 if mode == STICK_ACTIVE else y0 + j
            v = y1
            if rem > s:
                leave = mode
                mode = FLIGHT
                ex_dx = 0.0
                ex_dv = 1.0
                ex_log = 0.0
                ex_a2 = 0.0
                if tangent:
                    # the release time depends on the phase only, so the perturbation stays
                    # collapsed; a fresh unit vector restarts the measurement
                    dx = 0.7071067811865476
                    dv = 0.7071067811865476
                    committing = True
                    buf = 0.0
                    n_commit = n
                    t_commit = n * TWO_PI + tau
        if rem <= s:
            break

    if tangent and committing and mode == FLIGHT:
        nrm = np.sqrt(dx * dx + dv * dv)
        t_now = n * TWO_PI + tau
        if nrm > 0.0 and t_now > t_commit:
            exc_sum += buf + np.log(nrm)
            exc_time += t_now - t_commit
    if tangent and (exc_time >= min_exc or not stuck_in_window):
        lyap_sum += exc_sum
        lyap_time += exc_time
    if lyap_time <= 0.0 and stuck_in_window:
        lyap_sum = -np.inf
        lyap_time = 1.0
    return (status, n_imp, n_seg, n_str, n, tau, x, v, mode, lyap_sum, lyap_time,
            stick_time, n_stick, rounding_rec, loop_max, kicks)
