"""The paper's five claims (docs/model.md), computed from the solver under the paper's phase
reading; the literal reading fails them; the cases, the presets and the figure writer."""
from __future__ import annotations

import math

import numpy as np
import pytest

from rattle_core import RattleParams, classify, contact_boundary, simulate
from rattle_core.analysis.overlays import period1_limits_harmonic
from rattle_core.model.phases import core_to_paper, paper_to_core, paper_to_core_phases, wrap_deg
from rattle_core.paper.cases import CASES, explorer_presets, paper_params, poincare_cloud
from rattle_core.paper.evidence import (claim1_holds, claim2_holds, claim3_holds, claim4_holds,
                                        claim5_holds, evidence_values, phase_convention_evidence)
from rattle_core.paper.figures import write_paper_figures
from rattle_core.store.cache import cached_sweep

LAMS = evidence_values()          # 0.5 … 4 step 0.01
SETTINGS = {"transient": 500, "record": 200}


@pytest.fixture(scope="module")
def cache_directory(tmp_path_factory):
    # a private cache: the claims must come from the solver as it is now
    return tmp_path_factory.mktemp("claims-cache")


def _lam_sweep(params, directory):
    return cached_sweep(params, "lam", LAMS, directory=directory, **SETTINGS).summary


@pytest.fixture(scope="module")
def harmonic(cache_directory):
    return _lam_sweep(paper_params(1.0), cache_directory)


@pytest.fixture(scope="module")
def paper45(cache_directory):
    return _lam_sweep(paper_params(1.0, 45.0), cache_directory)


@pytest.fixture(scope="module")
def paper90(cache_directory):
    return _lam_sweep(paper_params(1.0, 90.0), cache_directory)


def _regimes(summary, lo, hi):
    s = summary[(summary["value"] >= lo - 1e-9) & (summary["value"] <= hi + 1e-9)]
    return s["regime"]


def test_paper_reading_is_the_named_case():
    """Paper φ2 = 45° and 90° are core −135° and 180° (y = Σ h sin(kt + φ)); the cases use them."""
    assert paper_to_core_phases((0.0, 45.0)) == (0.0, -135.0)
    assert paper_to_core_phases((0.0, 90.0)) == (0.0, 180.0)
    for key, phi in (("fig4", -135.0), ("fig5", 180.0), ("fig7", -135.0), ("fig8", 180.0)):
        p = CASES[key].params
        assert p.amplitudes == (1.0, 0.25) and p.phases_deg == (0.0, phi)
        assert (p.r, p.j) == (0.65, 8.0)
    assert CASES["fig2"].params.amplitudes == (1.0,)
    assert CASES["fig7"].params.lam == 3.3 and CASES["fig8"].params.lam == 3.3
    assert CASES["fig6"].params.lam == 1.95 and CASES["fig6"].name == "phi2"
    paper_axis = CASES["fig6"].axis(CASES["fig6"].values)
    np.testing.assert_allclose(paper_axis, np.linspace(0, 360, 600), atol=1e-12)
    np.testing.assert_allclose(core_to_paper(paper_to_core([45.0, 90.0], wrap=False), wrap=False),
                               [45.0, 90.0])
    assert paper_to_core(45.0) == -135.0 and core_to_paper(-135.0) == 45.0
    assert paper_to_core(90.0, k=3) == -270.0 + 360.0 and wrap_deg(-180.0) == 180.0
    # the sin(kt + φ) reading really is that excitation: same y up to a quarter-period shift
    t = np.linspace(0, 7, 50)
    p = paper_params(1.0, 45.0)
    y_core = np.cos(t) + 0.25 * np.cos(2 * t - np.deg2rad(p.phases_deg[1]))
    y_paper = np.sin(t + np.pi / 2) + 0.25 * np.sin(2 * (t + np.pi / 2) + np.deg2rad(45.0))
    np.testing.assert_allclose(y_core, y_paper, atol=1e-12)


def test_claim1_harmonic_regime_order(harmonic):
    """Claim 1: harmonic excitation gives A, B, C, D, E in that order; E covers a large range."""
    ok, first = claim1_holds(harmonic)
    assert ok, first
    assert first["A"] == 0.5 and 1.0 <= first["B"] < 1.05
    assert first["B"] < first["C"] < first["D"] < first["E"]
    # A exactly below the contact boundary Λc = 1
    assert (_regimes(harmonic, 0.5, 0.99) == "A").all()
    assert contact_boundary(paper_params(2.0)) == pytest.approx(1.0)
    # C only where the period-1 orbit exists and is stable (below the period-doubling limit)
    c = harmonic.loc[harmonic["regime"] == "C", "value"]
    assert c.max() < period1_limits_harmonic(0.65)[1]
    # E from about 1.58 up to 4: at least half of all values, all of Λ ∈ [1.6, 4]
    assert (harmonic["regime"] == "E").mean() >= 0.5
    assert (_regimes(harmonic, 1.6, 4.0) == "E").all()


def test_claim2_paper_45_no_c_no_e_chaos_beside_sticking(paper45):
    """Claim 2: φ2 = 45°: C and E disappear; chaotic two-flank responses beside stick-and-impact."""
    reg = paper45["regime"]
    assert not (reg == "C").any() and not (reg == "E").any()
    chaos = paper45[(reg == "D") & (paper45["n_active"] > 0) & (paper45["n_reverse"] > 0)]
    assert len(chaos) >= 0.05 * len(paper45)
    assert (chaos["lyapunov"] > 0).all() and (chaos["period"] == 0).all()
    assert (reg == "B").sum() >= 0.05 * len(paper45)
    assert claim2_holds(paper45)


def test_claim3_paper_90_periodic(paper90):
    """Claim 3: φ2 = 90°: periodic responses; the large range of chaos is gone."""
    reg = paper90["regime"]
    assert (reg == "D").sum() <= 0.02 * len(paper90)
    periodic = (paper90["period"] >= 1) & (reg != "A")
    assert periodic.mean() >= 0.75
    # E returns for large Λ, as in the harmonic case
    assert (_regimes(paper90, 3.0, 4.0) == "E").all()
    assert claim3_holds(paper90)


def test_claim4_lambda_3_3_paper_45_chaotic():
    """Claim 4: Λ = 3.3, φ2 = 45°: chaotic, a strange attractor in the Poincaré map."""
    p = paper_params(3.3, 45.0)
    c = classify(simulate(p, periods=1000, transient=500, lyapunov=True))
    assert claim4_holds(c), c.label
    assert c.lyapunov > 0.03 and c.period == 0
    # the section is a cloud, not a finite set: many distinct points over many grid boxes
    x, v, ph, imp = poincare_cloud(p, n_points=3000)
    assert len(x) == 3000
    assert len(np.unique(np.round(np.c_[x, v], 6), axis=0)) > 2900
    boxes = {(int(a), int(b)) for a, b in zip((x - x.min()) / np.ptp(x) * 39.999,
                                              (v - v.min()) / np.ptp(v) * 39.999)}
    assert len(boxes) > 150
    assert (imp > 0).any() and (imp < 0).any()


def test_claim5_lambda_3_3_paper_90_period_one_two_flanks():
    """Claim 5: Λ = 3.3, φ2 = 90°: periodic, one impact on each flank per period, like harmonic."""
    c = classify(simulate(paper_params(3.3, 90.0), periods=1000, transient=500, lyapunov=True))
    assert claim5_holds(c), c.label
    h = classify(simulate(paper_params(3.3), periods=1000, transient=500, lyapunov=True))
    assert h.regime == "E" and c.regime == "E"
    assert c.active_per_period == pytest.approx(1.0) and c.reverse_per_period == pytest.approx(1.0)


def test_literal_reading_fails(cache_directory):
    """The literal reading y = Σ h cos(kt − φ) (core φ2 = 45°, 90°) fails the paper's claims."""
    lit = {ph: RattleParams(lam=1.0, amplitudes=(1.0, 0.25), phases_deg=(0.0, ph))
           for ph in (45.0, 90.0)}
    s45 = _lam_sweep(lit[45.0], cache_directory)
    s90 = _lam_sweep(lit[90.0], cache_directory)
    c45 = classify(simulate(lit[45.0].replace(lam=3.3), periods=1000, transient=500, lyapunov=True))
    c90 = classify(simulate(lit[90.0].replace(lam=3.3), periods=1000, transient=500, lyapunov=True))
    verdicts = [claim2_holds(s45), claim3_holds(s90), claim4_holds(c45), claim5_holds(c90)]
    assert not all(verdicts)
    # specifically: E survives at 45°, and chaos fills a large range at 90°
    assert (s45["regime"] == "E").sum() > 20
    assert (s90["regime"] == "D").sum() > 0.1 * len(s90)


def test_phase_convention_evidence_singles_out_the_paper_reading(cache_directory, tmp_path):
    """Of the four readings only sin(kt + φ) reproduces all five claims; the table is written."""
    table = phase_convention_evidence(tmp_path, directory=cache_directory)
    assert len(table) == 4 and table["claim1"].all()
    winners = list(table.loc[table["all_hold"], "reading"])
    assert winners == ["sin(kt + φ) (paper preset)"]
    assert not table.loc[0, "all_hold"] and table.loc[0, "reading"].startswith("cos(kt − φ)")
    row = table.set_index("reading").loc["sin(kt + φ) (paper preset)"]
    assert row["core_phi2_45"] == -135.0 and row["core_phi2_90"] == 180.0
    assert row["lam3.3_45"] == "D" and row["lam3.3_90"] == "E"
    text = (tmp_path / "phase_convention.md").read_text(encoding="utf-8")
    assert "sin(kt + φ)" in text and "| claim 1 |" in text
    assert math.isfinite(row["lam3.3_lyapunov_45"]) and row["lam3.3_lyapunov_45"] > 0


def test_write_paper_figures(tmp_path):
    """``write_paper_figures`` writes fig2 … fig8 as PNG, reporting progress up to the total."""
    calls = []
    paths = write_paper_figures(tmp_path, progress=lambda d, n: calls.append((d, n)),
                                evidence=False, cache_directory=tmp_path / "cache")
    assert [p.name for p in paths] == [f"fig{k}.png" for k in range(2, 9)]
    for p in paths:
        assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and p.stat().st_size > 10_000
    done = [d for d, _ in calls]
    assert all(b >= a for a, b in zip(done, done[1:])) and done[-1] == calls[-1][1]


def test_explorer_presets_come_from_the_cases():
    """Each dashboard preset is its paper case's parameters (Figure 3: one per panel's Λ), and
    the regime a Figure 3 preset names is the one it shows."""
    presets = {p.label: p for p in explorer_presets()}
    assert list(presets) == ["Fig 2", "Fig 3B", "Fig 3C", "Fig 3D", "Fig 3E", "Fig 4", "Fig 5",
                             "Fig 6", "Fig 7", "Fig 8"]
    for label, preset in presets.items():
        case = CASES[f"fig{label[4]}"]
        assert preset.params.replace(lam=case.params.lam) == case.params, label
        if case.kind != "sweep":
            assert preset.params.lam in (case.lams or (case.params.lam,)), label
        assert preset.view["bif"] == ("phi2" if case.name == "phi2" else "lam"), label
    assert [presets[f"Fig 3{g}"].params.lam for g in "BCDE"] == list(CASES["fig3"].lams)
    for g in "BCE":
        tr = simulate(presets[f"Fig 3{g}"].params, periods=200, transient=300, lyapunov=True)
        assert classify(tr).regime == g
