"""Unit tests of the dashboard without a browser: view builders, state validation, the update path.

The view builders are checked against the trajectory they draw (every impact where the solver
put it, the gear between the walls, stick phases on a wall); the state layer against the
allowed ranges; and a whole :class:`app.dashboard.Dashboard`, built outside any server, against
the behaviour the UI tests see through the browser (a rejected value changes nothing).
"""
from __future__ import annotations

import io
import math
import time

import numpy as np
import pandas as pd
import pytest

from app import background, state as st, views
from rattle_core import RattleParams, classify, simulate
from rattle_core.model.excitation import TWO_PI, excitation

HARMONIC_E = RattleParams(lam=3.3)
STICKING_B = RattleParams(lam=1.1)


@pytest.fixture(scope="module")
def tr_e():
    return simulate(HARMONIC_E, periods=40, transient=100)


@pytest.fixture(scope="module")
def tr_b():
    return simulate(STICKING_B, periods=40, transient=100)


# ----- time history ---------------------------------------------------------------------------

def test_time_history_keeps_the_gear_between_the_teeth(tr_e):
    """Every sample of x(t) lies between the walls y and y + j, and the teeth lie outside them."""
    d = views.time_history_data(tr_e, shown=10)["motion"]
    assert np.all(d["x"] >= d["y"] - 1e-9) and np.all(d["x"] <= d["yj"] + 1e-9)
    assert np.all(d["tooth_lo"] < d["y"]) and np.all(d["tooth_hi"] > d["yj"])
    assert d["t"][0] == pytest.approx(tr_e.t_start)
    assert d["t"][-1] == pytest.approx(tr_e.t_start + 10 * TWO_PI)
    assert np.all(np.diff(d["t"]) > 0)


def test_time_history_samples_every_impact_instant_on_its_wall(tr_e):
    """Impact markers sit exactly on the wall of their flank, at the solver's impact times."""
    data = views.time_history_data(tr_e, shown=10)
    imp = data["impacts"]
    in_window = tr_e.impact_t[tr_e.impact_t <= tr_e.t_start + 10 * TWO_PI]
    np.testing.assert_array_equal(imp["t"], in_window)
    assert np.isin(imp["t"], data["motion"]["t"]).all()
    y = excitation(imp["t"], HARMONIC_E.h, HARMONIC_E.phi)
    expected = np.where(imp["flank"] > 0, y, y + HARMONIC_E.j)
    np.testing.assert_allclose(imp["x"], expected, atol=1e-9)
    assert set(imp["color"][imp["flank"] > 0]) == {views.ACTIVE_COLOR}
    assert set(imp["color"][imp["flank"] < 0]) == {views.REVERSE_COLOR}
    assert len(imp["t"]) == 20  # regime E: one impact per flank per period


def test_stick_phases_are_drawn_on_the_active_wall(tr_b):
    """In regime B the highlighted stick segments follow the active tooth y(t) exactly."""
    stick = views.time_history_data(tr_b, shown=5)["stick"]
    assert len(stick["xs"]) >= 1
    for ts, xs in zip(stick["xs"], stick["ys"]):
        np.testing.assert_allclose(xs, excitation(ts, STICKING_B.h, STICKING_B.phi), atol=1e-9)
    assert not views.time_history_data(simulate(HARMONIC_E, periods=5, transient=100), 5)["stick"]["xs"]


# ----- sections, rasters, overlays ----------------------------------------------------------

def test_section_points_follow_the_requested_section(tr_e):
    """Absolute, relative and impact sections return the strobe, strobe − wall and impact data."""
    x, v, *_ = views.section_points(tr_e, "absolute")
    np.testing.assert_array_equal(x, tr_e.strobe_x)
    xr, vr, *_ = views.section_points(tr_e, "relative")
    np.testing.assert_allclose(xr, tr_e.strobe_x - excitation(tr_e.strobe_t, HARMONIC_E.h, HARMONIC_E.phi))
    np.testing.assert_allclose(vr, tr_e.strobe_v - excitation(tr_e.strobe_t, HARMONIC_E.h, HARMONIC_E.phi, 1))
    p, i, *_ = views.section_points(tr_e, "impact")
    np.testing.assert_array_equal(i, tr_e.impact_impulse)
    with pytest.raises(ValueError, match="section mode"):
        views.section_points(tr_e, "sideways")


def test_rasterize_puts_points_in_their_pixels():
    """A point lands in the pixel of its coordinates; two flanks keep two distinct colours."""
    out = views.rasterize(np.array([0.25]), np.array([0.75]), (0, 1), (0, 1), 40, 20)
    img = out["image"][0]
    assert img.shape == (20, 40) and img.dtype == np.uint32
    rows, cols = np.nonzero(img)
    assert list(zip(rows, cols)) == [(15, 10)]  # row 0 is the bottom (y = 0)
    assert (out["x"], out["y"], out["dw"], out["dh"]) == ([0.0], [0.0], [1.0], [1.0])
    two = views.rasterize(np.array([0.1, 0.9]), np.array([0.5, 0.5]), (0, 1), (0, 1), 10, 10,
                          category=np.array([1, -1]), colors={1: "#ff0000", -1: "#0000ff"})["image"][0]
    opaque = two[(two >> 24) > 0]
    assert opaque.size == 2
    colours = {int(c) & 0xFFFFFF for c in opaque}
    assert colours == {0x0000FF, 0xFF0000}  # little-endian RGBA: red is the low byte
    with pytest.raises(ValueError, match="empty raster range"):
        views.rasterize(np.zeros(1), np.zeros(1), (1, 1), (0, 1), 10, 10)


def test_padded_range_is_finite_and_contains_the_data():
    """Ranges pad the data, ignore NaN, and open up around a single value or no data."""
    assert views.padded_range(np.array([1.0, 3.0])) == pytest.approx((0.9, 3.1))
    lo, hi = views.padded_range(np.array([2.0, 2.0, np.nan]))
    assert lo < 2.0 < hi
    assert views.padded_range(np.array([])) == (-1.0, 1.0)


def test_overlays_are_the_exact_one_sided_impulses():
    """Overlay curves are Ĩ = 2πn/Λ; the contact boundary shows against Λ only."""
    ov = views.overlay_lines("lam", 3.3, (0.5, 4.0), lam_c=1.0)
    for n, (xs, ys) in enumerate(zip(ov["curves"]["xs"], ov["curves"]["ys"]), start=1):
        np.testing.assert_allclose(ys, TWO_PI * n / xs, rtol=1e-15)
    assert ov["boundary"] == 1.0
    flat = views.overlay_lines("phi2", 2.0, (-180, 180), lam_c=1.0)
    assert flat["boundary"] is None
    np.testing.assert_allclose(flat["curves"]["ys"][1], [2 * math.pi, 2 * math.pi])


def test_badge_and_metrics_describe_the_classification(tr_e):
    """The badge shows the regime letter, period and Lyapunov exponent; HTML is escaped."""
    cls = classify(simulate(HARMONIC_E, periods=100, transient=300, lyapunov=True))
    html = views.badge_html(cls)
    assert 'data-regime="E"' in html and "period 1" in html and "not chaotic" in html
    assert f"{cls.lyapunov:+.4f}" in html
    table = views.metrics_html(cls, tr_e)
    assert "rattle intensity" in table and "<script" not in table


@pytest.mark.parametrize("params, noise, sticking, text", [
    (RattleParams(lam=1.05), True, "stick-locked", "stick-locked, exact, loop amplification 10^"),
    (RattleParams.paper(lam=3.3, amplitudes=(1.0, 0.25), phases_deg=(0.0, 45.0)), True,
     "chaos-through-sticking", "chaos through sticking, vanishing-noise statistics"),
    (RattleParams.paper(lam=3.3, amplitudes=(1.0, 0.25), phases_deg=(0.0, 45.0)), False,
     "chaos-through-sticking", "loop chosen by rounding: not resolvable (noise off)"),
])
def test_badge_says_which_kind_of_answer_motion_through_sticking_is(params, noise, sticking, text):
    """The badge tells a robust stick-locked orbit (exact) from chaos through sticking
    (vanishing-noise statistics) and from a strict run whose loop rounding chose."""
    cls = classify(simulate(params, periods=3000, transient=500, lyapunov=True, noise=noise))
    html = views.badge_html(cls)
    assert f'data-sticking="{sticking}"' in html and text in html


def test_impacts_csv_round_trips_exactly(tr_e):
    """The CSV export holds every impact with full float precision."""
    df = pd.read_csv(io.StringIO(views.impacts_csv(tr_e)))
    assert list(df.columns) == ["t", "phase", "impulse", "flank", "w"]
    np.testing.assert_array_equal(df["t"].to_numpy(), tr_e.impact_t)
    np.testing.assert_array_equal(df["impulse"].to_numpy(), tr_e.impact_impulse)
    assert set(df["flank"]) == {"active", "reverse"}


# ----- state ------------------------------------------------------------------------------

@pytest.mark.parametrize("name,value,fragment", [
    ("lam", -5, "Λ = -5.0 is outside the allowed range (1e-06, 10000]"),
    ("lam", "abc", "Λ must be a number"),
    ("r", 1.5, "r = 1.5 is outside the allowed range [0, 1]"),
    ("j", 0, "outside the allowed range (0, 10000]"),
    ("periods", 2.5, "whole number"),
    ("periods", 10**9, "outside the allowed range"),
    ("strobe", float("nan"), "must be finite"),
    ("section", "sideways", "allowed: absolute, relative, impact"),
    ("harmonics", "2:0.1:0", "order '2' must be a whole number in [3, 32]"),
    ("harmonics", "3:x:0", "must be a real number"),
])
def test_validate_field_names_the_control_and_its_range(name, value, fragment):
    """Bad values raise ValueError whose message names the symbol, the value and the range."""
    with pytest.raises(ValueError) as info:
        st.validate_field(name, value)
    assert fragment in str(info.value)


def test_harmonics_text_round_trips_into_the_core_parameters():
    """'k:h:φ' items become the core's amplitude and phase tuples, gaps filled with zeros."""
    s = st.DashboardState(harmonics=st.validate_field("harmonics", "5:0.05:-20, 3:0.1:30"))
    assert s.harmonics == "3:0.1:30.0,5:0.05:-20.0"
    p = st.rattle_params(s)
    assert p.amplitudes == (1.0, 0.25, 0.1, 0.0, 0.05)
    assert p.phases_deg == (0.0, s.phi2, 30.0, 0.0, -20.0)


def test_apply_values_keeps_good_values_and_reports_bad_ones():
    """One bad value does not cost the good ones, and leaves its own parameter unchanged."""
    s = st.DashboardState()
    errors = st.apply_values(s, {"lam": "abc", "r": 0.4, "j": -1, "nonsense": 1})
    assert s.r == 0.4 and s.lam == 3.3 and s.j == 8.0
    assert set(errors) == {"lam", "j", "nonsense"}


def test_presets_are_the_papers_cases_in_core_phases():
    """The Fig 7 and Fig 8 presets put the paper's φ₂ = 45° and 90° in as core −135° and 180°,
    and the default state opens on the paper's φ₂ = 45°."""
    assert st.PRESETS["Fig 7"][1]["phi2"] == -135.0
    assert abs(st.PRESETS["Fig 8"][1]["phi2"]) == 180.0
    assert st.DashboardState().phi2 == -135.0


@pytest.mark.parametrize("label,regime", [("Fig 3B", "B"), ("Fig 3C", "C"), ("Fig 3D", "D"),
                                          ("Fig 3E", "E"), ("Fig 7", "D"), ("Fig 8", "E")])
def test_presets_reproduce_the_papers_regimes(label, regime):
    """Each time-history preset, run as the dashboard runs it, shows the paper's regime."""
    s = st.DashboardState()
    assert st.apply_values(s, st.PRESETS[label][1]) == {}
    tr = simulate(st.rattle_params(s), periods=s.periods, transient=s.transient, lyapunov=True)
    assert classify(tr).regime == regime


# ----- the dashboard's update path, without a server ----------------------------------------------


def _xsum(d) -> float:
    return float(np.sum(d.th_src["motion"].data["x"]))


def test_slider_move_redraws_views(dash):
    """Moving Λ redraws time history, section and badge from one new trajectory (how fast:
    benchmarks/bench_app.py)."""
    before = _xsum(dash)
    dash.widgets["lam"].value = 3.4
    assert dash.state.lam == 3.4 and dash.tr.params.lam == 3.4
    assert _xsum(dash) != before
    assert len(dash.sec_src["points"].data["x"]) == dash.state.periods


def test_rejected_value_keeps_the_last_good_view(dash):
    """An out-of-range Λ shows a message beside Λ, reverts the control, and redraws nothing."""
    before = _xsum(dash)
    dash.widgets["lam"].value = -5.0
    assert dash.alerts["lam"].visible and "outside the allowed range" in dash.alerts["lam"].object
    assert dash.state.lam == 3.3 and dash.widgets["lam"].value == 3.3
    assert _xsum(dash) == before
    dash.widgets["lam"].value = 3.2
    assert not dash.alerts["lam"].visible


def test_initial_state_outside_the_backlash_is_reverted_with_a_message(dash):
    """x₀ outside the teeth is refused by the solver; x₀ returns to its last good value."""
    before = _xsum(dash)
    dash.widgets["x0"].value = 50.0
    assert dash.alerts["x0"].visible and "x0" in dash.alerts["x0"].object
    assert dash.state.x0 == "" and dash.widgets["x0"].value is None
    assert _xsum(dash) == before
    assert dash.advanced.collapsed is False


def test_preset_loads_all_its_parameters_in_one_redraw(dash):
    """The Fig 6 preset sets Λ = 1.95 and switches the diagram to φ₂ (the shipped Figure 6)."""
    dash.apply_preset("Fig 6")
    assert (dash.state.lam, dash.state.bif, dash.state.h2) == (1.95, "phi2", 0.25)
    assert dash.widgets["lam"].value == 1.95
    assert dash._bif is not None and dash._bif.name == "phi2"
    assert "fig6" in dash._bif.source
    assert dash.bif["marker"].location == dash.state.phi2


def test_click_on_the_section_starts_the_gear_there(dash):
    """A click on the Poincaré map sets (x₀, ẋ₀) at t₀ = strobe phase and marks the start point."""
    dash.state.strobe = 90.0
    y0 = float(excitation(math.pi / 2, dash.params.h, dash.params.phi))
    dash.start_from_section(y0 + 2.0, 1.5)
    assert float(dash.state.x0) == pytest.approx(y0 + 2.0)
    assert (dash.state.v0, dash.state.t0) == (1.5, pytest.approx(math.pi / 2))
    assert dash.tr.settings["x0"] == pytest.approx(y0 + 2.0)
    assert dash.sec_src["start"].data["x"] == [pytest.approx(y0 + 2.0)]
    dash.start_from_section(y0 - 1.0, 0.0)  # inside the active tooth
    assert dash.alerts["x0"].visible and float(dash.state.x0) == pytest.approx(y0 + 2.0)


def test_click_on_the_diagram_sets_lambda_and_moves_the_marker(dash):
    """A click on the Ĩ–Λ diagram sets Λ (rounded to 1e-4) and the current-value marker follows."""
    dash.set_from_diagram(2.123456)
    assert dash.state.lam == 2.1235
    assert dash.bif["marker"].location == 2.1235
    dash.set_from_diagram(-1.0)
    assert dash.alerts["lam"].visible and dash.state.lam == 2.1235


def test_zooming_the_diagram_recomputes_that_region_finer(dash):
    """A zoom into a narrow Λ window computes 300 values there in the background and merges them."""
    assert dash._bif is not None
    coarse = np.unique(dash._bif.value[(dash._bif.value >= 2.0) & (dash._bif.value <= 2.3)]).size
    dash._bif_view = (2.0, 2.3, -10.0, 10.0)
    assert dash.refine_visible()
    dash._job.future.result(timeout=120)
    fine = np.unique(dash._bif.value[(dash._bif.value >= 2.0) & (dash._bif.value <= 2.3)]).size
    assert fine > 2 * coarse
    assert "refined" in dash._bif.source
    assert not dash.refine_visible()  # already refined: nothing more to do


def test_parameter_change_cancels_the_running_sweep(dash):
    """Moving r while a diagram computes cancels that job and starts one for the new r."""
    dash.widgets["r"].value = 0.6
    first = dash._job
    assert first is not None and not first.cancelled
    dash.widgets["r"].value = 0.55
    assert first.cancelled and dash._job is not first
    dash._job.future.result(timeout=120)
    deadline = time.monotonic() + 10
    while dash.progress.visible and time.monotonic() < deadline:
        time.sleep(0.05)
    assert dash._bif is not None and dash._bif.name == "lam"
    assert len(dash.bif["sources"]["image"].data["image"]) == 1


def test_harmonics_can_be_added_and_removed(dash):
    """Adding order 3 puts it in the solver's harmonics; removing it restores two harmonics."""
    dash.harm_order.value, dash.harm_amp.value, dash.harm_phase.value = 3, 0.1, 30.0
    dash._on_harm_add()
    assert dash.tr.params.amplitudes == (1.0, 0.25, 0.1)
    assert dash.tr.params.phases_deg[2] == 30.0
    assert "k = 3" in dash.harm_list.object
    dash.harm_amp.value = -1.0
    dash._on_harm_add()
    assert dash.alerts["harmonics"].visible and dash.tr.params.amplitudes[2] == 0.1
    dash._on_harm_remove()
    assert dash.tr.params.amplitudes == (1.0, 0.25) and not dash.alerts["harmonics"].visible


def test_two_dashboards_do_not_share_state(dash):
    """Two sessions' dashboards hold separate states, figures and trajectories."""
    from app.dashboard import Dashboard

    other = Dashboard(sync_url=False)
    dash.widgets["lam"].value = 2.0
    assert other.state.lam == 3.3 and other.tr.params.lam == 3.3
    assert other.th_src["motion"] is not dash.th_src["motion"]


def test_background_job_cancelled_before_start_never_runs():
    """A job cancelled while queued returns without computing or reporting anything."""
    calls = []
    req = background.SweepRequest(RattleParams(lam=2.0), "lam", (2.0, 2.1), transient=1, record=1)
    job = background.Job(req, calls.append, calls.append, calls.append)
    job.cancel()
    job.run()
    assert calls == []
