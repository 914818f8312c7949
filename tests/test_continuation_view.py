"""The dashboard's continuation without a browser: the branch drawn on the diagram, its marks,
the multipliers plot, the state it leaves for the URL and the cache that redraws it.

The harmonic C orbit (r = 0.65, j = 8; the paper's Figure 3C at Λ = 1.2) is checked against
closed forms: its impulse is 2π/Λ all along the branch, and it period-doubles at
Λ = √(Γ₁² + (2(1+r²)/(1+r)²)²), Γ₁ = π(1−r)/(1+r).
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import wait_for

from app.work.branch import continue_both_ways, from_job
from app.ui.branch_glyphs import BranchGlyphs
from app.views.continuation import multipliers_element
from app.presets import PRESETS
from rattle_core import RattleParams
from rattle_core.analysis.continuation import c_orbit

R = 0.65
LAM_PD = math.hypot(math.pi * (1 - R) / (1 + R), 2 * (1 + R**2) / (1 + R) ** 2)


def drawn(glyphs) -> dict:
    """What ``glyphs`` hold on their figure: per renderer name, its finite points (lines: all
    polylines' points, one row each), and the legend."""
    out = {}
    for name, model in glyphs.models.items():
        if name == "cont-legend":
            continue
        data = model.data_source.data
        if "xs" in data:
            xy = np.array([(x, y) for xs, ys in zip(data["xs"], data["ys"]) for x, y in zip(xs, ys)],
                          float).reshape(-1, 2)
        else:
            xy = np.column_stack([np.asarray(data["x"], float), np.asarray(data["y"], float)])
        out[name] = xy[np.isfinite(xy).all(axis=1)]
    return out


def on_a_figure(branch, name):
    """``branch`` drawn on diagram ``name`` on a figure of its own: the glyphs."""
    from bokeh.plotting import figure
    glyphs = BranchGlyphs()
    assert glyphs.attach(figure()) and glyphs.models is not None
    glyphs.draw(branch, name, ((0.5, 4.0), (0.0, 10.0)))
    return glyphs


def continued(dash, **values):
    """Set the state, press "Continue this orbit" and wait for the branch."""
    s = dash.state
    s.param.update(**values)
    assert not dash.continuation.button.disabled
    dash.continuation.button.clicks += 1
    wait_for(lambda: s.branch is not None or "continuation" in s.messages, 180, "the branch")
    assert s.branch is not None, s.messages
    return s.branch


def test_c_branch_on_the_diagram_is_two_pi_over_lambda_and_period_doubles_at_the_closed_form(dash):
    """Continued from regime C at Λ = 1.2: stable part Ĩ = 2π/Λ to 1e-9, PD mark at 1.23940."""
    s = dash.state
    dash.diagram.pane.get_root()  # the diagram's figure, which the branch is drawn on as it comes
    b = continued(dash, **PRESETS["Fig 3C"][1])
    assert s.result.cls.regime == "C" and s.continuation and s.cont_from == 1.2
    # the branch arrives from the job's thread, and is drawn there just after it is set
    wait_for(lambda: len(drawn(dash.diagram.branch)["cont-labels"]) > 0, 30, "the branch drawn")
    glyphs = drawn(dash.diagram.branch)
    xy = glyphs["cont-stable"]
    marks = dash.diagram.branch.models["cont-marks"].data_source.data
    first = b.impacts[b.impacts["branch"] == 0]
    strict = np.concatenate([g[g["stable"]][["x", "y"]].to_numpy()
                             for _, g in first.groupby("direction")])
    assert len(strict) >= 10
    np.testing.assert_allclose(strict[:, 1], 2 * np.pi / strict[:, 0], rtol=0, atol=1e-9)
    # the drawn stable line is those points (plus where it meets the dashed part)
    assert np.isin(strict[:, 0], xy[:, 0]).all() and len(xy) <= len(strict) + 4
    unstable = glyphs["cont-unstable"]
    assert len(unstable) >= 2 and unstable[:, 0].max() > 3.9
    pd_at = [(x, y) for x, y, label in zip(marks["x"], marks["y"], marks["label"]) if label == "PD"]
    assert len(pd_at) >= 1
    assert pd_at[0][0] == pytest.approx(LAM_PD, abs=1e-6)
    assert pd_at[0][1] == pytest.approx(2 * np.pi / LAM_PD, abs=1e-6)
    labels = [dash.diagram.branch.models[n].data_source.data["label"]
              for n in ("cont-labels", "cont-labels-r")]
    assert "PD" in {t.strip() for layer in labels for t in layer}
    # HoloViews empties the figure's legends when it redraws the diagram; the entries come back
    dash.diagram.revision += 1
    legend = dash.diagram.branch.models["cont-legend"]
    assert legend.visible and [it.label.value for it in legend.items if it.visible] == [
        b.legend(i) for i in b.numbers]
    # going up from Λ = 1.2 the branch is stable until 1.2394, then unstable (μ crossed −1)
    up = b.points[(b.points["direction"] == "up") & (b.points["branch"] == 0)]
    assert up[up["x"] < LAM_PD - 1e-6]["stable"].all()
    assert not up[up["x"] > LAM_PD + 1e-6]["stable"].any()
    assert "PD at 1.2394" in dash.continuation.status.object


def test_multipliers_of_the_current_point_lie_inside_the_unit_circle_when_stable(dash):
    """The multipliers plot shows the nearest branch point's μ: inside |μ| = 1 at Λ = 1.2, one
    outside at Λ = 2 on the same (now unstable) branch; the C orbit's own multipliers."""
    s = dash.state
    continued(dash, **PRESETS["Fig 3C"][1])
    circle, pts = dash.continuation.multipliers[()].values()
    mu = pts.array()
    want = c_orbit(RattleParams(lam=1.2)).multipliers
    assert len(mu) == 2 and np.all(np.hypot(mu[:, 0], mu[:, 1]) < 1.0)
    np.testing.assert_allclose(np.sort_complex(mu[:, 0] + 1j * mu[:, 1]), np.sort_complex(want),
                               atol=1e-9)
    assert np.allclose(np.hypot(*circle.array().T), 1.0)
    # moving Λ keeps the branch and moves the point along it
    branch = s.branch
    s.lam = 2.0
    assert s.branch is branch and s.continuation and s.cont_from == 1.2
    _, pts = dash.continuation.multipliers[()].values()
    assert np.max(np.hypot(*pts.array().T)) > 1.0
    assert "unstable" in multipliers_element(s.branch, 2.0).opts.get().kwargs["title"]


def test_branch_is_redrawn_from_the_cache_and_dropped_when_other_parameters_change(dash, tmp_path):
    """The state (continuation, cont_from) alone brings the branch back, from the disk cache;
    a change of r hides it and clears those keys; the job's arrays round-trip without pickle."""
    s = dash.state
    first = continued(dash, **PRESETS["Fig 3C"][1])
    s.param.update(continuation=False, cont_from=None)
    assert s.branch is None
    s.param.update(continuation=True, cont_from=1.2)  # what a reopened link sets
    wait_for(lambda: s.branch is not None, 120, "the cached branch")
    assert s.branch.from_cache
    np.testing.assert_array_equal(s.branch.points["x"], first.points["x"])
    s.r = 0.6
    assert s.branch is None and not s.continuation and s.cont_from is None
    # the cache entry: saved as npz, loaded with allow_pickle=False, equal to a fresh run
    run = s.result
    args = (run.params.with_value("r", R).with_value("lam", 1.2), None, "lam", (0.5, 4.0),
            {"x0": None, "v0": 0.0, "t0": 0.0, "transient": 2000})
    fresh = continue_both_ways(*args, use_cache=False)
    stored = continue_both_ways(*args, directory=str(tmp_path))
    again = continue_both_ways(*args, directory=str(tmp_path))
    assert not stored["from_cache"] and again["from_cache"]
    assert list(tmp_path.glob("cont-*.npz"))
    for k, v in fresh["arrays"].items():
        np.testing.assert_array_equal(again["arrays"][k], v)
    assert again["meta"]["up"]["key"] == fresh["meta"]["up"]["key"]
    b = from_job("lam", "paper", None, (), 1.2, again)
    assert len(b.points) == len(first.points)


def test_button_needs_a_periodic_regime_and_no_branch_is_drawn_for_another_diagram(dash):
    """Chaos (Figure 3D, Λ = 1.16) disables the button; a branch of Λ draws nothing on φ₂."""
    s = dash.state
    s.param.update(**PRESETS["Fig 3D"][1])
    assert s.result.cls.chaotic and dash.continuation.button.disabled
    assert not any(len(xy) for xy in drawn(on_a_figure(None, "lam")).values())
    b = continued(dash, **PRESETS["Fig 3C"][1])
    assert any(len(xy) for xy in drawn(on_a_figure(b, "lam")).values())
    other = on_a_figure(b, "phi2")
    assert not any(len(xy) for xy in drawn(other).values())
    assert not other.models["cont-legend"].visible


def test_the_cascade_from_the_c_orbit_draws_each_branch_with_a_legend(dash):
    """From regime C at Λ = 1.2 the job switches branches at period doublings: at least two
    branches are drawn, each in its own colour with a legend entry naming its period; the first
    doubling is at the closed-form Λ_PD, where the period-2 branch starts with both impulses
    2π/Λ_PD; the next doublings come closer and closer (the cascade)."""
    b = continued(dash, **PRESETS["Fig 3C"][1])
    assert len(b.numbers) >= 2
    periods = [int(b.points[b.points["branch"] == i]["period"].iloc[0]) for i in b.numbers]
    assert periods[:3] == [1, 2, 4][:len(periods[:3])]
    pd_at = np.sort(b.marks[b.marks["kind"] == "period_doubling"]["x"].unique())
    assert pd_at[0] == pytest.approx(LAM_PD, abs=1e-7)
    gaps = np.diff(pd_at)
    assert len(gaps) >= 2 and np.all(gaps > 0) and np.all(gaps[1:] < gaps[:-1])
    start = b.impacts[(b.impacts["branch"] == 1)].sort_values("point")
    first = start[start["point"] == start["point"].min()]
    assert first["x"].to_numpy() == pytest.approx(LAM_PD, abs=1e-6)
    np.testing.assert_allclose(first["y"], 2 * np.pi / LAM_PD, atol=1e-6)
    assert b.legend(0) == "period 1, from 1.2"
    assert b.legend(1) == f"period 2, PD at {LAM_PD:.5g}"
    assert b.legend(2) == f"period 4, PD at {pd_at[1]:.5g}"
    # drawn: one legend item per branch, each holding its solid and its dashed line
    legend = on_a_figure(b, "lam").models["cont-legend"]
    assert legend.visible and legend.click_policy == "hide"  # a click on an entry hides that branch
    items = [it for it in legend.items if it.visible]
    assert [getattr(it.label, "value", it.label) for it in items] == [b.legend(i) for i in b.numbers]
    assert all(len(it.renderers) == 2 for it in items)
    colours = {it.renderers[0].glyph.line_color for it in items}
    assert len(colours) == len(items)
    for item in items:
        data = item.renderers[0].data_source.data
        assert sum(np.isfinite(np.asarray(x, dtype=float)).sum() for x in data["xs"]) >= 2
    # on a HoloViews figure the legend stays as drawn when HoloViews redraws the figure (it
    # empties and moves the figure's first legend), as the diagram's hook puts it back
    import holoviews as hv
    glyphs, redraws, hooked = BranchGlyphs(), hv.streams.Counter(), []

    def hook(plot, element):
        hooked.append(plot.state)
        if glyphs.attach(plot.state):
            glyphs.draw(b, "lam", ((1.0, 4.0), (0.0, 10.0)))
    dmap = hv.DynamicMap(lambda counter: hv.Curve([(1, 1), (4, 9)]) * hv.Scatter([(2, 3)]),
                         streams=[redraws]).opts(hv.opts.Overlay(hooks=[hook]))
    hv.renderer("bokeh").get_plot(dmap)
    legend = glyphs.models["cont-legend"]
    drawn_at = legend.location
    redraws.event()
    assert len(hooked) == 2 and hooked[0] is hooked[1]  # redrawn, on the same figure
    assert legend.location == drawn_at and legend.click_policy == "hide"
    assert [it.label.value for it in legend.items if it.visible] == [b.legend(i) for i in b.numbers]


def test_crowded_period_doublings_get_one_label_each_and_none_overlap():
    """The cascade's doublings crowd near Λ = 1.4: each labelled bifurcation gets one label,
    no two labels overlap (a label's box: 0.08 of the view's width, 0.06 of its height), all
    lie inside the view, and those with no free row are left out rather than piled up."""
    import pandas as pd

    from app.ui.branch_glyphs import MAX_STACKED, mark_labels

    xs = [1.2393959, 1.3764403, 1.4017300, 1.4069375, 1.4080577, 1.4083]
    marks = pd.DataFrame({"x": xs + xs[1:3], "y": [9.0, 9.5, 9.6, 9.7, 9.75, 9.8, 9.2, 9.3],
                          "kind": ["period_doubling"] * 8, "label": ["PD"] * 8})
    limits = ((1.2, 1.45), (0.0, 10.0))
    left, right = mark_labels(marks, limits)
    shown = pd.concat([left, right]).dropna()
    (x0, x1), (y0, y1) = limits
    assert 1 <= len(shown) <= len(xs)
    assert shown["x"].round(9).is_unique  # one label per doubling, never two
    assert shown["x"].between(x0, x1).all() and shown["y"].between(y0, y1).all()
    rows = list(zip(shown["x"], shown["y"]))
    for i, (xa, ya) in enumerate(rows):
        for xb, yb in rows[i + 1:]:
            assert abs(xa - xb) >= 0.08 * (x1 - x0) or abs(ya - yb) >= 0.06 * (y1 - y0) - 1e-12
    near_14 = shown[shown["x"] > 1.37]
    assert len(near_14) <= MAX_STACKED


def test_the_a_b_legend_goes_to_the_corner_free_of_points():
    """Pin B's single Poincaré point in the top right (where the legend used to sit) sends the
    legend to another corner; points in three corners leave it the empty fourth; with no
    point at all it stays top right."""
    from app.views.explorer import free_corner

    lims = ((0.0, 1.0), (0.0, 1.0))
    assert free_corner(np.array([0.9]), np.array([0.9]), *lims) != "top_right"
    x, y = np.array([0.9, 0.1, 0.9]), np.array([0.9, 0.9, 0.1])
    assert free_corner(x, y, *lims) == "bottom_left"
    assert free_corner(np.zeros(0), np.zeros(0), *lims) == "top_right"


def test_no_branch_drawn_again_sends_the_page_nothing():
    """A diagram with no branch, redrawn: no glyph's data is set again (each set is a message
    to the page: 13 of them at every redraw before), while a branch drawn after is set."""
    from bokeh.document import Document
    from bokeh.plotting import figure

    glyphs, fig = BranchGlyphs(), figure()
    assert glyphs.attach(fig)
    doc = Document()
    doc.add_root(fig)
    glyphs.draw(None, "lam")
    events: list = []
    doc.on_change(events.append)
    glyphs.draw(None, "lam")
    assert events == []
    marks = glyphs.models["cont-marks"].data_source
    marks.data = {k: np.array([1.0]) if k in ("x", "y") else np.array(["a"]) for k in marks.data}
    events.clear()
    glyphs.draw(None, "lam")  # drawn marks, then none: set
    assert len(marks.data["x"]) == 0 and [getattr(e, "attr", None) for e in events] == ["data"]
