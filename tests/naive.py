"""Slow, obvious references for the rattle model, written from ``docs/model.md`` alone.

Nothing here imports ``rattle_core``: the compiled solver is checked against code that shares
none of its kernels, bounds or tolerances.

* :func:`y_derivative` evaluates ``y(t) = Σ h_k cos(k t − φ_k)`` and its derivatives term by
  term, with the explicit ``cos, −sin, −cos, sin`` cycle.
* :func:`naive_simulate` is a plain-Python event loop.  Each flight is scanned on a dense grid
  for the first sign change of either gap, and the crossing is polished with ``brentq``.  It
  applies the same impact law, ``v_stick`` rule and stick/release rule as the model, so it
  agrees with the solver on every contact that is not grazing; a grazing contact (the gap dips
  below zero for less than one grid step) is exactly what it may miss.
* :func:`classify_reference` applies the regime rules of ``docs/model.md`` with plain numpy
  expressions, one window at a time (the library runs them compiled): the one copy of those
  rules in the tests.
* :func:`ivp_simulate` integrates ``Λ ẍ = −1`` with ``scipy.integrate.solve_ivp`` (DOP853,
  tight tolerances) and terminal events on both gaps.  It handles flights and impacts only, and
  stops with an error at the first contact slow enough to start a stick phase.
"""
from __future__ import annotations

import dataclasses

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

TWO_PI = 2.0 * np.pi


class ReferenceError_(RuntimeError):
    """The reference met a situation it is not built to resolve (e.g. a grazing start)."""


def y_derivative(t, h, phi, m: int = 0):
    """m-th derivative of ``y(t) = Σ_k h_k cos(k t − φ_k)`` (phases in radians).

    Uses ``d/dt cos = −sin``, ``d/dt sin = cos`` directly, with no reduction of ``t`` modulo
    2π, so it shares no code path with ``rattle_core.model.excitation``.
    """
    t = np.asarray(t, dtype=np.float64)
    out = np.zeros_like(t)
    for k, (hk, pk) in enumerate(zip(h, phi), start=1):
        arg = k * t - pk
        cycle = m % 4
        if cycle == 0:
            term = np.cos(arg)
        elif cycle == 1:
            term = -np.sin(arg)
        elif cycle == 2:
            term = -np.cos(arg)
        else:
            term = np.sin(arg)
        out = out + hk * float(k) ** m * term
    return out


def _y(t, h, phi, m=0) -> float:
    return float(y_derivative(np.float64(t), h, phi, m))


@dataclasses.dataclass
class NaiveRun:
    """Event log of a reference run (same meaning as the fields of ``Trajectory``)."""

    impact_t: np.ndarray
    impact_impulse: np.ndarray
    impact_flank: np.ndarray
    impact_w: np.ndarray
    stick_intervals: np.ndarray
    seg_t: np.ndarray
    seg_kind: np.ndarray
    seg_x: np.ndarray
    seg_v: np.ndarray
    t_end: float


def _first_scan_point(u, g2, g3, m2, m3, m4, ds):
    """A first grid point ``s1`` at which a gap leaving its wall is provably positive.

    The gap starts at 0 with slope ``u ≥ 0``, curvature ``g2`` and third derivative ``g3``;
    Taylor's theorem with ``|g''| ≤ m2``, ``|g'''| ≤ m3``, ``|g''''| ≤ m4`` gives
    ``g(s) ≥ u s − m2 s²/2`` (positive for ``s = u/(4 m2)``),
    ``g(s) ≥ g2 s²/2 − m3 s³/6`` (``s = g2/m3``) and ``g(s) ≥ g3 s³/6 − m4 s⁴/24`` (``s = g3/m4``).
    """
    cands = []
    if u > 0.0:
        cands.append(u / (4.0 * m2))
    if g2 > 0.0:
        cands.append(g2 / m3)
    if g2 >= -1e-14 and g3 > 0.0:
        cands.append(g3 / m4)
    if not cands:
        raise ReferenceError_(f"cannot leave the wall: u={u!r}, g''={g2!r}, g'''={g3!r}")
    return min(ds, max(cands))


def _scan_grid(s1, ds, smax, chunk=4096):
    """Grid from ``s1`` in chunks: steps grow geometrically (×1.25) up to ``ds``, then stay at
    ``ds``; the last point is ``smax``.  Chunks are made as the scan needs them, since a flight
    is usually short and ``smax`` is the rest of the run."""
    pts = [s1]
    while pts[-1] < smax:
        step = min(ds, max(s1, 0.25 * pts[-1]))
        if step >= ds:
            break
        pts.append(pts[-1] + step)
    head = np.array(pts)
    yield head[head <= smax]
    base = head[-1] + ds
    for k0 in range(0, 1 << 62, chunk):
        tail = base + ds * np.arange(k0, k0 + chunk)
        tail = tail[tail < smax]
        if len(tail):
            yield tail
        if len(tail) < chunk:
            break
    yield np.array([smax])


def naive_simulate(lam, r, j, h, phi, v_stick, t0, x0, v0, t_end, ds=TWO_PI / 1000,
                   max_events=200_000, noise=0.0, rng=None) -> NaiveRun:
    """Plain-Python event loop for the rattle model (docs/model.md), from ``t0`` to ``t_end``.

    Parameters
    ----------
    lam, r, j : float
        Λ, restitution and backlash.
    h, phi : sequence of float
        Harmonic amplitudes and phases (radians).
    v_stick : float
        An impact with ``|w| < v_stick`` is plastic; the gear then sticks while the reaction
        ``σ (1 + Λ ÿ)`` is positive, and leaves with ``ẋ = ẏ`` when it reaches zero.
    t0, x0, v0 : float
        Initial time and state (``y(t0) ≤ x0 ≤ y(t0) + j``).
    t_end : float
        End time.
    ds : float
        Longest scan step.  Contacts whose penetration lasts less than ``ds`` may be missed.
    noise, rng : float, numpy Generator
        The model's noise (docs/model.md, "Noise"): each rebound uses ``r (1 + noise ξ)``,
        capped at 1, with ``ξ`` uniform in (−1, 1) drawn from ``rng``.
    """
    if noise > 0.0 and rng is None:
        raise ValueError("noise > 0 needs a random generator rng")
    h = np.asarray(h, dtype=np.float64)
    phi = np.asarray(phi, dtype=np.float64)
    k = np.arange(1, len(h) + 1, dtype=np.float64)
    habs = np.abs(h)
    m2 = 1.0 / lam + float(np.sum(k**2 * habs))
    m3 = float(np.sum(k**3 * habs))
    m4 = float(np.sum(k**4 * habs))
    imp_t, imp_I, imp_fl, imp_w = [], [], [], []
    sticks, seg_t, seg_kind, seg_x, seg_v = [], [], [], [], []

    t, x, v = float(t0), float(x0), float(v0)
    pending = 0  # wall of a contact at the current time
    wall = 0  # wall the current flight leaves (for the first scan point)
    u = g2 = g3 = 0.0
    w0 = v - _y(t, h, phi, 1)
    for sigma, gap in ((1, x - _y(t, h, phi)), (-1, _y(t, h, phi) + j - x)):
        if abs(gap) <= 1e-12:
            # on a wall at t0: a contact if moving into it, else a flight leaving it
            if sigma * w0 <= 0.0:
                pending = sigma
            else:
                wall, u = sigma, abs(w0)

    for _ in range(max_events):
        if pending != 0:
            sigma = pending
            pending = 0
            yd = _y(t, h, phi, 1)
            ydd = _y(t, h, phi, 2)
            x = _y(t, h, phi) + (j if sigma == -1 else 0.0)
            w = v - yd
            if abs(w) >= v_stick and w != 0.0:
                rk = min(r * (1.0 + noise * rng.uniform(-1.0, 1.0)), 1.0) if noise > 0.0 else r
                vplus = yd - rk * w
                imp_t.append(t)
                imp_I.append(vplus - v)
                imp_fl.append(sigma)
                imp_w.append(w)
                v = vplus
                u = abs(rk * w)
            else:
                v = yd
                u = 0.0
            if u == 0.0:
                react = sigma * (1.0 + lam * ydd)
                if react > 0.0:
                    t_rel = _release_time(lam, h, phi, sigma, t, t_end, ds)
                    seg_t.append(t)
                    seg_kind.append(sigma)
                    seg_x.append(x)
                    seg_v.append(v)
                    sticks.append((t, min(t_rel, t_end)))
                    if t_rel >= t_end:
                        t = t_end
                        break
                    t = t_rel
                    x = _y(t, h, phi) + (j if sigma == -1 else 0.0)
                    v = _y(t, h, phi, 1)
                    react = 0.0
                g2 = -react / lam
                g3 = -sigma * _y(t, h, phi, 3)
            else:
                g2 = g3 = 0.0
            wall = sigma
            continue
        if t >= t_end:
            break
        seg_t.append(t)
        seg_kind.append(0)
        seg_x.append(x)
        seg_v.append(v)
        s, hit = _flight(lam, j, h, phi, t, x, v, t_end - t, wall, u, g2, g3, m2, m3, m4, ds)
        x = x + v * s - 0.5 * s * s / lam
        v = v - s / lam
        t = t + s
        wall = 0
        pending = hit
        if hit == 0:
            break
    else:
        raise ReferenceError_(f"more than {max_events} events before t_end")

    return NaiveRun(
        impact_t=np.array(imp_t), impact_impulse=np.array(imp_I),
        impact_flank=np.array(imp_fl, dtype=np.int8), impact_w=np.array(imp_w),
        stick_intervals=np.array(sticks, dtype=np.float64).reshape(-1, 2),
        seg_t=np.array(seg_t), seg_kind=np.array(seg_kind, dtype=np.int8),
        seg_x=np.array(seg_x), seg_v=np.array(seg_v), t_end=float(t_end))


def _flight(lam, j, h, phi, t, x, v, smax, wall, u, g2, g3, m2, m3, m4, ds):
    """First contact of the parabola from (t, x, v) within ``smax``: ``(s, wall)`` or ``(smax, 0)``."""
    def gaps(s):
        xs = x + v * s - 0.5 * s * s / lam
        ys = y_derivative(t + s, h, phi)
        return xs - ys, ys + j - xs

    s1 = ds if wall == 0 else _first_scan_point(u, g2, g3, m2, m3, m4, ds)
    if s1 >= smax:
        s1 = smax
    ga0, gr0 = gaps(np.array([0.0]))
    if wall == 0 and (ga0[0] <= 0.0 or gr0[0] <= 0.0):
        raise ReferenceError_("flight starts on a wall without a leaving state")
    ga1, gr1 = gaps(np.array([s1]))
    if ga1[0] <= 0.0 or gr1[0] <= 0.0:
        raise ReferenceError_(f"gap not positive at the first scan point s1={s1!r} "
                              f"(g_a={ga1[0]!r}, g_r={gr1[0]!r})")
    prev = s1
    for sg in _scan_grid(s1, ds, smax):
        ga, gr = gaps(sg)
        bad = (ga <= 0.0) | (gr <= 0.0)
        if np.any(bad):
            i = int(np.argmax(bad))
            lo, hi = (sg[i - 1] if i > 0 else prev), sg[i]
            roots = []
            for sgn, which in ((1, 0), (-1, 1)):
                f = (lambda s, w=which: float(gaps(np.array([s]))[w][0]))
                if f(hi) <= 0.0:
                    root = brentq(f, lo, hi, xtol=1e-15, rtol=4 * np.finfo(float).eps, maxiter=200)
                    roots.append((root, sgn))
            roots.sort()
            return roots[0]
        prev = sg[-1]
    return smax, 0


def _release_time(lam, h, phi, sigma, t, t_end, ds):
    """First time after ``t`` when the reaction ``σ (1 + Λ ÿ)`` reaches zero (or ``t_end``)."""
    def react(tt):
        return sigma * (1.0 + lam * y_derivative(tt, h, phi, 2))

    chunk = 4096
    lo_prev = t
    n_pts = max(1, int(np.ceil((t_end - t) / ds)))
    # the grid t + ds, t + 2 ds, ... (clipped at t_end) is built a chunk at a time: a stick
    # phase rarely lasts long, and the whole grid of a long run costs more than the run
    for start in range(0, n_pts, chunk):
        tg = np.minimum(t + ds * np.arange(start + 1, min(start + chunk, n_pts) + 1), t_end)
        vals = react(tg)
        bad = vals <= 0.0
        if np.any(bad):
            i = int(np.argmax(bad))
            lo = tg[i - 1] if i > 0 else lo_prev
            hi = tg[i]
            if float(react(lo)) <= 0.0:
                return lo
            return brentq(lambda s: float(react(s)), lo, hi, xtol=1e-15,
                          rtol=4 * np.finfo(float).eps, maxiter=200)
        lo_prev = tg[-1]
    return t_end


def naive_sample(run: NaiveRun, t, lam, j, h, phi):
    """Position and velocity of a :class:`NaiveRun` at times ``t`` (parabolas and walls)."""
    t = np.asarray(t, dtype=np.float64)
    idx = np.clip(np.searchsorted(run.seg_t, t, side="right") - 1, 0, len(run.seg_t) - 1)
    s = t - run.seg_t[idx]
    x = run.seg_x[idx] + run.seg_v[idx] * s - 0.5 * s * s / lam
    v = run.seg_v[idx] - s / lam
    kind = run.seg_kind[idx]
    stuck = kind != 0
    x[stuck] = y_derivative(t[stuck], h, phi) + np.where(kind[stuck] == -1, j, 0.0)
    v[stuck] = y_derivative(t[stuck], h, phi, 1)
    return x, v


def ivp_simulate(lam, r, j, h, phi, v_stick, t0, x0, v0, t_end, rtol=1e-12, atol=1e-12,
                 max_step=0.05, method="DOP853") -> NaiveRun:
    """``solve_ivp`` reference: integrate ``ẋ = v, v̇ = −1/Λ`` with terminal events on both gaps.

    After each event the impact law ``ẋ⁺ = ẏ − r w`` is applied and the integration restarts
    from the wall.  ``max_step`` keeps a contact from being stepped over (the right-hand side is
    a polynomial, so the error estimate alone would allow arbitrarily long steps).  A contact
    with ``|w| < v_stick`` raises :class:`ReferenceError_`: this reference does not model stick
    phases.
    """
    h = np.asarray(h, dtype=np.float64)
    phi = np.asarray(phi, dtype=np.float64)
    inv_lam = 1.0 / lam

    def rhs(_t, z):
        return [z[1], -inv_lam]

    def gap_active(tt, z):
        return z[0] - _y(tt, h, phi)

    def gap_reverse(tt, z):
        return _y(tt, h, phi) + j - z[0]

    for ev in (gap_active, gap_reverse):
        ev.terminal = True
        ev.direction = -1

    imp_t, imp_I, imp_fl, imp_w = [], [], [], []
    seg_t, seg_x, seg_v = [], [], []
    t, x, v = float(t0), float(x0), float(v0)
    while t < t_end:
        seg_t.append(t)
        seg_x.append(x)
        seg_v.append(v)
        sol = solve_ivp(rhs, (t, t_end), [x, v], method=method, events=(gap_active, gap_reverse),
                        rtol=rtol, atol=atol, max_step=max_step)
        if sol.status == -1:
            raise ReferenceError_(sol.message)
        if sol.status == 0:
            break
        hits = [(float(te[0]), sigma, ye[0]) for te, ye, sigma
                in zip(sol.t_events, sol.y_events, (1, -1)) if len(te)]
        t, sigma, z = min(hits, key=lambda e: e[0])
        yd = _y(t, h, phi, 1)
        w = float(z[1]) - yd
        if abs(w) < v_stick:
            raise ReferenceError_(f"slow contact |w|={abs(w):.3g} < v_stick at t={t:.12g}: "
                                  "stick phases are outside this reference")
        vplus = yd - r * w
        imp_t.append(t)
        imp_I.append(vplus - float(z[1]))
        imp_fl.append(sigma)
        imp_w.append(w)
        x = _y(t, h, phi) + (j if sigma == -1 else 0.0)
        v = vplus
    n = len(seg_t)
    return NaiveRun(
        impact_t=np.array(imp_t), impact_impulse=np.array(imp_I),
        impact_flank=np.array(imp_fl, dtype=np.int8), impact_w=np.array(imp_w),
        stick_intervals=np.zeros((0, 2)), seg_t=np.array(seg_t),
        seg_kind=np.zeros(n, dtype=np.int8), seg_x=np.array(seg_x), seg_v=np.array(seg_v),
        t_end=float(t_end))


def classify_trajectory(tr) -> dict:
    """:func:`classify_reference` of a simulated trajectory's recorded window."""
    return classify_reference(tr.impact_impulse, tr.impact_flank, tr.strobe_x, tr.strobe_v,
                              tr.periods, tr.stick_time, tr.lyapunov, tr.params.j,
                              rounding=tr.rounding_decided,
                              loop_amplification=tr.loop_amplification, kicks=tr.noise_kicks)


def _reference_period(sx, sv, scale, max_period, tol):
    m = len(sx)
    if m < 4:
        return 0
    start = m // 2
    thr = tol * (1.0 + scale)
    for n in range(1, min(max_period, m - start - 1) + 1):
        if (np.max(np.abs(sx[start + n:] - sx[start:m - n])) <= thr
                and np.max(np.abs(sv[start + n:] - sv[start:m - n])) <= thr):
            return n
    return 0


#: The regime rules' numbers, as docs/model.md ("Regimes") states them.
MAX_PERIOD = 32
PERIOD_TOL = 1e-6
LYAP_CHAOS = 1e-3


def classify_reference(impulse, flank, strobe_x, strobe_v, periods, stick_time, lyapunov, j,
                       *, max_period=MAX_PERIOD, tol=PERIOD_TOL, chaos=LYAP_CHAOS,
                       rounding=False, loop_amplification=-np.inf, kicks=0) -> dict:
    """Regime, period, kind of sticking and rattle metrics of one window, from the definitions
    (docs/model.md, "Regimes"): the one copy of the regime rules the tests hold."""
    periods = max(float(periods), 1e-300)
    act, rev = flank == 1, flank == -1
    n_act, n_rev = int(act.sum()), int(rev.sum())
    stick_fraction = min(1.0, stick_time / (periods * TWO_PI))
    period = _reference_period(strobe_x, strobe_v, j, max_period, tol)
    chaotic = period == 0 and lyapunov > chaos
    a_pp, r_pp = n_act / periods, n_rev / periods

    def stats(sel):
        if not sel.any():
            return 0.0, 0.0
        a = np.abs(impulse[sel])
        return float(a.mean()), float(np.sqrt(np.mean(a * a)))

    ma, ra = stats(act)
    mr, rr = stats(rev)
    if n_act + n_rev == 0 and stick_fraction > 0.99:
        regime = "A"
    elif chaotic:
        regime = "D"
    elif stick_fraction > 0:
        regime = "B"
    elif period == 1 and n_rev == 0 and abs(a_pp - 1) < 0.02:
        regime = "C"
    elif period == 1 and abs(a_pp - 1) < 0.02 and abs(r_pp - 1) < 0.02:
        regime = "E"
    elif period > 0:
        regime = "P"
    else:
        regime = "Q"
    return {"regime": regime, "period": period, "active_per_period": a_pp,
            "reverse_per_period": r_pp, "stick_fraction": stick_fraction,
            "lyapunov": float(lyapunov), "chaotic": bool(chaotic),
            "intensity": float(np.sum(impulse * impulse) / periods),
            "mean_impulse_active": ma, "rms_impulse_active": ra,
            "mean_impulse_reverse": mr, "rms_impulse_reverse": rr,
            "sticking": ("" if stick_fraction == 0 else
                         "chaos-through-sticking" if rounding else "stick-locked"),
            "loop_amplification": float(loop_amplification), "noisy": kicks > 0}


# ----- a run-up, replayed slowly in physical time ----------------------------------------------

@dataclasses.dataclass
class NaiveRunup:
    """A measured run-up as docs/model.md ("A run-up in physical time") writes it, in SI units.

    The shaft's mean speed ramps linearly, ``rpm(t) = rpm_from + c t``; its mean angle is
    ``ψ(t) = 2π/60 (rpm_from t + c t²/2)``; each harmonic ``n`` (engine order ``n ·
    engine_order``) has amplitude ``θ_n`` and phase ``φ_n`` given at ``knots_rpm`` and
    interpolated by scipy's cubic spline in rpm.  The driving tooth is
    ``y(t) = scale Σ_n θ_n cos(n · engine_order · ψ − φ_n)`` and the gear's flight deceleration
    is the constant ``q``.  Derivatives come from the chain rule, term by term.
    """

    knots_rpm: np.ndarray
    theta: np.ndarray
    phase_rad: np.ndarray
    engine_order: float
    rpm_from: float
    rpm_to: float
    duration: float
    scale: float
    q: float

    def __post_init__(self):
        from scipy.interpolate import CubicSpline
        self._th = CubicSpline(self.knots_rpm, self.theta, axis=0)
        self._ph = CubicSpline(self.knots_rpm, self.phase_rad, axis=0)
        self.c = (self.rpm_to - self.rpm_from) / self.duration

    def y(self, t, m: int = 0):
        """The tooth (m = 0) or its velocity (m = 1) at times ``t`` [s]."""
        t = np.atleast_1d(np.asarray(t, dtype=np.float64))
        rpm = self.rpm_from + self.c * t
        psi = 2.0 * np.pi / 60.0 * (self.rpm_from * t + 0.5 * self.c * t * t)
        omega = 2.0 * np.pi / 60.0 * rpm
        out = np.zeros_like(t)
        th, ph = self._th(rpm), self._ph(rpm)
        dth, dph = self._th(rpm, 1) * self.c, self._ph(rpm, 1) * self.c
        for i in range(self.theta.shape[1]):
            k = (i + 1) * self.engine_order
            arg = k * psi - ph[:, i]
            if m == 0:
                out += th[:, i] * np.cos(arg)
            else:
                out += dth[:, i] * np.cos(arg) - th[:, i] * np.sin(arg) * (k * omega - dph[:, i])
        return self.scale * out


def naive_runup(model: NaiveRunup, b, r, x0, v0, t_end, dt, v_stick=1e-9):
    """Impacts of the gear from ``(0, x0, v0)`` to ``t_end`` [s]: ``(times, Δv, flanks)``.

    Each flight ``x = x0 + v0 s − q s²/2`` is scanned on a grid of ``dt`` for the first sign
    change of either gap ``x − y`` or ``y + b − x``, and the crossing is polished with ``brentq``.
    Impacts ``ẋ⁺ = ẏ − r (ẋ⁻ − ẏ)``.  Built for rattle without sticking: an impact slower than
    ``v_stick`` [m/s] raises :class:`ReferenceError_`.
    """
    t, x, v = 0.0, float(x0), float(v0)
    times, dvs, flanks = [], [], []
    first = True
    while t < t_end:
        def gaps(s, t=t, x=x, v=v):
            xs = x + v * s - 0.5 * model.q * s * s
            ys = model.y(t + s)
            return xs - ys, ys + b - xs
        # leave the wall this flight starts on: the first grid point is a small step out
        s_prev = 0.0 if first else 1e-3 * dt
        first = False
        found = None
        while found is None:
            smax = t_end - t
            if s_prev >= smax:
                break
            sg = np.minimum(s_prev + dt * np.arange(1, 2049), smax)
            ga, gr = gaps(sg)
            bad = (ga <= 0.0) | (gr <= 0.0)
            if np.any(bad):
                i = int(np.argmax(bad))
                lo = sg[i - 1] if i > 0 else s_prev
                roots = []
                for which, flank in ((0, 1), (1, -1)):
                    f = (lambda s, w=which: float(gaps(np.array([s]))[w][0]))
                    if f(sg[i]) <= 0.0:
                        roots.append((brentq(f, lo, sg[i], xtol=1e-16, rtol=4 * np.finfo(float).eps,
                                             maxiter=200), flank))
                found = min(roots)
            else:
                s_prev = sg[-1]
                if sg[-1] >= smax:
                    break
        if found is None:
            break
        s, flank = found
        t = t + s
        v_minus = v - model.q * s
        yd = float(model.y(t, 1)[0])
        w = v_minus - yd
        if abs(w) < v_stick:
            raise ReferenceError_(f"an impact at t = {t!r} is slower than v_stick: the reference "
                                  "does not follow sticking")
        v = yd - r * w
        x = float(model.y(t)[0]) + (0.0 if flank == 1 else b)
        times.append(t)
        dvs.append(v - v_minus)
        flanks.append(flank)
    return np.array(times), np.array(dvs), np.array(flanks)
