"""A gearbox's run-up heard and measured: the WAV against the signal it was written from, the
fast-weighted level against its closed form, rattle intervals against the closed-form contact
boundary of a drag that rises and falls, run-up and run-down onsets, the comparison with the
quasi-steady verdict, and the CLI's refusals."""
from __future__ import annotations

import math
import re

import numpy as np
import pytest

from rattle_core.analysis.levels import fast_level_series, level
from rattle_core.analysis.loudness import loudness
from rattle_core.analysis.sound import render
from rattle_core.batch.gearbox import verdict
from rattle_core.batch.runup import (GAP_PERIODS, compare, gearbox_runup, rattle_intervals,
                                     verdict_grid)
from rattle_core.model.drag import Drag
from rattle_core.model.gearbox import Excitation, Gear, Gearbox
from rattle_core.solver.runup import replay
from gearboxes import SAMPLE_TWO_GEARS_DEFAULT_SOUND

GEARS = (Gear("5th idler", 4e-4, 0.035, 0.05, 80.0, 0.65),
         Gear("reverse idler", 2.5e-4, 0.03, 0.03, 120.0, 0.65, speed_ratio=0.8))

CLI_TOML = SAMPLE_TWO_GEARS_DEFAULT_SOUND


@pytest.fixture(scope="module")
def sample_box():
    # the shipped sample run-up's order map, as a gearbox file reads it
    omap = Gearbox.from_text(CLI_TOML).excitation.order_map
    assert list(omap.orders[:3]) == [2.0, 4.0, 6.0]
    return Gearbox(Excitation(2.0, 3, omap), GEARS)


def _boundary(box, gi, lo=1000.0, hi=3000.0):
    fine = np.arange(lo, hi, 1.0)
    ratio = box.contact_ratio(gi, fine)
    return fine, ratio


def test_fast_level_series_is_the_fast_weighting():
    """L_AF(t) of a 1 kHz tone at 94 dB settles at 94 dB (A-weighting 0 dB at 1 kHz); its
    maximum after the settling time, sampled at every sample, is level()'s L_AFmax; two
    incoherent sources add their energies (+3.01 dB for two equal ones)."""
    fs = 48_000
    t = np.arange(2 * fs) / fs
    p = math.sqrt(2) * 20e-6 * 10 ** (94 / 20) * np.sin(2 * math.pi * 1000 * t)
    ts, db = fast_level_series(p, fs)
    assert ts[1] == pytest.approx(0.002) and ts.size == 1000
    late = db[ts > 1.5]
    assert np.all(np.abs(late - 94.0) < 0.02)
    ts1, db1 = fast_level_series(p, fs, step_s=1 / fs)
    skip = ts1 >= 0.05
    assert db1[skip].max() == pytest.approx(level(p, fs).spl_dba_max, abs=1e-9)
    _, db2 = fast_level_series(np.stack([p, p[::-1].copy()]), fs)
    assert np.all(np.abs(db2[ts > 1.5] - 94.0 - 10 * math.log10(2)) < 0.03)
    with pytest.raises(ValueError, match="step_s"):
        fast_level_series(p, fs, step_s=0.0)


def test_gearbox_sound_is_the_sum_of_the_gears_and_one_gear_its_own_loudness(sample_box):
    """The gearbox's pressure is the sum, over gears, of the transfer times each gear's impacts
    rendered at 48 kHz (an independent re-render from replay()); it lasts the run; a one-gear
    box's N(t) is loudness() of its pressure, exactly (incoherent sum of one source)."""
    res = gearbox_runup(sample_box, 1500.0, 2500.0, 2.0, threads=2)
    assert res.pressure_pa.size == 2 * 48_000
    ref = sum(sample_box.transfer_pa_per_ns * render(r.impact_t, r.impact_impulse, 2.0, 48_000)
              for r in (replay(sample_box, gi, 1500.0, 2500.0, 2.0) for gi in range(2)))
    np.testing.assert_allclose(res.pressure_pa, ref, rtol=0, atol=1e-12 * np.abs(ref).max())
    assert res.time_s.size == res.loudness_t.size == res.level_dba_t.size == res.rpm_t.size
    np.testing.assert_allclose(res.rpm_t, 1500.0 + 500.0 * res.time_s)
    one = gearbox_runup(sample_box.replace(gears=GEARS[:1]), 1500.0, 2500.0, 2.0)
    direct = loudness(one.pressure_pa)
    np.testing.assert_array_equal(one.loudness_t, direct.loudness_t)
    np.testing.assert_array_equal(one.gear_loudness_t["5th idler"], direct.loudness_t)
    # two incoherent gears are louder than either, never quieter
    assert np.all(res.loudness_t >= np.maximum(*res.gear_loudness_t.values()) - 1e-9)


def test_intervals_rule_on_a_made_up_impact_train():
    """The interval rule: a gap longer than GAP_PERIODS forcing periods at the gap's speed
    splits; a shorter one does not."""
    rpm = np.full(7, 1200.0)                      # fundamental of order 2: 40 Hz, 25 ms
    period = 60.0 / (2 * 1200.0)
    t = np.array([0, 1, 2, 2 + GAP_PERIODS * 1.01, 3 + GAP_PERIODS * 1.01,
                  3 + GAP_PERIODS * 1.99, 4 + GAP_PERIODS * 4]) * period
    assert rattle_intervals(t, rpm, 2.0) == [(0, 2, 3), (3, 5, 3), (6, 6, 1)]
    assert rattle_intervals(np.empty(0), np.empty(0), 2.0) == []


def test_rattle_stops_and_starts_again_where_the_drag_table_crosses_the_boundary(sample_box):
    """A drag table that rises above the inertia torque and falls again: on a slow run-up the
    gear rattles, stops and rattles again, two intervals whose edges lie within one 50-rpm
    step of the closed-form crossings of contact_ratio = 1."""
    drag = Drag.from_value({"rpm": [1000, 1600, 1800, 2200, 2400, 3000],
                            "torque_Nm": [0.03, 0.05, 0.12, 0.12, 0.06, 0.06]}, "drag")
    box = sample_box.replace(gears=(GEARS[0].replace(drag=drag),))
    fine, ratio = _boundary(box, 0)
    loud = ratio > 1
    assert loud[0] and loud[-1] and not np.all(loud)
    falls = fine[np.nonzero(loud[:-1] & ~loud[1:])[0]]
    rises = fine[np.nonzero(~loud[:-1] & loud[1:])[0] + 1]
    assert falls.size == rises.size == 1
    res = gearbox_runup(box, 1000.0, 3000.0, 200.0, sound=False)
    iv = res.intervals
    assert list(iv.gear) == ["5th idler"] * 2, iv
    assert abs(iv.end_rpm[0] - falls[0]) <= 50.0, (iv, falls)
    assert abs(iv.start_rpm[1] - rises[0]) <= 50.0, (iv, rises)
    assert iv.start_rpm[0] < 1050.0 and iv.end_rpm[1] > 2950.0
    assert iv.impacts.sum() == res.replays["5th idler"].impact_t.size


def test_slow_run_up_and_run_down_onsets_are_the_contact_boundary(sample_box):
    """Hysteresis where the quasi-steady answer holds: on a slow run (1000 ↔ 3000 rpm in
    300 s) the run-up's onset and the run-down's (its lowest impact) both lie within one
    50-rpm step of the closed-form contact boundary, for each gear."""
    up = gearbox_runup(sample_box, 1000.0, 3000.0, 300.0, sound=False)
    down = gearbox_runup(sample_box, 3000.0, 1000.0, 300.0, sound=False)
    assert down.run_down and not up.run_down
    for gi, g in enumerate(sample_box.gears):
        fine, ratio = _boundary(sample_box, gi)
        boundary = fine[np.argmax(ratio > 1)]
        assert abs(up.onsets[g.name] - boundary) <= 50.0, (g.name, up.onsets, boundary)
        assert abs(down.onsets[g.name] - boundary) <= 50.0, (g.name, down.onsets, boundary)
        # the run-down rattles from its start and stops once, at the boundary
        iv = down.intervals
        assert (iv.gear == g.name).sum() == 1


def test_compare_says_the_quasi_steady_onset_holds_on_a_slow_run_only(sample_box):
    """Against the verdict on a 50-rpm grid: a slow run (10 rpm/s) has each gear's onset within
    one grid step of the verdict's, and the text says it holds; a fast one (200 rpm/s) is
    delayed by the mean acceleration's share of the drag beyond a grid step, and the text says
    it does not hold."""
    grid = verdict_grid(1000.0, 1600.0)
    np.testing.assert_array_equal(grid, np.arange(1000.0, 1601.0, 50.0))
    v = verdict(sample_box, grid, ensemble_runs=0, threads=1)
    slow = gearbox_runup(sample_box, 1000.0, 1600.0, 60.0)
    cmp = compare(slow, v)
    assert cmp.step == 50.0
    assert cmp.onsets.onset_holds.all(), cmp.onsets
    assert cmp.text.count("the quasi-steady onset holds") == 2
    assert set(cmp.loudness.gear) == {"5th idler", "reverse idler", "gearbox"}
    fast = gearbox_runup(sample_box, 1000.0, 1600.0, 3.0)
    cmp_fast = compare(fast, v)
    g = GEARS[0]
    share = g.inertia_kgm2 * g.drive_radius_m * 2 * math.pi / 60 * 200.0 / (
        g.base_radius_m * g.drag_torque_Nm)
    fine, ratio = _boundary(sample_box, 0, 1000.0, 1600.0)
    shift = fine[np.argmax(ratio > 1 + share)] - fine[np.argmax(ratio > 1)]
    assert shift > 2 * 50.0
    assert not cmp_fast.onsets.set_index("gear").onset_holds["5th idler"]
    assert "5th idler: " in cmp_fast.text and "does not hold" in cmp_fast.text


def test_cli_wav_keeps_its_level_and_intervals_are_written(tmp_path, capsys):
    """`rattle runup --wav`: the WAV lasts the run; scaled by the printed calibration (Pa per
    full scale) its loudness is that of the signal computed directly, to the int16
    quantisation; the intervals CSV holds each gear's rattle intervals."""
    import pandas as pd
    from scipy.io import wavfile

    from rattle_cli.main import main
    toml = tmp_path / "box.toml"
    toml.write_text(CLI_TOML)
    out, wav = tmp_path / "r.csv", tmp_path / "r.wav"
    assert main(["runup", str(toml), "--rpm-from", "1500", "--rpm-to", "2500", "--duration",
                 "2", "--out", str(out), "--wav", str(wav)]) == 0
    captured = capsys.readouterr()
    text = captured.err + captured.out
    cal = float(re.search(r"full scale \(1\.0, int16 32767\) = ([0-9.eE+-]+) Pa", text).group(1))
    rate, data = wavfile.read(wav)
    assert rate == 48_000 and data.size == 2 * 48_000 and data.dtype == np.int16
    box = Gearbox.from_toml(toml)
    res = gearbox_runup(box, 1500.0, 2500.0, 2.0)
    assert cal == pytest.approx(res.calibration_pa, rel=1e-5)
    heard = loudness(data / 32767.0 * cal)
    direct = loudness(res.pressure_pa)
    assert direct.loudness_sone > 5.0
    assert heard.loudness_sone == pytest.approx(direct.loudness_sone, rel=2e-3)
    np.testing.assert_allclose(heard.loudness_t, direct.loudness_t, rtol=0,
                               atol=5e-3 * direct.loudness_t.max())
    iv = pd.read_csv(tmp_path / "r_intervals.csv")
    assert list(iv.columns) == ["gear", "start_s", "end_s", "start_rpm", "end_rpm", "impacts"]
    for name, r in res.replays.items():
        rows = iv[iv.gear == name]
        assert rows.impacts.sum() == r.impact_t.size
        assert rows.start_s.iloc[0] == pytest.approx(r.impact_t[0], rel=1e-12)


@pytest.mark.parametrize("extra, message", [
    (["--rpm-to", "5000"], "outside the measurement's speed range [975.2"),
    (["--rpm-from", "100"], "outside the measurement's speed range [975.2"),
    (["--png", "{tmp}/missing/dir/r.png"], "--png"),
    (["--png", "{tmp}/r.txt"], "--png"),
])
def test_cli_refusals_are_one_line(tmp_path, capsys, extra, message):
    """Bad input: a speed outside the measurement and a bad --png path exit 2 with one line,
    before anything runs (no output written)."""
    from rattle_cli.main import main
    toml = tmp_path / "box.toml"
    toml.write_text(CLI_TOML)
    out = tmp_path / "r.csv"
    extra = [e.replace("{tmp}", str(tmp_path)) for e in extra]
    assert main(["runup", str(toml), "--duration", "1", "--out", str(out), *extra]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0], err
    assert not out.exists()


def test_cli_png_and_compare_verdict(tmp_path, capsys):
    """`--png --compare-verdict` draws the figure and prints, per gear, the onset on the run,
    the run-down and in the verdict."""
    from rattle_cli.main import main
    toml = tmp_path / "box.toml"
    toml.write_text(CLI_TOML)
    out, png = tmp_path / "r.csv", tmp_path / "r.png"
    assert main(["runup", str(toml), "--rpm-from", "1000", "--rpm-to", "1400", "--duration",
                 "2", "--out", str(out), "--png", str(png), "--compare-verdict"]) == 0
    text = capsys.readouterr()
    text = text.err + text.out
    assert png.stat().st_size > 10_000 and png.read_bytes()[:4] == b"\x89PNG"
    for name in ("5th idler", "reverse idler"):
        assert re.search(rf"{name}: onset on the run (\d+ rpm|never), on the run-down "
                         rf"(\d+ rpm|never), in the verdict (\d+ rpm|never)", text), text
