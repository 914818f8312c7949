"""Bifurcation curves in two parameters, against closed forms and fresh one-parameter runs.

The harmonic C orbit is known in closed form (impulse 2π/Λ, impact phase sin θ = −Γ/Λ with
Γ = π(1 − r)/(1 + r)), so its fold curve, its period-doubling curve, and where its flight
reaches the reverse flank are closed forms too; the contact boundary is 1/max(−ÿ), computed
here on its own; everything else is checked against ``continue_orbit`` run afresh at a point
of the curve.
"""
from __future__ import annotations

import math
import threading
from dataclasses import replace as dataclass_replace

import numpy as np
import pytest

from rattle_core import (RattleParams, contact_bifurcation, continue_bifurcation, continue_orbit,
                         find_orbit, units)
from rattle_core.analysis.continuation import c_orbit
from rattle_core.model.excitation import excitation

R = 0.65


def gamma(r):
    return np.pi * (1 - r) / (1 + r)


def lam_pd(r):
    return np.sqrt((2 * (1 + r**2) / (1 + r) ** 2) ** 2 + gamma(r) ** 2)


def c_height(lam, theta):
    """Largest ``x − y`` over the C orbit's flight from the impact at θ (harmonic): where the
    flight comes nearest to the reverse flank.  Grid, then Newton on the relative velocity."""
    s = np.linspace(0.0, 2 * np.pi, 20001)
    f = np.pi / lam * s - s * s / (2 * lam) + np.cos(theta) - np.cos(theta + s)
    x = s[int(np.argmax(f))]
    for _ in range(50):
        d = np.pi / lam - x / lam + np.sin(theta + x)
        dd = -1 / lam + np.cos(theta + x)
        x -= d / dd
    return np.pi / lam * x - x * x / (2 * lam) + np.cos(theta) - np.cos(theta + x)


def max_neg_ydd(h, phi_deg):
    """``max_t(−ÿ)`` by a fine grid polished with Newton on ``y⁽³⁾ = 0``."""
    phi = np.radians(phi_deg)
    k = np.arange(1, len(h) + 1)
    t = np.linspace(0, 2 * np.pi, 20000, endpoint=False)
    f = (np.asarray(h)[:, None] * k[:, None] ** 2 * np.cos(np.outer(k, t) - phi[:, None])).sum(0)
    x = t[int(np.argmax(f))]
    for _ in range(30):
        d3 = -(h * k**3 * np.sin(k * x - phi)).sum()
        d4 = -(h * k**4 * np.cos(k * x - phi)).sum()
        x -= d3 / d4
    return float((h * k**2 * np.cos(k * x - phi)).sum())


@pytest.fixture(scope="module")
def c_pd():
    res = continue_orbit(c_orbit(RattleParams(lam=1.2)), "lam", bounds=(1.2, 1.5))
    return next(b for b in res.bifurcations if b.kind == "period_doubling")


@pytest.fixture(scope="module")
def e_pd_curve():
    res = continue_orbit(find_orbit(RattleParams(lam=3.3)), "lam", bounds=(1.2, 3.3),
                         direction=-1, max_points=80)
    pd = next(b for b in res.bifurcations if b.kind == "period_doubling")
    return pd, continue_bifurcation(pd, "r", bounds=(0.5, 0.8))


def test_c_period_doubling_curve_is_the_closed_form_over_r(c_pd):
    """The C orbit's period doubling followed in r is Λ_PD(r) = √((2(1+r²)/(1+r)²)² + Γ(r)²)
    to 1e-8 at every point of r in [0.3, 0.9]; its impulse stays 2π/Λ, a multiplier −1."""
    cur = continue_bifurcation(c_pd, "r", bounds=(0.3, 0.9))
    pts = cur.points
    assert cur.status == "bound" and len(pts) > 10
    assert pts["r"].min() == pytest.approx(0.3, abs=1e-12)
    assert pts["r"].max() == pytest.approx(0.9, abs=1e-12)
    assert np.max(np.abs(pts["lam"] - lam_pd(pts["r"]))) < 1e-8
    assert np.allclose(pts["impulse_1"], 2 * np.pi / pts["lam"], atol=1e-9)
    assert np.allclose(pts["mu1_re"], -1.0, atol=1e-7)
    assert list(pts.columns[1:3]) == ["lam", "r"]


def test_c_fold_curve_is_the_closed_form_over_r():
    """The C orbit's fold followed in r is Λ_F(r) = π(1−r)/(1+r) to 1e-8 over [0.3, 0.9]
    (backlash 40, so that the orbit fits between the flanks all the way)."""
    res = continue_orbit(c_orbit(RattleParams(lam=0.9, j=40.0)), "lam", bounds=(0.5, 0.9),
                         direction=-1)
    fold = next(b for b in res.bifurcations if b.kind == "fold")
    cur = continue_bifurcation(fold, "r", bounds=(0.3, 0.9))
    pts = cur.points
    assert cur.status == "bound" and not cur.codim2
    assert pts["r"].min() == pytest.approx(0.3) and pts["r"].max() == pytest.approx(0.9)
    assert np.max(np.abs(pts["lam"] - gamma(pts["r"]))) < 1e-8
    assert np.allclose(pts["mu1_re"], 1.0, atol=1e-6)


@pytest.mark.parametrize("param2,bounds,h2,phi2", [("phi2", (-180.0, 180.0), 0.25, 45.0),
                                                    ("h2", (0.0, 1.0), 0.25, 45.0),
                                                    ("phi2", (0.0, 360.0), 0.6, 90.0)])
def test_contact_boundary_is_one_over_max_minus_ydd(param2, bounds, h2, phi2):
    """The contact boundary over H₂/H₁ or φ₂ is Λ_c = 1/max(−ÿ) to 1e-8 at every point,
    corners included (where another maximum of −ÿ takes over)."""
    p = RattleParams(lam=1.0, amplitudes=(1.0, h2), phases_deg=(0.0, phi2))
    cur = continue_bifurcation(contact_bifurcation(p), param2, bounds=bounds)
    pts = cur.points
    assert cur.status == "bound" and len(pts) > 10
    assert pts[param2].min() == pytest.approx(bounds[0]) and pts[param2].max() == \
        pytest.approx(bounds[1])
    for row in pts.itertuples():
        hh = (1.0, row.h2 if param2 == "h2" else h2)
        ff = (0.0, row.phi2 if param2 == "phi2" else phi2)
        assert row.lam == pytest.approx(1.0 / max_neg_ydd(np.array(hh), np.array(ff)), abs=1e-8)
    if h2 == 0.6:
        # the two maxima of −ÿ trade places at φ₂ = 180°
        (corner,) = pts.loc[pts["event"] == "corner", "phi2"]
        assert corner == pytest.approx(180.0, abs=1e-6)


def test_e_period_doubling_continued_in_r_matches_fresh_continuations(e_pd_curve):
    """The E orbit's period doubling (Λ = 1.550866099 at r = 0.65) followed in r agrees at
    r = 0.62, 0.70 and 0.78 with the first period doubling of a fresh continuation of E down
    from Λ = 3.3 at that r, to 1e-8."""
    pd, cur = e_pd_curve
    assert pd.value == pytest.approx(1.550866099, abs=1e-9)
    for r in (0.62, 0.70, 0.78):
        crossings = cur.at(r)
        assert crossings
        lam_curve = max(v for v, _ in crossings)
        fresh = continue_orbit(find_orbit(RattleParams(lam=3.3, r=r)), "lam", bounds=(1.0, 3.3),
                               direction=-1, max_points=200)
        first = next(b for b in fresh.bifurcations if b.kind == "period_doubling")
        assert lam_curve == pytest.approx(first.value, abs=1e-8)
    # the curve turns back in r: below r ≈ 0.588 E has no period doubling
    turns = [c for c in cur.codim2 if c.kind == "turn"]
    assert len(turns) == 1 and 0.58 < turns[0].value2 < 0.6
    assert not cur.at(0.55)


def test_fold_meets_period_doubling_where_the_doubled_orbits_change_side(e_pd_curve):
    """On E's period-doubling curve the doubling turns subcritical at a fold–flip point: just
    below its r the period-2 branch leaves on the stable side, just above on the unstable
    side and folds.  Restarted there, the period-2 orbits' fold curve passes through that
    fold of a fresh one-parameter continuation at r = 0.77, to 1e-8."""
    _, cur = e_pd_curve
    (gpd,) = [c for c in cur.codim2 if c.kind == "fold_period_doubling"]
    assert gpd.can_restart and gpd.other == "fold"
    for r, supercritical in ((gpd.value2 - 0.03, True), (gpd.value2 + 0.03, False)):
        fresh = continue_orbit(find_orbit(RattleParams(lam=3.3, r=r)), "lam", bounds=(1.0, 3.3),
                               direction=-1, max_points=200)
        first = next(b for b in fresh.bifurcations if b.kind == "period_doubling")
        p2 = continue_orbit(first, bounds=(1.0, 3.3), max_points=40)
        # E is stable above its doubling and unstable below it
        assert bool(p2.points["stable"].iloc[3]) == supercritical
        assert (p2.points["value"].iloc[3] < first.value) == supercritical
    fold_curve = continue_bifurcation(gpd, bounds=(0.5, 0.8))
    assert fold_curve.kind == "fold" and fold_curve.points["period"].eq(2).all()
    lam_curve = max(v for v, _ in fold_curve.at(0.77))
    fresh = continue_orbit(find_orbit(RattleParams(lam=3.3, r=0.77)), "lam", bounds=(1.0, 3.3),
                           direction=-1, max_points=200)
    first = next(b for b in fresh.bifurcations if b.kind == "period_doubling")
    p2 = continue_orbit(first, bounds=(1.0, 3.3), max_points=100)
    fold = next(b for b in p2.bifurcations if b.kind == "fold")
    assert lam_curve == pytest.approx(fold.value, abs=1e-8)


def test_grazing_meets_period_doubling_and_the_grazing_curve_is_exact(c_pd):
    """The C orbit's period doubling followed down in j ends where the flight reaches the
    reverse flank (j = max(x − y) of the closed-form orbit at Λ_PD, to 1e-8).  Restarted
    there, the grazing curve has j = max(x − y) of the C orbit at every point; it passes the
    period doubling again and, through the C orbit's fold at Λ = Γ, turns onto the unstable
    C orbit (a grazing–fold point)."""
    cur = continue_bifurcation(c_pd, "j", bounds=(1.0, 8.0))
    assert np.allclose(cur.points["lam"], lam_pd(R), atol=1e-9)
    (gp,) = [c for c in cur.codim2 if c.kind == "grazing_period_doubling"]
    assert gp.terminal and gp.can_restart and gp.other == "grazing"
    lp = lam_pd(R)
    theta = math.atan2(-gamma(R) / lp, math.sqrt(1 - (gamma(R) / lp) ** 2))
    assert gp.value2 == pytest.approx(c_height(lp, theta), abs=1e-8)
    gz = continue_bifurcation(gp, bounds=(1.0, 8.0), bounds1=(0.5, 3.0))
    assert gz.kind == "grazing" and len(gz.points) > 20
    for i in range(0, len(gz.points), 7):
        orb = gz.orbit(i)
        lam, theta = orb.params.lam, float(orb.t[0])
        assert math.sin(theta) == pytest.approx(-gamma(R) / lam, abs=1e-9)
        assert orb.params.j == pytest.approx(c_height(lam, theta), abs=1e-8)
    kinds = [c.kind for c in gz.codim2]
    assert "grazing_period_doubling" in kinds and "grazing_fold" in kinds
    gf = next(c for c in gz.codim2 if c.kind == "grazing_fold")
    assert gf.value1 == pytest.approx(gamma(R), abs=1e-8)
    assert [c.value2 for c in gz.codim2 if c.kind == "grazing_period_doubling"][0] == \
        pytest.approx(gp.value2, abs=1e-9)


def test_grazing_meets_the_onset_of_sticking():
    """An onset of sticking (r = 0.3, v_stick = 1e-3) followed in r ends where its flank
    stops pushing (σ(1 + Λÿ) = 0 at the slow impact, to 1e-8); restarted there, the grazing
    curve of the orbit without that impact touches the wall at a minimum of the gap, checked
    against the orbit's exact motion."""
    from scipy.optimize import minimize_scalar
    p = RattleParams(lam=1.05, r=0.3, v_stick=1e-3)
    up = continue_orbit(find_orbit(p), "lam", bounds=(1.0, 3.0))
    after = continue_orbit(up.bifurcations[-1], bounds=(1.0, 3.0))
    onset = after.bifurcations[-1]
    assert onset.kind == "stick_onset"
    cur = continue_bifurcation(onset, "r", bounds=(0.05, 0.6))
    k = onset.detail["impact"]
    for orb in cur.orbits:
        assert abs(orb.w[k]) == pytest.approx(1e-3, rel=1e-8)
    (gs,) = [c for c in cur.codim2 if c.kind == "grazing_sticking"]
    orb = gs.orbit
    q = orb.params
    assert abs(1 + q.lam * float(excitation(orb.t[k], q.h, q.phi, 2))) < 1e-8
    assert gs.can_restart and gs.other == "grazing"
    gz = continue_bifurcation(gs, bounds=(0.05, 0.6))
    assert gz.kind == "grazing" and len(gz.points) > 10
    for i in (len(gz.points) // 4, len(gz.points) // 2, 3 * len(gz.points) // 4):
        o = gz.orbit(i)
        cond = gz._ext.cond
        k0 = cond.k
        t1 = o.t[k0 + 1] if k0 + 1 < o.n_impacts else o.t[0] + 2 * np.pi * o.period
        pp = o.params

        def gap(t):
            x, _ = o.state_at(t)
            return float(x - excitation(t, pp.h, pp.phi)) if cond.wall == 1 else \
                float(excitation(t, pp.h, pp.phi) + pp.j - x)
        best = minimize_scalar(gap, bounds=(o.t[k0] + 1e-6, t1 - 1e-6), method="bounded",
                               options={"xatol": 1e-12})
        assert abs(best.fun) < 1e-8


def test_physical_plane_rpm_by_drag_torque():
    """In engine speed × drag torque the C orbit's period doubling is Λ(rpm, C) = Λ_PD, i.e.
    C = C₀ (Λ₀/Λ_PD)(rpm/rpm₀)², to 1e-8 relative at every point."""
    phys = units.PhysicalParams(inertia=2e-4, radius=0.04, drag_torque=0.02, backlash=160e-6,
                                rpm=2100.0, amplitudes=(5e-4,), order=2.0)
    p = phys.to_dimensionless()
    res = continue_orbit(c_orbit(p), "rpm", physical=phys, bounds=(2000.0, 2800.0))
    pd = next(b for b in res.bifurcations if b.kind == "period_doubling")
    cur = continue_bifurcation(pd, "drag_torque", bounds=(0.01, 0.03), bounds1=(1000, 4000))
    pts = cur.points
    assert list(pts.columns[1:3]) == ["rpm", "drag_torque"] and len(pts) > 5
    expect = phys.drag_torque * p.lam / lam_pd(R) * (pts["rpm"] / phys.rpm) ** 2
    assert np.allclose(pts["drag_torque"], expect, rtol=1e-8, atol=0)
    # the same from the drag torque's side, continued in engine speed
    res = continue_orbit(c_orbit(p), "drag_torque", physical=phys, bounds=(0.01, 0.02),
                         direction=-1)
    pd = next(b for b in res.bifurcations if b.kind == "period_doubling")
    cur = continue_bifurcation(pd, "rpm", bounds=(1500, 2500))
    expect = phys.drag_torque * p.lam / lam_pd(R) * (cur.points["rpm"] / phys.rpm) ** 2
    assert np.allclose(cur.points["drag_torque"], expect, rtol=1e-8, atol=0)


def test_bad_requests_name_the_parameter(c_pd):
    """Unknown or conflicting second parameters, bad bounds and kinds without a curve raise
    ValueError naming what is wrong."""
    cases = [(("zeta",), {}, "param"), (("lam",), {}, "own parameter"),
             (("r",), {"bounds": (0.9, 0.3)}, "bounds"), (("r",), {"bounds": (0.7, 0.9)}, "start"),
             (("r",), {"direction": 2}, "direction"), (("r",), {"max_points": 0}, "max_points"),
             (("rpm",), {}, "physical"), ((None,), {}, "param2"),
             (("r",), {"cancel": 3}, "cancel")]
    for args, kw, word in cases:
        with pytest.raises(ValueError, match=word):
            continue_bifurcation(c_pd, *args, **kw)
    with pytest.raises(ValueError, match="Bifurcation"):
        continue_bifurcation("pd", "r")
    stick = continue_orbit(find_orbit(RattleParams(lam=1.1)), "lam", bounds=(0.5, 1.1),
                           direction=-1)
    assert stick.bifurcations[-1].kind == "permanent_contact"
    with pytest.raises(ValueError, match="no curve"):
        continue_bifurcation(dataclass_replace(c_pd, kind="neimark_sacker"), "r")
    line = continue_bifurcation(stick.bifurcations[-1], "r", bounds=(0.3, 0.9))
    assert np.allclose(line.points["lam"], 1.0, atol=1e-9)  # r does not move Λ_c
    with pytest.raises(ValueError, match="param"):
        contact_bifurcation(RattleParams(lam=1.0), "r")


def test_end_of_sticking_continued_in_r_matches_a_fresh_continuation():
    """The harmonic B orbit's stick phase ends at Λ = 1.39591 (r = 0.65); followed in r (no
    extended system: the end is located in Λ at each r), a curve point agrees with the end of
    sticking a fresh continuation of B finds at that r, to 1e-8; every point's stick phase has
    shrunk below 1e-7."""
    up = continue_orbit(find_orbit(RattleParams(lam=1.1)), "lam", bounds=(1.1, 2.0))
    end = up.bifurcations[-1]
    assert end.kind == "stick_end"
    cur = continue_bifurcation(end, "r", bounds=(0.63, 0.66))
    pts = cur.points
    assert cur.status == "bound" and len(pts) >= 5 and (pts["stick_time"] < 1e-7).all()
    assert pts["r"].min() == pytest.approx(0.63) and pts["r"].max() == pytest.approx(0.66)
    assert np.all(np.diff(pts["lam"]) < 0)  # the end moves down in Λ as r grows
    row = pts.iloc[2]
    fresh = continue_orbit(find_orbit(RattleParams(lam=1.1, r=float(row["r"]))), "lam",
                           bounds=(1.1, 2.0))
    assert fresh.bifurcations[-1].kind == "stick_end"
    assert row["lam"] == pytest.approx(fresh.bifurcations[-1].value, abs=1e-8)


def test_progress_cancel_and_limit(c_pd):
    """Progress is reported per point; a set Event stops the curve; max_points stops it with a
    message."""
    ev = threading.Event()
    seen = []

    def progress(done, total):
        seen.append(done)
        if done == 4:
            ev.set()
    cur = continue_bifurcation(c_pd, "r", bounds=(0.3, 0.9), progress=progress, cancel=ev)
    assert cur.cancelled and len(cur.points) <= 6 and seen[:3] == [2, 3, 4]
    cur = continue_bifurcation(c_pd, "r", bounds=(0.3, 0.9), max_points=5)
    assert "max_points" in cur.status and "max_points" in cur.message
    assert cur.provenance["settings"]["max_points"] == 5


def test_contact_boundary_in_phase_zero_is_one_over_one_plus_four_h2():
    """With φ₂ = 0, −ÿ = cos t + 4h₂ cos 2t peaks at t = 0: Λ_c = 1/(1 + 4h₂) along h₂."""
    b = contact_bifurcation(RattleParams(lam=0.5))
    assert b.value == pytest.approx(1.0, abs=1e-12) and b.kind == "permanent_contact"
    cur = continue_bifurcation(b, "h2", bounds=(0.0, 2.0))
    pts = cur.points
    assert np.max(np.abs(pts["lam"] - 1 / (1 + 4 * pts["h2"]))) < 1e-12
    assert np.allclose(np.cos(pts["t_star"]), 1.0)


def test_atlas_of_a_window_holds_the_closed_forms():
    """The atlas of Λ ∈ [0.8, 2] × r ∈ [0.4, 0.8] (harmonic) holds the contact boundary Λ = 1
    and the C orbit's period doubling Λ_PD(r), both to 1e-8, every curve inside the window."""
    from rattle_core.analysis.continuation import atlas
    seen = []
    curves = atlas(RattleParams(lam=1.2), "lam", (0.8, 2.0), "r", (0.4, 0.8),
                   progress=lambda d, t: seen.append((d, t)))
    assert seen and seen[-1][0] <= seen[-1][1]
    kinds = [c.kind for c in curves]
    assert kinds[0] == "contact" and np.allclose(curves[0].points["lam"], 1.0, atol=1e-8)
    pds = [c for c in curves if c.kind == "period_doubling" and c.points["period"].eq(1).all()
           and c.points["n_impacts"].eq(1).all()]
    assert len(pds) == 1
    pts = pds[0].points
    assert np.max(np.abs(pts["lam"] - lam_pd(pts["r"]))) < 1e-8
    for c in curves:
        assert c.points["lam"].between(0.8 - 1e-9, 2.0 + 1e-9).all()
        assert c.points["r"].between(0.4 - 1e-9, 0.8 + 1e-9).all()
    with pytest.raises(ValueError, match="v_stick"):
        atlas(RattleParams(lam=1.2), "lam", (0.8, 2.0), "v_stick", (0, 1))


# ----- the command ------------------------------------------------------------------------------

def test_cli_atlas_writes_the_curve_its_codim2_points_and_png(tmp_path, capsys):
    """``rattle atlas --from c:lam:pd --param2 j`` writes the period-doubling curve (Λ_PD at
    every point), its grazing–doubling point and a PNG; in physical units the curve over
    drag torque is C = C₀ (Λ₀/Λ_PD)(rpm/rpm₀)²."""
    import pandas as pd
    from PIL import Image

    from rattle_cli.main import main
    out = tmp_path / "pd.csv"
    code = main(["atlas", "--lam", "1.2", "--from", "c:lam:pd", "--param2", "j", "--bounds",
                 "1,8", "--out", str(out), "--png", str(tmp_path / "pd.png"), "-q"])
    assert code == 0 and capsys.readouterr().out == ""
    pts = pd.read_csv(out)
    assert {"lam", "j", "impulse_1", "mu1_re", "mu2_re"} <= set(pts.columns)
    assert np.allclose(pts["lam"], lam_pd(R), atol=1e-9)
    c2 = pd.read_csv(tmp_path / "pd_codim2.csv")
    assert c2["kind"].tolist() == ["grazing_period_doubling"]
    with Image.open(tmp_path / "pd.png") as im:
        assert im.size[0] > 500
    out = tmp_path / "phys.csv"
    code = main(["atlas", "--inertia", "2e-4", "--radius", "0.04", "--drag-torque", "0.02",
                 "--backlash-um", "160", "--rpm", "2100", "--theta-amp", "5e-4", "--from",
                 "c:rpm:pd", "--bounds1", "1000,4000", "--param2", "drag_torque", "--bounds",
                 "0.01,0.03", "--out", str(out), "-q"])
    assert code == 0
    pts = pd.read_csv(out)
    lam0 = units.PhysicalParams(inertia=2e-4, radius=0.04, drag_torque=0.02, backlash=160e-6,
                                rpm=2100.0, amplitudes=(5e-4,)).to_dimensionless().lam
    expect = 0.02 * lam0 / lam_pd(R) * (pts["rpm"] / 2100.0) ** 2
    assert len(pts) > 5 and np.allclose(pts["drag_torque"], expect, rtol=1e-8, atol=0)


def test_cli_atlas_errors_are_one_line_and_come_first(tmp_path, capsys):
    """Bad specs, parameters, bounds and paths exit 2 with one line before any work; a
    bifurcation the branch never meets exits 1."""
    from rattle_cli.main import main
    ok = ["--from", "c:lam:pd", "--param2", "r", "--bounds", "0.3,0.9"]
    cases = [(["--from", "x:lam:pd"], "START"), (["--from", "c:lam:zz"], "KIND"),
             (["--from", "c:lam:pd:0"], "N"), (["--param2", "zeta"], "param"),
             (["--param2", "lam"], "same model number"), (["--bounds", "0.9"], "--bounds"),
             (["--bounds", "0.9,0.3"], "--bounds"), (["--param2", "rpm"], "physical"),
             (["--from", "contact:lam:pd"], "contact"), (["--max-points", "0"], "--max-points")]
    for extra, word in cases:
        argv = ["atlas", "--lam", "1.2", *ok, "--out", str(tmp_path / "x.csv"), *extra]
        code = main(argv)
        err = capsys.readouterr().err
        assert code == 2 and err.count("\n") == 1 and word in err, (extra, err)
    code = main(["atlas", "--lam", "1.2", *ok, "--out", str(tmp_path / "x.txt")])
    assert code == 2 and "--out" in capsys.readouterr().err
    code = main(["atlas", "--lam", "1.2", "--from", "c:lam:pd:3", "--bounds1", "1.2,1.5",
                 "--param2", "r", "--bounds", "0.3,0.9", "--out", str(tmp_path / "x.csv")])
    err = capsys.readouterr().err
    assert code == 1 and "asked for number 3" in err and err.count("\n") == 1
    assert not (tmp_path / "x.csv").exists()
