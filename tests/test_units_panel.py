"""The dashboard's physical-units mode, without a browser.

Every expectation comes from ``rattle_core.model.units`` itself (``PhysicalParams.lam``,
``rpm_from_lam``, ``lam_from_rpm``, ``impulse_scale_from_rpm``), so a panel that maps the
inputs differently, or forgets to map them, fails.
"""
from __future__ import annotations

import math
from html import escape

import numpy as np
import pytest

from rattle_core import contact_boundary, units
from rattle_core.analysis.vocabulary import physical_table
from rattle_core.model.units import PhysicalParams


@pytest.fixture()
def panel(dash):
    from app.units_panel import UnitsPanel

    p = next(p for p in dash.panels if isinstance(p, UnitsPanel))
    p.set_mode(True)
    return p


def test_mode_off_by_default_and_on_keeps_the_view(dash):
    """Off: no physical parameters and no table. On: the inputs solve for the same Λ, j, h₂, φ₂."""
    from app.units_panel import UnitsPanel

    p = next(p for p in dash.panels if isinstance(p, UnitsPanel))
    assert dash.physical is None and not p.table.visible and not p.body.visible
    before = dash.params
    p.set_mode(True)
    assert dash.physical is p.phys and p.table.visible and p.body.visible
    assert dash.params == before
    q = dash.physical.to_dimensionless()
    assert q.lam == pytest.approx(before.lam, rel=1e-12) and q.j == pytest.approx(before.j, rel=1e-12)
    assert q.amplitudes[1] == pytest.approx(before.amplitudes[1], rel=1e-12)
    p.set_mode(False)
    assert dash.physical is None and not p.table.visible


def test_engine_speed_sets_lambda_as_the_library_says(dash, panel):
    """Typing an engine speed sets Λ = PhysicalParams(...).lam, and Λ grows as rpm²."""
    assert panel.edit("rpm", 2000.0) is None
    expected = PhysicalParams(inertia=panel.phys.inertia, radius=panel.phys.radius,
                              drag_torque=panel.phys.drag_torque, backlash=panel.phys.backlash,
                              rpm=2000.0, amplitudes=panel.phys.amplitudes,
                              phases_deg=panel.phys.phases_deg, order=panel.phys.order).lam
    assert dash.state.lam == expected and dash.tr.params.lam == expected
    assert dash.widgets["lam"].value == expected
    lam_2000 = dash.state.lam
    panel.edit("rpm", 3000.0)
    assert dash.state.lam / lam_2000 == pytest.approx((3000.0 / 2000.0) ** 2, rel=1e-12)
    assert dash.state.j == pytest.approx(panel.phys.backlash / panel.phys.H1, rel=1e-12)


def test_lambda_slider_moves_the_engine_speed(dash, panel):
    """Moving Λ in dimensionless terms moves rpm by rpm_from_lam, every other input held."""
    held = panel.phys
    dash.widgets["lam"].value = 2.5
    assert panel.phys.rpm == pytest.approx(float(units.rpm_from_lam(held, 2.5)), rel=1e-12)
    assert panel.inputs["rpm"].value == pytest.approx(panel.phys.rpm, rel=1e-5)
    for name in ("inertia", "radius", "drag_torque", "backlash", "order", "amplitudes"):
        assert getattr(panel.phys, name) == getattr(held, name)


def test_other_quantities_can_absorb_lambda(dash, panel):
    """With the drag torque chosen, a Λ change moves C as C = R_b m H₁ ω² / Λ, rpm held."""
    panel.solve_for.value = "drag_torque"
    rpm = panel.phys.rpm
    dash.widgets["lam"].value = 2.0
    p = panel.phys
    assert p.rpm == rpm
    assert p.drag_torque == pytest.approx(p.radius * p.mass * p.H1 * p.omega ** 2 / 2.0, rel=1e-12)


def test_round_trip_physical_dimensionless_physical(dash, panel):
    """Inputs → state → inputs returns the inputs, also after a Λ move there and back."""
    for name, value in (("inertia", 3e-4), ("drag_torque", 0.03), ("backlash", 120.0),
                        ("amp2", 2e-4), ("phase2", 30.0), ("rpm", 2500.0)):
        assert panel.edit(name, value) is None
    typed = panel.phys
    assert (typed.inertia, typed.drag_torque, typed.rpm) == (3e-4, 0.03, 2500.0)
    assert typed.backlash_um == pytest.approx(120.0, rel=1e-14)
    back = PhysicalParams.from_dimensionless(dash.params, typed, solve_for="rpm")
    for a, b in zip(dataclass_values(back), dataclass_values(typed)):
        assert a == pytest.approx(b, rel=1e-12)
    lam = dash.state.lam
    dash.widgets["lam"].value = 1.5
    assert panel.phys.rpm != pytest.approx(2500.0)
    dash.widgets["lam"].value = lam
    assert panel.phys.rpm == pytest.approx(2500.0, rel=1e-12)
    assert panel.phys.backlash_um == pytest.approx(120.0, rel=1e-12)


def dataclass_values(p: PhysicalParams) -> list[float]:
    return [p.inertia, p.radius, p.drag_torque, p.backlash, p.rpm, *p.amplitudes,
            *p.phases_deg, p.order, p.r]


@pytest.mark.parametrize("name, value, words", [
    ("inertia", 50.0, ["inertia", "(0, 10]"]),
    ("inertia", math.nan, ["inertia", "(0, 10]"]),
    ("rpm", -100.0, ["rpm", "(0, 100000]"]),
    ("backlash", 0.0, ["backlash", "(0, 100000]"]),
])
def test_out_of_range_input_keeps_the_last_good_state(dash, panel, name, value, words):
    """A refused input: a message beside it naming it and its range; state, view and input unchanged."""
    phys, lam, x = panel.phys, dash.state.lam, np.sum(dash.th_src["motion"].data["x"])
    shown = panel.inputs[name].value
    msg = panel.edit(name, value)
    assert msg and panel.alerts[name].visible and panel.alerts[name].object == msg
    for w in words:
        assert w in msg
    assert panel.phys == phys and dash.state.lam == lam
    assert np.sum(dash.th_src["motion"].data["x"]) == x
    assert panel.inputs[name].value == shown
    assert panel.edit(name, shown) is None and not panel.alerts[name].visible


def test_inputs_that_push_lambda_out_of_the_model_are_refused(dash, panel):
    """rpm 1e5 with a heavier gear gives Λ > 1e4: refused beside rpm, naming Λ's range."""
    assert panel.edit("inertia", 25 * panel.phys.inertia) is None
    lam = dash.state.lam
    msg = panel.edit("rpm", 1e5)
    assert msg and "lam" in msg and "(1e-06, 10000]" in msg and "rpm" in msg.split(":")[0]
    assert dash.state.lam == lam


def test_acceleration_excitation_is_the_same_model(dash, panel):
    """Switching to accelerations converts α_k = θ_k (kω)² and leaves the model unchanged."""
    before = dash.params
    theta = panel.phys.amplitudes
    omega = panel.phys.omega
    panel.set_excitation("acceleration")
    assert panel.phys.amplitudes[0] == pytest.approx(theta[0] * omega ** 2, rel=1e-12)
    assert panel.phys.amplitudes[1] == pytest.approx(theta[1] * (2 * omega) ** 2, rel=1e-12)
    assert panel.solve_for.value != "rpm"
    assert dash.params.lam == pytest.approx(before.lam, rel=1e-12)
    # accelerations held: Λ no longer depends on speed, j grows as rpm²
    j = dash.state.j
    rpm = panel.phys.rpm
    panel.edit("rpm", 2 * rpm)
    assert dash.state.lam == pytest.approx(before.lam, rel=1e-12)
    assert dash.state.j == pytest.approx(4 * j, rel=1e-12)


def test_table_shows_both_sets_and_si_metrics(dash, panel):
    """The Explorer table lists each physical value beside its dimensionless image, and SI metrics."""
    html = panel.table.object
    for quantity, phys_value, dimless in physical_table(panel.phys):
        assert escape(quantity) in html and escape(phys_value) in html and escape(dimless) in html
    cls = dash.classification
    assert f"{panel.phys.frequency_hz:.6g} Hz" in html
    assert f"{1e3 * panel.phys.period_s:.6g} ms" in html
    rate = cls.active_per_period * panel.phys.frequency_hz
    assert f"{rate:.4g}" in html
    assert f"{cls.mean_impulse_active * panel.phys.impulse_scale:.4g}" in html


def test_rpm_diagram_is_a_lambda_sweep_drawn_against_rpm(dash, panel):
    """'Ĩ vs rpm' sweeps the Λ values of units.rpm_sweep; its x values map back by rpm_from_lam."""
    assert "rpm" in dash.widgets["bif"].options.values()
    dash.widgets["bif"].value = "rpm"
    job = dash._job
    assert job is not None
    req = job.request
    assert req.name == "lam"
    phys = dash.physical
    rpm = units.rpm_from_lam(phys, np.asarray(req.values))
    np.testing.assert_allclose(units.lam_from_rpm(phys, rpm), req.values, rtol=1e-12)
    assert rpm[0] <= phys.rpm <= rpm[-1]
    job.future.result(timeout=300)
    d = dash._bif
    assert d.name == "rpm" and dash.bif["marker"].location == phys.rpm
    assert set(np.round(d.value, 6)) <= set(np.round(rpm, 6))
    assert dash.bif_fig.xaxis.axis_label == "engine speed (rpm)"
    # impulses in N·s: the drawn y values are Ĩ × m ω H₁ at each speed
    dash.bif_si.value = True
    x, y = dash._bif_points()
    np.testing.assert_allclose(y, d.impulse * units.impulse_scale_from_rpm(phys, x), rtol=1e-12)
    assert "N·s" in dash.bif_fig.yaxis.axis_label
    # overlays: the one-sided impulses 2πn/Λ(rpm), in N·s; the contact boundary at rpm(Λ_c)
    curves = dash.bif["sources"]["curves"].data
    for n, (xs, ys) in enumerate(zip(curves["xs"], curves["ys"]), start=1):
        np.testing.assert_allclose(ys, 2 * np.pi * n / units.lam_from_rpm(phys, xs)
                                   * units.impulse_scale_from_rpm(phys, xs), rtol=1e-12)
    lam_c = contact_boundary(dash.params)
    assert dash.bif["boundary"].location == pytest.approx(float(units.rpm_from_lam(phys, lam_c)))
    # a click sets the engine speed, and so Λ
    dash.set_from_diagram(2222.04)
    assert panel.phys.rpm == 2222.0
    assert dash.state.lam == pytest.approx(float(units.lam_from_rpm(phys, 2222.0)), rel=1e-12)
    assert dash.bif["marker"].location == 2222.0
    # turning the mode off falls back to Ĩ vs Λ
    panel.set_mode(False)
    assert dash.state.bif == "lam" and "rpm" not in dash.widgets["bif"].options.values()
    assert dash.bif_fig.xaxis.axis_label == "Λ"


def test_rpm_diagram_zoom_refines_in_rpm(dash, panel):
    """A zoom into an rpm window sweeps Λ(rpm) at 300 speeds there and merges them."""
    dash.widgets["bif"].value = "rpm"
    dash._job.future.result(timeout=300)
    lo, hi = dash._bif.span
    a, b = lo + 0.4 * (hi - lo), lo + 0.5 * (hi - lo)
    dash._bif_view = (a, b, -10.0, 10.0)
    assert dash.refine_visible()
    req = dash._job.request
    rpm = units.rpm_from_lam(dash.physical, np.asarray(req.values))
    assert rpm[0] == pytest.approx(a, rel=1e-12) and rpm[-1] == pytest.approx(b, rel=1e-12)
    dash._job.future.result(timeout=300)
    assert "refined" in dash._bif.source and dash._bif.name == "rpm"


# ----- the mode in the URL --------------------------------------------------------------------

def _dashboard_at(query: str):
    """A dashboard opened on ``query``, with a URL of its own as in the browser."""
    from panel.io.location import Location

    from app.dashboard import Dashboard
    from app.units_panel import UnitsPanel

    loc = Location(search=query)
    d = Dashboard(location=loc)
    return d, next(p for p in d.panels if isinstance(p, UnitsPanel)), loc


def _query(loc) -> dict[str, str]:
    from urllib.parse import parse_qsl
    return dict(parse_qsl(loc.search[1:], keep_blank_values=True))


@pytest.fixture()
def opened():
    made = []

    def open_at(query: str):
        d, p, loc = _dashboard_at(query)
        made.append(d)
        return d, p, loc
    yield open_at
    for d in made:
        d._cancel_job()


@pytest.mark.parametrize("kind", ["displacement", "acceleration"])
def test_url_round_trip_restores_the_physical_set(dash, panel, opened, kind):
    """Mode on, inputs typed: a dashboard opened on the query values has the same physical set and Λ."""
    from urllib.parse import urlencode

    from app.state import URL_KEYS

    dash.state.harmonics = "3:0.1:30"
    dash.state.r = 0.5
    for name, value in (("inertia", 3e-4), ("drag_torque", 0.03), ("backlash", 123.4),
                        ("amp2", 2e-4), ("phase2", 30.0), ("rpm", 2345.6)):
        assert panel.edit(name, value) is None
    panel.set_excitation(kind)
    panel.solve_for.value = "drag_torque"
    panel.backlash_unit.value = "deg"
    assert len(dash.physical.amplitudes) == 3 and dash.physical.r == 0.5
    query = {**{k: dash._url_value(k) for k in URL_KEYS}, **panel.url_values()}
    d2, p2, loc2 = opened("?" + urlencode(query))
    assert p2.on and p2.switch.value
    # orders ≥ 3 travel as their dimensionless ratio (the harmonics key), so to rounding only
    third = dash.physical.amplitudes[2]
    assert d2.physical.amplitudes[2] == pytest.approx(third, rel=1e-14)
    assert d2.physical == dash.physical.replace(
        amplitudes=(*dash.physical.amplitudes[:2], d2.physical.amplitudes[2]))
    assert d2.state.lam == dash.state.lam == dash.physical.lam
    assert (d2.state.j, d2.state.h2, d2.state.phi2) == (dash.state.j, dash.state.h2, dash.state.phi2)
    assert d2.state.harmonics == dash.state.harmonics
    assert (p2.solve_for.value, p2.backlash_unit.value) == ("drag_torque", "deg")
    assert p2.url_values() == panel.url_values()
    assert {k: v for k, v in _query(loc2).items() if k in p2.url_values()} == panel.url_values()
    assert not any(a.visible for a in p2.alerts.values()) and not d2.global_alert.visible


def test_url_physical_inputs_win_over_lambda(opened):
    """units=1 with rpm and Λ: Λ follows the engine speed; without a physical key Λ is kept."""
    d, p, loc = opened("?units=1&rpm=2000&lam=2.0")
    want = units.example().with_rpm(2000.0).lam
    assert d.state.lam == want and d.physical.rpm == 2000.0
    assert _query(loc)["lam"] == repr(want) and _query(loc)["rpm"] == "2000"
    d, p, loc = opened("?units=1&lam=2.0")
    assert d.state.lam == 2.0 and p.on
    assert d.physical.rpm == pytest.approx(float(units.rpm_from_lam(units.example(), 2.0)), rel=1e-12)


def test_url_mode_off_adds_no_keys_and_switching_off_removes_them(opened):
    """Mode off: the URL holds the state only; on adds the physical keys, off takes them away."""
    from app.units_panel import URL_KEYS as UNITS_KEYS

    d, p, loc = opened("?lam=2.2&r=0.5")
    assert d.physical is None and not set(_query(loc)) & set(UNITS_KEYS)
    assert _query(loc)["lam"] == "2.2"
    p.set_mode(True)
    assert _query(loc)["units"] == "1" and float(_query(loc)["rpm"]) == d.physical.rpm
    p.edit("rpm", 2500.0)
    assert _query(loc)["rpm"] == "2500" and float(_query(loc)["lam"]) == d.state.lam
    p.set_mode(False)
    assert not set(_query(loc)) & set(UNITS_KEYS)
    d, p, loc = opened("?rpm=2000&J=1")  # physical keys without units=1 are ignored and removed
    assert d.physical is None and not set(_query(loc)) & set(UNITS_KEYS)


@pytest.mark.parametrize("key, text, name, words", [
    ("rpm", "nan", "rpm", ["rpm", "(0, 100000]"]),
    ("rpm", "-5", "rpm", ["rpm", "(0, 100000]"]),
    ("J", "abc", "inertia", ["J", "(0, 10]", "kg·m²"]),
    ("C", "1e9", "drag_torque", ["C", "(0, 10000]"]),
    ("b_um", "0", "backlash", ["b_um", "(0, 100000]", "µm"]),
    ("order", "inf", "order", ["order", "(0, 100]"]),
    ("a1", "4", "amp1", ["a1", "(0, 3.14159]", "rad"]),
    ("a2", "xyz", "amp2", ["a2", "[0, 3.14159]"]),
    ("p2", "1e7", "phase2", ["p2", "[-1e+06, 1e+06]"]),
    ("exc", "sideways", "amp1", ["exc", "displacement or acceleration"]),
    ("b_unit", "furlong", "backlash", ["b_unit", "um or deg"]),
    ("solve", "luck", "solve_for", ["solve", "drag_torque"]),
])
def test_garbage_url_values_show_a_message_and_keep_the_default(opened, key, text, name, words):
    """A bad physical key: its message beside its input, the example's value, the URL corrected."""
    from app.state import DashboardState
    from app.units_panel import URL_NUMERIC

    d, p, loc = opened(f"?units=1&{key}={text}&r=0.4")
    example = units.example().replace(r=0.4)
    assert p.on and d.state.r == 0.4
    if key in URL_NUMERIC:  # a physical key was given: the physical set (the example) wins
        assert d.physical == example and d.state.lam == example.lam
    else:  # none was: Λ stays and the example's engine speed moves to it
        lam = DashboardState.param["lam"].default
        assert d.state.lam == lam
        assert d.physical == PhysicalParams.from_dimensionless(d.params, example, solve_for="rpm")
    alert = p.alerts[name]
    assert alert.visible and alert.object.startswith("URL: ")
    for w in words:
        assert w in alert.object, (w, alert.object)
    assert "Kept" in alert.object
    assert [n for n, a in p.alerts.items() if a.visible] == [name]
    assert _query(loc)[key] == p.url_values()[key] != text


def test_url_mode_flag_garbage_and_unreachable_sets(opened):
    """units=banana: mode off, a page message. A physical set outside the model: Λ from the URL."""
    d, p, loc = opened("?units=banana&rpm=2000")
    assert d.physical is None and not p.on
    assert d.global_alert.visible and "units = 'banana'" in d.global_alert.object
    assert "rpm" not in _query(loc)
    # 1e-6 N·m of drag with the example gear gives Λ far beyond the model's range
    d, p, loc = opened("?units=1&C=1e-9&lam=2.0")
    assert p.on and d.state.lam == 2.0
    assert d.physical.to_dimensionless().lam == pytest.approx(2.0, rel=1e-12)
    assert d.global_alert.visible and "no valid model" in d.global_alert.object


def test_link_reported_again_by_the_browser_keeps_the_physical_inputs(opened):
    """The browser sends the link's query again once connected: the physical inputs still win."""
    link = "?units=1&rpm=2000&J=3e-4&lam=1"
    d, p, loc = opened(link)
    want = units.example().replace(rpm=2000.0, inertia=3e-4)
    assert d.physical == want and d.state.lam == want.lam
    loc.search = link  # Panel applies lam=1 to the state first, then the mode restores
    assert d.physical == want and d.state.lam == want.lam and d.params.lam == want.lam
    assert _query(loc)["rpm"] == "2000" and _query(loc)["J"] == "0.0003"
    loc.search = link.replace("rpm=2000", "rpm=oops")
    assert d.physical == units.example().replace(inertia=3e-4)
    assert "Kept 1500" in p.alerts["rpm"].object and p.alerts["rpm"].visible
