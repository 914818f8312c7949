"""Physical units: the mapping to (Λ, j, h_k, φ_k) and back, scaling laws and validation."""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from rattle_core import RattleParams, simulate
from rattle_core.model.units import (PhysicalParams, backlash_from_angle, backlash_from_um, example,
                               j_from_rpm, lam_from_rpm, omega_from_rpm, rpm_from_lam,
                               rpm_from_sweep, rpm_sweep, wrap_deg)

REL = 1e-12


def log_uniform(lo: float, hi: float) -> st.SearchStrategy[float]:
    return st.floats(math.log10(lo), math.log10(hi)).map(lambda e: 10.0**e)


@st.composite
def physical(draw, kind: str | None = None) -> PhysicalParams:
    kind = kind or draw(st.sampled_from(["displacement", "acceleration"]))
    n = draw(st.integers(1, 4))
    if kind == "displacement":
        amps = [draw(log_uniform(1e-6, 1e-2))] + [draw(st.just(0.0) | log_uniform(1e-9, 1e-2))
                                                  for _ in range(n - 1)]
    else:
        amps = [draw(log_uniform(1.0, 1e5))] + [draw(st.just(0.0) | log_uniform(1e-3, 1e5))
                                                for _ in range(n - 1)]
    return PhysicalParams(
        inertia=draw(log_uniform(1e-6, 1e-1)), radius=draw(log_uniform(5e-3, 0.2)),
        drag_torque=draw(log_uniform(1e-4, 10.0)), backlash=draw(log_uniform(1e-6, 1e-3)),
        rpm=draw(log_uniform(300.0, 12000.0)), amplitudes=tuple(amps),
        phases_deg=tuple(draw(st.floats(-180.0, 180.0)) for _ in range(n)),
        order=draw(st.sampled_from([0.5, 1.0, 1.5, 2.0, 3.0, 4.0])), excitation=kind,
        r=draw(st.floats(0.0, 1.0)), v_stick=draw(st.floats(0.0, 1e-3)),
        driver_radius=draw(st.none() | log_uniform(5e-3, 0.2)),
    )


def to_dimensionless_or_skip(phys: PhysicalParams) -> RattleParams:
    try:
        return phys.to_dimensionless()
    except ValueError:
        assume(False)
        raise


def assert_params_close(a: RattleParams, b: RattleParams, rel: float = 1e-9) -> None:
    assert a.lam == pytest.approx(b.lam, rel=rel)
    assert a.j == pytest.approx(b.j, rel=rel)
    assert a.r == pytest.approx(b.r, rel=rel, abs=1e-15)
    assert a.v_stick == pytest.approx(b.v_stick, rel=rel, abs=1e-18)
    assert np.allclose(a.amplitudes, b.amplitudes, rtol=rel, atol=1e-15)
    assert a.amplitudes[0] == 1.0 and b.amplitudes[0] == 1.0
    assert all(abs(wrap_deg(p - q)) < 1e-9 for p, q in zip(a.phases_deg, b.phases_deg))


def test_hand_computed_example():
    """The documented example maps to hand-computed Λ = 0.05π², j = 8, h2 = 0.25, φ2 = 45°."""
    phys = example()
    # m = 2e-4 / 0.04² = 0.125 kg; F = 0.02 / 0.04 = 0.5 N; ω = 2·2π·1500/60 = 100π rad/s;
    # H1 = 0.04 · 5e-4 = 20 µm; Λ = 0.125 · 20e-6 · (100π)² / 0.5 = 0.05 π².
    assert phys.mass == pytest.approx(0.125, rel=REL)
    assert phys.force == pytest.approx(0.5, rel=REL)
    assert phys.omega == pytest.approx(100 * math.pi, rel=REL)
    assert phys.frequency_hz == pytest.approx(50.0, rel=REL)
    assert phys.H1 == pytest.approx(20e-6, rel=REL)
    p = phys.to_dimensionless()
    assert p.lam == pytest.approx(0.05 * math.pi**2, rel=1e-12)
    assert p.j == pytest.approx(8.0, rel=1e-12)
    assert p.amplitudes == (1.0, pytest.approx(0.25, rel=1e-12))
    assert p.phases_deg == (0.0, 45.0)
    assert p.r == 0.65
    # I = Ĩ m ω H1 = 0.125 · 100π · 20e-6 N·s per unit Ĩ; t_phys = t / ω.
    assert phys.impulse(1.0) == pytest.approx(0.125 * 100 * math.pi * 20e-6, rel=REL)
    assert phys.angular_impulse(2.0) == pytest.approx(2 * 0.04 * 0.125 * 100 * math.pi * 20e-6, rel=REL)
    assert phys.time(2 * math.pi) == pytest.approx(0.02, rel=REL)
    assert phys.position(3.0) == pytest.approx(60e-6, rel=REL)
    assert phys.velocity(1.0) == pytest.approx(100 * math.pi * 20e-6, rel=REL)
    assert phys.reaction(2.0) == pytest.approx(1.0, rel=REL)


def test_acceleration_input_matches_displacement_input():
    """Angular accelerations α_k = (kω)² θ_k with phases φ_k − 180° give the same model."""
    disp = example()
    w = disp.omega
    acc = disp.replace(excitation="acceleration",
                       amplitudes=(5e-4 * w**2, 1.25e-4 * (2 * w) ** 2),
                       phases_deg=(-180.0, 45.0 - 180.0))
    assert acc.H == pytest.approx(disp.H, rel=1e-12)
    assert_params_close(acc.to_dimensionless(), disp.to_dimensionless(), rel=1e-12)


def test_lam_grows_as_rpm_squared():
    """With displacement amplitudes held, Λ ∝ rpm² and j stays put, matching a rebuilt model."""
    phys = example()
    rpm = np.array([600.0, 1500.0, 3000.0, 4500.0, 7000.0])
    lam = lam_from_rpm(phys, rpm)
    assert lam / rpm**2 == pytest.approx(np.full(rpm.size, phys.lam / phys.rpm**2), rel=1e-12)
    assert lam[1] == pytest.approx(phys.lam, rel=1e-14)
    assert lam[2] == pytest.approx(4 * phys.lam, rel=1e-12)
    rebuilt = [phys.with_rpm(v).to_dimensionless() for v in rpm]
    assert lam == pytest.approx([p.lam for p in rebuilt], rel=1e-12)
    assert j_from_rpm(phys, rpm) == pytest.approx([p.j for p in rebuilt], rel=1e-12)
    name, values = rpm_sweep(phys, rpm)
    assert name == "lam" and values == pytest.approx(lam, rel=1e-15)
    assert rpm_from_lam(phys, lam) == pytest.approx(rpm, rel=1e-12)
    assert rpm_from_sweep(phys, name, values) == pytest.approx(rpm, rel=1e-12)
    with pytest.raises(ValueError, match="'lam'"):
        rpm_from_sweep(phys, "j", values)


def test_acceleration_held_sweeps_j_not_lam():
    """With acceleration amplitudes held, Λ is speed-independent and j ∝ rpm² instead."""
    acc = example().replace(excitation="acceleration", amplitudes=(50.0, 20.0), phases_deg=(0.0, 10.0))
    rpm = np.array([800.0, 1600.0, 3200.0])
    rebuilt = [acc.with_rpm(v).to_dimensionless() for v in rpm]
    assert lam_from_rpm(acc, rpm) == pytest.approx([p.lam for p in rebuilt], rel=1e-12)
    assert np.ptp([p.lam for p in rebuilt]) < 1e-12 * rebuilt[0].lam
    name, values = rpm_sweep(acc, rpm)
    assert name == "j"
    assert values == pytest.approx([p.j for p in rebuilt], rel=1e-12)
    assert values[1] / values[0] == pytest.approx(4.0, rel=1e-12)
    assert rpm_from_sweep(acc, name, values) == pytest.approx(rpm, rel=1e-12)
    with pytest.raises(ValueError, match="rpm"):
        rpm_from_lam(acc, [1.0])


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.filter_too_much])
@given(phys=physical(), solve_for=st.sampled_from(["rpm", "drag_torque", "inertia", "amplitude"]))
def test_round_trip_physical(phys, solve_for):
    """Physical → dimensionless → physical returns the same inputs, whatever Λ is solved for."""
    assume(not (solve_for == "rpm" and phys.excitation == "acceleration"))
    p = to_dimensionless_or_skip(phys)
    back = PhysicalParams.from_dimensionless(p, phys, solve_for=solve_for)
    for field in ("inertia", "radius", "drag_torque", "backlash", "rpm", "order", "r", "v_stick"):
        assert getattr(back, field) == pytest.approx(getattr(phys, field), rel=1e-10), field
    assert back.driver_radius == phys.driver_radius
    assert back.excitation == phys.excitation
    assert np.allclose(back.amplitudes, phys.amplitudes, rtol=1e-10, atol=0.0)
    assert all(abs(wrap_deg(a - b)) < 1e-9 for a, b in zip(back.phases_deg, phys.phases_deg))


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.filter_too_much])
@given(held=physical(), lam=log_uniform(0.05, 50.0), j=log_uniform(0.1, 50.0),
       h2=st.floats(0.0, 2.0), phi2=st.floats(-720.0, 720.0), r=st.floats(0.0, 1.0),
       solve_for=st.sampled_from(["rpm", "drag_torque", "inertia", "amplitude"]))
def test_round_trip_dimensionless(held, lam, j, h2, phi2, r, solve_for):
    """Dimensionless → physical → dimensionless returns the same Λ, j, h_k, φ_k (mod 360°), r."""
    assume(not (solve_for == "rpm" and held.excitation == "acceleration"))
    p = RattleParams(lam=lam, r=r, j=j, amplitudes=(1.0, h2), phases_deg=(30.0, phi2))
    try:
        phys = PhysicalParams.from_dimensionless(p, held, solve_for=solve_for)
    except ValueError as exc:
        # Only a physical input pushed out of its documented range may refuse.
        assert "outside the allowed range" in str(exc)
        assume(False)
    assert_params_close(phys.to_dimensionless(), p, rel=1e-10)
    assert phys.lam == pytest.approx(lam, rel=1e-10)


def test_solve_for_each_quantity_changes_only_that_quantity():
    """Solving Λ for one quantity keeps the others held and scales that one as the formula says."""
    held = example()
    p = held.to_dimensionless().replace(lam=4 * held.lam)
    by_rpm = PhysicalParams.from_dimensionless(p, held, "rpm")
    assert by_rpm.rpm == pytest.approx(2 * held.rpm, rel=1e-12)  # Λ ∝ ω²
    by_drag = PhysicalParams.from_dimensionless(p, held, "drag_torque")
    assert by_drag.drag_torque == pytest.approx(held.drag_torque / 4, rel=1e-12)  # Λ ∝ 1/F
    by_inertia = PhysicalParams.from_dimensionless(p, held, "inertia")
    assert by_inertia.inertia == pytest.approx(4 * held.inertia, rel=1e-12)  # Λ ∝ m
    by_amp = PhysicalParams.from_dimensionless(p, held, "amplitude")
    assert by_amp.amplitudes[0] == pytest.approx(4 * held.amplitudes[0], rel=1e-12)  # Λ ∝ H1
    assert by_amp.backlash == pytest.approx(4 * held.backlash, rel=1e-12)  # j = b / H1 held
    for q in (by_rpm, by_drag, by_inertia):
        assert q.backlash == pytest.approx(held.backlash, rel=1e-12)


def test_regime_c_impulse_balances_drag_over_one_period():
    """In physical units the regime C impulse 2π/Λ equals drag force × excitation period."""
    held = example()
    p = RattleParams(lam=1.2, r=0.65, j=8.0)
    phys = PhysicalParams.from_dimensionless(p, held, "rpm")
    tr = simulate(phys.to_dimensionless(), periods=20, transient=300)
    impulses = phys.impulse(tr.impact_impulse)
    assert len(impulses) == 20  # one impact per period
    # Momentum balance: each impact restores what the drag F removed during one period T.
    assert impulses == pytest.approx(np.full(20, phys.force * phys.period_s), rel=1e-9)
    assert np.diff(phys.time(tr.impact_t)) == pytest.approx(np.full(19, phys.period_s), rel=1e-9)


def test_backlash_conversions():
    """Backlash from µm and from an angle at R_b gives b along the line of action."""
    assert backlash_from_um(160.0) == pytest.approx(160e-6, rel=REL)
    assert backlash_from_angle(4e-3, 0.04) == pytest.approx(160e-6, rel=REL)
    assert backlash_from_angle(math.degrees(4e-3), 0.04, unit="deg") == pytest.approx(160e-6, rel=REL)
    assert example().backlash_deg == pytest.approx(math.degrees(4e-3), rel=REL)
    with pytest.raises(ValueError, match="unit"):
        backlash_from_angle(1.0, 0.04, unit="grad")
    with pytest.raises(ValueError, match=r"backlash_um = -3.0 is outside the allowed range \(0, 100000\]"):
        backlash_from_um(-3)


def test_four_cylinder_order_two_convention():
    """Order 2 at 3000 rpm is the firing frequency, 100 Hz: ω = order·2π·rpm/60."""
    assert omega_from_rpm(3000.0, 2.0) == pytest.approx(2 * math.pi * 100.0, rel=REL)
    assert example().replace(rpm=3000.0).period_s == pytest.approx(0.01, rel=REL)


@pytest.mark.parametrize("changes, pattern", [
    ({"inertia": -1.0}, r"inertia = -1.0 is outside the allowed range \(0, 10\]"),
    ({"radius": 0.0}, r"radius = 0.0 is outside the allowed range \(0, 2\]"),
    ({"drag_torque": float("nan")}, r"drag_torque must be finite, got nan; the allowed range is \(0, 10000\]"),
    ({"backlash": 1.0}, r"backlash = 1.0 is outside the allowed range \(0, 0.1\]"),
    ({"rpm": 0.0}, r"rpm = 0.0 is outside the allowed range \(0, 100000\]"),
    ({"order": -2.0}, r"order = -2.0 is outside the allowed range \(0, 100\]"),
    ({"r": 1.5}, r"r = 1.5 is outside the allowed range \[0, 1\]"),
    ({"amplitudes": (4.0,), "phases_deg": (0.0,)}, r"amplitudes\[0\].*4.0 is outside the allowed range \[0, 3.14"),
    ({"amplitudes": (0.0,), "phases_deg": (0.0,)}, r"amplitudes\[0\].*0.0 is outside the allowed range \(0,"),
    ({"amplitudes": (), "phases_deg": ()}, r"amplitudes must hold at least one harmonic"),
    ({"phases_deg": (0.0,)}, r"phases_deg has 1 entries but amplitudes has 2"),
    ({"excitation": "velocity"}, r"excitation = 'velocity' is not allowed"),
    ({"driver_radius": -0.1}, r"driver_radius = -0.1 is outside the allowed range"),
])
def test_bad_physical_input_names_parameter_value_and_range(changes, pattern):
    """Each bad physical input raises ValueError naming the parameter, its value and its range."""
    with pytest.raises(ValueError, match=pattern):
        example().replace(**changes)


def test_derived_out_of_range_names_the_dimensionless_parameter():
    """A valid physical set whose Λ exceeds the model's range says so, naming lam."""
    phys = example().replace(drag_torque=1e-7)  # Λ ≈ 9.9e4 > 1e4
    with pytest.raises(ValueError, match=r"lam = 98696\.\d+ is outside the allowed range \(1e-06, 10000\]; "
                       r"it derives from the physical inputs \(H1 = 2e-05 m"):
        phys.to_dimensionless()


def test_bad_rpm_arrays_and_solve_for():
    """lam_from_rpm rejects empty/negative/NaN speeds; from_dimensionless rejects bad solve_for."""
    phys = example()
    for bad, pattern in [([], "empty"), ([1000.0, -5.0], r"rpm = -5.0 is outside"),
                         ([np.nan], r"rpm = nan is outside")]:
        with pytest.raises(ValueError, match=pattern):
            lam_from_rpm(phys, bad)
    with pytest.raises(ValueError, match="solve_for = 'speed' is not allowed"):
        PhysicalParams.from_dimensionless(phys.to_dimensionless(), phys, solve_for="speed")
    acc = phys.replace(excitation="acceleration", amplitudes=(100.0, 10.0))
    with pytest.raises(ValueError, match="does not depend on engine speed"):
        PhysicalParams.from_dimensionless(acc.to_dimensionless(), acc, solve_for="rpm")


def test_as_excitation_changes_the_description_not_the_model():
    """Displacements and accelerations describe the same excitation: Λ, j, h_k, φ_k unchanged."""
    phys = example().replace(amplitudes=(5e-4, 1.25e-4), phases_deg=(0.0, 45.0))
    acc = phys.as_excitation("acceleration")
    assert acc.excitation == "acceleration"
    assert acc.amplitudes[1] == pytest.approx(1.25e-4 * (2 * phys.omega) ** 2, rel=1e-14)
    assert acc.phases_deg[1] == pytest.approx(-135.0)
    a, b = phys.to_dimensionless(), acc.to_dimensionless()
    assert (b.lam, b.j) == pytest.approx((a.lam, a.j), rel=1e-12)
    assert b.amplitudes == pytest.approx(a.amplitudes, rel=1e-12)
    assert b.phases_deg == pytest.approx(a.phases_deg, abs=1e-9)
    back = acc.as_excitation("displacement")
    assert back.amplitudes == pytest.approx(phys.amplitudes, rel=1e-12)
    assert phys.as_excitation("displacement") is phys
    with pytest.raises(ValueError, match="excitation"):
        phys.as_excitation("velocity")


def test_physical_table_names_engine_orders_and_speaks_one_phase_convention():
    """The table names the fundamental's harmonics by engine order (k × order) and gives every
    phase, physical and dimensionless, in the convention asked for: the paper's is the map of
    rattle_core.model.phases applied to the core's, and the same on both sides."""
    from rattle_core.analysis.vocabulary import physical_table
    from rattle_core.model.phases import core_to_paper
    phys = example()
    core = {r[0]: r for r in physical_table(phys)}
    paper = {r[0]: r for r in physical_table(phys, phases="paper")}
    want = float(core_to_paper(phys.phases_deg[1], 2))
    row = paper[f"engine order {2 * phys.order:g} (θ_2, phase paper)"]
    assert row[1].endswith(f", {want:.6g}°") and row[2].endswith(f"φ_2 = {want:.6g}°")
    assert core[f"engine order {2 * phys.order:g} (θ_2, phase core)"][1].endswith(f", {phys.phases_deg[1]:.6g}°")
    assert f"θ₁ (engine order {phys.order:g})" in core
    with pytest.raises(ValueError, match="phases"):
        physical_table(phys, phases="sine")
