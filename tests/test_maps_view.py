"""The Maps tab without a browser: a whole dashboard session, its maps computed by the job pool.

The image the view draws is checked against ``rattle_core.batch.maps`` run on its own, cell by cell;
the messages against the limits they state; clicks against the session's state.
"""
from __future__ import annotations


import numpy as np
import pandas as pd
import pytest
from conftest import wait_for

from rattle_core import units
from rattle_core.analysis.vocabulary import REGIME_CODES
from rattle_core.batch.maps import basin_map, regime_map


def small(view, nx=7, ny=5, transient=60, record=30):
    view.settings.param.update(x_num=nx, y_num=ny, transient=transient, record=record)


def compute(view):
    view.result = None
    assert view.compute(), view.state.messages
    wait_for(lambda: view.result is not None and not view.progress.visible, what="the map")
    return view.result


def image(view, field=None):
    if field is not None:
        view.settings.field = field
    return view.image_element().dimension_values(2, flat=False)


def test_regime_image_equals_regime_map(dash):
    """The image holds the regime codes of regime_map for the same grid, value for value."""
    view = dash.maps
    small(view)
    view.settings.param.update(x_start=0.8, x_stop=3.5)
    r = compute(view)
    np.testing.assert_allclose(r.x_values, np.linspace(0.8, 3.5, 7), rtol=1e-12)
    lams, phis = r.x_values, r.y_values
    ref = regime_map(dash.state.result.params, "lam", lams, "phi2", -phis - 90.0, transient=60, record=30)
    np.testing.assert_array_equal(r.fields["regime"], ref.fields["regime"])
    np.testing.assert_array_equal(phis, np.linspace(0.0, 360.0, 5))  # the paper's φ₂ on the axis
    expected = ref.fields["regime"].astype(float)
    expected[expected < 0] = np.nan
    np.testing.assert_array_equal(image(view), expected)
    for k, c in REGIME_CODES.items():
        assert f"data-regime='{k}'" in view.legend.object
        assert f"({int((ref.fields['regime'] == c).sum())})" in view.legend.object


def test_each_field_has_its_own_colours_and_the_csv_has_every_cell(dash):
    """Intensity: a log colour bar over its own values (blank without impacts); CSV of all cells."""
    view = dash.maps
    small(view, 4, 3)
    r = compute(view)
    view.settings.field = "intensity"
    el = view.image_element()
    opts = el.opts.get().kwargs
    assert opts["cmap"] == "magma" and opts["logz"] and opts["colorbar"]
    inten = r.fields["intensity"]
    assert opts["clim"][1] == pytest.approx(np.nanmax(inten[inten > 0]))
    view.settings.field = "regime"
    reg = view.image_element().opts.get().kwargs
    assert reg["cmap"][:2] == ["#9e9e9e", "#ff9800"] and not reg["colorbar"]
    df = pd.read_csv(view.csv())
    assert len(df) == 12 and list(df.columns[:3]) == ["lam", "phi2", "regime"]


@pytest.mark.parametrize("setup, where, message", [
    ({"x_start": 3.0, "x_stop": 1.0}, "map-x", "'from' (3) must be below 'to' (1)"),
    ({"x_num": 400, "y_num": 400}, "map-run", "the allowed range is up to 100,000 points"),
    ({"x_num": 300, "y_num": 300, "transient": 1000}, "map-run", "the allowed range is up to 2e+07"),
    ({"x_start": -1.0}, "map-x", "x axis lam: lam = -1.0 is outside the allowed range (1e-06, 10000]"),
    ({"y_axis": "lam"}, "map-x", "x axis and y axis must differ"),
])
def test_bad_requests_show_a_message_naming_the_limit(dash, setup, where, message):
    """Out-of-range axes and oversized grids are refused with a message beside the controls."""
    view = dash.maps
    view.settings.param.update(**setup)
    if "x_start" in setup:
        view.settings.param.update(**setup)  # an axis change resets the range first
    assert not view.compute()
    assert message in dash.state.messages.get(where, ""), dash.state.messages
    assert view.result is None


def test_settings_refuse_values_outside_their_bounds(dash):
    """Points per axis outside [2, 400] are refused by param, with the message beside the box."""
    from app.ui.widgets import set_value
    m = dash.maps.settings
    assert not set_value(m, "x_num", 1)
    assert m.x_num == 60 and "x points = 1 is outside the allowed range; allowed [2, 400]" in m.messages["x_num"]


def test_click_sets_the_state_to_the_grid_point(dash):
    """A click on a regime map sets Λ and φ₂ (paper) to the nearest grid point, and runs."""
    view = dash.maps
    small(view, 6, 5)
    r = compute(view)
    view.select_point(r.x_values[2] + 0.01, r.y_values[3] - 1.0)
    s = dash.state
    assert (s.lam, s.phi2) == (r.x_values[2], r.y_values[3])
    assert s.result.params.lam == r.x_values[2]
    s.r = 0.5  # not an axis: the map no longer holds for these parameters
    assert "For other parameters" in view.status.object


def test_basin_map_and_click_starts_the_gear_there(dash):
    """Basins: the attractor image equals basin_map; a click starts the gear at (x₀, ẋ₀), t = 0."""
    s, view = dash.state, dash.maps
    s.param.update(lam=1.16, h2=0.0)
    view.settings.kind = "basin"
    p = s.result.params
    from rattle_core.model.excitation import excitation
    y0 = float(excitation(0.0, p.h, p.phi))
    assert (view.settings.x_start, view.settings.x_stop) == pytest.approx((y0, y0 + p.j))
    small(view, 6, 5, transient=150)
    r = compute(view)
    ref = basin_map(p, r.x_values, r.y_values, transient=150, record=30)
    np.testing.assert_array_equal(r.fields["attractor"], ref.fields["attractor"])
    view.select_point(r.x_values[1], r.y_values[4])
    assert (s.x0, s.v0, s.t0) == (r.x_values[1], r.y_values[4], 0.0)
    assert s.result.tr.settings["x0"] == pytest.approx(r.x_values[1])


def test_cancel_and_replace(dash, job_pool):
    """Cancel drops the running map; a new request replaces the last (one map job per session)."""
    view = dash.maps
    small(view, 40, 40, transient=400, record=100)
    view.settings.x_start = 0.512345  # a grid not in the disk cache
    assert view.compute()
    job = view.job
    view.cancel("Cancelled.")
    assert job.cancelled and "Cancelled." in view.status.object
    small(view, 4, 4)
    r = compute(view)
    assert r.x_values.size == 4
    # the cancelled map stops between chunks, or is killed with its worker after the grace
    wait_for(lambda: not [j for j in job_pool.pending(dash.session.key) if j.owner[1] == "map"],
             timeout=30, what="the cancelled map to end")


def test_physical_map_click_lands_on_the_clicked_rpm_and_torque(dash):
    """Units on: rpm × drag torque map; a click sets exactly that rpm and C, and Λ, j follow."""
    s, view = dash.state, dash.maps
    s.param.update(units=True, drag_torque=0.05, rpm=1500.0)
    assert (view.settings.x_axis, view.settings.y_axis) == ("rpm", "drag_torque")
    small(view, 5, 4, transient=40, record=20)
    r = compute(view)
    rpm, torque = float(r.x_values[3]), float(r.y_values[1])
    view.select_point(rpm + 1e-3, torque)
    want = units.example().replace(rpm=rpm, drag_torque=torque)
    assert (s.rpm, s.drag_torque) == (rpm, torque)
    assert s.lam == pytest.approx(want.lam, rel=1e-12) and s.j == pytest.approx(want.to_dimensionless().j, rel=1e-12)
    assert s.result.phys.rpm == rpm


def test_serve_sets_where_maps_run(monkeypatch):
    """serve(scheduler=...) is where maps run; there is no field for it on the page."""
    import app.main
    import app.views.maps as mv
    from app.work import map_plan
    monkeypatch.setattr(app.main.pn, "serve", lambda *a, **k: None)
    monkeypatch.setattr(app.main, "warm_up", lambda: None)
    monkeypatch.setattr(app.main, "_answers", lambda *a: True)
    try:
        app.main.serve(port=5999, scheduler="tcp://10.1.2.3:8786", threaded=True, quiet=True)
        assert map_plan.scheduler() == "tcp://10.1.2.3:8786"
        with pytest.raises(ValueError, match="not both"):
            app.main.serve(port=5999, scheduler="tcp://h:1", dask="local")
    finally:
        map_plan.set_scheduler("")
    assert "scheduler" not in mv.MapSettings.param


def test_the_empty_map_is_drawn_without_a_warning(dash):
    """Before any map is computed the Maps tab draws an invisible image: its plot is built and
    redrawn with no warning (an all-NaN image gave "All-NaN slice encountered" at each range
    HoloViews computed, some 200 per test run)."""
    import warnings

    import holoviews as hv

    view = dash.maps
    assert view.result is None
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        hv.renderer("bokeh").get_plot(view._plot())
        view.revision += 1
    assert [str(w.message) for w in caught] == []
