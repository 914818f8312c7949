"""Real measurement files: every quirk a data-acquisition export has, read to the same orders as
the clean file; tachometer pulses; imperfect sampling; a time window; the Campbell data."""
from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from rattle_core.measure.campbell import campbell
from rattle_core.measure.measurement import measurement_options, read_measurement
from rattle_core.measure.orders import OrderMap

ROOT = Path(__file__).resolve().parent.parent
DATA = Path(__file__).resolve().parent / "data"
ORDERS = (2.0, 4.0, 6.0)
THETA = {2.0: 0.004, 4.0: 0.0015, 6.0: 0.0006}
PHASE = {2.0: 30.0, 4.0: -50.0, 6.0: 100.0}


def mean_angle(t):
    """ψ(t) of a run-up 1200 → 1800 rpm over 6 s [rad], and Ω(t) [rad/s]."""
    w0, w1, T = 1200 * math.pi / 30, 1800 * math.pi / 30, 6.0
    return w0 * t + 0.5 * (w1 - w0) / T * t ** 2, w0 + (w1 - w0) / T * t


def speed_at(t):
    """The shaft speed [rpm] of ``ψ + Σ θ_k cos(kψ − φ_k)`` at times ``t``."""
    psi, om = mean_angle(t)
    d = 1.0 - sum(THETA[k] * k * np.sin(k * psi - np.deg2rad(PHASE[k])) for k in ORDERS)
    return om * d * 30 / math.pi


def angle_at(t):
    psi, _ = mean_angle(t)
    return psi + sum(THETA[k] * np.cos(k * psi - np.deg2rad(PHASE[k])) for k in ORDERS)


def uniform(rate=5000.0):
    return np.arange(0.0, 6.0, 1.0 / rate)


def write(path: Path, header: list[str], cols, fmt="{:.10g}", delim=",", decimal=".",
          before: list[str] = (), encoding="utf-8") -> Path:
    rows = [delim.join(fmt.format(v).replace(".", decimal) for v in row) for row in zip(*cols)]
    path.write_text("\n".join(list(before) + [delim.join(header)] + rows) + "\n",
                    encoding=encoding)
    return path


@pytest.fixture(scope="module")
def clean(tmp_path_factory):
    t = uniform()
    path = write(tmp_path_factory.mktemp("clean") / "clean.csv", ["time_s", "speed_rpm"],
                 [t, speed_at(t)])
    return OrderMap.from_csv(path, ORDERS, 200.0)


def assert_same_orders(omap, clean, rtol=0.005):
    assert omap.rpm.size == clean.rpm.size
    np.testing.assert_allclose(omap.rpm, clean.rpm, rtol=1e-3)
    np.testing.assert_allclose(omap.amplitude_rad, clean.amplitude_rad, rtol=rtol)


def test_the_clean_file_holds_the_orders_it_was_made_with(clean):
    """The clean run-up gives each order's θ_k within 1 %: the reference the quirks are held to."""
    for j, k in enumerate(ORDERS):
        np.testing.assert_allclose(clean.amplitude_rad[:, j], THETA[k], rtol=0.01)
    assert clean.detected.delimiter == "," and clean.detected.speed_unit == "rpm"
    assert clean.detected.sample_rate_hz == pytest.approx(5000.0)


QUIRKS = {
    "semicolon, decimal comma": dict(header=["Zeit [s]", "Drehzahl [1/min]"], delim=";",
                                     decimal=","),
    "tab": dict(header=["time_s", "speed_rpm"], delim="\t"),
    "spaces": dict(header=["t", "rpm"], delim=" "),
    "units row": dict(header=["Time", "Speed"], before=(), units=["s", "rpm"]),
    "bracketed headers": dict(header=["Time [s]", "Speed [rpm]"]),
    "parentheses, n [1/min], BOM, comments": dict(header=["t (s)", "n [1/min]"], bom=True,
                                                   before=["# DAQ export", "# channel 3"]),
    "rad/s": dict(header=["time_s", "omega [rad/s]"], scale=math.pi / 30),
    "rad/s by underscore": dict(header=["time_s", "speed_rad_s"], scale=math.pi / 30),
    "Hz": dict(header=["time_s", "f [Hz]"], scale=1 / 60),
    "extra columns": dict(header=["channel", "time_s", "torque", "speed_rpm"], extra=True),
}


@pytest.mark.parametrize("quirk", list(QUIRKS))
def test_each_quirk_reads_to_the_orders_of_the_clean_file(tmp_path, clean, quirk):
    """A file written with one quirk of a DAQ export gives the clean file's orders to 0.5 %,
    and says what it detected."""
    q = QUIRKS[quirk]
    t = uniform()
    w = speed_at(t) * q.get("scale", 1.0)
    cols = [t, w]
    header = list(q["header"])
    if q.get("extra"):
        cols = [np.full(t.size, 3.0), t, np.sin(t), w]
    before = list(q.get("before", ()))
    delim = q.get("delim", ",")
    path = tmp_path / "q.csv"
    write(path, header, cols, delim=delim, decimal=q.get("decimal", "."), before=before)
    if "units" in q:
        lines = path.read_text().split("\n")
        lines.insert(1, delim.join(q["units"]))
        path.write_text("\n".join(lines))
    if q.get("bom"):
        path.write_bytes(b"\xef\xbb\xbf" + path.read_bytes())
    omap = OrderMap.from_csv(path, ORDERS, 200.0)
    assert_same_orders(omap, clean)
    d = omap.detected
    assert d.delimiter == delim and d.decimal == q.get("decimal", ".")
    assert d.rows == t.size and d.warnings == ()
    assert d.units_row == ("units" in q)
    text = "\n".join(d.describe())
    assert "samples over" in text and "5000 Hz" in text


def test_rad_s_under_an_rpm_header_is_warned_about_and_read_with_speed_unit(tmp_path, clean):
    """rad/s values under a ``speed_rpm`` header (a mean of 39 where rpm would be 375, or of 157
    where it would be 1500) get a warning, not a refusal; ``speed_unit="rad/s"`` reads them to
    the clean file's orders."""
    t = uniform()
    path = write(tmp_path / "m.csv", ["time_s", "speed_rpm"], [t, speed_at(t) * math.pi / 30 / 4])
    meas = read_measurement(path)
    assert len(meas.detected.warnings) == 1
    assert "mean of 39.27 rpm" in meas.detected.warnings[0]
    assert "as rad/s it would be 375 rpm" in meas.detected.warnings[0]
    path = write(tmp_path / "m2.csv", ["time_s", "speed_rpm"], [t, speed_at(t) * math.pi / 30])
    assert OrderMap.from_csv(path, ORDERS, 200.0).detected.warnings != ()
    omap = OrderMap.from_csv(path, ORDERS, 200.0, speed_unit="rad/s")
    assert omap.detected.warnings == () and omap.detected.speed_unit == "rad/s"
    assert_same_orders(omap, clean)


def test_explicit_columns_override_the_guess(tmp_path, clean):
    """Columns no rule recognises are read when named; a name not in the header is refused
    naming the header's columns."""
    t = uniform()
    path = write(tmp_path / "m.csv", ["a", "b"], [t, speed_at(t)])
    with pytest.raises(ValueError, match=r"m.csv, line 1: no time column recognised.*--time-column"):
        OrderMap.from_csv(path, ORDERS, 200.0)
    omap = OrderMap.from_csv(path, ORDERS, 200.0, time_column="a", speed_column="b")
    assert_same_orders(omap, clean)
    with pytest.raises(ValueError, match=r"speed_column = 'c' is not a column of the header; its "
                                         r"columns are 'a', 'b'"):
        OrderMap.from_csv(path, ORDERS, 200.0, time_column="a", speed_column="c")


@pytest.mark.parametrize("kind", ["non-uniform", "jitter"])
def test_irregular_sampling_is_resampled_and_reported(tmp_path, clean, kind):
    """A sampling whose step varies by ±8 %, and ±20 µs of timestamp jitter at 10 kHz, are
    resampled to a uniform grid (and the report says how many steps), to the clean orders."""
    rng = np.random.default_rng(4)
    if kind == "jitter":
        t = uniform(10_000.0) + rng.uniform(-20e-6, 20e-6, 60_000)
        t[0] = 0.0
        rate = "10 kHz"
    else:
        steps = 2e-4 * (1 + 0.08 * np.sin(np.arange(31_000) * 0.37))
        t = np.concatenate([[0.0], np.cumsum(steps)])
        t = t[t < 6.0]
        rate = "4.999 kHz"
    path = write(tmp_path / "m.csv", ["time_s", "speed_rpm"], [t, speed_at(t)])
    omap = OrderMap.from_csv(path, ORDERS, 200.0)
    assert omap.detected.resampling.startswith("resampled ")
    assert "irregular steps to " + rate in omap.detected.resampling
    assert_same_orders(omap, clean)


def test_a_true_gap_is_still_refused_with_its_line(tmp_path):
    """A gap of 2 steps in jittered sampling is refused at its line, suggesting a window."""
    t = uniform()
    t = np.delete(t, [1000, 1001])
    path = write(tmp_path / "m.csv", ["time_s", "speed_rpm"], [t, speed_at(t)])
    with pytest.raises(ValueError, match=r"m.csv, line 1002: a gap of .*from_s/to_s"):
        OrderMap.from_csv(path, ORDERS, 200.0)


def test_a_time_window_analyses_part_of_the_file(tmp_path, clean):
    """from_s/to_s keep the samples between them: the bins outside are gone, the ones inside
    agree with the whole file's."""
    t = uniform()
    path = write(tmp_path / "m.csv", ["time_s", "speed_rpm"], [t, speed_at(t)])
    omap = OrderMap.from_csv(path, ORDERS, 200.0, from_s=2.0, to_s=6.0)
    assert omap.rpm[0] > 1350 and any("analysed 2 to" in n for n in omap.detected.notes)
    i = np.searchsorted(clean.rpm, omap.rpm[1])
    np.testing.assert_allclose(omap.amplitude_rad[1], clean.amplitude_rad[i], rtol=0.01)
    with pytest.raises(ValueError, match="from_s = 3 must be below to_s = 2"):
        OrderMap.from_csv(path, ORDERS, 200.0, from_s=3.0, to_s=2.0)


def test_an_order_is_analysed_where_the_sampling_resolves_it():
    """At 2 kHz order 6 has 20 samples per cycle up to 1000 rpm: in a run-up 800 → 1400 rpm it
    is analysed below that and NaN above, with a notice of its range; the other orders are
    analysed everywhere, and the verdict's check refuses order 6 at 1300 rpm naming its range."""
    t = np.arange(0.0, 12.0, 1 / 2000)
    rpm = 800 + 50 * t
    psi = np.cumsum(rpm) / 2000 * math.pi / 30
    w = rpm * (1 - 0.003 * 2 * np.sin(2 * psi) - 0.001 * 6 * np.sin(6 * psi))
    omap = OrderMap.from_arrays(t, w, (2, 6), 100.0)
    assert np.all(np.isfinite(omap.amplitude_rad[:, 0]))
    ok = np.isfinite(omap.amplitude_rad[:, 1])
    assert ok[0] and not ok[-1] and omap.rpm[ok].max() < 1000 < omap.rpm[~ok].min() + 100
    np.testing.assert_allclose(omap.amplitude_rad[ok, 1], 0.001, rtol=0.02)
    assert len(omap.notices) == 1 and omap.notices[0].startswith("order 6 is analysed from")
    back = OrderMap.from_table(omap.to_frame())
    np.testing.assert_array_equal(np.isnan(back.amplitude_rad), np.isnan(omap.amplitude_rad))
    lo, hi = omap.covered(6)
    omap.check_covers([2, 6], [lo + 1, hi - 1])
    with pytest.raises(ValueError, match=rf"order 6 is needed at 1300 rpm, but the measurement "
                                         rf"\(arrays\) resolves it at {lo:.0f} to {hi:.0f} rpm only"):
        omap.at(1300.0, [2, 6])


def pulse_times(ppr: int, t_end: float = 6.0) -> np.ndarray:
    fine = np.arange(0.0, t_end, 2e-6)
    a = angle_at(fine)
    targets = np.arange(math.ceil(a[0] * ppr / (2 * math.pi)),
                        int(a[-1] * ppr / (2 * math.pi)) + 1) * (2 * math.pi / ppr)
    return np.interp(targets, a, fine)


def test_pulses_at_60_per_rev_give_the_orders_they_were_made_from(tmp_path):
    """Pulse times of a shaft with known orders, 60 per revolution, give θ_2, θ_4, θ_6 within
    1 % (order 6 is a tenth of the pulse rate: the pulse-long average is divided out); as a
    sampled tachometer signal, the same; order 16 is above the 15 the pulses resolve."""
    p = pulse_times(60)
    path = tmp_path / "p.csv"
    path.write_text("pulse_s\n" + "\n".join(f"{v:.10f}" for v in p) + "\n")
    omap = OrderMap.from_csv(path, ORDERS, 200.0, pulse_column="pulse_s", pulses_per_rev=60)
    for j, k in enumerate(ORDERS):
        np.testing.assert_allclose(omap.amplitude_rad[:, j], THETA[k], rtol=0.01)
    assert omap.detected.pulses_per_rev == 60 and "orders up to 15" in " ".join(omap.detected.notes)
    with pytest.raises(ValueError, match=r"order 16 is above the highest order the pulses resolve, 15"):
        OrderMap.from_csv(path, (2, 16), 200.0, pulse_column="pulse_s", pulses_per_rev=60)
    # the same pulses as a 0/5 V square wave sampled at 200 kHz
    t = np.arange(0.0, 6.0, 5e-6)
    level = np.where((np.searchsorted(p, t) % 2) == 1, 5.0, 0.0)
    sig = tmp_path / "s.csv.gz"
    import gzip
    with gzip.open(sig, "wt") as f:
        f.write("time_s,tacho_V\n")
        f.write("\n".join(f"{a:.6f},{b:g}" for a, b in zip(t, level)))
    omap2 = OrderMap.from_csv(sig, ORDERS, 200.0, pulse_column="tacho_V", pulses_per_rev=30)
    np.testing.assert_allclose(omap2.amplitude_rad[:, 0], THETA[2.0], rtol=0.02)


def test_one_pulse_per_rev_resolves_only_slow_orders(tmp_path):
    """One pulse per revolution gives the mean speed, resolves orders up to 0.25 (an order-0.25
    fluctuation is found within 5 %), and refuses order 2 naming the limit."""
    t_end = 120.0
    fine = np.arange(0.0, t_end, 2e-5)
    psi = 1500 * math.pi / 30 * fine
    a = psi + 0.05 * np.cos(0.25 * psi)
    p = np.interp(np.arange(1, int(a[-1] / (2 * math.pi))) * 2 * math.pi, a, fine)
    path = tmp_path / "p.csv"
    path.write_text("time_s,pulse\n" + "\n".join(f"{v:.9f},{v:.9f}" for v in p) + "\n")
    with pytest.raises(ValueError, match=r"order 2 is above the highest order the pulses "
                                         r"resolve, 0.25"):
        OrderMap.from_csv(path, (2,), 100.0, pulse_column="pulse", pulses_per_rev=1)
    omap = OrderMap.from_csv(path, (0.25,), 100.0, pulse_column="pulse", pulses_per_rev=1)
    assert omap.rpm == pytest.approx([1500.0], rel=1e-3)
    assert omap.amplitude_rad[0, 0] == pytest.approx(0.05, rel=0.05)


def test_the_campbell_peak_lies_at_the_dominant_order(tmp_path):
    """The Campbell data's strongest order, over all speeds, is order 2, the largest θ_k; and at
    order 2 the level is 20 log10 θ_2 within 1 dB."""
    t = uniform()
    path = write(tmp_path / "m.csv", ["time_s", "speed_rpm"], [t, speed_at(t)])
    data = campbell(read_measurement(path), ORDERS, 200.0)
    assert data.dominant_order() == 2.0
    j = int(np.argmin(np.abs(data.orders - 2.0)))
    np.testing.assert_allclose(data.level_db[:, j], 20 * np.log10(THETA[2.0]), atol=1.0)
    assert data.level_db.shape == (data.rpm.size, data.orders.size)


def test_the_excitation_keys_are_checked():
    """A settings table's reading keys are checked and returned; others are left alone."""
    assert measurement_options({"speed_unit": "Hz", "from_s": 1, "harmonics": 3}) == \
        {"speed_unit": "Hz", "from_s": 1.0}
    with pytest.raises(ValueError, match=r"\[excitation\] speed_unit = 'rpms' is not a known unit"):
        measurement_options({"speed_unit": "rpms"}, "[excitation]")
    with pytest.raises(ValueError, match="pulse_column and pulses_per_rev go together"):
        measurement_options({"pulse_column": "p"})


@pytest.mark.parametrize("content, message", [
    (b"time_s,speed_rpm\n0,1500\n0.001,15\x0000\n", r"h.csv, line 3: a NUL byte; a measurement is a text file"),
    (b"time_s,speed_rpm\n0,1500\n" + b"1" * 70_000 + b"\n", r"h.csv, line 3: a line of over 65536 bytes"),
    (b"time_s,speed_rpm\n\x89PNG\x01\x02", r"h.csv, line 2: the byte 0x01"),
    (b"time_s,speed_rpm\n0,1500\n" + b"\n# c\n" * 60, r"h.csv, line 103: more than 102 lines \(blank and comment"),
])
def test_hostile_files_are_refused_naming_the_line(tmp_path, content, message):
    """NUL bytes, binary bytes, over-long lines, and blank and comment lines over the row limit
    are each refused naming the file and the line."""
    path = tmp_path / "h.csv"
    path.write_bytes(content)
    with pytest.raises(ValueError, match=message):
        read_measurement(path, max_rows=100)


BOMB = r"""
import gzip, sys, time
path, kind = sys.argv[1], sys.argv[2]
unit = {"lines": b"0.001,1500\n", "line": b"1" * 1024}[kind]
block = unit * ((1 << 20) // len(unit))
with gzip.open(path, "wb", compresslevel=1) as f:
    for _ in range(1024):            # about 1 GB decompressed
        f.write(block)
from rattle_core.measure.orders import OrderMap
import pandas, scipy.interpolate


def peak_mb():
    # this process's own peak resident memory (ru_maxrss would count the forking parent's)
    for line in open("/proc/self/status"):
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) / 1024


print("BASE_MB", peak_mb())
start = time.process_time()
try:
    OrderMap.from_csv(path)
except ValueError as exc:
    print("REFUSED", exc)
print("CPU", time.process_time() - start)
print("RSS_MB", peak_mb())
"""


@pytest.mark.parametrize("kind, message", [("lines", "more than 5000002 lines"),
                                           ("line", "a line of over 65536 bytes")])
def test_a_gzip_bomb_is_refused_within_seconds_with_bounded_memory(tmp_path, kind, message):
    """A gzip file that decompresses to about 1 GB (rows, or one endless line) is refused after
    reading a bounded part of it: under 10 CPU-seconds, and under 150 MB of memory beside the
    interpreter with its libraries loaded."""
    r = subprocess.run([sys.executable, "-c", BOMB, str(tmp_path / "bomb.csv.gz"), kind],
                       capture_output=True, text=True, cwd=ROOT, timeout=300)
    out = dict(line.split(" ", 1) for line in r.stdout.strip().splitlines())
    assert message in out["REFUSED"], r.stdout + r.stderr
    assert float(out["CPU"]) < 10.0, r.stdout
    assert float(out["RSS_MB"]) - float(out["BASE_MB"]) < 150.0, r.stdout


def test_cli_orders_reads_a_semicolon_file_and_draws_the_campbell_diagram(tmp_path):
    """``rattle orders`` on a `;`/decimal-comma file prints what it detected, writes the table
    and the Campbell PNG; --speed-unit and --from-s are passed on."""
    t = uniform()
    path = write(tmp_path / "m.csv", ["Zeit [s]", "Drehzahl [1/min]"], [t, speed_at(t)], delim=";",
                 decimal=",")
    run = [sys.executable, "-m", "rattle_cli", "orders", str(path), "--rpm-step", "200",
           "--out", str(tmp_path / "o.csv"), "--campbell", str(tmp_path / "c.png"),
           "--from-s", "1", "--speed-unit", "rpm"]
    r = subprocess.run(run, capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert r.returncode == 0, r.stderr
    assert "semicolon-separated, decimal mark ','" in r.stdout
    assert "analysed 1 to" in r.stdout
    assert (tmp_path / "c.png").stat().st_size > 5000


def test_a_gearbox_file_reads_its_measurement_with_the_excitation_keys(tmp_path, clean):
    """A GEARBOX.toml's [excitation] passes speed_column, speed_unit and from_s to the reading:
    an unrecognised rad/s column is read to the clean orders; a bad unit is refused naming the
    key."""
    from rattle_core.model.gearbox import Gearbox
    t = uniform()
    write(tmp_path / "m.csv", ["time_s", "w"], [t, speed_at(t) * math.pi / 30], delim=";",
          decimal=",")
    gear = ('[[gear]]\nname = "g"\ninertia_kgm2 = 4e-4\nbase_radius_m = 0.035\n'
            'drag_torque_Nm = 0.05\nbacklash_um = 80\n')
    exc = ('[excitation]\nmeasurement = "m.csv"\nengine_order = 2\nharmonics = 3\nrpm_step = 200\n'
           'speed_column = "w"\nspeed_unit = "{unit}"\n')
    (tmp_path / "g.toml").write_text(exc.format(unit="rad/s") + gear)
    omap = Gearbox.from_toml(tmp_path / "g.toml").excitation.order_map
    assert_same_orders(omap, clean)
    (tmp_path / "g.toml").write_text(exc.format(unit="rpms") + gear)
    with pytest.raises(ValueError, match=r"speed_unit = 'rpms' is not a known unit"):
        Gearbox.from_toml(tmp_path / "g.toml")


def test_a_verdict_needing_an_order_beyond_the_sampling_is_refused_naming_its_range():
    """The sample run-up (6410 Hz) resolves order 10 only up to 1923 rpm, order 18 up to 1068: a
    gearbox with 9 harmonics of order 2 is built, its gear is driven at 1000 rpm, and at 2000
    rpm it is refused naming order 10 and the speeds it was analysed at (bins to 1800 rpm)."""
    from rattle_core.model.gearbox import Gearbox
    text = ('[excitation]\nmeasurement = "sample"\nengine_order = 2\nharmonics = 9\n'
            '[[gear]]\nname = "g"\ninertia_kgm2 = 4e-4\nbase_radius_m = 0.035\n'
            'drag_torque_Nm = 0.05\nbacklash_um = 80\n')
    box = Gearbox.from_text(text)
    assert any(n.startswith("order 18 is analysed from") for n in box.excitation.order_map.notices)
    box.physical(0, 1000.0)
    with pytest.raises(ValueError, match=r"order 10 is needed at 2000 rpm, but the measurement "
                                         r"\(runup_4cyl_synthetic.csv.gz\) resolves it at 975 "
                                         r"to 1800 rpm only"):
        box.physical(0, 2000.0)


def test_the_shipped_daq_export_reads_to_its_order():
    """tests/data's DAQ export (BOM, comment, `;`, decimal commas, a units row, German names)
    is read as such and gives order 2's 4 mrad and 30° it was written with."""
    omap = OrderMap.from_csv(DATA / "daq_semicolon_decimal_comma.csv", (2,), 100.0)
    d = omap.detected
    assert (d.delimiter, d.decimal, d.units_row, d.speed_unit) == (";", ",", True, "rpm")
    assert (d.time_column, d.speed_column) == ("Zeit", "Drehzahl")
    assert omap.amplitude_rad[0, 0] == pytest.approx(0.004, rel=0.01)
    assert omap.phase_deg[0, 0] == pytest.approx(30.0, abs=1.0)
