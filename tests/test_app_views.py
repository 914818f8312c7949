"""The dashboard's views without a browser: what they draw, and what they write to the state.

Plot data are checked against the trajectory they come from (every impact where the solver
put it, the gear between the walls, physical units by ``PhysicalParams``); a whole
:class:`app.dashboard.Dashboard`, built outside any server, is driven through its public
state and its views' widgets, as the browser tests drive it through the page.
"""
from __future__ import annotations

import io
import math
import types

import numpy as np
import pandas as pd
import pytest
from conftest import wait_for

from app.work import diagram_data as dd
from app.ui import labels, plots
from app.views.controls import impacts_table
from rattle_core import RattleParams, classify, simulate, units
from rattle_core.analysis.overlays import contact_boundary
from rattle_core.model.excitation import TWO_PI, excitation

HARMONIC_E = RattleParams(lam=3.3)
STICKING_B = RattleParams(lam=1.1)


@pytest.fixture(scope="module")
def tr_e():
    return simulate(HARMONIC_E, periods=40, transient=100)


# ----- plot data ------------------------------------------------------------------------------

def test_time_history_keeps_the_gear_between_the_teeth_and_impacts_on_their_walls(tr_e):
    """x(t) lies between the walls, every impact of the window sits on its flank's wall."""
    d = plots.time_history_data(tr_e, shown=10)
    m, imp = d["motion"], d["impacts"]
    assert np.all(m["x"] >= m["y"] - 1e-9) and np.all(m["x"] <= m["yj"] + 1e-9)
    assert m["t"][-1] == pytest.approx(tr_e.t_start + 10 * TWO_PI)
    np.testing.assert_array_equal(imp["t"], tr_e.impact_t[tr_e.impact_t <= tr_e.t_start + 10 * TWO_PI])
    y = excitation(imp["t"], HARMONIC_E.h, HARMONIC_E.phi)
    np.testing.assert_allclose(imp["x"], np.where(imp["flank"] > 0, y, y + HARMONIC_E.j), atol=1e-9)
    assert len(imp["t"]) == 20 and set(imp["flank"]) == {1, -1}


def test_time_history_in_physical_units_is_um_against_ms():
    """Units: t in ms from the window start, positions in µm (or degrees of the idle gear)."""
    phys = units.example()
    tr = simulate(phys.to_dimensionless(), periods=10, transient=50)
    d = plots.time_history_data(tr, 5, phys)
    dim = plots.time_history_data(tr, 5)
    assert d["labels"][:2] == ("t [ms]", "position along the line of action [µm]")
    np.testing.assert_allclose(d["motion"]["t"], 1e3 * (dim["motion"]["t"] - tr.t_start) / phys.omega)
    np.testing.assert_allclose(d["motion"]["x"], 1e6 * phys.H1 * dim["motion"]["x"])
    assert d["motion"]["t"][-1] == pytest.approx(5 * 1e3 * phys.period_s)
    ang = plots.time_history_data(tr, 5, phys, angle=True)
    np.testing.assert_allclose(ang["motion"]["x"], np.degrees(phys.H1 * dim["motion"]["x"] / phys.radius))


def test_one_sided_overlays_are_two_pi_n_over_lambda():
    """Overlay curves are Ĩ = 2πn/Λ against Λ, and 2πn/Λ(rpm) × m ω H₁ against rpm (N·s)."""
    run = types.SimpleNamespace(params=HARMONIC_E, phys=units.example())
    for n, c in enumerate(dd.one_sided("lam", run, 0.5, 4.0), start=1):
        np.testing.assert_allclose(c[:, 1], TWO_PI * n / c[:, 0], rtol=1e-15)
    for n, c in enumerate(dd.one_sided("rpm", run, 500, 6000), start=1):
        want = TWO_PI * n / units.lam_from_rpm(run.phys, c[:, 0]) * units.impulse_scale_from_rpm(run.phys, c[:, 0])
        np.testing.assert_allclose(c[:, 1], want, rtol=1e-12)


def test_marks_are_the_contact_boundary_and_the_first_chaotic_value():
    """Onset = contact_boundary (rpm_from_lam of it against rpm); chaos = first value in D."""
    run = types.SimpleNamespace(params=HARMONIC_E, phys=units.example())
    d = dd.Diagram("lam", (0.5, 4.0), np.zeros(0), np.zeros(0), np.zeros(0, np.int8),
                   np.array([0.5, 1.0, 1.5, 2.0]), np.array(["A", "C", "D", "D"]), "test")
    m = dd.marks("lam", run, d)
    assert m == {"onset": pytest.approx(contact_boundary(HARMONIC_E)), "chaos": 1.5}
    m = dd.marks("rpm", run, None)
    assert m["onset"] == pytest.approx(float(units.rpm_from_lam(run.phys, contact_boundary(HARMONIC_E))))


def test_diagram_range_holds_the_current_value():
    """The range asked for is the default one, stretched only to hold the current value."""
    assert dd.full_range("lam", "paper", 0.6) == (0.5, 4.0)
    assert dd.full_range("lam", "paper", 0.3) == (pytest.approx(0.24), 4.0)
    assert dd.full_range("rpm", "paper", 1500.0) == (500.0, 6000.0)
    assert dd.full_range("phi2", "paper", 45.0) == (0.0, 360.0)


def test_badge_says_how_the_gear_sticks_whatever_the_classification_carries():
    """Sticking reads as a percentage (not 1e+02 %), or the core's sticking kind when present."""
    cls = classify(simulate(RattleParams(lam=0.8), periods=50, transient=100, lyapunov=True))
    b = labels.regime_badge(cls)
    assert b["letter"] == "A" and "sticking 100 % of the time" in b["detail"] and "e+" not in b["detail"]
    fake = types.SimpleNamespace(**{**{k: getattr(cls, k) for k in cls.__dataclass_fields__},
                                    "sticking": "chaos-through-sticking",
                                    "loop_amplification": 4.2, "noisy": True})
    assert "chaos through sticking, statistics at this noise level" in labels.regime_badge(fake)["detail"]
    fake.sticking, fake.period, fake.regime = "stick-locked", 3, "B"
    assert "stick-locked, exact, period 3, loop amplification 10^4.2" in \
        labels.regime_badge(fake)["detail"]
    html = labels.badge_html(fake)
    assert 'data-regime="B"' in html and "<script" not in html


def test_messages_and_tables_escape_text():
    """User text reaches the page escaped: a script payload stays text."""
    html = labels.message_html("x = '<img src=x onerror=alert(1)>'")
    assert "<img" not in html and "&lt;img src=x onerror=alert(1)&gt;" in html
    assert "<script>" not in labels.table_html([("<script>", "a")], "t")


def test_impacts_csv_is_the_clis_table(tmp_path):
    """The CSV export equals `rattle simulate --impacts` for the same run, flank as
    active/reverse."""
    from rattle_cli.main import main
    out = tmp_path / "imp.csv"
    assert main(["simulate", "--lam", "3.3", "--h2", "0.25", "--phi2", "45", "--paper-phases",
                 "--periods", "50", "--transient", "300", "--impacts", str(out), "-q"]) == 0
    params = RattleParams.paper(3.3, amplitudes=(1.0, 0.25), phases_deg=(0.0, 45.0))
    tr = simulate(params, periods=50, transient=300, lyapunov=True)
    run = types.SimpleNamespace(tr=tr, phys=None)
    ours = impacts_table(run).to_csv(index=False)
    assert ours == out.read_text()
    assert set(pd.read_csv(io.StringIO(ours))["flank"]) == {"active", "reverse"}


def test_file_names_and_captions_carry_the_parameters():
    """PNG/CSV names and plot titles name Λ, r, j, h₂, φ₂ and the convention (and rpm in SI)."""
    run = types.SimpleNamespace(params=RattleParams.paper(3.3, amplitudes=(1, 0.25), phases_deg=(0, 45)),
                                phases="paper", phys=None)
    assert plots.file_stem(run, "time") == "rattle_time_lam3.3_r0.65_j8_h2-0.25_phi2-45paper"
    assert plots.caption(run) == "Λ = 3.3 · r = 0.65 · j = 8 · h2 = 0.25, φ2 = 45° (paper)"
    assert plots.caption(run, "lam") == "r = 0.65 · j = 8 · h2 = 0.25, φ2 = 45° (paper)"
    assert plots.caption(run, "phi2") == "Λ = 3.3 · r = 0.65 · j = 8 · h2 = 0.25 (paper)"
    run.phys = units.example()
    assert plots.file_stem(run, "time").endswith("_1500rpm") and "1500 rpm" in plots.caption(run)
    by_speed = plots.caption(run, "rpm")
    assert "rpm" not in by_speed and "Λ" not in by_speed and "j =" not in by_speed
    assert by_speed.startswith("r = 0.65 · h2 = 0.25") and "C = " in by_speed


# ----- a whole dashboard, driven through its state and widgets ---------------------------------------

def _xsum(d) -> float:
    return float(np.sum(d.time_history.sources["motion"].data["x"]))


def test_slider_box_moves_the_state_and_redraws_every_view(dash):
    """Λ typed in its box: one new run, drawn by the time history, section and badge."""
    before = _xsum(dash)
    dash.controls.fields["lam"].box.value = 3.4
    s = dash.state
    assert s.lam == 3.4 and s.result.params.lam == 3.4 and _xsum(dash) != before
    assert len(dash.section.points[0]) == s.periods
    assert f'data-regime="{s.result.cls.regime}"' in dash.regime.badge.object


def test_rejected_value_keeps_the_view_and_the_slider_range(dash):
    """r = −0.5: message beside r, r kept, view unchanged, the slider's range not stretched."""
    field = dash.controls.fields["r"]
    before = _xsum(dash)
    field.box.value = -0.5
    s = dash.state
    assert s.r == 0.65 and field.box.value == 0.65 and _xsum(dash) == before
    assert "r = -0.5 is outside the allowed range; allowed [0, 1]" in s.messages["r"]
    assert (field.slider.start, field.slider.end) == (0.0, 1.0)
    assert field.msg.visible and "&lt;" not in field.msg.object
    field.box.value = 0.6
    assert "r" not in s.messages and not field.msg.visible
    dash.controls.fields["lam"].box.value = 8.0  # a good value outside the slider's range
    assert dash.controls.fields["lam"].slider.end == 8.0


def test_click_on_the_section_starts_the_gear_there(dash):
    """A click on the Poincaré map sets (x₀, ẋ₀) at t₀ = strobe phase; outside the teeth it is refused."""
    from app.views.explorer import start_from_section
    s = dash.state
    s.strobe = 90.0
    p = s.result.params
    y0 = float(excitation(math.pi / 2, p.h, p.phi))
    assert start_from_section(s, y0 + 2.0, 1.5)
    assert s.x0 == pytest.approx(y0 + 2.0) and (s.v0, s.t0) == (1.5, pytest.approx(math.pi / 2))
    assert s.result.tr.settings["x0"] == pytest.approx(y0 + 2.0)
    assert not start_from_section(s, y0 - 1.0, 0.0) and "outside the backlash" in s.messages["start"]


def test_diagram_is_shipped_marks_the_current_value_and_a_click_sets_lambda(dash):
    """The default diagram is the shipped Figure 4; its range holds Λ; a click sets Λ."""
    d = dash.diagram
    assert d.diagram is not None and "fig4" in d.diagram.source
    assert d.span == (0.5, 4.0) and "600 values of Λ swept" in d.status.object
    d.set_swept(2.123456)
    assert dash.state.lam == 2.1235 and dash.state.result.params.lam == 2.1235
    assert d.marker in (None, 2.1235)  # on a drawn page, the marker follows
    assert d.diagram is not None and "fig4" in d.diagram.source  # Λ moves only the marker
    assert d._title == "Bifurcation diagram · r = 0.65 · j = 8 · h2 = 0.25, φ2 = 45° (paper)"


def test_diagram_at_lambda_06_shows_the_whole_range_and_counts_every_value(dash):
    """Λ = 0.6, r = 0.6: computed over [0.5, 4] (marker inside); the count names every value."""
    s = dash.state
    s.param.update(lam=0.6, r=0.6)
    d = dash.diagram
    wait_for(lambda: d.diagram is not None and d.revision > 0 and "swept" in d.status.object,
             what="the diagram")
    assert d.span == (0.5, 4.0) and d.diagram.swept.size == 400
    assert d.status.object.count("400 values of Λ swept") == 1 and "without impacts" in d.status.object
    assert d.diagram.swept.min() <= 0.6 <= d.diagram.swept.max()


def test_zoom_recomputes_the_visible_region_finer(dash):
    """A zoom into a narrow Λ window computes 300 values there and merges them."""
    d = dash.diagram
    coarse = np.unique(d.diagram.swept[(d.diagram.swept >= 2.0) & (d.diagram.swept <= 2.3)]).size
    assert d.refine(2.0, 2.3)
    wait_for(lambda: "refined" in d.status.object, what="the refined region")
    fine = np.count_nonzero((d.diagram.swept >= 2.0) & (d.diagram.swept <= 2.3))
    assert fine >= 300 > 2 * coarse and "1 region refined" in d.status.object
    assert not d.refine(2.05, 2.25)


def test_parameter_change_cancels_the_running_diagram(dash, job_pool):
    """Moving r while a diagram computes cancels that job; the new one finishes."""
    s = dash.state
    r = 0.55 + 0.05 * np.random.default_rng().random()  # not in the disk cache
    s.r = round(r, 12)
    first = [j for j in job_pool.pending(dash.session.key) if j.owner[1] == "diagram"]
    s.r = round(r + 1e-3, 12)
    assert first and all(j.cancelled for j in first)
    wait_for(lambda: dash.diagram.diagram is not None, what="the diagram")
    assert dash.diagram.diagram.name == "lam"


def test_units_mode_draws_rpm_and_si(dash):
    """Units on: the diagram runs against rpm over the whole range with N·s, the table shows SI."""
    s = dash.state
    s.units = True
    assert s.bif == "rpm" and dash.units.table.visible and "rpm" in dash.units.table.object
    assert dash.time_history.fig.xaxis.axis_label == "t [ms]"
    assert "impact rate" in dash.regime.metrics.object and "N·s" in dash.regime.metrics.object
    d = dash.diagram
    wait_for(lambda: d.diagram is not None and d.diagram.name == "rpm", what="the rpm diagram")
    assert d.span == (500.0, 6000.0) and d.axes()[0] == "engine speed [rpm]"
    phys = s.result.phys
    wanted = units.impulse_scale_from_rpm(phys, d.diagram.x)
    assert np.all(np.abs(d.diagram.impulse) <= 1e3 * np.max(wanted))
    d.set_swept(2222.04)
    assert s.rpm == 2222.0 and s.lam == pytest.approx(float(units.lam_from_rpm(phys, 2222.0)), rel=1e-12)
    s.units = False
    assert s.bif == "lam"


def test_harmonics_can_be_added_and_removed(dash):
    """Adding order 3 (paper phases) puts it in the solver's harmonics; removing restores two."""
    c, s = dash.controls, dash.state
    assert c.add_harmonic(3, 0.1, 30.0)
    assert s.result.params.amplitudes == (1.0, 0.25, 0.1)
    assert s.result.params.phases_deg[2] == RattleParams.paper(1, amplitudes=(1, 0, 0.1),
                                                               phases_deg=(0, 0, 30)).phases_deg[2]
    assert not c.add_harmonic(3, -1.0, 0.0) and "harmonics" in s.messages
    assert c.remove_harmonic(3) and s.result.params.amplitudes == (1.0, 0.25)


def test_two_dashboards_do_not_share_state(dash, job_pool):
    """Two sessions hold separate states, runs and figures."""
    from app.dashboard import Dashboard
    other = Dashboard(pool=job_pool)
    try:
        dash.state.lam = 2.0
        assert other.state.lam == 3.3 and other.state.result.params.lam == 3.3
        assert other.time_history.sources["motion"] is not dash.time_history.sources["motion"]
    finally:
        other.destroy()


def test_skipped_model_walks_leave_the_document_exact(dash):
    """After redraws, the document's model set equals a full recompute (the Bokeh patch is sound)."""
    from bokeh.document import Document
    doc = Document()
    dash.layout.server_doc(doc)
    for lam in (3.0, 3.1, 3.2):
        dash.state.lam = lam
    dash.state.section = "impact"
    dash.state.units = True
    kept = set(doc.models)
    doc.models.recompute()
    assert set(doc.models) == kept


@pytest.mark.parametrize("params, noise, sticking, text", [
    (RattleParams(lam=1.05), True, "stick-locked", "stick-locked, exact, period 1, loop amplification 10^"),
    (RattleParams.paper(lam=3.3, amplitudes=(1.0, 0.25), phases_deg=(0.0, 45.0)), True,
     "chaos-through-sticking", "chaos through sticking, statistics at this noise level"),
    (RattleParams.paper(lam=3.3, amplitudes=(1.0, 0.25), phases_deg=(0.0, 45.0)), False,
     "chaos-through-sticking", "loop chosen by rounding: not resolvable (noise off)"),
])
def test_badge_says_which_kind_of_answer_motion_through_sticking_is(params, noise, sticking, text):
    """The badge tells a robust stick-locked orbit (exact) from chaos through sticking
    (statistics at the run's noise) and from a strict run whose loop rounding chose."""
    from app.ui.labels import badge_html
    cls = classify(simulate(params if noise else params.replace(noise=0.0), periods=3000,
                            transient=500, lyapunov=True))
    html = badge_html(cls)
    assert f'data-sticking="{sticking}"' in html and text in html


def test_time_history_zoom_lasts_while_the_time_axis_keeps_its_meaning(dash):
    """A zoom survives a Λ change, but an engine-speed change reframes the time history."""
    th, s = dash.time_history, dash.state
    th.fig.x_range.update(start=1.0, end=2.0)  # what a zoom in the page sends back
    zoom = th.fig.x_range
    s.lam = 3.1
    assert th.fig.x_range is zoom and (zoom.start, zoom.end) == (1.0, 2.0)
    s.units = True
    t_end = th.sources["motion"].data["t"][-1]
    th.fig.x_range.update(start=10.0, end=20.0)
    zoom = th.fig.x_range
    s.rpm = 0.8 * s.rpm
    new_end = th.sources["motion"].data["t"][-1]
    assert new_end == pytest.approx(t_end / 0.8, rel=1e-6)
    fresh = th.fig.x_range
    assert fresh is not zoom and math.isnan(fresh.start) and math.isnan(fresh.end)


def test_plots_share_an_axis_only_where_it_means_the_same(dash):
    """Panel links the ranges of plots whose axes share a name; on this page only the twin
    trajectory and its separation share one (time), so only they may be linked."""
    import panel as pn
    dash.state.twin = True
    panes = [dash.section.pane, dash.diagram.pane, dash.maps.pane, dash.continuation.pane,
             dash.curve.pane, *dash.sensitivity.plots]
    root = pn.Column(*panes).get_root()
    shared: dict[int, list] = {}
    for pane in panes:
        fig = pane._plots[root.ref["id"]][0].state
        for axis, rng in (("x", fig.x_range), ("y", fig.y_range)):
            shared.setdefault(id(rng), []).append((pane.css_classes[0], axis))
    linked = sorted(v for v in shared.values() if len(v) > 1)
    assert linked == [[("twin-paths", "x"), ("twin-gap", "x")]], linked
