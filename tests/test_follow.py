"""Excitation that follows engine speed: rpm sweeps and rpm × drag-torque maps whose harmonics
come from a measurement at each speed."""
from __future__ import annotations

import numpy as np
import pytest

from rattle_core import classify, simulate
from rattle_core.batch.sweep import sweep
from rattle_core.model.gearbox import Excitation
from rattle_core.model.orders import SAMPLE_RUNUP, OrderMap
from rattle_core.model.units import PhysicalParams, rpm_sweep
from rattle_core.store.requests import run_map

PHYS = PhysicalParams(inertia=4e-4, radius=0.035, drag_torque=0.05, backlash=80e-6, rpm=1500.0,
                      amplitudes=(1e-3,), order=2.0)


@pytest.fixture(scope="module")
def follow() -> Excitation:
    return Excitation(engine_order=2.0, harmonics=3,
                      order_map=OrderMap.from_csv(SAMPLE_RUNUP, (2, 4, 6)))


def test_follow_takes_each_speeds_orders(follow):
    """At each speed the driving gear's θ_k and φ_k are the order map's, times the speed ratio,
    and the fundamental's order is the chosen engine order."""
    theta, phase = follow.order_map.at([1234.0], (2, 4, 6))
    p = follow.follow(PHYS, 1234.0, speed_ratio=1.5)
    np.testing.assert_allclose(p.amplitudes, 1.5 * theta[0])
    np.testing.assert_allclose(p.phases_deg, phase[0])
    assert p.rpm == 1234.0 and p.order == 2.0 and p.excitation == "displacement"


def test_rpm_sweep_with_following_harmonics_matches_single_runs(follow):
    """Each speed of a sweep with columns from the measurement gives the same regime and
    impacts as simulate() on that speed's own parameters; Λ grows as the sample's order-2
    acceleration (Λ = m R_d α₂ / F, which more than doubles), not as rpm² as it would with
    amplitudes held (almost seven times)."""
    rpm = np.array([1100.0, 1700.0, 2300.0, 2900.0])
    cols = follow.columns(PHYS, rpm)
    growth = cols["lam"][-1] / cols["lam"][0]
    assert 1.8 < growth < 3.0
    res = sweep(PHYS.to_dimensionless(), "rpm", rpm, transient=150, record=60, columns=cols)
    assert res.name == "rpm" and res.summary["value"].tolist() == rpm.tolist()
    for k, r in enumerate(rpm):
        p = follow.follow(PHYS, r).to_dimensionless()
        tr = simulate(p, periods=60, transient=150, lyapunov=True)
        assert res.summary["regime"].iloc[k] == classify(tr).regime
        n = int(res.summary["n_active"].iloc[k] + res.summary["n_reverse"].iloc[k])
        assert n == tr.impact_t.size


def test_constant_measured_orders_reduce_to_the_plain_rpm_sweep():
    """Orders held constant (one displacement amplitude) give the same Λ at each speed as the
    plain engine-speed sweep of the same gear."""
    exc = Excitation(engine_order=2.0, harmonics=1, constant=((2.0, 1e-3, 0.0, "disp"),))
    rpm = np.linspace(900, 3100, 7)
    name, lam = rpm_sweep(PHYS, rpm)
    np.testing.assert_allclose(exc.columns(PHYS, rpm)["lam"], lam, rtol=1e-12)


def test_rpm_by_drag_map_follows_the_measurement(follow, tmp_path, monkeypatch):
    """An rpm × drag-torque map with following harmonics: a point's regime is the one a single
    run at that speed and drag gives; without following, the map differs somewhere."""
    monkeypatch.setenv("RATTLE_CACHE_DIR", str(tmp_path))
    rpm = np.array([1200.0, 2000.0, 2800.0])
    drag = np.array([0.03, 0.06])
    m = run_map(PHYS.to_dimensionless(), PHYS, "rpm", rpm, "drag_torque", drag, follow=follow,
                transient=150, record=60)
    assert m.fields["regime"].shape == (2, 3)
    for iy, d in enumerate(drag):
        for ix, r in enumerate(rpm):
            p = follow.follow(PHYS.replace(drag_torque=d), r).to_dimensionless()
            tr = simulate(p, periods=60, transient=150, lyapunov=True)
            assert m.table()["regime"].iloc[iy * 3 + ix] == classify(tr).regime
    plain = run_map(PHYS.to_dimensionless(), PHYS, "rpm", rpm, "drag_torque", drag,
                    transient=150, record=60)
    assert not np.allclose(plain.fields["intensity"], m.fields["intensity"])


def test_cli_rpm_sweep_takes_its_harmonics_from_a_measurement(tmp_path):
    """``rattle sweep --param rpm --orders-from`` writes the rpm of every value and the impulse
    in N·s at each speed's own scale; without physical units it exits 2 with one line."""
    import subprocess
    import sys
    from pathlib import Path

    import pandas as pd
    root = Path(__file__).resolve().parent.parent
    env = {"RATTLE_CACHE_DIR": str(tmp_path / "cache"), "PATH": "/usr/bin:/bin",
           "RATTLE_CONFIG_DIR": str(tmp_path / "config")}
    gear = ["--inertia", "4e-4", "--radius", "0.035", "--drag-torque", "0.05", "--backlash-um",
            "80", "--rpm", "1500", "--theta-amp", "1e-3"]
    out = tmp_path / "rpm.csv"
    cmd = [sys.executable, "-m", "rattle_cli", "sweep", "--param", "rpm", "--start", "1200",
           "--stop", "2800", "--num", "5", "--transient", "100", "--record", "40",
           "--orders-from", str(SAMPLE_RUNUP), "--out", str(out), "--no-png", "-q"]
    r = subprocess.run(cmd + gear, capture_output=True, text=True, cwd=root, timeout=600, env=env)
    assert r.returncode == 0, r.stderr
    summary = pd.read_csv(tmp_path / "rpm_summary.csv")
    assert summary["rpm"].tolist() == [1200.0, 1600.0, 2000.0, 2400.0, 2800.0]
    table = pd.read_csv(out)
    follow = Excitation(engine_order=2.0, harmonics=3,
                        order_map=OrderMap.from_csv(SAMPLE_RUNUP, (2, 4, 6)))
    row = table.iloc[-1]
    scale = follow.follow(PHYS, row["rpm"]).impulse_scale
    assert row["impulse_Ns"] == pytest.approx(row["impulse"] * scale, rel=1e-12)
    r = subprocess.run(cmd[:-4] + ["--out", str(out), "-q"], capture_output=True, text=True,
                       cwd=root, timeout=600, env=env)
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "--orders-from needs physical" in r.stderr
