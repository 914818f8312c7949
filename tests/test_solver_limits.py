"""The solver over the whole accepted parameter range: invariants hold, time never runs back,
and a run that cannot make progress stops with :class:`SolverError` instead of hanging.

The draws cover every value :class:`RattleParams` accepts (Λ from 1e-6 to 1e4, backlash up to
1e4, harmonic amplitudes up to 100, ``v_stick = 0``), not only the dashboard's slider ranges.
"""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, note, settings
from hypothesis import strategies as st

from naive import y_derivative
from rattle_core import RattleParams, SolverError, simulate

SETTINGS = settings(max_examples=200, deadline=None, derandomize=True,
                    suppress_health_check=[HealthCheck.too_slow])


def log_uniform(lo: float, hi: float):
    return st.floats(np.log10(lo), np.log10(hi)).map(lambda e: float(10.0 ** e))


@st.composite
def wide_cases(draw):
    """Any accepted RattleParams (up to 5 harmonics) with a start state inside the backlash."""
    lam = draw(log_uniform(1.001e-6, 1e4))
    r = draw(st.floats(0.0, 1.0))
    j = draw(log_uniform(1e-3, 1e4))
    extra = draw(st.integers(0, 4))
    amps = [1.0] + [draw(st.one_of(st.just(0.0), log_uniform(1e-3, 100.0))) for _ in range(extra)]
    phases = [draw(st.floats(-360.0, 360.0)) for _ in range(extra + 1)]
    v_stick = draw(st.sampled_from([0.0, 1e-9, 1e-6, 1e-3, 1.0]))
    p = RattleParams(lam=lam, r=r, j=j, amplitudes=tuple(amps), phases_deg=tuple(phases),
                     v_stick=v_stick)
    y0 = float(y_derivative(0.0, p.h, p.phi))
    x0 = y0 + draw(st.floats(0.0, 1.0)) * j
    v0 = draw(st.floats(-100.0, 100.0))
    return p, min(max(x0, y0), y0 + j), v0, draw(st.integers(1, 6))


@SETTINGS
@given(wide_cases())
def test_invariants_hold_over_the_whole_accepted_range(case):
    """Ordered times, the gear inside the backlash, incoming velocity into the wall, impulse
    sign = flank and |Ĩ| = (1 + r)|w| -- or a SolverError that names the limit it hit."""
    p, x0, v0, periods = case
    note(f"{p!r}, x0={x0!r}, v0={v0!r}, periods={periods}")
    try:
        tr = simulate(p, periods=periods, x0=x0, v0=v0, max_impacts_per_period=20_000)
    except SolverError as err:
        assert "runaway" in str(err) or "iteration budget" in str(err)
        assume(False)
        return
    assert np.all(np.diff(tr.impact_t) >= 0.0)
    assert np.all(np.diff(tr.seg_t) >= 0.0)
    fl = tr.impact_flank
    assert np.all(tr.impact_w[fl == 1] < 0.0) and np.all(tr.impact_w[fl == -1] > 0.0)
    np.testing.assert_array_equal(np.sign(tr.impact_impulse), fl)
    # Ĩ = ẋ⁺ − ẋ⁻ is a difference of velocities: its rounding scales with the largest of them
    scale = 1.0 + float(np.max(np.abs(tr.impact_impulse), initial=0.0)) + abs(v0)
    np.testing.assert_allclose(np.abs(tr.impact_impulse), (1 + p.r) * np.abs(tr.impact_w),
                               rtol=1e-12, atol=1e-14 * scale)
    t = np.linspace(tr.t_start, tr.t_end, 4001)
    x, _ = tr.sample(t)
    y = y_derivative(t, p.h, p.phi)
    # positions are O(j + Σ h_k): allow their rounding, as the 1e-9 of docs/model.md does for O(1)
    tol = 1e-9 * (1.0 + p.j + float(np.sum(p.h)))
    assert np.min(x - y) >= -tol and np.max(x - y - p.j) <= tol


def test_large_second_harmonic_finishes():
    """H₂/H₁ = 100 at Λ = 3.3 used to run time backwards and never finish: now 2 periods run."""
    tr = simulate(RattleParams(lam=3.3, amplitudes=(1.0, 100.0), phases_deg=(0.0, 0.0)), periods=2)
    assert len(tr.impact_t) > 0 and np.all(np.diff(tr.impact_t) >= 0.0)


def test_fuzzed_case_keeps_every_invariant():
    """A fuzzed case (four harmonics, v_stick = 0) that once gave 16 backward steps, impulses
    of the wrong sign and a gear outside the backlash."""
    p = RattleParams(lam=32.8143078439077, r=0.17929698285764528, j=56.70090036685719,
                     amplitudes=(1.0, 0.5636925507940339, 0.051545615611086504, 3.3810690471595395),
                     phases_deg=(-134.86103908541835, -80.8101783746177, 42.845442338677316,
                                 121.4119962065131), v_stick=0.0)
    tr = simulate(p, periods=109, x0=3.396787168177733, v0=5.528332746952538)
    assert len(tr.impact_t) > 100
    assert np.all(np.diff(tr.impact_t) >= 0.0)
    np.testing.assert_array_equal(np.sign(tr.impact_impulse), tr.impact_flank)
    assert np.all(tr.impact_w * tr.impact_flank < 0.0)
    t = np.linspace(tr.t_start, tr.t_end, 50001)
    x, _ = tr.sample(t)
    y = y_derivative(t, p.h, p.phi)
    assert np.min(x - y) >= -1e-9 and np.max(x - y - p.j) <= 1e-9


@pytest.mark.parametrize("periods", [1, 3])
def test_runaway_stops_with_a_message(periods):
    """Elastic impacts (r = 1) of a gear pressed on a wall by Λ = 2e-6: more impacts per period
    than the limit raise SolverError naming the limit, promptly."""
    p = RattleParams(lam=2e-6, r=1.0, j=1.0, v_stick=0.0)
    with pytest.raises(SolverError, match="max_impacts_per_period"):
        simulate(p, periods=periods, x0=1.5, max_impacts_per_period=1000)


#: the audit's link: a small backlash between fast walls, where a time error shows most
FAST_WALLS = RattleParams(lam=1.0, j=0.01, amplitudes=(1.0, 100.0), phases_deg=(0.0, 0.0))


@pytest.mark.parametrize("t0", [2e7, -2e7, 1e9])
def test_start_times_beyond_double_resolution_are_refused(t0):
    """A start time whose doubles no longer resolve the motion is refused, naming t0 and its range.

    At |t0| = 2e7 the spacing of doubles is 3.7e-9, and the sampled gear of ``FAST_WALLS``
    sat 5e-7 outside the backlash (2e-5 at 1e9) before such starts were refused.
    """
    with pytest.raises(ValueError, match=r"t0 = .* outside the allowed range \[-1e\+06, 1e\+06\]"):
        simulate(FAST_WALLS, periods=5, t0=t0)


@pytest.mark.parametrize("t0", [-1e6, 1e6, 123456.789])
def test_allowed_start_times_keep_the_gear_between_its_teeth(t0):
    """Within the allowed start times, the sampled gear stays in the backlash to the time's resolution.

    The bound is the doubles' spacing at the run's end times the largest relative speed, the
    error a one-ulp time shift can make; the motion itself never crosses a tooth.
    """
    tr = simulate(FAST_WALLS, periods=20, t0=t0)
    t = np.linspace(tr.t_start, tr.t_end, 100_001)
    x, v = tr.sample(t)
    y, y_top = tr.walls(t)
    yd = y_derivative(t, FAST_WALLS.h, FAST_WALLS.phi, 1)
    bound = 4 * np.spacing(abs(tr.t_end)) * float(np.max(np.abs(v - yd)))
    assert float(np.max(y - x)) <= bound and float(np.max(x - y_top)) <= bound
