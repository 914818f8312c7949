"""A gearbox of loose gears: its file, the verdict's onset against the closed-form contact
boundary, physical rates against single simulations, loudness, the cache and the CLI."""
from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from rattle_core import classify, simulate
from rattle_core.analysis.loudness import loudness, loudness_zwtv
from rattle_core.analysis.sound import render
from rattle_core.batch.gearbox import GEARBOX, verdict
from rattle_core.model.gearbox import Gear, Gearbox
from rattle_core.measure.orders import SAMPLE_RUNUP, OrderMap
from rattle_core.store.verdicts import cached_verdict

ROOT = Path(__file__).resolve().parent.parent

TOML = """
[excitation]
measurement = "sample"
engine_order = 2
harmonics = 3

[sound]
duration_s = 0.2

[[gear]]
name = "5th idler"
inertia_kgm2 = 4e-4
base_radius_m = 0.035
drag_torque_Nm = 0.05
backlash_um = 80
restitution = 0.65

[[gear]]
name = "reverse idler"
inertia_kgm2 = 2.5e-4
base_radius_m = 0.03
drag_torque_Nm = 0.03
backlash_um = 120
speed_ratio = 0.8
driver_radius_m = 0.028
"""


@pytest.fixture(scope="module")
def box() -> Gearbox:
    return Gearbox.from_text(TOML)


@pytest.fixture(scope="module")
def run(box):
    """The verdict from 1000 to 3000 rpm in 100 rpm steps (computed once for the module)."""
    return verdict(box, np.arange(1000.0, 3001.0, 100.0), transient=150, record=60)


def closed_form_onset(gear: Gear, lo: float, hi: float) -> float:
    """The speed where ``J R_d max(−θ̈_drive) / (R_b C)`` first reaches 1, from the sample's
    orders (read here from the file) and the gear's data alone, by bisection."""
    omap = OrderMap.from_csv(SAMPLE_RUNUP, (2, 4, 6))
    t = np.linspace(0, 2 * math.pi, 4096, endpoint=False)

    def ratio(rpm: float) -> float:
        theta, phase = omap.at([rpm], (2, 4, 6))
        w = 2 * math.pi * rpm / 60
        acc = sum(-gear.speed_ratio * theta[0, n] * (k * w) ** 2
                  * np.cos(k * t / 2 - math.radians(phase[0, n]))
                  for n, k in enumerate((2, 4, 6)))
        return gear.inertia_kgm2 * gear.drive_radius_m * float(np.max(-acc)) / (
            gear.base_radius_m * gear.drag_torque_Nm)
    assert ratio(lo) < 1 < ratio(hi)
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if ratio(mid) < 1 else (lo, mid)
    return hi


def test_onset_agrees_with_the_closed_form_contact_boundary(box, run):
    """Each gear's onset rpm lies within one rpm step above the speed where
    J R_d max(−θ̈_drive)/(R_b C) = 1; below it every point is in permanent contact (A), above
    it none is."""
    for g, gear in enumerate(box.gears):
        boundary = closed_form_onset(gear, 1000.0, 3000.0)
        onset = run.onsets[gear.name]
        assert boundary <= onset < boundary + 100.0, (gear.name, boundary, onset)
        rows = run.gear(gear.name)
        below = rows["rpm"].to_numpy() < boundary
        assert np.all(rows["regime"].to_numpy()[below] == "A")
        assert np.all(rows["regime"].to_numpy()[~below] != "A")
        np.testing.assert_allclose(rows["contact_ratio"] < 1, below)


def test_a_gear_in_permanent_contact_is_silent_and_the_rest_is_heard(run):
    """Permanent contact gives 0 impacts, 0 intensity and 0 sone; a rattling gear is heard."""
    t = run.table[run.table["gear"] != GEARBOX]
    quiet = t[t["regime"] == "A"]
    loud = t[t["regime"] != "A"]
    assert len(quiet) > 0 and len(loud) > 0
    assert (quiet[["impacts_per_s", "intensity", "loudness_sone"]] == 0).all().all()
    assert (loud["impacts_per_s"] > 0).all() and (loud["loudness_sone"] > 0).all()
    assert (loud["sharpness_acum"] > 0).all()


def test_the_gearbox_rows_add_the_gears(run, box):
    """The gearbox's impacts and intensity are the gears' sums; where one gear alone rattles,
    the gearbox is as loud as that gear; it is never quieter than its loudest gear by more than
    rounding of the percentile."""
    names = [g.name for g in box.gears]
    t = run.table
    for rpm, rows in t.groupby("rpm"):
        gears = rows[rows["gear"].isin(names)]
        total = rows[rows["gear"] == GEARBOX].iloc[0]
        assert total["impacts_per_s"] == pytest.approx(gears["impacts_per_s"].sum())
        assert total["intensity"] == pytest.approx(gears["intensity"].sum())
        heard = gears[gears["loudness_sone"] > 0]
        if len(heard) == 1:
            assert total["loudness_sone"] == heard["loudness_sone"].iloc[0]
        assert total["loudness_sone"] >= 0.97 * gears["loudness_sone"].max()


def test_physical_rates_match_a_single_simulation(box, run):
    """At 2500 rpm the first gear's impacts per second and intensity Σ I²/s equal those of
    simulate() on the same parameters, converted by hand (f = order·rpm/60, I = Ĩ m ω H₁)."""
    phys = box.physical(0, 2500.0)
    tr = simulate(phys.to_dimensionless(), periods=run.settings["record"],
                  transient=run.settings["transient"], lyapunov=True)
    seconds = run.settings["record"] * 60.0 / (2 * 2500.0)
    m = phys.inertia / phys.radius ** 2
    H1 = phys.drive_radius * phys.amplitudes[0]
    impulse = tr.impact_impulse * m * phys.omega * H1
    row = run.gear(box.gears[0].name).set_index("rpm").loc[2500.0]
    assert row["regime"] == classify(tr).regime
    assert row["impacts_per_s"] == pytest.approx(tr.impact_t.size / seconds)
    assert row["intensity"] == pytest.approx(np.sum(impulse ** 2) / seconds, rel=1e-9)


def test_periodic_points_have_zero_width_intervals(run):
    """A period-1 orbit repeats block after block: its 95 % intervals are zero."""
    t = run.table[run.table["regime"].isin(["C", "E"])]
    for _, row in t.iterrows():
        assert row["impacts_per_s_ci95"] == pytest.approx(0.0, abs=1e-9)


def test_non_repeating_points_take_their_intervals_from_independent_runs(box, run):
    """A point whose motion does not repeat reports the rates and 95 % intervals of
    statistics() over 8 runs of its own parameters (converted to per second), taken from the
    attractor its own run is on: where attractors coexist, the non-periodic one of its regime,
    labelled "k of 8 runs", never a coexisting periodic orbit's exact value."""
    from rattle_core.batch.ensemble import statistics
    t = run.table[run.table["gear"] != GEARBOX]
    wild = t[t["interval"].str.endswith("8 runs")]
    assert len(wild) > 0 and (wild["impacts_per_s_ci95"] > 0).all()
    assert set(t[t["interval"] == "exact"]["impacts_per_s_ci95"]) <= {0.0}
    mixed = wild[wild["attractors"] != ""]
    assert len(mixed) > 0, "the sweep should hold a point with coexisting attractors"
    for _, row in pd.concat([wild.iloc[:1], mixed]).iterrows():
        g = [x.name for x in box.gears].index(row["gear"])
        phys = box.physical(g, float(row["rpm"]))
        st = statistics(phys.to_dimensionless(), runs=8, periods=run.settings["record"],
                        transient=run.settings["transient"])
        own = [a for a in st.attractors if not a.periodic and a.regime == row["regime"]]
        assert own, (row["gear"], row["rpm"], [a.label for a in st.attractors])
        a = max(own, key=lambda a: len(a.runs))
        label = "8 runs" if len(st.attractors) == 1 else f"{len(a.runs)} of 8 runs"
        assert row["interval"] == label
        f = phys.frequency_hz
        rate, energy = a.estimates["impacts_per_period"], a.estimates["intensity"]
        assert row["impacts_per_s"] == pytest.approx(rate.value * f, rel=1e-12)
        assert row["impacts_per_s_ci95"] == pytest.approx(rate.ci95 * f, rel=1e-12)
        assert row["intensity"] == pytest.approx(energy.value * phys.impulse_scale**2 * f,
                                                 rel=1e-12)


def test_one_run_intervals_come_from_blocks_of_its_window(box):
    """With ensemble_runs=0 a non-repeating point's interval is Student's t over five block
    means of its one window: positive, and labelled so."""
    res = verdict(box, np.array([2300.0, 2500.0, 2900.0]), transient=150, record=60,
                  ensemble_runs=0)
    t = res.table[res.table["gear"] != GEARBOX]
    assert set(t["interval"]) <= {"exact", "blocks"}
    blocks = t[t["interval"] == "blocks"]
    assert len(blocks) > 0 and (blocks["impacts_per_s_ci95"] > 0).all()


def test_compiled_loudness_equals_mosqito():
    """The loudness with the compiled nonlinear decay equals mosqito's loudness_zwtv exactly
    on a rattle sound (time-varying loudness and specific loudness)."""
    from mosqito.sq_metrics import loudness_zwtv as reference
    rng = np.random.default_rng(2)
    times = np.sort(rng.uniform(0, 0.3, 25))
    p = 5.0 * render(times, rng.uniform(-0.02, 0.02, 25), 0.3, 48_000)
    N, spec, _, t = loudness_zwtv(p, 48_000)
    N_ref, spec_ref, _, t_ref = reference(p, 48_000)
    np.testing.assert_allclose(N, N_ref, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(spec, spec_ref, rtol=1e-12, atol=1e-12)


def test_loudness_grows_with_level_but_not_in_proportion():
    """Ten times the transfer (+20 dB) is louder by far less than ten times: roughly 2^(20/10)
    = 4 by Zwicker's rule; silence is 0 sone."""
    rng = np.random.default_rng(4)
    s = render(np.sort(rng.uniform(0, 0.5, 60)), rng.uniform(-0.02, 0.02, 60), 0.5, 48_000)
    a, b = loudness(5.0 * s).loudness_sone, loudness(50.0 * s).loudness_sone
    assert 2.5 < b / a < 6.0
    assert loudness(np.zeros(48_000)).loudness_sone == 0.0


def test_verdict_is_cached_and_a_changed_gear_is_not_served(box, tmp_path):
    """The same verdict asked twice comes from the cache, table for table, with progress at
    its end; drag +20 % on one gear is computed afresh."""
    rpm = np.array([1500.0, 2500.0])
    seen = []
    first = cached_verdict(box, rpm, transient=100, record=40, directory=tmp_path)
    again = cached_verdict(box, rpm, transient=100, record=40, directory=tmp_path,
                           progress=lambda d, t: seen.append((d, t)))
    assert not first.from_cache and again.from_cache and seen[-1] == (4, 4)
    assert again.table.equals(first.table)
    g = box.gears[0]
    variant = box.replace(gears=(g.replace(drag_torque_Nm=1.2 * g.drag_torque_Nm),) + box.gears[1:])
    changed = cached_verdict(variant, rpm, transient=100, record=40, directory=tmp_path)
    assert not changed.from_cache


def test_verdict_cancels_between_chunks(box):
    """A cancel after the first chunk returns the speeds done, flagged cancelled."""
    calls = []
    res = verdict(box, np.linspace(1200, 2800, 6), transient=50, record=20, chunk_speeds=2,
                  cancel=lambda: len(calls) > 0, progress=lambda d, t: calls.append(d))
    assert res.cancelled and calls == [4] and sorted(set(res.table["rpm"])) == [1200.0, 1520.0]


@pytest.mark.parametrize("text, message", [
    (TOML.replace("backlash_um = 80", "backlash_um = -80"),
     r"gearbox text, \[\[gear\]\] number 1 \('5th idler'\): backlash_um = -80.0 is outside "
     r"the allowed range"),
    (TOML.replace("restitution = 0.65", "restitution = 0.65\nstiffness = 3"),
     r"gearbox text, \[\[gear\]\] number 1 \('5th idler'\): unknown key 'stiffness'"),
    (TOML.replace('measurement = "sample"', 'measurement = "/etc/passwd"'),
     r"a gearbox given as text names no file"),
    (TOML + '\n[[gear]]\nname = "5th idler"\ninertia_kgm2 = 1e-4\nbase_radius_m = 0.03\n'
            'drag_torque_Nm = 0.02\nbacklash_um = 50\n', r"'5th idler' appears twice"),
    ("[excitation\n", r"gearbox text: TOML syntax: .*\(at line 1, column 12\)"),
])
def test_bad_gearbox_text_is_refused_naming_what(text, message):
    """Bad values, unknown keys, a file path in uploaded text, missing orders, twin names and
    broken TOML are refused with a message saying what."""
    with pytest.raises(ValueError, match=message):
        Gearbox.from_text(text)


def test_constant_orders_hold_acceleration_over_speed():
    """Constant orders given as accelerations give θ_k = α_k/(kΩ)² at each speed, and a gear's
    contact ratio is then the same at every speed."""
    box = Gearbox.from_text(TOML.replace('measurement = "sample"',
                                         'orders = [{order = 2, accel_rad_s2 = 150, phase_deg = 10},'
                                         ' {order = 4, accel_rad_s2 = 40}]'))
    theta, phase = box.excitation.shaft([1200.0, 2400.0])
    w = 2 * math.pi * np.array([1200.0, 2400.0]) / 60
    np.testing.assert_allclose(theta[:, 0], 150 / (2 * w) ** 2)
    np.testing.assert_allclose(theta[:, 1], 40 / (4 * w) ** 2)
    assert np.all(theta[:, 2] == 0) and np.all(phase[:, 0] == 10)
    r = box.contact_ratio(0, [1200.0, 2400.0])
    assert r[0] == pytest.approx(r[1], rel=1e-9)


def test_cli_gearbox_writes_the_verdict_and_refuses_bad_files(tmp_path):
    """``rattle gearbox`` writes the verdict's columns for every gear and speed; a bad file
    exits 2 with one line."""
    (tmp_path / "gb.toml").write_text(TOML)
    out = tmp_path / "verdict.csv"
    env = {"RATTLE_CACHE_DIR": str(tmp_path / "cache"), "PATH": "/usr/bin:/bin",
           "RATTLE_CONFIG_DIR": str(tmp_path / "config")}
    cmd = [sys.executable, "-m", "rattle_cli", "gearbox"]
    r = subprocess.run(cmd + [str(tmp_path / "gb.toml"), "--rpm", "1500:2500:3", "--out", str(out),
                              "--transient", "60", "--record", "30", "-q", "--png"],
                       capture_output=True, text=True, cwd=ROOT, timeout=600, env=env)
    assert r.returncode == 0, r.stderr
    import pandas as pd
    df = pd.read_csv(out)
    assert list(df.columns[:6]) == ["gear", "rpm", "regime", "impacts_per_s", "intensity",
                                    "loudness_sone"]
    assert len(df) == 3 * 3 and set(df["gear"]) == {"5th idler", "reverse idler", GEARBOX}
    assert (tmp_path / "verdict.png").stat().st_size > 1000
    (tmp_path / "bad.toml").write_text(TOML.replace("inertia_kgm2 = 4e-4", "inertia_kgm2 = 'heavy'"))
    r = subprocess.run(cmd + [str(tmp_path / "bad.toml"), "--rpm", "1500:2500:3", "--out",
                              str(tmp_path / "v.csv")], capture_output=True, text=True, cwd=ROOT,
                       timeout=600, env=env)
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "inertia_kgm2" in r.stderr


def test_verdict_on_dask_equals_the_local_one(box):
    """The same verdict run as tasks on a two-worker Dask LocalCluster gives the same table."""
    from rattle_core.batch.executor import dask_session
    rpm = np.array([1100.0, 1900.0, 2700.0])
    here = verdict(box, rpm, transient=100, record=40, chunk_speeds=1)
    with dask_session("local", 2) as client:
        there = verdict(box, rpm, transient=100, record=40, chunk_speeds=1, executor=client)
    assert there.table.equals(here.table)


# ----- a user's file: bounded, printable names, every error one line at its place ----------

GEAR = ('[[gear]]\nname = "{name}"\ninertia_kgm2 = 4e-4\nbase_radius_m = 0.035\n'
        'drag_torque_Nm = 0.05\nbacklash_um = 80\n')
HEAD = '[excitation]\nmeasurement = "sample"\nengine_order = 2\nharmonics = 3\n'


def refused(tmp_path, text: str) -> str:
    """The message of a gearbox file holding ``text``: one line naming the file."""
    path = tmp_path / "box.toml"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(ValueError) as err:
        Gearbox.from_toml(path)
    msg = str(err.value)
    assert "\n" not in msg and msg.startswith("gearbox file 'box.toml'"), msg
    assert not isinstance(err.value.__cause__ or err.value.__context__, RecursionError)
    return msg


@pytest.mark.parametrize("deep", [
    "orders = " + "[" * 5000 + "]" * 5000,
    "orders = " + "{a = " * 3000 + "1" + "}" * 3000,
    "orders = [" + "[" * 9 + "]" * 9 + "]",
])
def test_deep_nesting_is_refused_before_parsing_naming_the_line(deep, tmp_path):
    """Arrays or inline tables nested past the stated depth (8) are refused at their line
    before the parser recurses: a one-line ValueError, never a RecursionError."""
    from rattle_core.model.gearbox import MAX_TOML_DEPTH
    msg = refused(tmp_path, "[excitation]\nengine_order = 2\n" + deep + "\n")
    assert "line 3" in msg and f"allowed depth is {MAX_TOML_DEPTH}" in msg, msg


def test_brackets_in_strings_and_comments_do_not_count_as_nesting():
    """Brackets inside strings (all four kinds) and comments are text: the file still reads."""
    deep = "[" * 20 + "{" * 20
    text = (f"# {deep}\n" + HEAD + f"# again {deep}\n"
            + GEAR.format(name=deep) + f"# '{deep}\n"
            + GEAR.format(name="b").replace('"b"', f"'''b{deep}'''")
            + GEAR.format(name="c").replace('"c"', f'"""c\\"{deep}"""'))
    box = Gearbox.from_text(text)
    assert [g.name for g in box.gears] == [deep, f"b{deep}", f'c"{deep}']


def test_exactly_the_allowed_depth_is_taken():
    """Nesting of exactly the stated depth, counted from the top of the file, reaches the
    checks of the keys; one level more is refused by the bound."""
    from rattle_core.model.gearbox import MAX_TOML_DEPTH
    d = MAX_TOML_DEPTH
    with pytest.raises(ValueError) as err:
        Gearbox.from_text("stack = " + "[" * d + "]" * d + "\n")
    assert "deep" not in str(err.value) and "[stack]: unknown table" in str(err.value)
    with pytest.raises(ValueError, match="deep"):
        Gearbox.from_text("stack = " + "[" * (d + 1) + "]" * (d + 1) + "\n")


@pytest.mark.parametrize("text, place, words", [
    (HEAD.replace('"sample"', '"sample"\n' + "a." * 12 + "b = 1") + GEAR.format(name="x"),
     "excitation.a.a.a.a.a.a.a", "nest more than 8"),
    ("[excitation]\norders = [" + ", ".join(["{order = 2, accel_rad_s2 = 1}"] * 300) + "]\n",
     "excitation.orders", "300 items"),
    (HEAD + GEAR.format(name="x" * 2000), "gear[0].name", "2000 characters"),
    (f'{"k" * 1100} = 1\n' + HEAD + GEAR.format(name="x"), "the top level", "1100 characters"),
])
def test_arrays_strings_and_tables_are_bounded_at_their_key_path(text, place, words, tmp_path):
    """An array over 256 items, a string or key over 1024 characters, or tables nested past 8
    are refused naming the key path, before any value is read."""
    msg = refused(tmp_path, text)
    assert place in msg and words in msg, msg


BAD_CHARACTERS = ["\x00", "\x07", "\x1b", "\x7f", "\x85", "\u2028", "\u2029", "\u200e", "\u200f",
                  "\u061c"] + [chr(c) for c in range(0x202A, 0x202F)] + \
                 [chr(c) for c in range(0x2066, 0x206A)]


@pytest.mark.parametrize("ch", BAD_CHARACTERS, ids=[f"U+{ord(c):04X}" for c in BAD_CHARACTERS])
def test_names_with_control_or_bidirectional_characters_are_refused(ch, tmp_path):
    """A gear name holding a control character (NUL included), a line separator or a
    bidirectional formatting character is refused naming the gear's number and the character,
    from a file, from uploaded text and from the API; so is a measurement file name."""
    escaped = f"\\u{ord(ch):04x}"
    text = HEAD + GEAR.format(name="ok") + GEAR.format(name=f"5th{escaped}idler")
    msg = refused(tmp_path, text)
    assert "[[gear]] number 2" in msg and f"U+{ord(ch):04X}" in msg, msg
    assert ch not in msg  # shown escaped
    with pytest.raises(ValueError, match=f"U\\+{ord(ch):04X}"):
        Gearbox.from_text(text)
    with pytest.raises(ValueError, match=f"gear name .* U\\+{ord(ch):04X}"):
        Gear(name=f"5th{ch}idler", inertia_kgm2=4e-4, base_radius_m=0.035, drag_torque_Nm=0.05,
             backlash_um=80)
    named = HEAD.replace('"sample"', f'"run{escaped}up.csv"') + GEAR.format(name="ok")
    msg = refused(tmp_path, named)
    assert "[excitation] measurement" in msg and f"U+{ord(ch):04X}" in msg, msg


def test_printable_names_in_any_script_are_kept():
    """Names in other scripts, with accents, emoji joiners or right-to-left letters are text,
    not control: they are taken as written."""
    names = ["5. Gang Losrad", "ترس الخامس", "第五档", "idler \u00e9\u0301", "👨\u200d🔧 gear"]
    text = HEAD + "".join(GEAR.format(name=n) for n in names)
    assert [g.name for g in Gearbox.from_text(text).gears] == names


@pytest.mark.parametrize("text, place", [
    (HEAD + GEAR.format(name="a") + GEAR.format(name="b").replace("80", "-1"),
     "[[gear]] number 2 ('b'): backlash_um = -1.0"),
    (HEAD + GEAR.format(name="a") + "[[gear]]\nname = 'c'\n", "[[gear]] number 2 ('c'): missing key"),
    (HEAD.replace("harmonics = 3", "harmonics = 2.5") + GEAR.format(name="a"),
     "[excitation] harmonics: harmonics = 2.5"),
    (HEAD.replace("engine_order = 2", "engine_order = 'two'") + GEAR.format(name="a"),
     "[excitation] engine_order"),
    ("[excitation]\norders = [{order = 2, accel_rad_s2 = 1}, {order = 4, accel_rad_s2 = -5}]\n"
     + GEAR.format(name="a"), "[excitation] orders[1]: accel_rad_s2 = -5.0"),
    (HEAD + "[sound]\nduration_s = 99\n" + GEAR.format(name="a"), "[sound]: duration_s = 99"),
    (HEAD + "[noise]\n" + GEAR.format(name="a"), "[noise]: unknown table"),
    ("gear = 3\n" + HEAD, "[[gear]]: give at least one"),
    (HEAD.replace('"sample"', '"missing.csv"') + GEAR.format(name="a"),
     "[excitation] measurement = 'missing.csv'"),
    (HEAD + GEAR.format(name="a") + "x = = 1\n", "TOML syntax"),
])
def test_every_error_of_a_file_is_one_line_naming_the_file_and_the_place(text, place, tmp_path):
    """Each bad file gives one line: the file's name, then the place (gear number and name,
    key path, line), then what is wrong."""
    msg = refused(tmp_path, text)
    assert place in msg, msg
