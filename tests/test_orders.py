"""Order analysis of a measured speed: accuracy on signals with known orders, refusals, files.

The synthetic signals are written here from the convention alone: the mean angle ``ψ(t)`` is
integrated from the mean speed, the fluctuation is ``θ = Σ θ_k cos(k ψ − φ_k)``, and the
measured speed is ``ψ̇ + θ̇`` with ``θ̇`` differentiated analytically, plus white noise of 1 %
of the fluctuation's standard deviation.
"""
from __future__ import annotations

import gzip
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from rattle_core.model import orders as om
from rattle_core.model.orders import OrderMap

ROOT = Path(__file__).resolve().parent.parent
SAMPLE = ROOT / "rattle_core" / "assets" / "measurements" / "runup_4cyl_synthetic.csv.gz"
ORDERS = (2.0, 4.0, 6.0)
PHASES = (30.0, -100.0, 60.0)


def synthetic(rpm0: float, rpm1: float, duration: float, rate: float, amps, phases=PHASES,
              noise: float = 0.01, seed: int = 3, accel: bool = False):
    """``(t, speed_rpm, θ_k(rpm))``: a linear speed ramp with orders 2, 4, 6.

    ``amps`` are displacement amplitudes θ_k [rad], or with ``accel`` acceleration amplitudes
    α_k [rad/s²] held over the ramp (then ``θ_k = α_k / (k Ω)²``)."""
    t = np.arange(int(duration * rate)) / rate
    w0 = rpm0 * 2 * math.pi / 60
    a = (rpm1 - rpm0) * 2 * math.pi / 60 / duration
    psi = w0 * t + 0.5 * a * t * t
    omega = w0 + a * t
    dtheta = np.zeros_like(t)
    for k, amp, ph in zip(ORDERS, amps, phases):
        th = amp / (k * omega) ** 2 if accel else amp * np.ones_like(t)
        dth_dt = -2 * amp * a / (k * k * omega ** 3) if accel else 0.0
        arg = k * psi - math.radians(ph)
        dtheta += dth_dt * np.cos(arg) - th * k * omega * np.sin(arg)
    rng = np.random.default_rng(seed)
    speed = omega + dtheta + noise * np.std(dtheta) * rng.standard_normal(t.size)

    def truth(rpm):
        om_ = np.asarray(rpm)[:, None] * 2 * math.pi / 60
        k = np.asarray(ORDERS)[None, :]
        return np.asarray(amps)[None, :] / (k * om_) ** 2 if accel else \
            np.broadcast_to(np.asarray(amps)[None, :], (len(rpm), 3))
    return t, speed * 60 / (2 * math.pi), truth


def phase_error(a, b):
    return (np.asarray(a) - np.asarray(b) + 180.0) % 360.0 - 180.0


def test_steady_speed_orders_within_one_percent_and_one_degree():
    """A steady 1500 rpm signal with 1 % noise: every amplitude within 1 %, φ4 − 2φ2 within 1°."""
    amps = (2e-3, 5e-4, 1e-4)
    t, w, _ = synthetic(1500, 1500, 4.0, 6000, amps)
    m = OrderMap.from_arrays(t, w, ORDERS)
    assert m.rpm.size == 1 and abs(m.rpm[0] - 1500) < 0.5
    assert np.all(np.abs(m.amplitude_rad[0] / amps - 1) < 0.01), m.amplitude_rad
    k = np.asarray(ORDERS)
    alpha = np.asarray(amps) * (k * 1500 * 2 * math.pi / 60) ** 2
    assert np.all(np.abs(m.accel_rad_s2[0] / alpha - 1) < 0.01)
    rel = phase_error(m.phase_deg[0, 1] - 2 * m.phase_deg[0, 0], PHASES[1] - 2 * PHASES[0])
    assert abs(rel) < 1.0
    assert np.all(np.abs(phase_error(m.phase_deg[0], PHASES)) < 1.0)


def test_run_up_orders_within_one_percent_and_one_degree_in_every_bin():
    """A run-up 1000 → 3000 rpm in 30 s, acceleration amplitudes held (θ_k ∝ 1/rpm²), 1 % noise:
    every bin's amplitudes within 1 % of the truth at the bin's speed, φ4 − 2φ2 within 1°."""
    alphas = (300.0, 120.0, 40.0)
    t, w, truth = synthetic(1000, 3000, 30.0, 6400, alphas, accel=True)
    m = OrderMap.from_arrays(t, w, ORDERS, rpm_step=100)
    assert m.rpm.size >= 19 and m.rpm[0] < 1100 and m.rpm[-1] > 2900
    assert np.all(np.abs(m.amplitude_rad / truth(m.rpm) - 1) < 0.01)
    assert np.all(np.abs(m.accel_rad_s2 / np.asarray(alphas)[None, :] - 1) < 0.01)
    rel = phase_error(m.phase_deg[:, 1] - 2 * m.phase_deg[:, 0], PHASES[1] - 2 * PHASES[0])
    assert np.all(np.abs(rel) < 1.0), rel


def test_interpolation_between_bins_and_across_the_phase_wrap():
    """Halfway between two bins the amplitude is the mean; a phase crossing ±180° goes the short
    way; a speed outside the measured range is refused."""
    m = OrderMap(rpm=np.array([1000.0, 1100.0]), orders=np.array([2.0]),
                 amplitude_rad=np.array([[1e-3], [3e-3]]), accel_rad_s2=np.array([[1.0], [1.0]]),
                 phase_deg=np.array([[170.0], [-170.0]]), rpm_step=100.0)
    amp, ph = m.at([1050.0])
    assert amp[0, 0] == pytest.approx(2e-3) and abs(ph[0, 0]) == pytest.approx(180.0)
    amp, _ = m.at([960.0])
    assert amp[0, 0] == pytest.approx(1e-3)
    with pytest.raises(ValueError, match="rpm = 900.0 is outside the measured range"):
        m.at([900.0])
    with pytest.raises(ValueError, match="order 4 is not in the order map"):
        m.at([1000.0], [4.0])
    theta, phase = m.harmonics([1000.0], 2.0, 1, scale=2.0)
    assert theta[0, 0] == pytest.approx(2e-3) and phase[0, 0] == pytest.approx(170.0)


def test_table_round_trip(tmp_path):
    """An order map written as a table and read back (OrderMap.read) is the same map."""
    t, w, _ = synthetic(1500, 1800, 6.0, 6000, (2e-3, 5e-4, 1e-4))
    m = OrderMap.from_arrays(t, w, ORDERS)
    path = tmp_path / "orders.csv"
    m.to_frame().to_csv(path, index=False)
    back = OrderMap.read(path)
    np.testing.assert_allclose(back.rpm, m.rpm)
    np.testing.assert_allclose(back.amplitude_rad, m.amplitude_rad)
    np.testing.assert_allclose(back.phase_deg, m.phase_deg)


def write(tmp_path, text: str, name: str = "m.csv") -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


def steady_lines(n: int = 2000, rate: float = 4000.0, rpm: float = 1500.0) -> list[str]:
    return [f"{i / rate:.6f},{rpm + 2 * math.sin(4 * math.pi * i * rpm / 60 / rate):.4f}"
            for i in range(n)]


@pytest.mark.parametrize("mutate, message", [
    (lambda L: ["time,speed"] + L, r"line 1: the header lacks the column\(s\) time_s, speed_rpm"),
    (lambda L: ["time_s,speed_rpm"] + L[:99] + ["0.01,1500"] + L[100:],
     r"line 101: time_s = 0.01 does not increase"),
    (lambda L: ["time_s,speed_rpm"] + L[:500] + L[520:], r"line 502: a gap of"),
    (lambda L: ["time_s,speed_rpm"] + L[:40] + ["0.01025,nan"] + L[42:],
     r"line 42: speed_rpm = nan is not a finite number"),
    (lambda L: ["time_s,speed_rpm"] + L[:7] + ["0.00175,fast"] + L[8:],
     r"line 9: time_s and speed_rpm must be numbers"),
])
def test_bad_files_are_refused_with_the_line_at_fault(tmp_path, mutate, message):
    """Missing columns, time going back, a gap, NaN and text each name their line."""
    path = write(tmp_path, "\n".join(mutate(steady_lines())) + "\n")
    with pytest.raises(ValueError, match=message):
        OrderMap.from_csv(path)


def test_too_few_samples_per_cycle_names_the_line(tmp_path):
    """Sampled at 1000 Hz, order 6 at 1500 rpm (150 Hz) has under 20 samples per cycle."""
    lines = ["# a comment", "time_s,speed_rpm"] + steady_lines(rate=1000.0)
    path = write(tmp_path, "\n".join(lines) + "\n")
    with pytest.raises(ValueError, match=r"line 3: at 1500[.\d]* rpm the sampling gives 6\.67 "
                                         r"samples per cycle of order 6"):
        OrderMap.from_csv(path)
    assert OrderMap.from_csv(path, orders=(0.5,)).orders.tolist() == [0.5]


def test_a_bin_with_under_four_revolutions_is_refused(tmp_path):
    """A jump through the 1600 rpm bin in well under four revolutions is refused with its
    lines; the same file analysed in 400 rpm bins passes."""
    rate = 6000.0
    t = np.arange(int(3.0 * rate)) / rate
    rpm = np.where(t < 1.4, 1500.0, np.where(t < 1.45, 1500 + 200 * (t - 1.4) / 0.05, 1700.0))
    rows = ["time_s,speed_rpm"] + [f"{a:.6f},{b:.4f}" for a, b in zip(t, rpm)]
    path = write(tmp_path, "\n".join(rows) + "\n")
    with pytest.raises(ValueError, match=r"line \d+ to line \d+: the 1600 rpm bin holds "
                                         r"\d\.\d\d revolutions; at least 4"):
        OrderMap.from_csv(path)
    assert OrderMap.from_csv(path, rpm_step=400).rpm.size >= 1


def test_an_absurd_size_is_refused_before_reading(tmp_path, monkeypatch):
    """A file over the byte limit is refused whole; so is one over the row limit, at its line."""
    path = write(tmp_path, "\n".join(["time_s,speed_rpm"] + steady_lines()) + "\n")
    monkeypatch.setattr(om, "MAX_BYTES", 1000)
    with pytest.raises(ValueError, match=r"has \d+ bytes; the allowed size is up to 1000 bytes"):
        OrderMap.from_csv(path)
    monkeypatch.setattr(om, "MAX_BYTES", 10**9)
    monkeypatch.setattr(om, "MAX_ROWS", 100)
    with pytest.raises(ValueError, match=r"line 102: more than 100 samples"):
        OrderMap.from_csv(path)


def test_the_shipped_sample_is_labelled_synthetic_and_holds_its_orders():
    """The sample run-up says it is synthetic, and its order-2 acceleration follows the law it
    was made with (120 → 300 rad/s² over 1000 → 3000 rpm) within the 5 % cycle-to-cycle
    variation's scatter; its phases are the made ones."""
    with gzip.open(SAMPLE, "rt") as f:
        assert "SYNTHETIC" in f.readline()
    m = OrderMap.from_csv(SAMPLE)
    law = 120.0 + 180.0 * (m.rpm - 1000.0) / 2000.0
    assert np.all(np.abs(m.accel_rad_s2[:, 0] / law - 1) < 0.03)
    assert np.all(np.abs(phase_error(m.phase_deg[:, 0], 20.0)) < 1.0)
    assert np.all(np.abs(phase_error(m.phase_deg[:, 1], -60.0)) < 3.0)


def test_cli_orders_writes_the_table_and_refuses_a_bad_file(tmp_path):
    """``rattle orders`` writes one row per bin and order; a bad file exits 2 with one line."""
    out = tmp_path / "orders.csv"
    run = [sys.executable, "-m", "rattle_cli", "orders"]
    r = subprocess.run(run + [str(SAMPLE), "--orders", "2,4", "--rpm-step", "200", "--out",
                              str(out), "--png"], capture_output=True, text=True, cwd=ROOT,
                       timeout=300)
    assert r.returncode == 0, r.stderr
    import pandas as pd
    df = pd.read_csv(out)
    assert list(df.columns) == ["rpm", "order", "amplitude_rad", "accel_rad_s2", "phase_deg"]
    assert sorted(set(df["order"])) == [2.0, 4.0] and len(df) == 2 * df["rpm"].nunique()
    assert (tmp_path / "orders.png").stat().st_size > 1000
    bad = write(tmp_path, "time_s,speed\n0,1\n")
    r = subprocess.run(run + [str(bad), "--out", str(tmp_path / "b.csv")], capture_output=True,
                       text=True, cwd=ROOT, timeout=300)
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "line 1" in r.stderr


# ----- the streamed reader and analysis against the slow reference (tests/naive_orders.py) ---

def test_analysis_equals_the_in_memory_reference_on_a_run_down():
    """An independent 40 s run-down 3200 → 900 rpm with its own orders and phases: the
    blocked, compiled analysis gives the reference's rpm, amplitudes and phases to rounding
    (1e-9, far inside 0.3 % and 0.3°)."""
    import naive_orders
    t, w, _ = synthetic(3200, 900, 40.0, 8000, (250.0, 90.0, 30.0), phases=(-45.0, 120.0, 10.0),
                        seed=11, accel=True)
    m = OrderMap.from_arrays(t, w, ORDERS, rpm_step=100)
    ref = naive_orders.analyse(t, w, ORDERS, 100.0, "arrays", lambda i: f"sample {i}")
    assert m.rpm.size == ref.rpm.size >= 20
    np.testing.assert_allclose(m.rpm, ref.rpm, rtol=1e-12)
    np.testing.assert_allclose(m.amplitude_rad, ref.amplitude_rad, rtol=1e-9)
    np.testing.assert_allclose(m.accel_rad_s2, ref.accel_rad_s2, rtol=1e-9)
    assert np.max(np.abs(phase_error(m.phase_deg, ref.phase_deg))) < 1e-7


def test_noise_across_a_bin_edge_is_one_visit_of_the_bin():
    """Strong sensor noise carries a few samples back and forth across a bin's edge: the
    reference fits each such piece its own quadratic trend and fails (singular normal
    equations); here they belong to the visit, and the amplitudes stay within 3 %."""
    import naive_orders
    t, w, truth = synthetic(1420, 1580, 60.0, 6000, (300.0, 120.0, 40.0), accel=True, noise=0.3)
    with pytest.raises(np.linalg.LinAlgError):
        naive_orders.analyse(t, w, ORDERS, 100.0, "arrays", lambda i: f"sample {i}")
    m = OrderMap.from_arrays(t, w, ORDERS)
    assert m.rpm.size == 3
    assert np.all(np.abs(m.amplitude_rad / truth(m.rpm) - 1) < 0.03)


def messy_file(tmp_path, gz: bool = False) -> Path:
    """A measurement with comments, blank lines, CRLF ends, spaces, a quoted header, extra
    columns in another order, a comment-looking quoted field and a spelt-out number."""
    rows = steady_lines(400)
    body = []
    for i, row in enumerate(rows):
        a, b = row.split(",")
        if i == 10:
            body += ["# a comment between samples", "", "   ", " ,  ,"]
        if i == 20:
            body.append("  # an indented comment")
        body.append(f"{b} , x{i},{a}" if i % 7 else f" {b},\"q\",  {a} ")
    text = "\r\n".join(["# measured on the bench", "", '"speed_rpm", note ,"time_s"'] + body) + "\r\n"
    p = tmp_path / ("messy.csv.gz" if gz else "messy.csv")
    if gz:
        with gzip.open(p, "wt", newline="") as f:
            f.write(text)
    else:
        p.write_bytes(text.encode())
    return p


@pytest.mark.parametrize("gz", [False, True])
def test_reader_equals_the_row_by_row_reader(tmp_path, gz):
    """pandas' reader behind the line classification gives the csv module's row-by-row
    reading: the same numbers and the same line number for every sample."""
    import naive_orders
    path = messy_file(tmp_path, gz)
    t, w, lines = om.read_speed_csv(path)
    rt, rw, rlines = naive_orders.read_speed_csv(path)
    assert t.size == 400
    np.testing.assert_array_equal(t, rt)
    np.testing.assert_array_equal(w, rw)
    np.testing.assert_array_equal(lines, rlines)


@pytest.mark.parametrize("text, message", [
    ("time_s,speed_rpm\n0,1500\n0.001,\n", r"line 3: time_s and speed_rpm must be numbers, got '0.001,'"),
    ("time_s,speed_rpm\n0,1500\n0.001\n0.002,1500\n", r"line 3: time_s and speed_rpm must be numbers"),
    ("# c\ntime_s,speed_rpm\n0,1500\n\n# c\n0.001,1_5x\n", r"line 6: time_s and speed_rpm must be numbers"),
    ("time_s,speed_rpm,z\n0,1\n1,2\n", None),
    ("# only comments\n\n", r"holds no header line"),
])
def test_the_reader_names_the_line_the_row_by_row_reader_names(tmp_path, text, message):
    """Empty and missing fields and text name their line (as the row-by-row reader does), past
    blank lines and comments; a short but well-formed file is read."""
    import naive_orders
    path = write(tmp_path, text)
    if message is None:
        t, w, lines = om.read_speed_csv(path)
        assert t.tolist() == [0.0, 1.0] and w.tolist() == [1.0, 2.0] and lines.tolist() == [2, 3]
        return
    with pytest.raises(ValueError, match=message):
        om.read_speed_csv(path)
    with pytest.raises(ValueError, match=message):
        naive_orders.read_speed_csv(path)


def test_a_file_that_is_not_utf8_or_not_gzip_is_refused(tmp_path):
    """Bytes that are not UTF-8, and a .gz that is not gzip, are refused naming the file."""
    bad = tmp_path / "latin.csv"
    bad.write_bytes("time_s,speed_rpm\n0,1500 \xe9\n".encode("latin-1"))
    with pytest.raises(ValueError, match="latin.csv is not a UTF-8 text file"):
        OrderMap.from_csv(bad)
    fake = tmp_path / "fake.csv.gz"
    fake.write_bytes(b"time_s,speed_rpm\n")
    with pytest.raises(ValueError, match="fake.csv.gz cannot be read"):
        OrderMap.from_csv(fake)


def test_progress_rises_to_the_end_and_cancel_stops_the_analysis():
    """``progress`` counts up to PROGRESS_STEPS without going back; a ``cancel`` that turns
    True part-way raises AnalysisCancelled before the end."""
    seen: list[tuple[int, int]] = []
    m = OrderMap.from_csv(SAMPLE, progress=lambda d, n: seen.append((d, n)))
    done = [d for d, _ in seen]
    assert m.rpm.size > 10 and {n for _, n in seen} == {om.PROGRESS_STEPS}
    assert done == sorted(done) and done[0] == 0 and done[-1] == om.PROGRESS_STEPS and len(done) > 20
    calls = []

    def cancel() -> bool:
        calls.append(1)
        return len(calls) > 30
    with pytest.raises(om.AnalysisCancelled):
        OrderMap.from_csv(SAMPLE, cancel=cancel)
    assert len(calls) == 31


MEMORY_PROBE = """
import resource, sys
import numpy as np
from rattle_core.model.orders import OrderMap
OrderMap.from_csv(sys.argv[2])   # imports and compiled kernels loaded
base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
m = OrderMap.from_csv(sys.argv[1])
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
print(m.rpm.size, (peak - base) * 1024)
"""


def test_memory_of_a_large_steady_file_is_linear_and_small(tmp_path):
    """A million-row steady file (one rpm bin, 20 MB) in a fresh process: the peak resident
    memory grows by under 400 bytes per sample over the interpreter's.  The whole-matrix
    least squares needs over 1.2 kB per sample for that one bin (51 columns, three copies)."""
    n, rate = 1_000_000, 10_000.0
    t = np.arange(n) / rate
    psi = 1500 * 2 * math.pi / 60 * t
    speed = 1500 + 3 * np.sin(2 * psi) + np.random.default_rng(5).normal(0, 0.2, n)
    path = tmp_path / "steady.csv"
    with open(path, "w") as f:
        f.write("time_s,speed_rpm\n")
        np.savetxt(f, np.column_stack([t, speed]), fmt=["%.5f", "%.3f"], delimiter=",")
    assert path.stat().st_size > 15_000_000
    r = subprocess.run([sys.executable, "-c", MEMORY_PROBE, str(path), str(SAMPLE)],
                       capture_output=True, text=True, cwd=ROOT, timeout=600)
    assert r.returncode == 0, r.stderr
    bins, grown = r.stdout.split()
    assert int(bins) == 1
    assert int(grown) < 400 * n, f"{int(grown) / n:.0f} bytes per sample"


# ----- an uploaded measurement's own bounds (the dashboard's worker function) -----------------

def test_an_upload_has_its_own_size_row_and_time_bounds_told_about_the_file(monkeypatch):
    """The dashboard's measurement job refuses a file over 20 MB, over its row bound and over
    its own time bound, each with a message about the file (never the compute jobs' "fewer
    values or periods"); the server's websocket takes a 20 MB file base64-encoded, with room."""
    from app import main
    from app.views.gearbox import GearboxView
    from app.work import gearbox as work
    text = "\n".join(["time_s,speed_rpm"] + steady_lines(4000)).encode() + b"\n"
    assert work.measurement(text, ORDERS, 100.0).rpm.size == 1
    with pytest.raises(ValueError, match=r"the uploaded file has 20000001 bytes; the allowed "
                                         r"size is up to 20000000 bytes \(20 MB\)"):
        work.measurement(b"x" * 20_000_001, ORDERS, 100.0)
    monkeypatch.setattr(work, "MEASUREMENT_MAX_ROWS", 1000)
    with pytest.raises(ValueError, match=r"the uploaded file, line 1002: more than 1000 samples"):
        work.measurement(text, ORDERS, 100.0)
    monkeypatch.setattr(work, "MEASUREMENT_MAX_ROWS", 10**6)
    monkeypatch.setattr(work, "MEASUREMENT_SECONDS", 0.0)
    with pytest.raises(ValueError, match=r"the uploaded file took over 0 s to read and analyse"):
        work.measurement(text, ORDERS, 100.0)
    killed = GearboxView._file_error("stopped after 90 s, the time limit of one job on this "
                                     "server; try fewer values or periods")
    assert "the uploaded file took too long" in killed and "fewer values" not in killed
    assert main.WEBSOCKET_MAX_BYTES > 4 / 3 * work.MAX_MEASUREMENT_BYTES * 1.2
    assert work.MEASUREMENT_JOB_LIMIT > work.MEASUREMENT_SECONDS
