"""The explorer state, its URL and the session's update rules, without a browser.

The state's bounds are checked against the core's ranges, the paper's phase convention against
the core's conversion, the URL against ``pn.state.location``-style sync (a ``Location``
object), and the physical-units link against ``rattle_core.units`` itself.
"""
from __future__ import annotations

import gc
import math
import urllib.parse

import pytest
from panel.io.location import Location

from app import state as st
from app.query import rejection
from app.presets import preset_values
from app.session import LIVE, Session
from rattle_core import RattleParams, classify, simulate, units
from rattle_core.paper.cases import CASES


def opened(query: str) -> tuple[Session, Location]:
    loc = Location(search=query)
    return Session(location=loc), loc


def query(loc: Location) -> dict[str, str]:
    return dict(urllib.parse.parse_qsl(loc.search[1:], keep_blank_values=True))


# ----- the state ------------------------------------------------------------------------------

@pytest.mark.parametrize("name, value, fragment", [
    ("lam", -5, "Λ = -5.0 is outside the allowed range; allowed (1e-06, 10000]. Kept 3.3."),
    ("lam", "abc", "Λ must be a number, got 'abc'; allowed (1e-06, 10000]"),
    ("r", 1.5, "r = 1.5 is outside the allowed range; allowed [0, 1]"),
    ("periods", 2.5, "N = 2.5 must be a whole number; allowed [1, 20000]"),
    ("strobe", math.nan, "θ must be finite, got nan"),
    ("section", "<b>x</b>", "section = '<b>x</b>' is not allowed; allowed: absolute, relative, impact"),
    ("overlays", "maybe", "overlays = 'maybe' is not allowed; allowed: true or false"),
    ("harmonics", "2:0.1:0", "harmonic order '2' must be a whole number in [3, 32]"),
    ("harmonics", "3:x:0", "must be a real number"),
])
def test_param_refuses_bad_values_and_the_message_names_control_value_and_range(name, value, fragment):
    """param's bounds refuse the value; the message names the control, the value and the range."""
    s = st.ExplorerState()
    before = getattr(s, name)
    with pytest.raises(ValueError):
        setattr(s, name, value)
    assert getattr(s, name) == before
    assert fragment in rejection(s, name, value)


def test_bounds_are_the_cores_ranges():
    """Λ, r, j, h₂ carry exactly the core's allowed ranges (open where the core's are)."""
    from rattle_core.model.params import AMPLITUDE_RANGE, J_RANGE, LAM_RANGE, R_RANGE
    p = st.ExplorerState.param
    assert (p["lam"].bounds, p["lam"].inclusive_bounds) == (LAM_RANGE, (False, True))
    assert (p["j"].bounds, p["j"].inclusive_bounds) == (J_RANGE, (False, True))
    assert p["r"].bounds == R_RANGE and p["h2"].bounds == AMPLITUDE_RANGE


def test_paper_convention_is_the_default_and_switching_keeps_the_model():
    """Default φ₂ = 45° (paper) is the core's −135°; switching converts φ₂ and extra harmonics."""
    s = st.ExplorerState(harmonics="3:0.1:30")
    assert (s.phases, s.phi2) == ("paper", 45.0)
    before = st.rattle_params(s)
    assert before.phases_deg[:2] == (0.0, -135.0)
    assert before == RattleParams.paper(3.3, amplitudes=(1.0, 0.25, 0.1), phases_deg=(0, 45, 30))
    s.set_phase_convention("core")
    assert (s.phases, s.phi2) == ("core", -135.0)
    assert st.rattle_params(s) == before
    s.set_phase_convention("paper")
    assert s.phi2 == 45.0 and st.rattle_params(s) == before


def test_paper_45_degrees_at_lambda_33_is_chaotic_and_core_45_is_not():
    """The paper's Figure 7 case (φ₂ = 45° paper) is chaos; the same number in the core is not."""
    s = st.ExplorerState(lam=3.3)
    cls = classify(simulate(st.rattle_params(s), periods=400, transient=300, lyapunov=True))
    assert cls.regime == "D" and cls.chaotic
    s.phases = "core"  # same number, other convention: another model
    cls = classify(simulate(st.rattle_params(s), periods=400, transient=300, lyapunov=True))
    assert cls.regime != "D"


@pytest.mark.parametrize("label, regime", [("Fig 3B", "B"), ("Fig 3C", "C"), ("Fig 3D", "D"),
                                           ("Fig 3E", "E"), ("Fig 7", "D"), ("Fig 8", "E")])
def test_presets_reproduce_the_papers_regimes(label, regime):
    """Each time-history preset, run as the dashboard runs it, shows the paper's regime."""
    s = st.ExplorerState()
    s.param.update(**preset_values(s, label))
    tr = simulate(st.rattle_params(s), periods=s.periods, transient=s.transient, lyapunov=True)
    assert classify(tr).regime == regime


def test_presets_come_from_the_papers_cases():
    """Fig 4 and Fig 8 carry the paper's cases' parameters (rattle_core.paper)."""
    for label, key in (("Fig 4", "fig4"), ("Fig 8", "fig8")):
        s = st.ExplorerState()
        s.param.update(**preset_values(s, label))
        p = st.rattle_params(s).with_value("lam", CASES[key].params.lam)
        assert p == CASES[key].params
    s = st.ExplorerState(phases="core", phi2=0.0)
    assert preset_values(s, "Fig 8")["phi2"] == st.convert_phase(90.0, 2) == 180.0


# ----- the session: runs, reverts, the URL ----------------------------------------------------------

def test_a_run_that_fails_reverts_with_a_message_and_the_last_view():
    """x₀ outside the backlash: the solver refuses it, x₀ returns, the last result stays."""
    sess = Session()
    s = sess.state
    before = s.result
    s.x0 = 50.0
    assert s.x0 is None and s.result is before
    assert "x0" in s.messages["x0"] and "Showing the last good view" in s.messages["x0"]
    s.lam = 3.2
    assert s.result.params.lam == 3.2 and "lam" not in s.messages


def test_url_with_garbage_keeps_the_good_values_and_says_why():
    """Every garbage key: a message beside its control, its last good value, the URL corrected."""
    sess, loc = opened("?lam=abc&r=0.4&j=-3&harmonics=zz&overlays=junk&section=%3Cscript%3E"
                       "&x0=1e5&lam2=1&%3Cimg%20src%3Dx%3E=1&phi2=")
    s = sess.state
    assert (s.lam, s.r, s.j, s.harmonics, s.overlays, s.section, s.x0) == (3.3, 0.4, 8.0, "", True,
                                                                         "absolute", None)
    for name in ("lam", "j", "harmonics", "overlays", "section", "x0", "phi2"):
        assert s.messages[name].startswith("URL: ") or name == "x0", (name, s.messages)
    assert "'lam2'" in s.messages["url"] and "'<img src=x>'" in s.messages["url"]
    assert "φ₂ is empty" in s.messages["phi2"]
    q = query(loc)
    assert (q["lam"], q["r"], q["j"], q["section"], q["x0"]) == ("3.3", "0.4", "8.0", "absolute", "")
    assert "lam2" not in q and not any("<" in k for k in q)
    assert s.result.params.r == 0.4


def test_url_round_trips_the_state_including_physical_keys():
    """A session opened on another's URL has the same state, physical inputs included."""
    a, loc = opened("?lam=2.2&r=0.5&phases=core&phi2=30&units=1&rpm=2345.6&C=0.03&b_um=123.4")
    b, _ = opened(loc.search)
    for name in st.URL_KEYS:
        assert getattr(b.state, name) == getattr(a.state, name), name
    assert b.state.result.params == a.state.result.params
    assert a.state.units and a.state.rpm == 2345.6


def test_physical_inputs_of_a_link_win_over_lambda():
    """units=1 with rpm and Λ: Λ follows the engine speed; without a physical key Λ is kept."""
    sess, loc = opened("?units=1&rpm=2000&J=3e-4&C=0.03&lam=1")
    want = units.example().replace(rpm=2000.0, inertia=3e-4, drag_torque=0.03)
    assert sess.state.lam == pytest.approx(want.lam, rel=1e-12)
    assert float(query(loc)["lam"]) == sess.state.lam
    loc.search = "?units=1&rpm=2000&J=3e-4&C=0.03&lam=1"  # the browser reports the link again
    assert sess.state.lam == pytest.approx(want.lam, rel=1e-12) and sess.state.rpm == 2000
    sess, _ = opened("?units=1&lam=2.0")
    assert sess.state.lam == 2.0
    assert sess.state.rpm == pytest.approx(float(units.rpm_from_lam(units.example(), 2.0)), rel=1e-12)
    sess, _ = opened("?units=1&rpm=abc&C=0.03")
    assert sess.state.rpm == 1500.0 and "Kept 1500" in sess.state.messages["rpm"]
    assert sess.state.lam == pytest.approx(units.example().replace(drag_torque=0.03).lam, rel=1e-12)


def test_lambda_moves_the_engine_speed_and_rpm_moves_lambda():
    """Units on: Λ moves rpm by rpm_from_lam (all else held); rpm sets Λ ∝ rpm²."""
    s = Session().state
    s.units = True
    held = units.example()
    assert s.rpm == pytest.approx(float(units.rpm_from_lam(held, 3.3)), rel=1e-12)
    s.lam = 2.5
    assert s.rpm == pytest.approx(float(units.rpm_from_lam(held, 2.5)), rel=1e-12)
    assert (s.inertia, s.drag_torque, s.backlash_um) == (held.inertia, held.drag_torque,
                                                         pytest.approx(held.backlash_um))
    s.rpm = 2000.0
    assert s.lam == pytest.approx(held.with_rpm(2000.0).lam, rel=1e-12)
    assert s.result.params.lam == s.lam and s.result.phys.rpm == 2000.0
    s.solve_for = "drag_torque"
    s.lam = 2.0
    assert s.rpm == 2000.0
    p = s.result.phys
    assert p.drag_torque == pytest.approx(p.radius * p.mass * p.H1 * p.omega ** 2 / 2.0, rel=1e-12)


def test_physical_input_outside_the_model_is_refused_beside_it():
    """A physical set giving Λ > 1e4 is refused beside the input; nothing changes."""
    s = Session().state
    s.units = True
    s.inertia = 25 * s.inertia
    lam, rpm = s.lam, s.rpm
    s.rpm = 99_000.0
    assert (s.lam, s.rpm) == (lam, rpm)
    assert "rpm" in s.messages and "Kept the last good values" in s.messages["rpm"]


def test_closed_sessions_are_garbage():
    """Sessions opened and destroyed leave nothing alive (the weak registry empties)."""
    gc.collect()
    before = len(LIVE)
    for _ in range(5):
        sess, _ = opened("?lam=2.5&units=1")
        sess.destroy()
    del sess
    gc.collect()
    assert len(LIVE) == before
