"""The exact event-driven solver against closed forms, slow references and built-on-purpose cases."""
from __future__ import annotations

import math

import numpy as np
import pytest

from naive import ivp_simulate, naive_sample, naive_simulate, y_derivative
from rattle_core import RattleParams, SolverError, simulate
from rattle_core.solver import kernel as solver
from rattle_core.model.excitation import _bounds, excitation

TWO_PI = 2.0 * np.pi
R = 0.65
J = 8.0


def y_of(p: RattleParams, t, m: int = 0):
    return y_derivative(t, p.h, p.phi, m)


# ----- regime C: the closed-form one-impact orbit ------------------------------------------


def c_orbit(lam: float, r: float = R) -> tuple[float, float]:
    """Impact phase θ and post-impact velocity of the regime C orbit (docs/model.md).

    Flight time 2π and a symmetric parabola give ẋ⁺ = π/Λ, ẋ⁻ = −π/Λ; the impact law then needs
    ẏ(θ) = −sin θ = (1 − r)π / ((1 + r)Λ).  Of the two roots, the one with cos θ > 0 (the wall
    high and rising) is the one the solver settles on; it is checked below.
    """
    s = (1.0 - r) * np.pi / ((1.0 + r) * lam)
    return TWO_PI - math.asin(s), np.pi / lam


@pytest.mark.parametrize("lam", [1.18, 1.2, 1.22])
def test_regime_c_impulse_and_phase_are_closed_form(lam):
    """Regime C (harmonic, r = 0.65, j = 8): impulse 2π/Λ and sin θ = −(1 − r)π/((1 + r)Λ), to 1e-9."""
    p = RattleParams(lam=lam, r=R, j=J)
    tr = simulate(p, periods=30, transient=400, lyapunov=True)
    theta, _ = c_orbit(lam)
    assert len(tr.impact_t) == 30
    assert np.all(tr.impact_flank == 1)
    np.testing.assert_allclose(tr.impact_impulse, TWO_PI / lam, rtol=0, atol=1e-9)
    np.testing.assert_allclose(np.sin(tr.impact_phase),
                               -(1 - R) * np.pi / ((1 + R) * lam), rtol=0, atol=1e-9)
    np.testing.assert_allclose(tr.impact_phase, theta, rtol=0, atol=1e-9)
    np.testing.assert_allclose(np.diff(tr.impact_t), TWO_PI, rtol=0, atol=1e-9)
    assert len(tr.stick_intervals) == 0
    # stable: the largest Lyapunov exponent is negative
    assert tr.lyapunov < -0.005


def test_regime_c_orbit_started_exactly_closes_after_one_period():
    """Started on the analytic C orbit, the next impact comes 2π later with impulse 2π/Λ (1e-12)."""
    lam = 1.2
    p = RattleParams(lam=lam, r=R, j=J)
    theta, vplus = c_orbit(lam)
    tr = simulate(p, periods=3, t0=theta, x0=math.cos(theta), v0=vplus)
    assert tr.impact_t[0] == pytest.approx(theta + TWO_PI, abs=1e-12)
    assert tr.impact_impulse[0] == pytest.approx(TWO_PI / lam, abs=1e-12)
    assert tr.impact_w[0] == pytest.approx(-np.pi / lam + math.sin(theta), abs=1e-12)


def test_regime_c_attracts_a_perturbed_start():
    """A 1e-3 perturbation of the C orbit decays: after 300 periods the impulse is 2π/Λ to 1e-9."""
    lam = 1.2
    p = RattleParams(lam=lam, r=R, j=J)
    theta, vplus = c_orbit(lam)
    tr = simulate(p, periods=5, transient=300, t0=theta, x0=math.cos(theta) + 1e-3, v0=vplus - 1e-3)
    np.testing.assert_allclose(tr.impact_impulse, TWO_PI / lam, atol=1e-9)
    np.testing.assert_allclose(tr.impact_phase, theta, atol=1e-9)


# ----- regime A / B: permanent contact -------------------------------------------------------


def test_permanent_contact_when_started_on_the_active_flank():
    """Harmonic, Λ = 0.8, at rest on the active flank: no impact at all, stuck for the whole run."""
    p = RattleParams(lam=0.8, r=R, j=J)
    tr = simulate(p, periods=40, x0=1.0, v0=0.0, lyapunov=True)
    assert len(tr.impact_t) == 0
    assert tr.stick_intervals.shape == (1, 2)
    assert tr.stick_intervals[0, 0] == pytest.approx(0.0, abs=1e-12)
    assert tr.stick_intervals[0, 1] == pytest.approx(tr.t_end, abs=1e-12)
    assert tr.stick_time == pytest.approx(40 * TWO_PI, rel=1e-12)
    t = np.linspace(tr.t_start, tr.t_end, 5001)
    x, v = tr.sample(t)
    np.testing.assert_allclose(x, np.cos(t), atol=1e-12)
    np.testing.assert_allclose(v, -np.sin(t), atol=1e-12)
    assert tr.lyapunov == -np.inf


@pytest.mark.parametrize("lam", [0.3, 0.8, 0.99])
def test_chatter_then_permanent_contact_from_mid_backlash(lam):
    """Λ < 1 from mid-backlash: impacts only on the active flank, then one stick phase to the end."""
    p = RattleParams(lam=lam, r=R, j=J)
    tr = simulate(p, periods=40)
    assert 0 < len(tr.impact_t) < 60
    assert np.all(tr.impact_flank == 1)
    assert tr.stick_intervals.shape == (1, 2)
    t_stick = tr.stick_intervals[0, 0]
    assert tr.stick_intervals[0, 1] == pytest.approx(tr.t_end, abs=1e-12)
    assert t_stick < 4 * TWO_PI
    assert tr.impact_t[-1] <= t_stick
    # the impacts decay geometrically in the chatter that precedes the stick phase
    tail = np.abs(tr.impact_w[-10:])
    np.testing.assert_array_less(tail[1:], tail[:-1])


@pytest.mark.parametrize("lam, r, v_stick", [(0.3, 0.65, 1e-6), (0.8, 0.65, 1e-6), (0.8, 0.65, 0.0),
                                             (0.3, 0.9, 1e-6), (0.3, 0.9, 0.0), (0.8, 0.3, 1e-3),
                                             (0.8, 0.0, 1e-6), (0.5, 0.65, 1e-6)])
def test_chatter_ends_in_finite_time_with_bounded_impacts(lam, r, v_stick):
    """Chatter ends: at most log(v/|w|max)/log r + 5 impacts, then a stick phase; v_stick = 0 too."""
    p = RattleParams(lam=lam, r=r, j=J, v_stick=v_stick)
    tr = simulate(p, periods=20)
    v_eff = max(v_stick, solver.V_FLOOR)
    w_max = np.max(np.abs(tr.impact_w))
    bound = 1 if r == 0.0 else math.log(v_eff / w_max) / math.log(r) + 5
    assert len(tr.impact_t) <= bound, (len(tr.impact_t), bound)
    assert tr.stick_intervals.shape == (1, 2)
    assert tr.stick_intervals[0, 1] == pytest.approx(tr.t_end)
    assert tr.impact_t[-1] <= tr.stick_intervals[0, 0] < tr.t_end
    # the last recorded impacts are the slow ones, just above the resolution
    assert v_eff <= np.min(np.abs(tr.impact_w))
    if r > 0:
        assert np.abs(tr.impact_w[-1]) < v_eff / r * 1.5


def test_zero_v_stick_chatters_down_to_the_velocity_floor():
    """With v_stick = 0 the chatter runs down to V_FLOOR (1e-12) and still ends in finite time."""
    p = RattleParams(lam=0.8, r=R, j=J, v_stick=0.0)
    tr = simulate(p, periods=5)
    assert np.abs(tr.impact_w[-1]) < 1e-10
    assert len(tr.stick_intervals) == 1


@pytest.mark.parametrize("lam, x0", [(1.0, None), (1.0, 1.0), (1.0, 9.0), (1.0 - 1e-15, 9.0),
                                     (1.0 + 1e-7, 1.0), (1.0 + 1e-7, 9.0),
                                     (float(np.arange(0.5, 4.0, 0.02)[25]), None)])
def test_reaction_touching_zero_does_not_stall(lam, x0):
    """Λ ≈ 1 (R̃ = 1 − Λ cos t touches 0 at t = 0), started at t = 0: 400 periods, no SolverError."""
    p = RattleParams(lam=lam, r=R, j=J)
    tr = simulate(p, periods=400, x0=x0)
    if x0 is None or x0 == 1.0:
        # resting on the active flank, the reaction is ≥ 0 (up to ~1e-7): permanent contact
        assert tr.stick_time > 0.95 * 400 * TWO_PI


def test_slow_impact_with_wrong_reaction_leaves_at_once():
    """Λ = 3.3 at rest on the active flank at t = 0 (R̃ = 1 − 3.3 < 0): no stick phase at all."""
    p = RattleParams(lam=3.3, r=R, j=J)
    tr = simulate(p, periods=3, x0=1.0, v0=0.0)
    assert len(tr.stick_intervals) == 0
    assert tr.seg_kind[0] == 0


def test_reverse_flank_stick_and_release():
    """At rest on the reverse flank at t = −0.2 (Λ = 3.3) it sticks until R̃ = 1 − Λ cos t hits 0."""
    # on the reverse flank the contact holds while R̃ < 0, i.e. cos t > 1/Λ
    p = RattleParams(lam=3.3, r=R, j=J)
    tr = simulate(p, periods=1, t0=-0.2, x0=math.cos(-0.2) + J, v0=-math.sin(-0.2))
    assert tr.stick_intervals.shape[0] >= 1
    assert tr.stick_flank[0] == -1
    start, end = tr.stick_intervals[0]
    assert start == pytest.approx(-0.2, abs=1e-12)
    # release where R̃ = 1 + Λ ÿ = 1 − 3.3 cos t reaches 0 from below: cos t = 1/3.3, t > 0
    assert end == pytest.approx(math.acos(1 / 3.3), abs=1e-9)


# ----- grazing built on purpose ---------------------------------------------------------------


def crafted_flight(p: RattleParams, tc: float, S: float, delta: float, flank: int):
    """A parabola whose gap to one wall has a local minimum ``delta`` at time ``tc``.

    The gear matches the wall's velocity at ``tc`` at a distance ``delta``; the flight is traced
    back by ``S`` to its start.  Returns ``(t0, x0, v0)``.
    """
    y = float(excitation(tc, p.h, p.phi))
    yd = float(excitation(tc, p.h, p.phi, 1))
    xc = y + delta if flank == 1 else y + p.j - delta
    x0 = xc - yd * S - S * S / (2 * p.lam)
    v0 = yd + S / p.lam
    return tc - S, x0, v0


def call_flight(p: RattleParams, t0: float, x0: float, v0: float, smax: float):
    mb = _bounds(p.h)
    inv = 1.0 / p.lam
    out = solver._flight(p.lam, p.j, p.h, np.cos(p.phi), np.sin(p.phi), inv + mb[2], mb[3], mb[4],
                         t0, x0, v0, smax, 0)
    return float(out[0]), int(out[1])


# (params, touch time, flank): ÿ(τc) < −1/Λ on the active wall, ÿ(τc) > −1/Λ on the reverse one
GRAZE_CASES = [
    (RattleParams(lam=3.3, r=R, j=J), 0.3, 1),
    (RattleParams(lam=3.3, r=R, j=J), np.pi - 0.3, -1),
    (RattleParams(lam=2.0, r=R, j=J, amplitudes=(1.0, 0.25), phases_deg=(0.0, 45.0)), 0.2, 1),
    (RattleParams(lam=2.0, r=R, j=J, amplitudes=(1.0, 0.25), phases_deg=(0.0, 45.0)), 2.8, -1),
]


def _check_graze_case(p, tc, flank):
    ydd = float(excitation(tc, p.h, p.phi, 2))
    if flank == 1:
        assert ydd < -1.0 / p.lam
    else:
        assert ydd > -1.0 / p.lam
    # the gap stays well clear of both walls before the touch
    t0, x0, v0 = crafted_flight(p, tc, 1.0, 0.0, flank)
    s = np.linspace(0.0, 0.98, 2000)
    xs = x0 + v0 * s - s * s / (2 * p.lam)
    ys = y_derivative(t0 + s, p.h, p.phi)
    assert np.min(xs - ys) > 1e-6 and np.min(ys + p.j - xs) > 1e-6


@pytest.mark.parametrize("p, tc, flank", GRAZE_CASES)
def test_grazing_touch_is_found(p, tc, flank):
    """A flight whose gap has a local minimum of exactly 0 at τc is stopped at τc (to 1e-6)."""
    _check_graze_case(p, tc, flank)
    t0, x0, v0 = crafted_flight(p, tc, 1.0, 0.0, flank)
    s, hit = call_flight(p, t0, x0, v0, 2.0)
    assert hit == flank
    assert s == pytest.approx(1.0, abs=1e-6)


@pytest.mark.parametrize("p, tc, flank", GRAZE_CASES)
def test_grazing_penetration_of_1e10_is_found(p, tc, flank):
    """A minimum gap of −1e-10 is found, at the first root just before τc."""
    t0, x0, v0 = crafted_flight(p, tc, 1.0, -1e-10, flank)
    s, hit = call_flight(p, t0, x0, v0, 2.0)
    g2 = abs(-1.0 / p.lam - float(excitation(tc, p.h, p.phi, 2)))
    half_width = math.sqrt(2e-10 / g2)
    assert hit == flank
    assert 1.0 - 1.5 * half_width <= s <= 1.0 - 0.5 * half_width


@pytest.mark.parametrize("p, tc, flank", GRAZE_CASES)
def test_grazing_miss_by_1e10_is_not_a_contact(p, tc, flank):
    """A minimum gap of +1e-10 is a miss: the flight goes on past τc."""
    t0, x0, v0 = crafted_flight(p, tc, 1.0, 1e-10, flank)
    s, hit = call_flight(p, t0, x0, v0, 2.0)
    assert hit == 0 or s > 1.0 + 0.05, (s, hit)


@pytest.mark.parametrize("p, tc, flank", GRAZE_CASES[:2])
def test_grazing_through_simulate(p, tc, flank):
    """Through simulate(): a touch (gap −1e-10) is an impact at τc, a miss (+1e-10) is none there."""
    t0, x0, v0 = crafted_flight(p, tc, 1.0, -1e-10, flank)
    tr = simulate(p, periods=1, t0=t0, x0=x0, v0=v0)
    assert tr.impact_t[0] == pytest.approx(tc, abs=1e-4)
    assert tr.impact_flank[0] == flank
    t0, x0, v0 = crafted_flight(p, tc, 1.0, 1e-10, flank)
    tr = simulate(p, periods=1, t0=t0, x0=x0, v0=v0)
    assert len(tr.impact_t) == 0 or tr.impact_t[0] > tc + 0.05
    assert not np.any(np.abs(tr.seg_t - tc) < 1e-3)


# ----- agreement with independent slow references -------------------------------------------

AGREE_CASES = {
    "E harmonic": dict(lam=3.3),
    "C harmonic": dict(lam=1.2),
    "E large lam": dict(lam=5.0),
    "P2 harmonic": dict(lam=1.3),
    "2nd harmonic 90": dict(lam=3.3, amplitudes=(1.0, 0.25), phases_deg=(0.0, 90.0)),
    "2nd harmonic 45": dict(lam=3.3, amplitudes=(1.0, 0.25), phases_deg=(0.0, 45.0)),
    "3 harmonics": dict(lam=2.0, amplitudes=(1.0, 0.2, 0.1), phases_deg=(0.0, 60.0, 120.0)),
    "B stick v=1e-3": dict(lam=1.1, v_stick=1e-3),
    "B stick 2 harm": dict(lam=1.38, v_stick=1e-3, amplitudes=(1.0, 0.1), phases_deg=(0.0, 120.0)),
    "A chatter": dict(lam=0.8, v_stick=1e-3),
}


def assert_same_events(tr, ref, atol=1e-8):
    n = len(ref.impact_t)
    assert len(tr.impact_t) == n, (len(tr.impact_t), n)
    np.testing.assert_array_equal(tr.impact_flank, ref.impact_flank)
    np.testing.assert_allclose(tr.impact_t, ref.impact_t, rtol=0, atol=atol)
    np.testing.assert_allclose(tr.impact_impulse, ref.impact_impulse, rtol=0, atol=atol)


@pytest.mark.parametrize("name", list(AGREE_CASES))
def test_agrees_with_naive_event_loop(name):
    """Same impacts as the plain-Python event loop over 30 periods: times and impulses to 1e-8."""
    p = RattleParams(r=R, j=J, **AGREE_CASES[name])
    periods = 30
    tr = simulate(p, periods=periods)
    ref = naive_simulate(p.lam, p.r, p.j, p.h, p.phi, p.v_stick, 0.0, tr.settings["x0"], 0.0,
                         periods * TWO_PI)
    assert len(ref.impact_t) >= 10
    assert_same_events(tr, ref)
    assert tr.stick_intervals.shape == ref.stick_intervals.shape
    np.testing.assert_allclose(tr.stick_intervals, ref.stick_intervals, rtol=0, atol=1e-8)
    t = np.linspace(0.0, periods * TWO_PI, 20001)
    x, v = tr.sample(t)
    xr, vr = naive_sample(ref, t, p.lam, p.j, p.h, p.phi)
    near = np.min(np.abs(t[:, None] - ref.impact_t[None, :]), axis=1) < 1e-7
    np.testing.assert_allclose(x[~near], xr[~near], atol=1e-8)
    np.testing.assert_allclose(v[~near], vr[~near], atol=1e-8)


@pytest.mark.parametrize("name", ["E harmonic", "C harmonic", "P2 harmonic", "2nd harmonic 45",
                                  "3 harmonics"])
def test_agrees_with_solve_ivp(name):
    """Same impacts as solve_ivp (DOP853, rtol = atol = 1e-12, terminal events) over 8 periods."""
    p = RattleParams(r=R, j=J, **AGREE_CASES[name])
    periods = 8
    tr = simulate(p, periods=periods)
    ref = ivp_simulate(p.lam, p.r, p.j, p.h, p.phi, p.v_stick, 0.0, tr.settings["x0"], 0.0,
                       periods * TWO_PI)
    assert len(ref.impact_t) >= 5
    assert_same_events(tr, ref)


CHAOS_CASES = {
    "D harmonic": dict(lam=1.16),
    "2nd harmonic 45, lam 1.95": dict(lam=1.95, amplitudes=(1.0, 0.25), phases_deg=(0.0, 45.0)),
    "3 harmonics, lam 4": dict(lam=4.0, amplitudes=(1.0, 0.3, 0.2), phases_deg=(0.0, 30.0, 200.0)),
}


@pytest.mark.parametrize("name", list(CHAOS_CASES))
def test_every_flight_agrees_with_naive_in_chaotic_runs(name):
    """Chaotic runs: from each impact, the naive loop finds the solver's next impact (to 1e-8)."""
    # whole-run agreement is impossible here (errors grow like exp(λ t)), so each flight is
    # checked on its own, from the solver's post-impact state
    p = RattleParams(r=R, j=J, **CHAOS_CASES[name])
    # the strict model: the chaotic set of "lam 1.95" is a transient once noise is on
    tr = simulate(p.replace(noise=0.0), periods=40, transient=100, lyapunov=True)
    assert tr.lyapunov > 0.0 or len(tr.stick_intervals) > 0
    checked = 0
    for i in range(len(tr.impact_t) - 1):
        t_i, t_next = tr.impact_t[i], tr.impact_t[i + 1]
        between = (tr.seg_t > t_i + 1e-9) & (tr.seg_t < t_next - 1e-9)
        if np.any(between):
            continue  # a plastic contact or stick phase in between
        if min(abs(tr.impact_w[i]), abs(tr.impact_w[i + 1])) < 1e-3:
            continue  # chatter: the naive gap x − y is only good to ~1e-13 at these times
        x, v = tr.sample(np.array([t_i]))
        ref = naive_simulate(p.lam, p.r, p.j, p.h, p.phi, p.v_stick, t_i, float(x[0]), float(v[0]),
                             t_next + 0.5)
        assert ref.impact_t[0] == pytest.approx(t_next, abs=1e-8), (i, t_i)
        assert ref.impact_flank[0] == tr.impact_flank[i + 1]
        assert ref.impact_impulse[0] == pytest.approx(tr.impact_impulse[i + 1], abs=1e-8)
        checked += 1
    assert checked >= 30


# ----- Trajectory: exact sampling and stroboscopic samples -----------------------------------


@pytest.mark.parametrize("kw", [dict(lam=3.3), dict(lam=1.1),
                                dict(lam=2.0, amplitudes=(1.0, 0.25), phases_deg=(0.0, 90.0))])
def test_sample_is_the_parabola_between_impacts_and_the_wall_while_stuck(kw):
    """sample() equals x_i + v⁺ s − s²/(2Λ) after each impact, and y (+ j), ẏ while stuck."""
    p = RattleParams(r=R, j=J, **kw)
    tr = simulate(p, periods=20, transient=3)
    seg_starts = tr.seg_t
    for i, ti in enumerate(tr.impact_t):
        t_next = tr.impact_t[i + 1] if i + 1 < len(tr.impact_t) else tr.t_end
        later = seg_starts[seg_starts > ti + 1e-12]
        t_stop = min(t_next, later[0] if len(later) else tr.t_end)
        # up to, not including, the next event: sample() gives the post-event state there
        s = np.linspace(0.0, t_stop - ti, 50, endpoint=False)
        wall = float(y_of(p, ti)) + (p.j if tr.impact_flank[i] == -1 else 0.0)
        vplus = float(y_of(p, ti, 1)) - p.r * tr.impact_w[i]
        x, v = tr.sample(ti + s)
        np.testing.assert_allclose(x, wall + vplus * s - s * s / (2 * p.lam), atol=1e-11)
        np.testing.assert_allclose(v, vplus - s / p.lam, atol=1e-11)
        # the position is continuous through the next event
        s_end = t_stop - ti
        x_end, _ = tr.sample(np.array([t_stop]))
        assert x_end[0] == pytest.approx(wall + vplus * s_end - s_end**2 / (2 * p.lam), abs=1e-10)
    for (a, b), fl in zip(tr.stick_intervals, tr.stick_flank):
        t = np.linspace(a, b, 200)
        x, v = tr.sample(t)
        np.testing.assert_allclose(x, y_of(p, t) + (p.j if fl == -1 else 0.0), atol=1e-12)
        np.testing.assert_allclose(v, y_of(p, t, 1), atol=1e-12)


@pytest.mark.parametrize("theta", [0.0, 1.0, 4.5])
def test_strobe_samples_equal_sample_at_strobe_times(theta):
    """Stroboscopic samples (x, ẋ) at t = 2πn + θ equal sample() there, one per period."""
    for kw in (dict(lam=3.3), dict(lam=1.1), dict(lam=0.8)):
        p = RattleParams(r=R, j=J, **kw)
        tr = simulate(p, periods=25, transient=2, strobe_phase=theta)
        assert len(tr.strobe_t) == 25
        phase_err = np.angle(np.exp(1j * (tr.strobe_t - theta)))
        np.testing.assert_allclose(phase_err, 0.0, atol=1e-9)
        np.testing.assert_allclose(np.diff(tr.strobe_t), TWO_PI, atol=1e-9)
        x, v = tr.sample(tr.strobe_t)
        np.testing.assert_allclose(tr.strobe_x, x, atol=1e-11)
        np.testing.assert_allclose(tr.strobe_v, v, atol=1e-11)


def test_transient_window_is_the_tail_of_a_longer_run():
    """Recording after a transient gives exactly the tail of one long recorded run."""
    p = RattleParams(lam=2.5, r=R, j=J, amplitudes=(1.0, 0.25), phases_deg=(0.0, 45.0))
    full = simulate(p, periods=30)
    tail = simulate(p, periods=10, transient=20)
    keep = full.impact_t >= tail.t_start
    np.testing.assert_array_equal(full.impact_t[keep], tail.impact_t)
    np.testing.assert_array_equal(full.impact_impulse[keep], tail.impact_impulse)
    np.testing.assert_array_equal(full.strobe_x[20:], tail.strobe_x)


def test_late_start_time_gives_the_same_orbit():
    """Starting at t0 = 2π·10⁵ instead of 0 shifts the impacts by exactly that much (to 1e-8)."""
    p = RattleParams(lam=3.3, r=R, j=J)
    a = simulate(p, periods=20)
    n = 100_000
    b = simulate(p, periods=20, t0=n * TWO_PI)
    np.testing.assert_allclose(np.mod(b.impact_phase, TWO_PI), a.impact_phase, atol=1e-8)
    np.testing.assert_allclose(b.impact_impulse, a.impact_impulse, atol=1e-8)
    np.testing.assert_allclose(b.impact_t - n * TWO_PI, a.impact_t, atol=1e-6)


# ----- limits: runaway, never hang -------------------------------------------------------------


def test_runaway_chatter_raises():
    """max_impacts_per_period = 5 in a chattering case raises SolverError saying so (how fast:
    benchmarks/bench_core.py)."""
    p = RattleParams(lam=0.8, r=R, j=J)
    with pytest.raises(SolverError) as err:
        simulate(p, periods=50, max_impacts_per_period=5)
    msg = str(err.value)
    assert "runaway" in msg and "max_impacts_per_period" in msg and "5" in msg


def test_default_limit_allows_long_chatter():
    """The default runaway limit does not fire on a legitimate long chatter (r = 0.95)."""
    p = RattleParams(lam=0.5, r=0.95, j=J, v_stick=0.0)
    tr = simulate(p, periods=20)
    assert len(tr.impact_t) > 200


# ----- Lyapunov exponent ------------------------------------------------------------------------


def test_lyapunov_negative_for_stable_periodic_orbit():
    """Regime E (Λ = 3.3, harmonic) is a stable periodic orbit: Lyapunov exponent < 0."""
    tr = simulate(RattleParams(lam=3.3, r=R, j=J), periods=200, transient=100, lyapunov=True)
    assert -1.0 < tr.lyapunov < -1e-3


def test_lyapunov_minus_infinity_when_sticking():
    """A window spent in permanent contact has Lyapunov exponent −∞; without the option, NaN."""
    p = RattleParams(lam=0.8, r=R, j=J)
    assert simulate(p, periods=10, transient=5, lyapunov=True).lyapunov == -np.inf
    assert simulate(p, periods=10, x0=1.0, lyapunov=True).lyapunov == -np.inf
    assert math.isnan(simulate(p, periods=10, transient=5).lyapunov)


def test_lyapunov_positive_for_chaos():
    """Harmonic Λ = 1.16 (regime D) has a positive exponent, stable across window lengths."""
    p = RattleParams(lam=1.16, r=R, j=J)
    a = simulate(p, periods=400, transient=300, lyapunov=True).lyapunov
    b = simulate(p, periods=800, transient=300, lyapunov=True).lyapunov
    assert a > 0.01 and b > 0.01
    assert abs(a - b) < 0.5 * max(a, b)
