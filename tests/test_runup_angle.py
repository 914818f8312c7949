"""The measured angle itself as the run-up's wall: against the order reconstruction at steady
speed, containment over random measured-like angles, its spline bounds, and its refusals."""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rattle_core.model.gearbox import Gear, Gearbox
from rattle_core.solver.angle_wall import filter_angle
from rattle_core.solver.runup import measured_window, replay, replay_angle
from test_runup import STEADY

FS = 20_000.0


def _steady_angle(box, rpm, seconds, cutoff_hz=600.0):
    """A steady measurement whose angle is the gearbox's three orders about a constant speed,
    sampled at FS; the fundamental's phase is 0 at every multiple of its period."""
    th, ph = box.excitation.shaft(np.array([rpm]))
    t = np.arange(int(seconds * FS)) / FS
    om = 2 * math.pi * rpm / 60
    psi = 2 * om * t
    angle = om * t + sum(th[0, k] * np.cos((k + 1) * psi - np.deg2rad(ph[0, k])) for k in range(3))
    return filter_angle(t, cutoff_hz=cutoff_hz, angle_rad=angle, engine_order=2.0)


@pytest.mark.parametrize("rpm, r", [(1200.0, 0.8), (3500.0, 0.65)])
def test_steady_angle_wall_gives_the_order_walls_impacts(rpm, r):
    """Two walls, one motion: a steady measurement whose angle holds three orders well below
    the cutoff, replayed with the measured angle (filtered at four times the highest order's
    frequency, a cubic spline through 20 kHz samples), gives the order reconstruction's impacts
    (which are simulate()'s to 1e-9; periodic regimes): the same flanks, times to 1e-4 of a
    forcing period and, after simulate()'s 200-period transient, to 1e-6 relative, impulses
    to 1e-3 of the largest."""
    box = Gearbox.from_text(STEADY)
    box = box.replace(gears=(box.gears[0].replace(restitution=r),))
    periods = 300
    duration = periods * 60 / (2 * rpm)
    start = 2.4                             # a whole number of periods at both speeds
    fa = _steady_angle(box, rpm, start + duration + 2.6, cutoff_hz=4 * 6 * rpm / 60)
    orders = replay(box, 0, rpm, rpm, duration, start="middle")
    angle = replay_angle(box, 0, fa, start, start + duration, start="middle")
    assert orders.impact_t.size > 100
    assert angle.impact_t.size == orders.impact_t.size
    np.testing.assert_array_equal(angle.impact_flank, orders.impact_flank)
    period = 60 / (2 * rpm)
    np.testing.assert_allclose(angle.impact_t, orders.impact_t, rtol=0, atol=1e-4 * period)
    late = orders.impact_t >= 200 * period
    np.testing.assert_allclose(angle.impact_t[late], orders.impact_t[late], rtol=1e-6, atol=0)
    big = np.max(np.abs(orders.impact_impulse))
    np.testing.assert_allclose(angle.impact_impulse, orders.impact_impulse, rtol=0,
                               atol=1e-3 * big)
    np.testing.assert_allclose(angle.impact_rpm, rpm, rtol=1e-8)


def test_filter_keeps_orders_below_the_cutoff_and_removes_those_above():
    """The low-pass, against closed form: at steady speed the fluctuation of an angle holding
    an order at a quarter of the cutoff comes back to 1e-7 of its amplitude, and one at four
    times the cutoff is gone to 1e-6 of its amplitude; the mean speed is the constant one."""
    t = np.arange(int(6 * FS)) / FS
    om = 2 * math.pi * 1800 / 60                   # 30 rev/s; order 2 at 60 Hz
    keep = 1e-3 * np.cos(2 * om * t - 0.4)
    drop = 2e-4 * np.cos(16 * 2 * om * t)          # 960 Hz
    fa = filter_angle(t, cutoff_hz=240.0, angle_rad=om * t + keep + drop, engine_order=2.0)
    lo, hi = fa.usable_s
    mid = (t >= lo) & (t <= hi)
    assert np.max(np.abs(fa.fluctuation_rad[mid] - keep[mid])) < 1e-7 * 1e-3 + 1e-6 * 2e-4
    np.testing.assert_allclose(fa.mean_rpm(t[mid]), 1800.0, rtol=1e-9)


def test_spline_wall_bounds_hold_on_every_piece():
    """The per-piece derivative bounds of the angle wall (the spline's cubics about each
    piece's midpoint) hold at 50 points inside every piece, for the value and the first three
    derivatives, and the wall is the spline through the filtered samples."""
    box = Gearbox.from_text(STEADY)
    fa = _steady_angle(box, 2000.0, 5.0)
    rr = replay_angle(box, 0, fa, 2.2, 2.4)
    w = rr.runup.wall
    s = np.linspace(0.0, 1.0, 50)
    t = (w.t0[:, None] + s[None, :] * w.length[:, None]).ravel()
    p = np.repeat(np.arange(w.t0.size), s.size)
    for m in range(4):
        v = w.values(np.minimum(t, np.nextafter(w.t0[p] + w.length[p], -np.inf)), m)
        assert np.all(np.abs(v) <= w.bounds[p, m])
    scale = box.gears[0].drive_radius_m * box.gears[0].speed_ratio / rr.runup.H_ref
    i0 = int(np.argmin(np.abs(fa.time_s - 2.2)))
    np.testing.assert_allclose(w.values(w.t0), fa.fluctuation_rad[i0:i0 + w.t0.size] * scale,
                               rtol=1e-12, atol=1e-15)


@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(a=st.lists(st.floats(1e-4, 3e-3), min_size=3, max_size=3),
       p=st.lists(st.floats(-3.0, 3.0), min_size=3, max_size=3),
       noise=st.floats(0.0, 2e-4), seed=st.integers(0, 2 ** 31),
       drag=st.floats(0.005, 0.2), backlash=st.floats(20.0, 300.0), r=st.floats(0.0, 0.95),
       rpm_a=st.floats(1500.0, 2500.0), ramp=st.floats(-150.0, 150.0))
def test_containment_under_random_measured_angles(a, p, noise, seed, drag, backlash, r, rpm_a,
                                                  ramp):
    """Containment: driven by random measured-like angles (three orders with amplitudes that
    vary with time, broadband noise, speed ramps up or down), filtered at 500 Hz, the gear
    never leaves the backlash by more than 1e-9 of it at any sampled time, and every impact
    leaves the wall."""
    fs = 10_000.0
    t = np.arange(int(6.4 * fs)) / fs
    rpm = rpm_a + ramp * t
    psi_shaft = 2 * math.pi * np.cumsum(rpm / 60) / fs
    env = 1 + 0.3 * np.sin(3 * t)
    fluct = sum(a[k] * env * np.cos(2 * (k + 1) * psi_shaft - p[k]) for k in range(3))
    fluct = fluct + noise * np.random.default_rng(seed).standard_normal(t.size)
    fa = filter_angle(t, cutoff_hz=500.0, angle_rad=psi_shaft + fluct, engine_order=2.0,
                      mean_hz=8.0)
    box = Gearbox.from_text(STEADY).replace(gears=(Gear("g", 3e-4, 0.03, drag, backlash, r),))
    rr = replay_angle(box, 0, fa, 3.0, 3.3, start="middle", segments=True)
    run, w = rr.run, rr.runup.wall
    ts = np.sort(np.concatenate([np.linspace(w.t0[0], w.t_end, 20_001)[:-1],
                                 run.impact_t, run.seg_t]))
    x, _ = run.sample(ts)
    y = w.values(ts)
    tol = 1e-9 * run.j
    assert np.all(x >= y - tol)
    assert np.all(x <= y + run.j + tol)
    assert np.all(-r * run.impact_w * run.impact_flank >= 0.0)


@pytest.mark.parametrize("cutoff", [0.0, -5.0, float("nan"), 10_000.0, 12_000.0])
def test_cutoff_outside_nyquist_is_refused_with_the_range(cutoff):
    """Bad input: a cutoff ≤ 0, NaN, or at or above the sampling's Nyquist frequency (10 kHz at
    20 kHz) is refused with a ValueError naming cutoff_hz, its value and the range."""
    t = np.arange(2000) / FS
    with pytest.raises(ValueError, match=r"cutoff_hz .*(0, 10000\.?0*\))"):
        filter_angle(t, cutoff_hz=cutoff, speed_rpm=np.full(t.size, 1500.0))


def test_run_outside_the_measured_speeds_is_refused_with_the_range():
    """Bad input: a run whose speeds the measurement's mean speed (clear of the filters'
    edges) never reaches is refused with that range."""
    t = np.arange(int(8 * FS)) / FS
    fa = filter_angle(t, cutoff_hz=400.0, speed_rpm=1000.0 + 250.0 * t, engine_order=2.0)
    with pytest.raises(ValueError, match=r"rpm_to = 3000\.0 is outside the measurement's speed "
                                         r"range \[1600(\.0\d)?, 2399\.9\d\] rpm"):
        measured_window(fa, 1700.0, 3000.0)
    with pytest.raises(ValueError, match=r"rpm_from = 1500\.0 is outside"):
        measured_window(fa, 1500.0, 2000.0)
    a, b = measured_window(fa, 1700.0, 2200.0)
    assert a == pytest.approx(2.8, abs=2 / FS) and b == pytest.approx(4.8, abs=2 / FS)


def test_a_run_against_the_measurements_direction_is_refused_by_name():
    """Bad input: a run-down asked of a measured run-up (both speeds inside its range, the
    second never reached after the first) is refused with a ValueError naming rpm_to and the
    measurement's direction, not an IndexError."""
    t = np.arange(int(8 * FS)) / FS
    fa = filter_angle(t, cutoff_hz=400.0, speed_rpm=1000.0 + 250.0 * t, engine_order=2.0)
    with pytest.raises(ValueError, match=r"rpm_to = 1700\.0 is not reached after rpm_from = "
                                         r"2200\.0 .* from 1600(\.0\d)? to 2399\.9\d rpm"):
        measured_window(fa, 2200.0, 1700.0)


def test_cli_runup_angle_wall_and_its_refusals(tmp_path, capsys):
    """`rattle runup --wall angle --cutoff-hz F` replays the measurement itself, each CSV row
    its impact; a cutoff above Nyquist exits 2 with one line naming cutoff_hz and the range,
    and so does --duration with the angle wall."""
    import pandas as pd

    from gearboxes import SAMPLE_TWO_GEARS_DEFAULT_SOUND
    from rattle_cli.main import main
    toml = tmp_path / "box.toml"
    toml.write_text(SAMPLE_TWO_GEARS_DEFAULT_SOUND)
    out = tmp_path / "r.csv"
    assert main(["runup", str(toml), "--wall", "angle", "--cutoff-hz", "400", "--rpm-from",
                 "2000", "--rpm-to", "2050", "--out", str(out), "-q"]) == 0
    table = pd.read_csv(out)
    assert len(table) > 0 and table.rpm.between(1999.0, 2051.0).all()
    for args, text in ((["--cutoff-hz", "5000"], "cutoff_hz = 5000.0 is outside the allowed "
                                                 "range (0, 3205.13)"),
                       (["--cutoff-hz", "400", "--duration", "3"], "--duration does not apply")):
        capsys.readouterr()
        assert main(["runup", str(toml), "--wall", "angle", *args, "--out", str(out)]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and text in err[0]


def test_cache_key_holds_the_wall_and_the_cutoff():
    """The run-up cache tells the walls apart: the order reconstruction, and the measured angle
    at two cutoffs, give three different keys, and the same angle twice the same key."""
    from rattle_core.store.cache import canonical_hash as request_key
    from rattle_core.store.runups import runup_request
    box = Gearbox.from_text(STEADY)
    t = np.arange(int(4 * FS)) / FS
    speed = np.full(t.size, 1500.0)
    keys = [request_key(runup_request(box, 1500.0, 1600.0, 2.0))]
    for cutoff in (300.0, 400.0, 400.0):
        fa = filter_angle(t, cutoff_hz=cutoff, speed_rpm=speed, engine_order=2.0)
        keys.append(request_key(runup_request(box, 1500.0, 1600.0, None, fa)))
    assert len(set(keys[:3])) == 3 and keys[2] == keys[3]
