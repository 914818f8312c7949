"""Invariants of the exact solver under hypothesis-generated parameters and initial states.

Whatever the parameters: the gear never leaves the backlash, every impact sends it away from
the wall it hit, and each impulse obeys the restitution law ``|Ĩ| = (1 + r)|w|``.
"""
from __future__ import annotations

import numpy as np
from hypothesis import HealthCheck, assume, given, note, settings
from hypothesis import strategies as st

from naive import y_derivative
from rattle_core import RattleParams, simulate

TWO_PI = 2.0 * np.pi
PERIODS = 12
SETTINGS = settings(max_examples=150, deadline=None, derandomize=True,
                    suppress_health_check=[HealthCheck.too_slow])


@st.composite
def cases(draw):
    """RattleParams (Λ ∈ [0.3, 6], r ∈ [0, 1], j ∈ [0.5, 12], up to 3 harmonics) and (x0, v0)."""
    lam = draw(st.floats(0.3, 6.0))
    r = draw(st.floats(0.0, 1.0))
    j = draw(st.floats(0.5, 12.0))
    extra = draw(st.integers(0, 2))
    amps = [1.0] + [draw(st.floats(0.0, 0.5)) for _ in range(extra)]
    phases = [draw(st.floats(-180.0, 180.0)) for _ in range(extra + 1)]
    v_stick = draw(st.sampled_from([0.0, 1e-9, 1e-6, 1e-3]))
    p = RattleParams(lam=lam, r=r, j=j, amplitudes=tuple(amps), phases_deg=tuple(phases),
                     v_stick=v_stick)
    frac = draw(st.floats(0.0, 1.0))
    v0 = draw(st.floats(-5.0, 5.0))
    y0 = float(y_derivative(0.0, p.h, p.phi))
    x0 = min(max(y0 + frac * j, y0), y0 + j)
    return p, x0, v0


def run(case):
    p, x0, v0 = case
    note(f"params={p!r}, x0={x0!r}, v0={v0!r}")
    return p, simulate(p, periods=PERIODS, x0=x0, v0=v0)


def dense_times(tr):
    """A fine uniform grid plus every segment's start, midpoint and apex of its parabola."""
    t = [np.linspace(tr.t_start, tr.t_end, 30001)]
    ends = np.append(tr.seg_t[1:], tr.t_end)
    t.append(tr.seg_t)
    t.append(0.5 * (tr.seg_t + ends))
    # the apex of a flight parabola (ẋ = 0) is where the gear comes closest to the reverse wall
    lam = tr.params.lam
    apex = tr.seg_t + lam * tr.seg_v
    ok = (tr.seg_kind == 0) & (apex > tr.seg_t) & (apex < ends)
    t.append(apex[ok])
    out = np.concatenate(t)
    return np.clip(out, tr.t_start, tr.t_end)


@SETTINGS
@given(cases())
def test_gear_stays_inside_the_backlash(case):
    """At densely sampled times, y − 1e-9 ≤ x ≤ y + j + 1e-9."""
    p, tr = run(case)
    t = dense_times(tr)
    x, _ = tr.sample(t)
    y = y_derivative(t, p.h, p.phi)
    below = np.min(x - y)
    above = np.max(x - y - p.j)
    assert below >= -1e-9, (below, t[np.argmin(x - y)])
    assert above <= 1e-9, (above, t[np.argmax(x - y - p.j)])


@SETTINGS
@given(cases())
def test_every_impact_sends_the_gear_away_from_the_wall(case):
    """Impacts happen on the wall, moving into it; afterwards the relative velocity points away."""
    p, tr = run(case)
    assume(len(tr.impact_t) > 0)  # a draw without impacts checks nothing here
    t = tr.impact_t
    fl = tr.impact_flank
    y = y_derivative(t, p.h, p.phi)
    yd = y_derivative(t, p.h, p.phi, 1)
    x_after, v_after = tr.sample(t)  # sample() at an impact time gives the post-impact state
    wall = y + np.where(fl == -1, p.j, 0.0)
    np.testing.assert_allclose(x_after, wall, atol=1e-9)
    w_after = v_after - yd
    active = fl == 1
    assert np.all(w_after[active] >= -1e-12), np.min(w_after[active], initial=0.0)
    assert np.all(w_after[~active] <= 1e-12), np.max(w_after[~active], initial=0.0)
    # incoming: into the wall (active w < 0, reverse w > 0)
    assert np.all(tr.impact_w[active] < 0.0)
    assert np.all(tr.impact_w[~active] > 0.0)
    # and the restitution law itself: ẋ⁺ − ẏ = −r w
    np.testing.assert_allclose(w_after, -p.r * tr.impact_w, atol=1e-12, rtol=1e-12)


@SETTINGS
@given(cases())
def test_impulse_obeys_the_restitution_law(case):
    """|Ĩ| = (1 + r)|w| to 1e-12 relative, and the impulse sign is the flank (+ active, − reverse)."""
    p, tr = run(case)
    assume(len(tr.impact_t) > 0)  # a draw without impacts checks nothing here
    np.testing.assert_allclose(np.abs(tr.impact_impulse), (1 + p.r) * np.abs(tr.impact_w),
                               rtol=1e-12, atol=1e-15)
    np.testing.assert_array_equal(np.sign(tr.impact_impulse), tr.impact_flank)
    assert set(np.unique(tr.impact_flank)) <= {-1, 1}
    # impulses are recorded only above the chatter threshold
    assert np.all(np.abs(tr.impact_w) >= max(p.v_stick, 1e-12))


@SETTINGS
@given(cases())
def test_event_log_is_ordered_and_consistent(case):
    """Impacts, segments and stick phases are in time order inside the window; strobes one per period."""
    p, tr = run(case)
    assert np.all(np.diff(tr.impact_t) >= 0.0)
    # non-decreasing only: a flight after an impact at |w| ~ 1e-12 with small r can last less
    # than one ulp of t
    assert np.all(np.diff(tr.seg_t) >= 0.0)
    assert np.all((tr.impact_t >= tr.t_start) & (tr.impact_t <= tr.t_end))
    si = tr.stick_intervals
    if len(si):
        assert np.all(si[:, 1] >= si[:, 0])
        assert np.all(si[1:, 0] >= si[:-1, 1])
        # no impact strictly inside a stick phase
        for a, b in si:
            assert not np.any((tr.impact_t > a + 1e-12) & (tr.impact_t < b - 1e-12))
    assert len(tr.strobe_t) == PERIODS
    x, v = tr.sample(tr.strobe_t)
    np.testing.assert_allclose(tr.strobe_x, x, atol=1e-10)
    np.testing.assert_allclose(tr.strobe_v, v, atol=1e-10)
