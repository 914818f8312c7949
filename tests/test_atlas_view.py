"""The dashboard's atlas without a browser: curves over a regime map, and a marked bifurcation
of the continued branch traced in a second parameter.

The harmonic C orbit's period doubling is the closed form Λ_PD(r) = √(Γ(r)² +
(2(1+r²)/(1+r)²)²), Γ(r) = π(1−r)/(1+r), and its contact boundary is Λ = 1; the curves the
views draw are checked against them, and the job's arrays against a reload from the cache.
"""
from __future__ import annotations

import numpy as np
import pytest
from conftest import wait_for

from app.views.atlas import curves_overlay
from app.work.atlas import atlas_curves, from_job


def lam_pd(r):
    return np.sqrt((2 * (1 + r**2) / (1 + r) ** 2) ** 2 + (np.pi * (1 - r) / (1 + r)) ** 2)


def paths(overlay, k: int) -> np.ndarray:
    el = list(overlay.values())[k]
    parts = [p for p in el.split(datatype="array")]
    xy = np.concatenate(parts) if parts else np.zeros((0, 2))
    return xy[np.all(np.isfinite(xy[:, :2]), axis=1)]


def test_draw_the_atlas_over_a_lam_by_r_map(dash):
    """Over a Λ × r map the atlas holds the contact boundary Λ = 1 and the C orbit's doubling
    Λ_PD(r) to 1e-8, in the element the map's plot overlays; the state keeps atlas = True;
    hiding it empties the element."""
    s, maps, atlas = dash.state, dash.maps, dash.atlas
    s.param.update(lam=1.2, h2=0.0)
    maps.settings.param.update(x_axis="lam", y_axis="r")
    maps.settings.param.update(x_start=0.8, x_stop=2.0, x_num=6, y_start=0.4, y_stop=0.8,
                               y_num=4, transient=40, record=20)
    assert maps.compute(), s.messages
    wait_for(lambda: maps.result is not None and not maps.progress.visible, what="the map")
    assert atlas.element in maps.overlays
    atlas.draw()
    assert s.atlas
    wait_for(lambda: atlas.curves is not None or "atlas" in s.messages, 240, "the atlas")
    assert atlas.curves is not None, s.messages
    ov = atlas.element[()]
    contact = paths(ov, 0)
    assert len(contact) >= 2 and np.allclose(contact[:, 0], 1.0, atol=1e-8)
    pd = paths(ov, 2)
    on_c = np.abs(pd[:, 0] - lam_pd(pd[:, 1])) < 1e-8
    assert on_c.sum() >= 10
    assert abs(pd[on_c, 1].min() - 0.4) < 1e-9 and abs(pd[on_c, 1].max() - 0.8) < 1e-9
    assert "curves" in atlas.run.status.object and "contact boundary" in atlas.legend.object
    s.atlas = False
    assert atlas.curves is None and len(paths(atlas.element[()], 2)) == 0


def test_atlas_job_reloads_from_the_cache_and_draws_paper_phases(tmp_path):
    """The job's arrays come back from the disk cache unchanged (without pickle); drawn in the
    paper's phase convention, the contact boundary over φ₂ is 1/max(−ÿ) at each point."""
    from app.main import configure
    from rattle_core import RattleParams
    configure()  # the plotting extension the overlay's options need
    p = RattleParams(lam=1.0, amplitudes=(1.0, 0.25), phases_deg=(0.0, 0.0))
    args = (p, None, "lam", (0.4, 1.2), "phi2", (-180.0, 180.0))
    first = atlas_curves(*args, directory=str(tmp_path))
    again = atlas_curves(*args, directory=str(tmp_path))
    assert not first["from_cache"] and again["from_cache"]
    for k, v in first["arrays"].items():
        np.testing.assert_array_equal(again["arrays"][k], v)
    c = from_job(again, "paper", "lam", "phi2")
    assert c.from_cache and c.count == len(first["meta"]["curves"])
    contact = c.paths["contact"][0]
    t = np.linspace(0, 2 * np.pi, 200001)
    for lam, phi_paper in contact[::5]:
        core = np.radians(-phi_paper - 90.0)  # the paper's φ₂ in the core's convention
        peak = np.max(np.cos(t) + np.cos(2 * t - core))
        assert abs(lam - 1.0 / peak) < 1e-6
    from rattle_core.analysis.vocabulary import CURVE_STYLES
    assert len(curves_overlay(c).values()) == len(CURVE_STYLES) + 1  # a path per kind, points


def test_a_click_on_a_marked_period_doubling_traces_its_curve(dash):
    """Continued from regime C at Λ = 1.2, the branch's PD mark clicked (the diagram's
    parameter set onto it): its curve in r is Λ_PD(r) to 1e-8; the state holds the kind, the
    value and the second parameter for the URL."""
    s = dash.state
    s.param.update(lam=1.2, h2=0.0)
    s.param.update(continuation=True, cont_from=1.2)
    wait_for(lambda: s.branch is not None or "continuation" in s.messages, 180, "the branch")
    assert s.branch is not None, s.messages
    pd = s.branch.marks[s.branch.marks["kind"] == "period_doubling"]["x"].iloc[0]
    s.curve_param2 = "r"
    s.lam = round(float(pd), 4)  # what a click on the mark does
    assert s.curve_kind == "period_doubling" and abs(s.curve_at - pd) < 1e-12
    view = dash.curve
    wait_for(lambda: view.curves is not None or "curve" in s.messages, 240, "the curve")
    assert view.curves is not None, s.messages
    xy = paths(view.element[()], 2)
    assert len(xy) >= 10 and np.max(np.abs(xy[:, 0] - lam_pd(xy[:, 1]))) < 1e-8
    assert xy[:, 1].min() < 0.35 and xy[:, 1].max() > 0.9
    assert "Traced in r" in view.run.status.object
    s.param.update(curve_kind="", curve_at=None)
    assert view.curves is None


def test_atlas_over_engine_speed_and_drag_torque(dash):
    """In physical units, over engine speed × drag torque: both move Λ only (Λ ∝ rpm²/C), so
    every curve of the atlas is a line of constant Λ, Λ(rpm, C) the same at all its points to
    1e-8 (relative), and the contact boundary's Λ is 1/max(−ÿ)."""
    from rattle_core.analysis.overlays import contact_boundary
    s, maps, atlas = dash.state, dash.maps, dash.atlas
    s.param.update(units=True, drag_torque=0.05, rpm=1500.0)
    assert (maps.settings.x_axis, maps.settings.y_axis) == ("rpm", "drag_torque")
    maps.settings.param.update(x_start=1000.0, x_stop=3000.0, x_num=5, y_start=0.02,
                               y_stop=0.08, y_num=4, transient=40, record=20)
    assert maps.compute(), s.messages
    wait_for(lambda: maps.result is not None and not maps.progress.visible, what="the map")
    atlas.draw()
    wait_for(lambda: atlas.curves is not None or "atlas" in s.messages, 300, "the atlas")
    assert atlas.curves is not None, s.messages
    phys = s.result.phys
    assert atlas.curves.count >= 2 and "contact" in atlas.curves.paths
    for kind, paths in atlas.curves.paths.items():
        for xy in paths:
            lam = np.array([phys.replace(rpm=float(a), drag_torque=float(b)).lam for a, b in xy])
            assert np.max(np.abs(lam / lam[0] - 1.0)) < 1e-8, kind
            if kind == "contact":
                assert lam[0] == pytest.approx(contact_boundary(phys.to_dimensionless()),
                                               rel=1e-9)
