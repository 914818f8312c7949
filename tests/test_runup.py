"""Run-up replay: the measured wall against the harmonic core, the closed-form contact boundary,
containment over random measured-like walls, a slow independent reference, and refusals."""
from __future__ import annotations

import math
import time

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from naive import NaiveRunup, naive_runup
from rattle_core import classify, simulate
from rattle_core.model.gearbox import Excitation, Gear, Gearbox
from rattle_core.measure.orders import SAMPLE_RUNUP, OrderMap
from rattle_core.solver.runup import RUNUP_PERIOD_BUDGET, replay, runup_wall
from gearboxes import SAMPLE_TWO_GEARS_DEFAULT_SOUND

STEADY = """
[excitation]
orders = [{order = 2, amplitude_rad = 0.002, phase_deg = 0}, {order = 4, amplitude_rad = 0.0005, phase_deg = 30}, {order = 6, amplitude_rad = 0.0002, phase_deg = -70}]
engine_order = 2
harmonics = 3

[[gear]]
name = "idler"
inertia_kgm2 = 4e-4
base_radius_m = 0.035
drag_torque_Nm = 0.05
backlash_um = 80
restitution = 0.65
"""

GEARS = (Gear("5th idler", 4e-4, 0.035, 0.05, 80.0, 0.65),
         Gear("reverse idler", 2.5e-4, 0.03, 0.03, 120.0, 0.65, speed_ratio=0.8))


@pytest.fixture(scope="module")
def sample_map():
    return OrderMap.from_csv(SAMPLE_RUNUP, orders=(2, 4, 6), rpm_step=100)


@pytest.fixture(scope="module")
def sample_box(sample_map):
    return Gearbox(Excitation(2.0, 3, sample_map), GEARS)


def _steady_pair(rpm, r, transient=200, periods=100):
    box = Gearbox.from_text(STEADY)
    box = box.replace(gears=(box.gears[0].replace(restitution=r),))
    params = box.physical(0, rpm).to_dimensionless().replace(noise=0.0)
    omega = 2 * 2 * math.pi * rpm / 60
    rr = replay(box, 0, rpm, rpm, (transient + periods) * 2 * math.pi / omega, start="middle")
    w = rr.runup.wall
    assert np.allclose(w.length, 2 * math.pi, rtol=1e-12) and w.t0.size == transient + periods
    assert rr.runup.j == pytest.approx(params.j, rel=1e-15)
    assert 1 / w.decel[0, 0] == pytest.approx(params.lam, rel=1e-15)
    tr = simulate(params, periods=periods, transient=transient, v0=float(w.values(0.0, 1)[0]))
    keep = rr.run.impact_t >= transient * 2 * math.pi
    assert tr.impact_t.size > 20 and keep.sum() == tr.impact_t.size
    np.testing.assert_array_equal(rr.run.impact_flank[keep], tr.impact_flank)
    np.testing.assert_allclose(rr.run.impact_t[keep], tr.impact_t, rtol=1e-9, atol=0)
    return box, rr, tr, keep


@pytest.mark.parametrize("rpm, r", [(1200.0, 0.8), (3500.0, 0.65), (4000.0, 0.8)])
def test_steady_replay_equals_the_harmonic_core(rpm, r):
    """Two code paths: a steady measurement replayed gives simulate()'s impacts on the
    equivalent harmonic model to 1e-9 relative, in times and impulses, after the same transient
    (periodic regimes; the physical impulse is the dimensionless one times m ω H₁)."""
    box, rr, tr, keep = _steady_pair(rpm, r)
    assert classify(tr).label.startswith("P")
    np.testing.assert_allclose(rr.run.impact_impulse[keep], tr.impact_impulse, rtol=1e-9, atol=0)
    phys = box.physical(0, rpm)
    scale = phys.mass * phys.omega * float(phys.H[0])
    np.testing.assert_allclose(rr.impact_impulse[keep], tr.impact_impulse * scale, rtol=1e-9)


def test_steady_replay_with_chatter_and_sticking_equals_the_core():
    """Two code paths through chatter and sticking: the same impacts, flanks and times to 1e-9
    relative; impulses to 1e-8 of the largest (a chatter rebound of 1e-6 is a difference of
    velocities, whose rounding no relative tolerance of its own size can absorb)."""
    box, rr, tr, keep = _steady_pair(1200.0, 0.65)
    assert "sticking" in classify(tr).label
    scale = np.abs(tr.impact_impulse).max()
    np.testing.assert_allclose(rr.run.impact_impulse[keep], tr.impact_impulse, rtol=0,
                               atol=1e-8 * scale)


def test_slow_runup_onset_is_the_contact_boundary(sample_box):
    """A slow run-up, 1000 → 3000 rpm in 300 s: each gear's first impact lies within one 50-rpm
    step of the closed-form contact boundary (Gearbox.contact_ratio = 1)."""
    fine = np.arange(1000.0, 3000.0, 1.0)
    for gi in range(len(sample_box.gears)):
        ratio = sample_box.contact_ratio(gi, fine)
        assert ratio[0] < 1 < ratio[-1]
        boundary = fine[np.argmax(ratio > 1)]
        rr = replay(sample_box, gi, 1000.0, 3000.0, 300.0)
        assert rr.impact_t.size > 1000
        assert abs(rr.onset_rpm - boundary) <= 50.0, (gi, rr.onset_rpm, boundary)
        # below the boundary the gear rides the tooth: not one impact
        assert np.all(rr.impact_rpm >= boundary - 50.0)


def test_fast_runup_onset_is_later_by_the_mean_acceleration(sample_box):
    """A fast run-up delays the onset: the mean acceleration adds J R_d ratio dΩ/dt / R_b to the
    drag, so the gear leaves the tooth where contact_ratio = 1 + that share (within 50 rpm)."""
    g = sample_box.gears[0]
    fine = np.arange(1000.0, 3000.0, 1.0)
    dOmega = 2 * math.pi / 60 * 2000.0 / 30.0
    share = g.inertia_kgm2 * g.drive_radius_m * g.speed_ratio * dOmega / (g.base_radius_m *
                                                                          g.drag_torque_Nm)
    ratio = sample_box.contact_ratio(0, fine)
    boundary = fine[np.argmax(ratio > 1 + share)]
    rr = replay(sample_box, 0, 1000.0, 3000.0, 30.0)
    assert abs(rr.onset_rpm - boundary) <= 50.0
    assert rr.onset_rpm > fine[np.argmax(ratio > 1)] + 20.0


def _random_map(draw_amp, draw_phase, rpm):
    """An order table with smooth random amplitudes and phases over ``rpm`` (orders 2, 4, 6)."""
    orders = np.array([2.0, 4.0, 6.0])
    amp = draw_amp[None, :] * (1.0 + 0.5 * np.sin(rpm[:, None] / 300.0 + draw_phase[None, :]))
    ph = np.rad2deg(draw_phase[None, :] + 0.8 * np.cos(rpm[:, None] / 170.0))
    omega = 2 * np.pi * rpm / 60.0
    table = {"rpm": np.repeat(rpm, 3), "order": np.tile(orders, rpm.size),
             "amplitude_rad": amp.ravel(),
             "accel_rad_s2": (amp * (orders[None, :] * omega[:, None]) ** 2).ravel(),
             "phase_deg": ph.ravel()}
    return OrderMap.from_table(table)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(a1=st.floats(5e-4, 4e-3), a2=st.floats(0.0, 0.5), a3=st.floats(0.0, 0.3),
       p=st.lists(st.floats(-3.0, 3.0), min_size=3, max_size=3),
       drag=st.floats(0.005, 0.2), backlash=st.floats(20.0, 300.0), r=st.floats(0.0, 0.95),
       rpm_a=st.floats(1100.0, 2800.0), span=st.floats(-800.0, 800.0),
       dur=st.floats(0.05, 1.0))
def test_containment_over_random_measured_walls(a1, a2, a3, p, drag, backlash, r, rpm_a, span,
                                                dur):
    """Containment: over random measured-like walls (smooth random orders, run-ups and
    run-downs), the gear never leaves the backlash by more than 1e-9 of it, at any sampled
    time, and every impact leaves the wall (or sticks)."""
    rpm = np.arange(1000.0, 3001.0, 100.0)
    omap = _random_map(np.array([a1, a1 * a2, a1 * a3]), np.array(p), rpm)
    box = Gearbox(Excitation(2.0, 3, omap), (Gear("g", 3e-4, 0.03, drag, backlash, r),))
    rpm_b = min(max(rpm_a + span, 1000.0), 3000.0)
    rr = replay(box, 0, rpm_a, rpm_b, dur, start="middle", segments=True)
    run, w = rr.run, rr.runup.wall
    t = np.sort(np.concatenate([np.linspace(w.t0[0], w.t_end, 20_001)[:-1],
                                run.impact_t, run.seg_t]))
    x, _ = run.sample(t)
    y = w.values(t)
    tol = 1e-9 * run.j
    assert np.all(x >= y - tol)
    assert np.all(x <= y + run.j + tol)
    # after each impact the relative velocity points away from the wall
    out = -r * run.impact_w
    assert np.all(out * run.impact_flank >= 0.0)


def test_replay_agrees_with_a_slow_naive_reference(sample_map, sample_box):
    """An independent reference: a slow naive replay (physical time, scipy's spline evaluated
    term by term, fine time steps plus bisection) gives the same impacts over a short segment
    of a run-up, in time, flank and impulse."""
    gi = 1
    g = sample_box.gears[gi]
    rpm_from, rpm_to, duration = 2500.0, 2900.0, 2.0
    t_end = 0.13  # the motion is chaotic: differences of 1e-18 grow ~10x per 2 impacts
    rr = replay(sample_box, gi, rpm_from, rpm_to, duration, start="middle")
    cols = [list(sample_map.orders).index(o) for o in (2.0, 4.0, 6.0)]
    mass = g.inertia_kgm2 / g.base_radius_m ** 2
    scale = g.drive_radius_m * g.speed_ratio
    c = (rpm_to - rpm_from) / duration
    q = g.drag_torque_Nm / g.base_radius_m / mass + scale * 2 * math.pi / 60 * c
    model = NaiveRunup(sample_map.rpm, sample_map.amplitude_rad[:, cols],
                       np.unwrap(np.deg2rad(sample_map.phase_deg[:, cols]), axis=0), 2.0,
                       rpm_from, rpm_to, duration, scale, q)
    b = g.backlash_um * 1e-6
    x0 = float(model.y(0.0)[0]) + 0.5 * b
    v0 = float(model.y(0.0, 1)[0])
    period = 60.0 / (2.0 * rpm_from)
    t_ref, dv_ref, fl_ref = naive_runup(model, b, g.restitution, x0, v0, t_end, period / 2000)
    keep = rr.impact_t < t_end
    assert t_ref.size > 20
    assert keep.sum() == t_ref.size
    np.testing.assert_array_equal(rr.impact_flank[keep], fl_ref)
    # the two agree to rounding at first; the chaos then amplifies that rounding about tenfold
    # every two impacts, so the first 21 impacts are held to 1e-9 and the rest to 1e-6
    np.testing.assert_allclose(rr.impact_t[keep][:21], t_ref[:21], rtol=1e-9)
    np.testing.assert_allclose(rr.impact_t[keep], t_ref, rtol=1e-6)
    np.testing.assert_allclose(rr.impact_impulse[keep], dv_ref * mass, rtol=1e-6)


def test_refusals_name_the_range_and_the_budget(sample_box):
    """Bad input: a speed outside the measurement's range is refused with the range; a replay
    over the period budget is refused before it starts."""
    lo, hi = sample_box.excitation.rpm_range
    with pytest.raises(ValueError, match=rf"rpm_to = 4000\.0 is outside the measurement's speed "
                                         rf"range \[{lo:g}, {hi:g}\] rpm"):
        replay(sample_box, 0, 1000.0, 4000.0, 10.0)
    with pytest.raises(ValueError, match=r"rpm_from = 500\.0 is outside"):
        runup_wall(sample_box, 0, 500.0, 2000.0, 10.0)
    t0 = time.process_time()
    with pytest.raises(ValueError, match=rf"period budget allows up to {RUNUP_PERIOD_BUDGET}"):
        replay(sample_box, 0, 1000.0, 3000.0, 3500.0)
    assert time.process_time() - t0 < 0.5
    with pytest.raises(ValueError, match="gear = 'third' is not in the gearbox"):
        replay(sample_box, "third", 1000.0, 2000.0, 1.0)
    with pytest.raises(ValueError, match=r"duration_s"):
        replay(sample_box, 0, 1000.0, 2000.0, 0.0)


CLI_TOML = SAMPLE_TWO_GEARS_DEFAULT_SOUND


def test_cli_runup_writes_every_impact_and_the_sound(tmp_path, capsys):
    """`rattle runup` writes one CSV row per impact of every gear, equal to replay()'s, and a
    48 kHz WAV as long as the run; a speed outside the measurement exits 2 with the range."""
    import pandas as pd
    from scipy.io import wavfile

    from rattle_cli.main import main
    toml = tmp_path / "box.toml"
    toml.write_text(CLI_TOML)
    out, wav = tmp_path / "r.csv", tmp_path / "r.wav"
    args = ["runup", str(toml), "--rpm-from", "1500", "--rpm-to", "2500", "--duration", "2",
            "--out", str(out), "--wav", str(wav), "-q"]
    assert main(args) == 0
    table = pd.read_csv(out)
    box = Gearbox.from_toml(toml)
    for gi, g in enumerate(box.gears):
        rr = replay(box, gi, 1500.0, 2500.0, 2.0)
        rows = table[table.gear == g.name]
        assert len(rows) == rr.impact_t.size > 0
        np.testing.assert_array_equal(rows.t_s.to_numpy(), rr.impact_t)
        np.testing.assert_array_equal(rows.impulse_Ns.to_numpy(), rr.impact_impulse)
    assert np.all(np.diff(table.t_s.to_numpy()) >= 0)
    rate, data = wavfile.read(wav)
    assert rate == 48_000 and data.size == 2 * 48_000
    capsys.readouterr()
    assert main(["runup", str(toml), "--rpm-to", "5000", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "outside the measurement's speed range [975.2" in err[0]
