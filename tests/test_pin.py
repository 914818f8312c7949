"""Pinning a run (A) beside the live one (B), without a browser.

The session's state, its URL (a ``Location`` object) and the views' data are checked against
runs of ``rattle_core.simulate`` made here, independently of the page, for A's settings.
"""
from __future__ import annotations

import math
import urllib.parse

import numpy as np
import pytest
from panel.io.location import Location

from app import state as st
from app.pinning import PIN_KEYS, PIN_PHYSICAL_KEYS, parse_pin, pin_text, pinned_state
from app.session import Session
from conftest import new_dashboard
from app.ui.labels import message_html
from app.ui.plots import time_history_data
from rattle_core import RattleParams, simulate
from rattle_core.model.phases import paper_to_core_phases

FIG4 = dict(lam=3.3, h2=0.25, phi2=45.0)


def opened(search: str) -> tuple[Session, Location]:
    loc = Location(search=search)
    return Session(location=loc), loc


def query(loc: Location) -> dict[str, str]:
    return dict(urllib.parse.parse_qsl(loc.search[1:], keep_blank_values=True))


def independent(lam: float, phi2: float, h2: float = 0.25, **kw):
    """A's run made here: the paper's phase convention converted by the core's own function,
    and the page's default run settings."""
    p = RattleParams(lam=lam, r=0.65, j=8.0, amplitudes=(1.0, h2),
                     phases_deg=tuple(paper_to_core_phases([0.0, phi2])))
    settings = dict(periods=200, transient=300, strobe_phase=0.0, **kw)
    return simulate(p, **settings)


# ----- the pin text -----------------------------------------------------------------------------

def test_pin_text_round_trips_every_run_setting():
    """A pin's text reads back as the very values it was made from (floats exactly)."""
    s = st.ExplorerState(lam=1.0 / 3.0, harmonics="3:0.1:30,5:0.05:-20", x0=1.25, periods=321,
                         phases="core", phi2=-135.0, strobe=12.5)
    values = parse_pin(pin_text(s))
    assert values == {k: getattr(s, k) for k in PIN_KEYS}
    assert st.rattle_params(pinned_state(pin_text(s))) == st.rattle_params(s)


@pytest.mark.parametrize("text, fragment", [
    ("NaN", "pin item 'NaN' must be 'key:value'"),
    ("lam:-5", "Λ = -5.0 is outside the allowed range; allowed (1e-06, 10000]"),
    ("r:1.5;lam:3", "r = 1.5 is outside the allowed range; allowed [0, 1]"),
    ("periods:2.5", "N = 2.5 must be a whole number; allowed [1, 20000]"),
    ("x0:abc", "x₀ must be a number, got 'abc'"),
    ("phases:cos", "phase convention = 'cos' is not allowed; allowed: paper, core"),
    ("harmonics:2:0.1:0", "harmonic order '2' must be a whole number in [3, 32]"),
    ("colour:red", "pin key 'colour' is unknown"),
    ("lam:3;lam:4", "pin key 'lam' is given twice"),
    ("rpm:-5", "engine speed [rpm] = -5.0 is outside the allowed range; allowed (0, 100000]"),
    ("drag_torque:abc", "C must be a number, got 'abc'; allowed (0, 10000]"),
    ("excitation:torque", "excitation = 'torque' is not allowed; allowed: displacement, acceleration"),
    ("lam:3.3;rpm:2000", "its physical inputs give Λ = 0.877298, j = 8, not its Λ = 3.3, j = 8"),
    (";;", "at least one 'key:value' item"),
])
def test_a_bad_pin_is_refused_naming_the_item_and_range(text, fragment):
    """Each malformed or out-of-range pin is refused, by the parser and by a session (which keeps
    its last pin); the message names the item and its range."""
    with pytest.raises(ValueError) as info:
        parse_pin(text)
    assert fragment in str(info.value)
    s = Session().state
    s.pinned = good = pin_text(s)
    a = s.pinned_result
    s.pinned = text
    assert s.pinned == good and s.pinned_result is a and fragment in s.messages["pinned"]


# ----- the session ------------------------------------------------------------------------------

def test_pin_keeps_the_run_and_a_change_of_lambda_makes_only_b_new():
    """Pinned: A is the run shown, not run again; Λ changes: B is new and A stays the same."""
    session = Session()
    s = session.state
    s.param.update(**FIG4)
    runs, a = session.runs, s.result
    s.pinned = pin_text(s)
    assert s.pinned_result is a and session.runs == runs  # pinning reuses the run on the page
    s.lam = 2.0
    assert s.result is not a and s.result.params.lam == 2.0
    assert s.pinned_result is a and s.pinned_result.params.lam == 3.3
    assert parse_pin(s.pinned)["lam"] == 3.3


def test_unpin_clears_a():
    """Unpinned: no pinned text, no pinned run."""
    session = Session()
    s = session.state
    s.pinned = pin_text(s)
    assert s.pinned_result is not None
    s.pinned = ""
    assert s.pinned_result is None and "pinned" not in s.messages


def test_a_pin_of_other_settings_is_run_once_as_the_core_runs_it():
    """A pin that is not the run on the page is simulated once; its strobe points are the core's."""
    session = Session()
    s = session.state
    s.pinned = "lam:2.5;h2:0;phi2:0"
    a = s.pinned_result
    ref = independent(2.5, 0.0, h2=0.0)
    np.testing.assert_array_equal(a.tr.strobe_x, ref.strobe_x)
    np.testing.assert_array_equal(a.tr.strobe_v, ref.strobe_v)
    s.lam, s.r = 3.0, 0.6
    assert s.pinned_result is a  # B's changes never rerun A


def test_a_pin_over_the_budget_is_refused_and_the_last_pin_stays():
    """A pin whose run is over the page's budget: a message beside the pin, the last pin kept."""
    session = Session()
    s = session.state
    s.pinned = first = pin_text(s)
    a = s.pinned_result
    harm = ",".join(f"{k}:0.3:0" for k in range(3, 33))
    s.pinned = f"lam:0.05;periods:20000;transient:100000;harmonics:{harm}"
    assert s.pinned == first and s.pinned_result is a
    assert "Run A cannot be pinned" in s.messages["pinned"] and "budget" in s.messages["pinned"]


def test_a_heavy_pin_runs_in_a_worker_beside_a_heavy_live_run(job_pool):
    """A pin over the inline limit runs in a worker as its own job: a heavy change of B at the
    same time cancels neither; each is published where it belongs."""
    from conftest import wait_for
    session = Session(pool=job_pool)
    s = session.state
    # twice the inline limit: a worker's job, yet well within its time limit on a loaded machine
    harm = "3:0.01:0,4:0.01:0"
    s.pinned = f"lam:2.5;periods:20000;transient:20000;harmonics:{harm}"
    assert s.pinned_result is None and session.pinner.page.pending is not None
    s.param.update(lam=3.0, periods=20000, transient=20000, harmonics=harm)
    assert session.page.pending is not None and session.pinner.page.pending is not None
    wait_for(lambda: s.pinned_result is not None and s.result.params.lam == 3.0, 120, "both runs")
    assert s.pinned_result.params.lam == 2.5 and s.pinned_result.tr.settings["periods"] == 20000
    assert s.result.tr.settings["periods"] == 20000 and "pinned" not in s.messages
    session.destroy()


# ----- the URL ----------------------------------------------------------------------------------

def test_the_pin_survives_the_url_round_trip():
    """A pinned link reopens A (run anew, the same as the core's run) beside the link's B."""
    session, loc = opened("?lam=3.3&h2=0.25&phi2=45")
    s = session.state
    s.pinned = pin_text(s)
    s.phi2 = 90.0
    q = query(loc)
    assert q["pin"] == s.pinned and q["phi2"] == "90.0"
    again, loc2 = opened(loc.search)
    s2 = again.state
    assert s2.pinned == s.pinned and s2.phi2 == 90.0 and "pinned" not in s2.messages
    a = s2.pinned_result
    assert a is not None and a is not s2.result
    assert a.params == s.pinned_result.params
    ref = independent(3.3, 45.0)
    np.testing.assert_array_equal(a.tr.strobe_x, ref.strobe_x)
    assert query(loc2)["pin"] == s.pinned


@pytest.mark.parametrize("pin, fragment", [
    ("lam:-5", "Λ = -5.0 is outside the allowed range; allowed (1e-06, 10000]"),
    ("<script>alert(1)</script>", "must be 'key:value'"),
    ("lam:3.3;evil:<b>x</b>", "pin key 'evil' is unknown"),
    ("lam:3.3;rpm:1e9", "engine speed [rpm] = 1000000000.0 is outside the allowed range; "
                        "allowed (0, 100000]"),
])
def test_a_bad_pin_in_the_url_is_refused_with_a_message(pin, fragment):
    """A link's bad pin: the page draws B, no A, a message beside the pin, and the URL says no pin;
    the message is text (escaped when shown), never HTML."""
    session, loc = opened("?" + urllib.parse.urlencode({"lam": 2.0, "pin": pin}))
    s = session.state
    assert s.result is not None and s.result.params.lam == 2.0
    assert s.pinned == "" and s.pinned_result is None
    text = s.messages["pinned"]
    assert text.startswith("URL: ") and fragment in text and len(text) < 400
    assert query(loc)["pin"] == ""
    shown = message_html(text)
    assert "<script>" not in shown and "<b>" not in shown


@pytest.mark.parametrize("value", ["NaN", "-Infinity", "9" * 5000, "[" * 3000, "[" * 50 + "]" * 50,
                                   "a" * 3000, "lam:" + "1" * 5000])
def test_a_hostile_pin_in_the_url_draws_the_page_and_says_so(value):
    """Hostile pins (digits Python will not convert, nesting, long text): B is drawn, no A, and
    a short message beside the pin names the URL."""
    session, loc = opened("?" + urllib.parse.urlencode({"pin": value}))
    s = session.state
    assert s.result is not None and s.pinned == "" and s.pinned_result is None
    assert "URL" in s.messages["pinned"] and len(s.messages["pinned"]) < 400
    assert query(loc).get("pin", "") == ""


# ----- the views --------------------------------------------------------------------------------

def test_the_overlays_draw_a_as_the_core_runs_it(dash):
    """Fig 4 pinned, then Fig 5: the time history's A trace and the section's A points are the
    core's run of Fig 4; B's are Fig 5's; the caption and the legends name A and B."""
    s = dash.state
    dash.controls.apply_preset("Fig 4")
    dash.pin.pin()
    dash.controls.apply_preset("Fig 5")
    assert s.result.params.phases_deg[1] == pytest.approx(180.0)  # Fig 5: φ₂ = 90° (paper)
    ref = independent(3.3, 45.0)
    trace = dash.time_history.sources["pinned"].data
    x_ref, _ = ref.sample(np.asarray(trace["t"]))
    assert len(trace["t"]) > 100 and trace["t"][0] == pytest.approx(ref.t_start)
    np.testing.assert_allclose(trace["x"], x_ref, rtol=0, atol=1e-12)
    b = dash.time_history.sources["motion"].data
    assert not np.allclose(b["x"][:len(trace["x"])], trace["x"][:len(b["x"])])
    ax, av = dash.section.pinned_points()
    np.testing.assert_array_equal(ax, ref.strobe_x)
    np.testing.assert_array_equal(av, ref.strobe_v)
    legend = dash.time_history.fig.legend[0].items
    assert [str(getattr(i.label, "value", i.label)) for i in legend[:2]] == [
        "B (live): gear x(t)", "A (pinned): gear x(t)"] and legend[1].visible
    a_line, b_line = dash.pin.lines()
    assert a_line.startswith("A: Λ = 3.3, r = 0.65, j = 8, H₂/H₁ = 0.25, φ₂ = 45°")
    assert b_line.startswith("B: Λ = 3.3, r = 0.65, j = 8, H₂/H₁ = 0.25, φ₂ = 90°")
    assert "chaotic" in a_line and "period 1" in b_line
    dash.pin.unpin()
    assert len(dash.time_history.sources["pinned"].data["t"]) == 0
    assert not dash.time_history.fig.legend[0].items[1].visible
    assert dash.section.pinned_points()[0].size == 0


def test_the_diagram_marks_a_and_b_at_their_lambdas(dash):
    """The diagram's A marker stands at A's Λ and B's at B's, both named, once the plot is drawn."""
    from bokeh.document import Document
    d = dash.diagram
    d.pane.get_root(Document())
    s = dash.state
    s.lam = 2.0
    dash.pin.pin()
    s.lam = 3.1
    assert d.pins.location == 2.0 and d.marker == 3.1
    span, label_a, label_b = d.pins.models
    assert (label_a.text.strip(), label_b.text.strip()) == ("A", "B")
    assert label_a.visible and label_b.visible and (label_a.x, label_b.x) == (2.0, 3.1)
    dash.pin.unpin()
    assert d.pins.location is None and not label_a.visible and not label_b.visible


def test_the_caption_is_text_and_says_how_to_pin():
    """Without a pin the caption says what the button does; with one, its text is escaped."""
    from app.views.pin import PinView
    s = Session().state
    view = PinView(state=s)
    assert "Pin this run" in view.caption.object and view.unpin_button.disabled
    view.pin()
    assert "A: Λ = 3.3" in view.caption.object and not view.unpin_button.disabled
    assert math.isclose(parse_pin(s.pinned)["lam"], 3.3)


# ----- physical units ---------------------------------------------------------------------------

def physical_pin(**changes) -> tuple[str, dict]:
    """A pin made on a page in physical units after ``changes`` (the physical side follows)."""
    session = Session()
    s = session.state
    s.units = True
    for name, value in changes.items():  # one at a time, as the page's controls make them
        setattr(s, name, value)
        assert getattr(s, name) == value
    assert s.result.phys is not None
    return pin_text(s), {k: getattr(s, k) for k in (*PIN_KEYS, *PIN_PHYSICAL_KEYS)}


def linked(search: str, job_pool):
    return new_dashboard(job_pool, search)


def test_a_physical_pin_round_trips_its_physical_inputs():
    """In physical units the pin also holds the physical inputs, and reads back exactly; on a
    dimensionless page it holds none."""
    text, values = physical_pin(phases="core", rpm=1234.5, lam=2.5)
    assert parse_pin(text) == values and values["phases"] == "core"
    assert values["lam"] == 2.5 and values["rpm"] != 1234.5  # Λ moved the engine speed
    assert all(f";{k}:" in text for k in PIN_PHYSICAL_KEYS)
    assert pinned_state(text).units and not pinned_state("lam:2.5").units
    assert not any(f";{k}:" in pin_text(st.ExplorerState()) for k in PIN_PHYSICAL_KEYS)


def test_a_physical_pin_from_a_link_is_drawn_in_ms_and_on_the_rpm_diagram(job_pool):
    """A link in physical units holding a physical pin: A has its physical side (its rpm, the
    pin's), its time history is the core's run of A with time in ms from the start, as
    t / ω with ω = order · 2π · rpm / 60, and positions R_b θ₁ x in µm; the engine-speed
    diagram marks A at its rpm and B at B's."""
    from bokeh.document import Document
    text, a_in = physical_pin(lam=2.5)
    dash = linked("?" + urllib.parse.urlencode({"units": "true", "lam": 3.3, "pin": text}), job_pool)
    try:
        s = dash.state
        assert s.units and s.result.phys is not None and "pinned" not in s.messages
        a = s.pinned_result
        assert a is not None and a.phys is not None and a is not s.result
        assert a.params.lam == 2.5 and a.phys.rpm == a_in["rpm"] != s.result.phys.rpm
        ref = independent(2.5, 45.0)
        omega = a_in["order"] * 2.0 * math.pi * a_in["rpm"] / 60.0
        trace = dash.time_history.sources["pinned"].data
        t_ms = np.asarray(trace["t"])
        assert len(t_ms) > 100 and t_ms[0] == 0.0
        assert t_ms[-1] == pytest.approx(1e3 * 2.0 * math.pi * s.shown / omega, rel=1e-12)
        x_ref, _ = ref.sample(ref.t_start + t_ms * 1e-3 * omega)
        np.testing.assert_allclose(trace["x"], 1e6 * a_in["radius"] * a_in["amp1"] * x_ref,
                                   rtol=1e-9, atol=1e-9)
        assert dash.time_history.fig.legend[0].items[1].visible
        d = dash.diagram
        d.pane.get_root(Document())
        assert d.swept() == "rpm"
        assert d.pins.location == pytest.approx(a_in["rpm"], rel=1e-12)
        assert d.pins.models[1].visible and d.pins.models[1].x == d.pins.location
        assert d.marker == pytest.approx(s.result.phys.rpm, rel=1e-12)
    finally:
        dash.destroy()


def test_a_physical_pin_made_on_the_page_reuses_the_run_and_reopens_the_same(job_pool):
    """Pinned on a page in physical units, A is the run shown (its physical side too); its link
    reopens A with the same physical set and the same time-history trace."""
    session, loc = opened("?units=true&lam=2.5")
    s = session.state
    runs, a = session.runs, s.result
    s.pinned = pin_text(s)
    assert s.pinned_result is a and session.runs == runs and a.phys is not None
    s.lam = 3.0
    assert s.pinned_result is a and s.result.phys.rpm != a.phys.rpm
    again = linked(loc.search, job_pool)
    try:
        assert again.state.pinned == s.pinned and again.state.pinned_result.phys == a.phys
        mine = dash_trace(again)
        page = time_history_data(a.tr, s.shown, a.phys)["motion"]
        assert len(mine["t"]) > 100 and mine["t"][0] == 0.0
        np.testing.assert_array_equal(mine["t"], page["t"])
        np.testing.assert_array_equal(mine["x"], page["x"])
    finally:
        again.destroy()


def dash_trace(dash) -> dict:
    return {k: np.asarray(v) for k, v in dash.time_history.sources["pinned"].data.items()}


def test_a_dimensionless_pin_in_physical_units_has_no_physical_side(job_pool):
    """A pin without physical inputs (an older link) in physical units: A is run with no physical
    side, since its scale is unknown; its section points and caption are drawn, its time
    history and its place on the engine-speed diagram are not. On a dimensionless page a
    physical pin's A is drawn dimensionless."""
    from bokeh.document import Document
    dash = linked("?units=true&lam=3.3&pin=" + urllib.parse.quote("lam:2.5;h2:0;phi2:0"), job_pool)
    try:
        s = dash.state
        a = s.pinned_result
        assert a is not None and a.phys is None and a.params.lam == 2.5 and "pinned" not in s.messages
        assert s.result.phys is not None
        assert len(dash.time_history.sources["pinned"].data["t"]) == 0
        assert not dash.time_history.fig.legend[0].items[1].visible
        np.testing.assert_array_equal(dash.section.pinned_points()[0], independent(2.5, 0.0, 0.0).strobe_x)
        assert dash.pin.lines()[0].startswith("A: Λ = 2.5")
        d = dash.diagram
        d.pane.get_root(Document())
        assert d.swept() == "rpm" and d.pins.location is None
        text, _ = physical_pin(lam=2.5)
        s.units = False
        s.pinned = text
        assert s.pinned_result.phys is not None and s.result.phys is None
        trace = dash_trace(dash)
        ref = independent(2.5, 45.0)
        x_ref, _ = ref.sample(trace["t"])
        assert trace["t"][0] == pytest.approx(ref.t_start)
        np.testing.assert_allclose(trace["x"], x_ref, rtol=0, atol=1e-12)
    finally:
        dash.destroy()
