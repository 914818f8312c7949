"""``rattle gearbox`` beyond one design: two designs side by side (``--compare``), a target from
the command line, the round default speeds, and the options it refuses in one line."""
from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from rattle_cli.commands.gearbox import GRID_STEPS, round_grid
from rattle_cli.main import main
from rattle_core.model.gearbox import Gearbox
from gearboxes import OIL_ONE_GEAR as OIL, SAMPLE_TWO_GEARS

pytestmark = pytest.mark.timeout(600)

TOML = SAMPLE_TWO_GEARS
FAST = ["--transient", "60", "--record", "30", "--runs", "0"]


@pytest.fixture()
def files(tmp_path, monkeypatch):
    monkeypatch.setenv("RATTLE_CACHE_DIR", str(tmp_path / "cache"))
    (tmp_path / "a.toml").write_text(TOML)
    (tmp_path / "b.toml").write_text(TOML.replace("drag_torque_Nm = 0.05", "drag_torque_Nm = 0.09"))
    return tmp_path


def test_compare_two_designs(files, capsys):
    """``--compare``: both designs at the same speeds in one CSV (a ``design`` column named by
    file), the B - A rows equal B's loudness minus A's row by row, the target's margin is its
    limit minus the loudness; more drag in B never rattles earlier; both are printed side by side."""
    out = files / "v.csv"
    code = main(["gearbox", str(files / "a.toml"), "--compare", str(files / "b.toml"),
                 "--rpm", "1000:3000:5", "--out", str(out), "--png",
                 "--target", "1000:0.5,3000:2 sone", *FAST])
    assert code == 0, capsys.readouterr().err
    printed = capsys.readouterr().out
    assert "A = a.toml, B = b.toml" in printed
    assert "5th idler: A rattles from" in printed and "| B " in printed
    df = pd.read_csv(out)
    assert set(df["design"]) == {"a.toml", "b.toml", "B - A"}
    a, b, d = (df[df["design"] == k].set_index(["gear", "rpm"]) for k in ("a.toml", "b.toml", "B - A"))
    assert len(a) == len(b) == len(d) == 3 * 5
    np.testing.assert_allclose(d["loudness_sone"], (b["loudness_sone"] - a["loudness_sone"]).loc[d.index])
    limit = np.interp(a.index.get_level_values("rpm"), [1000, 3000], [0.5, 2.0])
    np.testing.assert_allclose(a["target_sone"], limit)
    np.testing.assert_allclose(a["margin_sone"], limit - a["loudness_sone"])
    assert (a["pass"].astype(str) == (a["margin_sone"] >= 0).astype(str)).all()
    on_a = a.loc["5th idler", "onset_rpm"].iloc[0]
    on_b = b.loc["5th idler", "onset_rpm"].iloc[0]
    assert not (on_b < on_a)
    assert (files / "v.png").stat().st_size > 1000


def test_default_speeds_are_round(files):
    """Without --rpm the speeds are every 50, 100, ... rpm inside the measured range: round
    numbers, evenly spaced, and no more than the grid allows."""
    box = Gearbox.from_toml(files / "a.toml")
    rpm = round_grid(box)
    lo, hi = box.excitation.rpm_range
    step = rpm[1] - rpm[0]
    assert step in GRID_STEPS and np.all(np.diff(rpm) == step)
    assert np.all(rpm % step == 0) and lo <= rpm[0] < lo + step and hi - step < rpm[-1] <= hi


@pytest.mark.parametrize("extra, words", [
    (["--oil-temp", "200"], ["--oil-temp '200'", "[-40, 150]"]),
    (["--oil-temp", "-41"], ["[-40, 150]"]),
    (["--oil-temps=-60:20:3"], ["--oil-temps", "-40"]),
    (["--target", "1000:10,3000 sone"], ["--target", "'3000' is not RPM:VALUE"]),
    (["--target", "1000:10,3000:20 phon"], ["--target", "sone", "dba"]),
    (["--target", "3000:10,1000:20 sone"], ["--target", "increase"]),
    (["--rpm", "1000:3000:3", "--compare", "{tmp}/missing.toml"], ["missing.toml"]),
])
def test_bad_options_exit_2_with_one_line(files, capsys, extra, words):
    """A temperature outside −40…150 °C, a target that does not read, and a missing second
    design are refused before any work: exit 2, one line that names the option and the range."""
    extra = [e.replace("{tmp}", str(files)) for e in extra]
    code = main(["gearbox", str(files / "a.toml"), "--out", str(files / "v.csv"), *extra])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1, err
    for w in words:
        assert w in err, (w, err)
    assert not (files / "v.csv").exists()




def _onset_closed_form(temp_C: float) -> float:
    """Where the inertia torque J θ ω² (ω = 2·2π rpm/60) of a constant θ = 1e-3 rad equals the
    drag 0.01 + 0.02 ν(T)/ν(40 °C) rpm/2000 N·m, with ν(T) of VG 68 (ν(100 °C) = 9 cSt) by
    ASTM D341."""
    z = [math.log10(math.log10(v + 0.7)) for v in (68.0, 9.0)]
    x = [math.log10(273.15 + T) for T in (40.0, 100.0)]
    b = (z[0] - z[1]) / (x[1] - x[0])
    nu = lambda T: 10 ** 10 ** (z[0] + b * x[0] - b * math.log10(273.15 + T)) - 0.7  # noqa: E731
    a = 4e-4 * 1e-3 * (2 * 2 * math.pi / 60) ** 2
    c = 0.02 * nu(temp_C) / nu(40.0) / 2000
    return (c + math.sqrt(c * c + 4 * a * 0.01)) / (2 * a)


def test_oil_temps_write_the_rpm_temperature_map(files, capsys):
    """``--oil-temps A:B:N`` runs a gearbox with [oil] and an oil-drag gear at N temperatures:
    the CSV holds every row once per temperature with its ``oil_temp_C``, each temperature's
    onset lies within one grid step above the closed-form contact boundary (cold oil drags
    more, so it rattles later), and the PNG map is written."""
    (files / "oil.toml").write_text(OIL)
    out = files / "t.csv"
    code = main(["gearbox", str(files / "oil.toml"), "--rpm", "600:3000:25",
                 "--oil-temps=20:80:2", "--out", str(out), "--png", "--transient", "150",
                 "--record", "40", "--runs", "0"])
    assert code == 0, capsys.readouterr().err
    df = pd.read_csv(out)
    assert df.columns[0] == "oil_temp_C" and sorted(set(df["oil_temp_C"])) == [20.0, 80.0]
    assert len(df) == 2 * 25 * 2
    onsets = {}
    for temp in (20.0, 80.0):
        onsets[temp] = df[(df["oil_temp_C"] == temp) & (df["gear"] == "idler")]["onset_rpm"].iloc[0]
        boundary = _onset_closed_form(temp)
        assert boundary <= onsets[temp] < boundary + 100.0, (temp, boundary, onsets[temp])
    assert onsets[20.0] > onsets[80.0] + 300
    assert (files / "t.png").stat().st_size > 1000
