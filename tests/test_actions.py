"""Ranges, countermeasures and drag what-ifs of a verdict (rattle_core.batch.actions) against
closed forms."""
from __future__ import annotations

import numpy as np
import pytest

from rattle_core.batch.actions import (added_drag, energy_shares, quiet_summary, rattle_ranges,
                                       scaled_drag)
from rattle_core.model.drag import Drag, Oil
from rattle_core.model.gearbox import Gear


def _ratio(x):
    # crosses 1 at 1430 (up), 1910 (down) and 2230 (up)
    x = np.asarray(x, float)
    return 1 + (x - 1430) * (x - 1910) * (x - 2230) / 1e8


def test_a_gear_that_rattles_falls_quiet_and_rattles_again_has_two_ranges():
    """Both ranges, their edges located between grid speeds at the contact ratio's crossings."""
    rpm = np.arange(1000, 3001, 100.0)
    ranges = rattle_ranges(rpm, _ratio(rpm) > 1, _ratio)
    assert len(ranges) == 2
    (a, b), (c, d) = ranges
    assert (a, b, c) == pytest.approx((1430, 1910, 2230), abs=0.01)
    assert d == 3000


def test_an_edge_without_a_crossing_stays_on_the_grid():
    """Rattle below the boundary (a coexisting attractor) is reported at its grid speeds."""
    rpm = np.arange(1000, 1600, 100.0)
    rattles = np.array([0, 1, 1, 0, 0, 0], bool)           # the ratio stays below 1 throughout
    assert rattle_ranges(rpm, rattles, lambda x: 0.5) == [(1100.0, 1200.0)]
    assert rattle_ranges(rpm, np.ones(6, bool), lambda x: 2.0) == [(1000.0, 1500.0)]
    assert rattle_ranges(rpm, np.zeros(6, bool), lambda x: 0.5) == []


def test_the_drag_and_inertia_to_quiet_are_the_worst_speeds_closed_form():
    """Drag to add = max(ratio·C − C); inertia to remove = 1 − 1/max(ratio)."""
    s = quiet_summary("3rd", np.array([0.01, 0.01, 0.02]), np.array([0.5, 2.0, 1.5]), 4e-4,
                      np.array([1000, 2000, 3000.0]))
    assert s["drag_add_Nm"] == pytest.approx(0.01)
    assert s["inertia_remove"] == pytest.approx(0.5)
    assert "add 0.01 N·m of drag, or remove 50 % of inertia" in s["line"]
    assert "3rd quiet up to 3000 rpm" in s["line"]
    calm = quiet_summary("5th", np.full(3, 0.05), np.array([0.2, 0.4, 0.9]), 4e-4,
                         np.array([1000, 2000, 3000.0]))
    assert calm["drag_add_Nm"] == 0 and "nothing to change" in calm["line"]


def test_energy_shares_add_to_one_and_follow_the_levels():
    """Shares of incoherent sources: 10 dB more is ten times the energy; silence is no share."""
    s = energy_shares(np.array([[70.0, 60.0, -np.inf], [-np.inf, -np.inf, -np.inf]]))
    assert s[0] == pytest.approx([10 / 11, 1 / 11, 0])
    assert np.all(np.isnan(s[1]))


OIL = Oil(iso_vg=68, nu100_cSt=9, temp_C=40)
DRAGS = {
    "constant": Drag.constant(0.05),
    "oil": Drag.from_value({"bush_Nm": 0.01, "churn_Nm": 0.02, "at_rpm": 2000, "at_temp_C": 40}, "gear"),
    "table": Drag.from_value({"rpm": [1000, 3000], "torque_Nm": [0.02, 0.06]}, "gear"),
    "table over temperature": Drag.from_value({"rpm": [1000, 3000], "temp_C": [0, 80],
                                               "torque_Nm": [[0.08, 0.12], [0.02, 0.03]]},
                                              "gear"),
}


@pytest.mark.parametrize("kind", DRAGS)
def test_scaled_and_added_drag_hold_for_every_drag_kind(kind):
    """Scaling a gear's drag by k multiplies its torque by k at every speed and temperature;
    adding δ adds δ there (each compared with the original drag's torque)."""
    gear = Gear("g", inertia_kgm2=4e-4, base_radius_m=0.035, drag_torque_Nm=None,
                backlash_um=80, drag=DRAGS[kind])
    rpm = np.array([1000.0, 1700.0, 3000.0])
    for temp in (10.0, 40.0, 70.0):
        before = gear.drag.torque(rpm, temp, OIL)
        np.testing.assert_allclose(scaled_drag(gear, 1.5).drag.torque(rpm, temp, OIL),
                                   1.5 * before, rtol=1e-12)
        np.testing.assert_allclose(added_drag(gear, 0.004).drag.torque(rpm, temp, OIL),
                                   before + 0.004, rtol=1e-12)
    with pytest.raises(ValueError, match="drag factor"):
        scaled_drag(gear, 0.0)
