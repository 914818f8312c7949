"""The ``rattle`` command: files written and their contents, units, help, and one-line errors."""
from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest
from PIL import Image
from scipy.io import wavfile

import rattle_cli.commands.simulate as simulate_command
from rattle_cli.main import build_parser, main
from rattle_cli.options import build_params
from rattle_core import RattleParams, SolverError, simulate
from rattle_core.model.units import PhysicalParams, lam_from_rpm

#: The command as a checkout runs it; the installed script is tested in test_packaging.py.
RATTLE = [sys.executable, "-m", "rattle_cli"]
PHYS = ["--inertia", "2e-4", "--radius", "0.04", "--drag-torque", "0.02", "--backlash-um", "160",
        "--rpm", "1500", "--theta-amp", "5e-4,1.25e-4", "--theta-phase", "0,45"]
PHYS_OBJ = PhysicalParams(inertia=2e-4, radius=0.04, drag_torque=0.02, backlash=160e-6, rpm=1500.0,
                          amplitudes=(5e-4, 1.25e-4), phases_deg=(0.0, 45.0))


@pytest.fixture(autouse=True)
def private_cache(tmp_path, monkeypatch):
    """Every test gets its own sweep cache, so nothing leaks between tests or into ~/.cache."""
    monkeypatch.setenv("RATTLE_CACHE_DIR", str(tmp_path / "cache"))


def params_of(argv: list[str]):
    return build_params(build_parser().parse_args(["units", *argv]))


def run(argv: list[str], capsys) -> tuple[int, str, str]:
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err


# ----- parameters ------------------------------------------------------------------------

def test_three_harmonic_spellings_agree():
    """--harmonics, --harmonic K,H,PHI and --h2/--phi2 build the same RattleParams."""
    a, _ = params_of(["--lam", "2.5", "--harmonics", "1,0.25:0,45"])
    b, _ = params_of(["--lam", "2.5", "--harmonic", "2,0.25,45"])
    c, _ = params_of(["--lam", "2.5", "--h2", "0.25", "--phi2", "45"])
    expected = RattleParams(lam=2.5, amplitudes=(1.0, 0.25), phases_deg=(0.0, 45.0))
    assert a == b == c == expected
    d, _ = params_of(["--harmonics", "1,0.25,0.1:0,45,10", "--harmonic", "3,0.2,30", "--phi2", "90"])
    assert d.amplitudes == (1.0, 0.25, 0.2) and d.phases_deg == (0.0, 90.0, 30.0)
    assert d.lam == 3.3 and d.r == 0.65 and d.j == 8.0


def test_paper_phases_option_converts_to_core_convention():
    """--paper-phases reads φ2 in the paper's sin(kt + φ) reading, as RattleParams.paper does."""
    p, _ = params_of(["--lam", "3.3", "--h2", "0.25", "--phi2", "45", "--paper-phases"])
    assert p == RattleParams.paper(3.3, amplitudes=(1.0, 0.25), phases_deg=(0.0, 45.0))
    assert p.phases_deg[1] != 45.0


def test_physical_options_build_physical_params():
    """Physical options give the PhysicalParams of rattle_core.model.units and its dimensionless twin."""
    p, phys = params_of(PHYS + ["--r", "0.7"])
    assert phys == PHYS_OBJ.replace(r=0.7)
    assert p == PHYS_OBJ.replace(r=0.7).to_dimensionless()
    assert p.lam == pytest.approx(0.05 * math.pi**2, rel=1e-12)
    # Backlash as an angle at Rb, and accelerations instead of displacements.
    _, phys2 = params_of([a if a != "--backlash-um" else a for a in PHYS[:6]]
                         + ["--backlash-deg", str(math.degrees(4e-3)), "--rpm", "1500",
                            "--alpha-amp", "50", "--order", "3"])
    assert phys2.backlash == pytest.approx(160e-6, rel=1e-12)
    assert phys2.excitation == "acceleration" and phys2.order == 3.0


# ----- simulate --------------------------------------------------------------------------

def test_simulate_writes_impacts_and_history(tmp_path, capsys):
    """simulate writes exactly the solver's impacts (CSV) and a history inside the walls (Parquet)."""
    imp, hist = tmp_path / "imp.csv", tmp_path / "hist.parquet"
    code, out, err = run(["simulate", "--lam", "3.3", "--h2", "0.25", "--phi2", "45", "--periods", "40",
                          "--transient", "10", "--samples-per-period", "32",
                          "--impacts", str(imp), "--history", str(hist)], capsys)
    assert code == 0, err
    assert "wrote" in out
    tr = simulate(RattleParams(lam=3.3, amplitudes=(1.0, 0.25), phases_deg=(0.0, 45.0)),
                  periods=40, transient=10)
    df = pd.read_csv(imp)
    assert list(df.columns) == ["t", "phase", "impulse", "flank", "w"]
    assert len(df) == tr.impact_t.size > 0
    assert np.array_equal(df["t"].to_numpy(), tr.impact_t)
    assert np.array_equal(df["impulse"].to_numpy(), tr.impact_impulse)
    assert np.array_equal(df["flank"].map({"active": 1, "reverse": -1}).to_numpy(), tr.impact_flank)
    h = pd.read_parquet(hist)
    assert len(h) == 40 * 32 + 1
    assert h["t"].iloc[0] == pytest.approx(tr.t_start) and h["t"].iloc[-1] == pytest.approx(tr.t_end)
    assert np.all(h["x"] >= h["y"] - 1e-9) and np.all(h["x"] <= h["y_plus_j"] + 1e-9)
    x, _ = tr.sample(h["t"].to_numpy())
    assert np.allclose(h["x"], x, rtol=0, atol=1e-12)
    meta = json.loads(pq.read_schema(hist).metadata[b"rattle"])
    assert meta["params"]["lam"] == 3.3 and meta["params"]["phases_deg"] == [0.0, 45.0]


def test_simulate_in_physical_units_adds_seconds_and_newton_seconds(tmp_path, capsys):
    """In physical units impact rows carry t_s = t/ω and impulse_Ns = Ĩ m ω H1."""
    imp = tmp_path / "imp.parquet"
    code, _, err = run(["simulate", *PHYS, "--rpm", "4000", "--periods", "20", "--impacts", str(imp)],
                       capsys)
    assert code == 0, err
    phys = PHYS_OBJ.replace(rpm=4000.0)
    df = pd.read_parquet(imp)
    assert len(df) > 0
    assert np.allclose(df["t_s"], df["t"] / phys.omega, rtol=1e-14, atol=0)
    assert np.allclose(df["impulse_Ns"], df["impulse"] * phys.mass * phys.omega * phys.H1,
                       rtol=1e-14, atol=0)


# ----- sweep -----------------------------------------------------------------------------

def test_sweep_csv_png_and_npz_match_the_sweep_function(tmp_path, capsys):
    """sweep writes the impacts of sweep() to CSV, a summary, a PNG, and a loadable .npz."""
    from rattle_core.batch.sweep import sweep
    from rattle_core.store.files import load_result

    out = tmp_path / "fig.csv"
    argv = ["sweep", "--param", "lam", "--start", "1", "--stop", "3.5", "--num", "12",
            "--transient", "60", "--record", "20", "--out", str(out)]
    code, _, err = run(argv, capsys)
    assert code == 0, err
    ref = sweep(RattleParams(lam=3.3), "lam", np.linspace(1, 3.5, 12), transient=60, record=20)
    df = pd.read_csv(out)
    assert len(df) == len(ref.table) > 0
    assert np.array_equal(df["value"], ref.table["value"])
    assert np.array_equal(df["impulse"], ref.table["impulse"])
    summary = pd.read_csv(tmp_path / "fig_summary.csv")
    assert list(summary["regime"]) == list(ref.summary["regime"])
    with Image.open(tmp_path / "fig.png") as im:
        assert im.format == "PNG" and im.size[0] > 500
    code, _, err = run(argv[:-1] + [str(tmp_path / "diagram.npz"), "--no-png"], capsys)
    assert code == 0, err
    loaded, _ = load_result(tmp_path / "diagram.npz")
    assert np.array_equal(loaded.table["impulse"], ref.table["impulse"])
    assert not (tmp_path / "diagram.png").exists()


def test_rpm_sweep_is_a_lam_sweep_with_lam_proportional_to_rpm_squared(tmp_path, capsys):
    """--param rpm sweeps Λ = lam_from_rpm(rpm) and labels every row with its engine speed."""
    out = tmp_path / "rpm.parquet"
    code, _, err = run(["sweep", *PHYS, "--param", "rpm", "--values", "2000,3000,4000,5000",
                        "--transient", "50", "--record", "10", "--out", str(out), "--no-png"], capsys)
    assert code == 0, err
    summary = pd.read_parquet(tmp_path / "rpm_summary.parquet")
    rpm = np.array([2000.0, 3000.0, 4000.0, 5000.0])
    assert np.array_equal(summary["rpm"], rpm)
    assert np.allclose(summary["value"], lam_from_rpm(PHYS_OBJ, rpm), rtol=1e-14)
    assert np.allclose(summary["value"] / rpm**2, PHYS_OBJ.lam / 1500.0**2, rtol=1e-12)
    table = pd.read_parquet(out)
    assert set(table["rpm"]) <= set(rpm) and len(table) > 0
    scale = PHYS_OBJ.mass * PHYS_OBJ.H1 * 2 * 2 * math.pi * table["rpm"] / 60
    assert np.allclose(table["impulse_Ns"], table["impulse"] * scale, rtol=1e-12)


def test_two_d_map_matches_regime_map(tmp_path, capsys):
    """--param2 writes one row per grid point with the regimes of maps.regime_map."""
    from rattle_core.analysis.vocabulary import REGIME_CODES
    from rattle_core.batch.maps import regime_map

    out = tmp_path / "map.csv"
    code, _, err = run(["sweep", "--h2", "0.25", "--param", "lam", "--values", "1,2,3.3",
                        "--param2", "phi2", "--values2", "0,90", "--transient", "50", "--record", "20",
                        "--out", str(out)], capsys)
    assert code == 0, err
    df = pd.read_csv(out)
    assert len(df) == 6 and list(df.columns[:2]) == ["lam", "phi2"]
    ref = regime_map(RattleParams(lam=3.3, amplitudes=(1.0, 0.25), phases_deg=(0.0, 0.0)),
                     "lam", [1, 2, 3.3], "phi2", [0, 90], transient=50, record=20)
    letters = {v: k for k, v in REGIME_CODES.items()}
    assert list(df["regime"]) == [letters[int(c)] for c in ref.fields["regime"].ravel()]
    assert np.allclose(df["intensity"], ref.fields["intensity"].ravel(), equal_nan=True)
    assert (tmp_path / "map.png").stat().st_size > 1000


def test_rpm_by_drag_torque_map_uses_lam_of_each_point(tmp_path, capsys):
    """An rpm × drag torque map runs each point at its own Λ = m H1 ω²/F."""
    from rattle_core.batch.sweep import sweep

    out = tmp_path / "rc.csv"
    code, _, err = run(["sweep", *PHYS, "--param", "rpm", "--values", "2000,4000",
                        "--param2", "drag_torque", "--values2", "0.01,0.03",
                        "--transient", "50", "--record", "20", "--out", str(out), "--no-png"], capsys)
    assert code == 0, err
    df = pd.read_csv(out)
    lam = [PHYS_OBJ.replace(rpm=r, drag_torque=c).lam for r, c in zip(df["rpm"], df["drag_torque"])]
    assert list(df["rpm"]) == [2000, 4000, 2000, 4000]
    ref = sweep(PHYS_OBJ.to_dimensionless(), "lam", lam, transient=50, record=20).summary
    assert list(df["regime"]) == list(ref["regime"])
    assert np.allclose(df["intensity"], ref["intensity"], rtol=1e-9)


def test_sweep_on_dask_local_equals_local(tmp_path, capsys):
    """--dask local runs the sweep on a LocalCluster and writes the same file as the local run."""
    argv = ["sweep", "--param", "lam", "--values", "1.5,2.5,3.3", "--transient", "40", "--record", "10",
            "--no-png", "--no-cache", "-q"]
    code, _, err = run(argv + ["--out", str(tmp_path / "local.csv")], capsys)
    assert code == 0, err
    code, _, err = run(argv + ["--out", str(tmp_path / "dask.csv"), "--dask", "local", "--workers", "2"],
                       capsys)
    assert code == 0, err
    assert (tmp_path / "local.csv").read_bytes() == (tmp_path / "dask.csv").read_bytes()


# ----- sound, paper, serve ---------------------------------------------------------------

def test_sound_writes_wav_whose_length_follows_engine_speed(tmp_path, capsys):
    """sound writes 16-bit WAV at 0.99 peak; in physical units twice the rpm halves the duration."""
    lengths = {}
    for rpm in ("3000", "6000"):
        out = tmp_path / f"r{rpm}.wav"
        argv = ["sound", *PHYS, "--rpm", rpm, "--periods", "100", "--transient", "50", "--rate", "22050",
                "--tail", "0", "--out", str(out)]
        code, _, err = run(argv, capsys)
        assert code == 0, err
        rate, data = wavfile.read(out)
        assert rate == 22050 and data.dtype == np.int16
        assert int(np.max(np.abs(data))) == round(0.99 * 32767)
        lengths[rpm] = data.size / rate
    # 100 periods of 60 / (order · rpm) seconds.
    assert lengths["3000"] == pytest.approx(100 * 60 / (2 * 3000), abs=1 / 22050)
    assert lengths["6000"] == pytest.approx(lengths["3000"] / 2, abs=1 / 22050)


def test_paper_calls_write_paper_figures_with_progress(tmp_path, capsys, monkeypatch):
    """paper --out DIR hands the directory and a progress callback to write_paper_figures."""
    import rattle_core.paper.figures as figures

    calls = []

    def fake(out_dir, progress=None):
        calls.append(Path(out_dir))
        for i in range(3):
            progress(i + 1, 3)
        path = Path(out_dir) / "fig2.png"
        path.write_bytes(b"png")
        return [path]

    monkeypatch.setattr(figures, "write_paper_figures", fake)
    code, out, err = run(["paper", "--out", str(tmp_path / "figs")], capsys)
    assert code == 0, err
    assert calls == [tmp_path / "figs"]
    assert "fig2.png" in out and "3/3" in err  # the tqdm bar reached its end


def _fake_dashboard(monkeypatch, serve):
    """Install ``serve`` as the dashboard's ``rattle_app.main.serve``, with the real one's
    signature, so the CLI is tested against what the dashboard accepts."""
    import types

    import app.main
    inspect_sig = __import__("inspect").signature(app.main.serve)

    def checked(**kwargs):
        inspect_sig.bind(**kwargs)
        return serve(**kwargs)
    import app.signals

    main_mod = types.ModuleType("rattle_app.main")
    main_mod.serve = checked
    pkg = types.ModuleType("rattle_app")
    pkg.__path__ = []  # a package: ``rattle_app.signals`` is imported from it too
    pkg.main, pkg.signals = main_mod, app.signals
    monkeypatch.setitem(sys.modules, "rattle_app", pkg)
    monkeypatch.setitem(sys.modules, "rattle_app.signals", app.signals)
    monkeypatch.setitem(sys.modules, "rattle_app.main", main_mod)


def test_serve_passes_port_address_show(monkeypatch, capsys):
    """serve hands --port, --address, --show and -q to the dashboard's serve()."""
    seen = {}
    _fake_dashboard(monkeypatch, lambda **kw: seen.update(kw))
    code, _, err = run(["serve", "--port", "5123", "--address", "127.0.0.1", "--show"], capsys)
    assert code == 0, err
    assert seen == {"port": 5123, "address": "127.0.0.1", "show": True, "quiet": False}


# ----- help and errors -------------------------------------------------------------------

def test_help_lists_every_subcommand_and_option(capsys):
    """--help of each subcommand documents its options, physical units included."""
    code, out, _ = run(["--help"], capsys)
    assert code == 0
    for name in ("serve", "simulate", "sweep", "sound", "paper", "units"):
        assert name in out
    expected = {
        "serve": ["--port", "--address", "--show"],
        "simulate": ["--lam", "--harmonics", "--harmonic", "--paper-phases", "--inertia", "--radius",
                     "--drag-torque", "--backlash-um", "--backlash-deg", "--rpm", "--order",
                     "--theta-amp", "--alpha-amp", "--impacts", "--history", "--samples-per-period"],
        "sweep": ["--param", "--values", "--mode", "--out", "--png", "--no-cache", "--dask",
                  "--scheduler", "--param2", "rpm"],
        "sound": ["--out", "--rate", "--excitation-hz", "--modes", "--polarity"],
        "paper": ["--out"],
    }
    for command, options in expected.items():
        code, out, _ = run([command, "--help"], capsys)
        assert code == 0
        for opt in options:
            assert opt in out, (command, opt)


@pytest.mark.parametrize("argv, message", [
    (["simulate", "--lam", "abc", "--impacts", "x.csv"], "argument --lam: invalid float value: 'abc'"),
    (["simulate", "--lam", "-1", "--impacts", "x.csv"], "lam = -1.0 is outside the allowed range (1e-06, 10000]"),
    (["simulate", "--r", "2", "--impacts", "x.csv"], "r = 2.0 is outside the allowed range [0, 1]"),
    (["simulate", "--lam", "2", "--rpm", "1000", "--impacts", "x.csv"], "cannot be combined with physical"),
    (["simulate", "--rpm", "1000", "--impacts", "x.csv"], "physical units need --inertia"),
    (["simulate", *PHYS[:-4], "--rpm", "-5", "--theta-amp", "1e-3", "--impacts", "x.csv"],
     "rpm = -5.0 is outside the allowed range (0, 100000]"),
    (["simulate", "--lam", "2"], "give --impacts FILE and/or --history FILE"),
    (["simulate", "--impacts", "x.txt"], "the extension must be one of .csv, .parquet"),
    (["simulate", "--impacts", "/no/such/dir/x.csv"], "directory '/no/such/dir' does not exist"),
    (["simulate", "--harmonics", "1,0.2:0", "--impacts", "x.csv"], "gives 2 amplitudes but 1 phases"),
    (["simulate", "--harmonics", "0.5", "--impacts", "x.csv"], "must be exactly 1"),
    (["simulate", "--harmonic", "1,0.3", "--impacts", "x.csv"], "harmonic order K = 1 is outside"),
    (["simulate", "--periods", "0", "--impacts", "x.csv"], "periods = 0.0 is outside the allowed range"),
    (["sweep", "--param", "zeta", "--values", "1", "--out", "x.csv"], "unknown parameter name 'zeta'"),
    (["sweep", "--param", "lam", "--out", "x.csv"], "give --start and --stop"),
    (["sweep", "--param", "r", "--values", "0.5,1.5", "--out", "x.csv"],
     "r = 1.5 is outside the allowed range [0, 1]"),
    (["sweep", "--values", "1", "--record", "0", "--out", "x.csv"], "record = 0.0 is outside"),
    (["sweep", "--param", "rpm", "--values", "1000", "--out", "x.csv"], "--param rpm needs physical units"),
    (["sweep", "--values", "1", "--out", "x.csv", "--dask", "remote"], "the only value is 'local'"),
    (["sweep", "--values", "1,2", "--out", "x.csv", "--mode", "continuation", "--dask", "local"],
     "continuation sweeps run value after value"),
    (["sweep", "--param", "lam", "--values", "1", "--param2", "lam", "--values2", "1", "--out", "x.csv"],
     "--param and --param2 must differ"),
    (["sweep", *PHYS, "--param", "rpm", "--values", "1000,2000", "--param2", "lam", "--values2", "1,2",
      "--out", "x.csv"], "--param rpm leaves the dimensionless model unchanged with lam also swept"),
    (["sound", "--out", "x.mp3"], "the extension must be one of .wav"),
    (["sound", "--out", "x.wav", "--rate", "100"], "sample_rate = 100.0 is outside the allowed range"),
    (["sound", "--out", "x.wav", "--modes", "30000:0.02"], "mode freq_hz = 30000.0 is outside"),
    (["sound", *PHYS, "--out", "x.wav", "--excitation-hz", "40"], "--excitation-hz is for dimensionless"),
    (["serve", "--port", "99999"], "--port 99999 is outside the allowed range [1, 65535]"),
    (["bogus"], "invalid choice: 'bogus'"),
    ([], "the following arguments are required: COMMAND"),
])
def test_bad_arguments_give_one_line_and_exit_2(argv, message, capsys, tmp_path, monkeypatch):
    """Each bad argument prints exactly one 'rattle: error:' line naming the problem, exit 2."""
    monkeypatch.chdir(tmp_path)
    code, out, err = run(argv, capsys)
    assert code == 2
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("rattle: error: ")
    assert message in lines[0]
    assert "Traceback" not in err
    assert not list(tmp_path.glob("x.*"))  # nothing half-written


@pytest.fixture()
def no_work(monkeypatch):
    """Every computation a command could start fails the test: errors must come first."""
    import rattle_core
    import rattle_core.batch.sweep as sweep_module
    import rattle_core.paper.figures as figures
    import rattle_core.store.cache as cache
    import rattle_core.store.requests as requests

    def started(*a, **k):
        raise AssertionError("work started before the request was checked")
    # the commands import these inside run(), so they find the stand-ins
    for mod, name in ((sweep_module, "sweep"), (cache, "cached_sweep"), (requests, "run_map"),
                      (rattle_core, "simulate"), (figures, "write_paper_figures")):
        monkeypatch.setattr(mod, name, started)


@pytest.mark.parametrize("argv, message", [
    (["sweep", "--values", "1", "--out", "{dir}/table.csv"], "is a directory; give a file name"),
    (["sweep", "--values", "1", "--out", "/proc/x.csv"], "cannot write in directory '/proc'"),
    (["sweep", "--values", "1", "--out", "x.csv", "--png", "/proc/x.png"],
     "--png '/proc/x.png': cannot write in directory '/proc'"),
    (["sweep", "--values", "1", "--out", "x.csv", "--png", "{dir}"], "the extension must be one of .png"),
    (["sweep", "--values", "1", "--out", "x.csv", "--png", "{dir}/picture.png"], "is a directory"),
    (["sweep", "--values", "1", "--out", ""], "--out is empty"),
    (["simulate", "--impacts", ""], "--impacts is empty"),
    (["simulate", "--history", "/proc/h.parquet"], "cannot write in directory '/proc'"),
    (["simulate", "--impacts", "{dir}/table.csv"], "is a directory"),
    (["paper", "--out", ""], "--out is empty; give a directory"),
    (["paper", "--out", "{file}"], "exists and is not a directory"),
    (["paper", "--out", "/proc/figures"], "cannot write in directory '/proc'"),
    (["sweep", "--start", "1", "--stop", "inf", "--out", "x.csv"], "--stop inf must be a finite number"),
    (["sweep", "--start=-inf", "--stop", "2", "--out", "x.csv"], "--start -inf must be a finite number"),
    (["sweep", "--values", "1", "--param2", "r", "--start2", "0.1", "--stop2", "nan", "--out", "x.csv"],
     "--stop2 nan must be a finite number"),
    (["sweep", "--values", "1,inf", "--out", "x.csv"], "values must all be finite, got inf"),
    (["sweep", "--x0", "inf", "--values", "1", "--out", "x.csv"], "--x0 inf must be a finite number"),
    (["sweep", "--start", "1", "--stop", "3", "--num", "1000", "--transient", "1000000",
      "--out", "x.csv"], "over the budget of 1e+08 per request"),
    (["sweep", "--values", "1,2", "--param2", "r", "--start2", "0.1", "--stop2", "0.9",
      "--num2", "1000", "--transient", "100000", "--out", "x.csv"], "over the budget"),
])
def test_bad_outputs_and_requests_are_refused_before_any_work(argv, message, capsys, tmp_path,
                                                              monkeypatch, no_work):
    """Unusable output paths (empty, a directory, an unwritable directory), infinite ranges and
    requests over the period budget are one 'rattle: error:' line, exit 2, before any work."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "a_dir").mkdir()
    (tmp_path / "a_dir" / "table.csv").mkdir()
    (tmp_path / "a_dir" / "picture.png").mkdir()
    (tmp_path / "a_file").write_text("x")
    argv = [a.format(dir=tmp_path / "a_dir", file=tmp_path / "a_file") for a in argv]
    code, _, err = run(argv, capsys)
    assert code == 2, err
    assert len(err.splitlines()) == 1 and err.startswith("rattle: error: ") and message in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a_dir", "a_file"]


def test_cache_command_shows_and_clears(tmp_path, capsys, monkeypatch):
    """``rattle cache`` shows the directory, its entries and the size limit; ``clear`` empties it."""
    cache_dir = tmp_path / "cache"
    monkeypatch.setenv("RATTLE_CACHE_DIR", str(cache_dir))
    monkeypatch.setenv("RATTLE_CACHE_SIZE_MB", "50")
    code, out, err = run(["sweep", "--values", "1.5,2.5", "--transient", "20", "--record", "5",
                          "--out", str(tmp_path / "s.csv"), "--no-png", "-q"], capsys)
    assert code == 0, err
    code, out, _ = run(["cache", "show"], capsys)
    assert code == 0
    assert str(cache_dir) in out and "1 entries (1 sweeps, 0 maps)" in out and "of 50.0 MB" in out
    assert "sweep-" in out
    code, out, _ = run(["cache", "clear"], capsys)
    assert code == 0 and "cleared" in out and "1 files" in out
    assert list(cache_dir.glob("*.npz")) == []
    code, out, _ = run(["cache"], capsys)
    assert code == 0 and "0 entries" in out
    from rattle_core.store.cache import DEFAULT_SIZE_MB
    code, out, _ = run(["cache", "--help"], capsys)
    assert code == 0 and f"(default {DEFAULT_SIZE_MB})" in " ".join(out.split())


def test_solver_limit_exits_1_with_one_line(monkeypatch, capsys, tmp_path):
    """A run stopped by the solver (SolverError) is one line and exit status 1."""
    def runaway(*args, **kwargs):
        raise SolverError("runaway: more than 10 impacts within one forcing period")

    monkeypatch.setattr("rattle_core.simulate", runaway)  # imported inside the command's run()
    code, _, err = run(["simulate", "--impacts", str(tmp_path / "x.csv")], capsys)
    assert code == 1
    assert err == "rattle: error: runaway: more than 10 impacts within one forcing period\n"


def test_unexpected_failure_is_still_one_line(monkeypatch, capsys, tmp_path):
    """Even an internal bug prints one line (with how to see the traceback), exit 1."""
    monkeypatch.delenv("RATTLE_DEBUG", raising=False)
    monkeypatch.setattr(simulate_command, "build_params", lambda args: 1 / 0)
    code, _, err = run(["simulate", "--impacts", str(tmp_path / "x.csv")], capsys)
    assert code == 1
    assert err.count("\n") == 1 and "ZeroDivisionError" in err and "Traceback" not in err


def test_console_script_help_and_error_in_a_subprocess(tmp_path):
    """`python -m rattle_cli` prints help (exit 0) and a one-line error (exit 2)."""
    env = dict(os.environ, RATTLE_CACHE_DIR=str(tmp_path / "cache"))
    ok = subprocess.run([*RATTLE, "--help"], capture_output=True, text=True, timeout=120, env=env)
    assert ok.returncode == 0 and "simulate" in ok.stdout and "sound" in ok.stdout
    bad = subprocess.run([*RATTLE, "sweep", "--values", "1", "--lam", "nan", "--out",
                          str(tmp_path / "x.csv")], capture_output=True, text=True, timeout=120, env=env)
    assert bad.returncode == 2
    assert bad.stderr.splitlines() == [bad.stderr.strip()]
    assert bad.stderr.startswith("rattle: error: lam must be finite, got nan")
    assert "Traceback" not in bad.stderr


def test_units_prints_both_sets_side_by_side(capsys):
    """units prints each physical input beside the dimensionless number it becomes."""
    code, out, err = run(["units", *PHYS], capsys)
    assert code == 0, err
    assert "0.49348" in out and "j = 8" in out and "h_2 = 0.25" in out and "1500 rpm" in out


def test_serve_passes_the_maps_dask_default(monkeypatch, capsys):
    """serve --scheduler ADDR and --dask local reach the dashboard's serve(); together they are
    refused."""
    seen = []
    _fake_dashboard(monkeypatch, lambda scheduler=None, dask=None, **kw: seen.append(
        {"scheduler": scheduler, "dask": dask}))
    code, _, err = run(["serve", "--scheduler", "tcp://10.0.0.5:8786"], capsys)
    assert code == 0, err
    code, _, err = run(["serve", "--dask", "local"], capsys)
    assert code == 0, err
    assert seen == [{"scheduler": "tcp://10.0.0.5:8786", "dask": None},
                    {"scheduler": None, "dask": "local"}]
    for argv, message in ((["--dask", "local", "--scheduler", "tcp://h:1"], "not both"),
                          (["--scheduler", "10.0.0.5"], "give a Dask scheduler address such as tcp://"),
                          (["--dask", "remote"], "invalid choice: 'remote'")):
        code, _, err = run(["serve", *argv], capsys)
        assert code == 2 and len(err.splitlines()) == 1 and message in err, err
    assert len(seen) == 2
    code, out, _ = run(["serve", "--help"], capsys)
    assert code == 0 and "--scheduler" in out and "--dask" in out and "Dask" in out


def test_strict_switch_reaches_simulate_and_sweep(tmp_path, capsys):
    """--strict runs the strict model: the summary says the loop was chosen by rounding, and
    the impacts equal the noiseless simulate; --noise sets the level; a map takes it too."""
    argv = ["simulate", "--lam", "3.3", "--h2", "0.25", "--phi2", "45", "--paper-phases",
            "--periods", "2000", "--transient", "500", "--impacts", str(tmp_path / "s.csv")]
    code, out, _ = run(argv + ["--strict"], capsys)
    assert code == 0 and "not resolvable" in out
    p = RattleParams.paper(lam=3.3, amplitudes=(1.0, 0.25), phases_deg=(0.0, 45.0))
    strict = simulate(p.replace(noise=0.0), periods=2000, transient=500)
    np.testing.assert_array_equal(pd.read_csv(tmp_path / "s.csv")["impulse"], strict.impact_impulse)
    code, out, _ = run(argv, capsys)
    assert code == 0 and "statistics at this noise level" in out
    code, out, _ = run(argv[:-1] + [str(tmp_path / "n.csv"), "--noise", "1e-6"], capsys)
    noisy = simulate(p.replace(noise=1e-6), periods=2000, transient=500)
    np.testing.assert_array_equal(pd.read_csv(tmp_path / "n.csv")["impulse"], noisy.impact_impulse)
    code, _, err = run(argv + ["--noise", "0.9"], capsys)
    assert code == 2 and "noise" in err and "[0, 0.5]" in err
    code, _, err = run(argv + ["--noise", "1e-6", "--strict"], capsys)
    assert code == 2 and "--strict" in err
    code, out, _ = run(["sweep", "--lam", "3.3", "--h2", "0.25", "--phi2", "45", "--paper-phases",
                        "--values", "3.3", "--transient", "300", "--record", "2000", "--strict",
                        "--out", str(tmp_path / "w.csv"), "--no-png"], capsys)
    assert code == 0 and "chaos-through-sticking 1 (strict model" in out
    code, _, err = run(["sweep", "--param", "lam", "--values", "1,2", "--param2", "r",
                        "--values2", "0.5,0.6", "--strict", "--out", str(tmp_path / "m.csv"),
                        "--no-png"], capsys)
    assert code == 0


def test_ctrl_c_stops_a_long_sweep_at_once(tmp_path):
    """SIGINT during a sweep whose chunks each take tens of seconds ends the command within a
    few seconds, with status 130 and no output file."""
    import signal
    import time
    out = tmp_path / "long.npz"
    env = dict(os.environ, RATTLE_CACHE_DIR=str(tmp_path / "cache"))
    proc = subprocess.Popen([sys.executable, "-m", "rattle_cli", "sweep", "--param", "lam",
                             "--start", "3", "--stop", "3.5", "--num", "40", "--transient",
                             "2000000", "--record", "100", "--out", str(out), "--no-cache"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    import threading
    chunks: list[str] = []
    reader = threading.Thread(target=lambda: chunks.extend(iter(lambda: proc.stderr.read(1), "")),
                              daemon=True)
    reader.start()
    try:
        deadline = time.monotonic() + 120
        while "sweep lam" not in "".join(chunks):  # the bar: the sweep has begun its chunks
            assert proc.poll() is None and time.monotonic() < deadline, "".join(chunks)
            time.sleep(0.05)
        sent = time.perf_counter()
        proc.send_signal(signal.SIGINT)
        proc.wait(timeout=60)
        waited = time.perf_counter() - sent
        reader.join(timeout=10)
        err = "".join(chunks)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130 and "interrupted" in err
    assert waited < 5.0, f"took {waited:.1f} s to stop"
    assert not out.exists()
