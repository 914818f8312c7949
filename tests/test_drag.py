"""Drag torque over speed and oil temperature (rattle_core.model.drag): closed forms and refusals."""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, strategies as st

from rattle_core.model.drag import ISO_VG, Drag, Oil

VG68 = Oil(iso_vg=68, nu100_cSt=8.8)


def _walther_z(nu):
    return np.log10(np.log10(nu + 0.7))


def test_viscosity_meets_the_grade_and_the_data_sheet():
    """ν(40 °C) is the ISO VG grade and ν(100 °C) the data sheet's value, to rounding."""
    assert VG68.viscosity_cSt(40.0) == pytest.approx(68.0, rel=1e-12)
    assert VG68.viscosity_cSt(100.0) == pytest.approx(8.8, rel=1e-12)


@given(st.floats(-40, 150), st.floats(-40, 150))
def test_walther_is_a_straight_line_in_log_log(t1, t2):
    """ASTM D341: log log(ν + 0.7) is linear in log T_K, through the 40 and 100 °C points."""
    lt = np.log10(np.array([40.0, 100.0, t1, t2]) + 273.15)
    z = _walther_z(VG68.viscosity_cSt(np.array([40.0, 100.0, t1, t2])))
    slope = (z[1] - z[0]) / (lt[1] - lt[0])
    assert np.allclose(z[2:], z[0] + slope * (lt[2:] - lt[0]), atol=1e-10)


def test_cold_oil_is_thicker():
    """Viscosity falls as the oil warms: cold idle (−20 °C) is orders of magnitude thicker."""
    nu = VG68.viscosity_cSt(np.array([-20.0, 0.0, 40.0, 80.0, 120.0]))
    assert np.all(np.diff(nu) < 0) and nu[0] > 20 * nu[2]


def test_the_oil_model_is_bush_plus_viscous_churning():
    """C = bush + churn · ν(T)/ν(T_ref) · rpm/rpm_ref, at its reference and away from it."""
    d = Drag.from_value({"bush_Nm": 0.01, "churn_Nm": 0.03, "at_rpm": 2000, "at_temp_C": 40},
                        "gear 'x'")
    assert d.torque(2000, 40.0, VG68)[0] == pytest.approx(0.04, rel=1e-12)
    nu_ratio = VG68.viscosity_cSt(-10.0) / 68.0
    assert d.torque(1000, -10.0, VG68)[0] == pytest.approx(0.01 + 0.03 * nu_ratio * 0.5, rel=1e-12)


def test_tables_interpolate_over_speed_and_temperature():
    """A 1-D table interpolates linearly in rpm; a 2-D one bilinearly in rpm and temperature."""
    one = Drag.from_value({"rpm": [1000, 3000], "torque_Nm": [0.02, 0.06]}, "g")
    assert one.torque([1000, 1500, 3000]) == pytest.approx([0.02, 0.03, 0.06])
    two = Drag.from_value({"rpm": [1000, 3000], "temp_C": [0, 80],
                           "torque_Nm": [[0.10, 0.20], [0.02, 0.04]]}, "g")
    # at 2000 rpm: 0.15 at 0 °C, 0.03 at 80 °C; at 20 °C, a quarter of the way
    assert two.torque(2000, 20.0)[0] == pytest.approx(0.15 + 0.25 * (0.03 - 0.15))


@pytest.mark.parametrize("value, words", [
    ({"rpm": [1000, 900], "torque_Nm": [0.1, 0.1]}, "increase strictly"),
    ({"rpm": [1000, 2000], "torque_Nm": [0.1]}, "shape"),
    ({"rpm": [1000, 2000], "torque_Nm": [0.1, -1]}, "torque_Nm"),
    ({"rpm": [1000, 2000], "temp_C": [-60, 20], "torque_Nm": [[1, 1], [1, 1]]}, r"temp_C\[0\].*-40"),
    ({"bush_Nm": 0.01, "churn_Nm": 0.02, "at_rpm": 1000}, "at_temp_C is required"),
    ({"bush_Nm": 0.01, "speed": 3}, "either"),
    (float("nan"), "drag_torque_Nm"),
    ("lots", "number"),
])
def test_bad_drag_is_refused_naming_the_gear_and_key(value, words):
    """A bad drag names the gear, the key and what is allowed."""
    with pytest.raises(ValueError, match=words) as err:
        Drag.from_value(value, "gear '3rd'")
    assert "gear '3rd'" in str(err.value)


def test_speed_and_temperature_outside_a_table_are_refused():
    """A table is not extrapolated: a speed or temperature outside it is refused with its span."""
    two = Drag.from_value({"rpm": [1000, 3000], "temp_C": [0, 80],
                           "torque_Nm": [[0.1, 0.2], [0.02, 0.04]]}, "g")
    with pytest.raises(ValueError, match="1000 to 3000 rpm"):
        two.torque(3500, 20.0)
    with pytest.raises(ValueError, match="0 to 80 °C"):
        two.torque(2000, 100.0)
    with pytest.raises(ValueError, match="temp_C"):
        two.torque(2000)


@pytest.mark.parametrize("table, words", [
    ({"iso_vg": 70, "nu100_cSt": 9}, "not an ISO 3448 viscosity grade"),
    ({"iso_vg": 68, "nu100_cSt": 80}, "nu100_cSt"),
    ({"iso_vg": 68, "nu100_cSt": 8.8, "temp_C": 151}, r"temp_C.*\[-40, 150\]"),
    ({"iso_vg": 68}, "nu100_cSt is required"),
    ({"iso_vg": 68, "nu100_cSt": 8.8, "grade": 2}, "unknown key"),
])
def test_bad_oil_is_refused_with_the_allowed_values(table, words):
    """An oil that is not an ISO VG grade, or out of range, is refused with what is allowed."""
    with pytest.raises(ValueError, match=words):
        Oil.from_table(table)
    assert 68 in ISO_VG and 70 not in ISO_VG
