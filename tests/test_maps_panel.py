"""The Maps tab without a browser: a whole dashboard session, its map computed in the test's thread.

The image the panel sends to the browser is checked against ``rattle_core.batch.maps`` run on its
own, cell by cell; the messages against the limits they state; clicks against the dashboard's
state.
"""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from rattle_core.model.excitation import excitation
from rattle_core.analysis.vocabulary import REGIME_CODES
from rattle_core.batch.maps import basin_map, regime_map


@pytest.fixture(autouse=True)
def private_cache(tmp_path, monkeypatch):
    """Each test gets its own map cache, so a first run is always computed."""
    monkeypatch.setenv("RATTLE_CACHE_DIR", str(tmp_path / "cache"))


@pytest.fixture()
def panel(dash):
    from app.maps_panel import MapsPanel
    p = next(p for p in dash.panels if isinstance(p, MapsPanel))
    assert p.tab[0] == "Maps"
    return p


def small(panel, nx=7, ny=5, transient=60, record=30):
    panel.x_num.value, panel.y_num.value = nx, ny
    panel.transient.value, panel.record.value = transient, record


def visible_messages(panel) -> dict[str, str]:
    return {k: a.object for k, a in panel.alerts.items() if a.visible}


def test_regime_image_equals_regime_map(panel, dash):
    """The image holds the regime codes of regime_map for the same grid, value for value."""
    small(panel)
    panel.x_start.value, panel.x_stop.value = 0.8, 3.5
    panel.compute_now()
    assert visible_messages(panel) == {}
    lams, phis = np.linspace(0.8, 3.5, 7), np.linspace(-180.0, 180.0, 5)
    ref = regime_map(dash.params, "lam", lams, "phi2", phis, transient=60, record=30)
    image = panel.source.data["image"][0]
    expected = ref.fields["regime"].astype(float)
    expected[expected < 0] = np.nan
    np.testing.assert_array_equal(image, expected)
    assert panel.source.name == "map_image"
    # what the hover tool reads, per cell
    letters = {v: k for k, v in REGIME_CODES.items()}
    data = panel.source.data
    assert data["regime"][0] == [[letters[int(c)] for c in row] for row in ref.fields["regime"]]
    np.testing.assert_array_equal(data["xv"][0], np.meshgrid(lams, phis)[0])
    np.testing.assert_array_equal(data["yv"][0], np.meshgrid(lams, phis)[1])
    for col, field in (("period", "period"), ("intensity", "intensity"), ("lyapunov", "lyapunov")):
        np.testing.assert_array_equal(data[col][0], ref.fields[field])
    fields = {f for _, f in panel.hover.tooltips}
    for col in ("xv", "yv", "regime", "period", "intensity", "lyapunov"):
        assert any(f"@{col}" in f for f in fields), col
    # the pixels are centred on the grid values
    assert data["x"][0] + data["dw"][0] / 2 == pytest.approx((0.8 + 3.5) / 2)
    # legend: one entry per regime, with its count
    for k, c in REGIME_CODES.items():
        assert f"data-regime='{k}'" in panel.legend.object
        assert f"({int((ref.fields['regime'] == c).sum())})" in panel.legend.object


def test_other_fields_and_csv_export(panel, dash):
    """The intensity field shows the intensity (blank where no impacts); the CSV has every cell."""
    small(panel, 4, 3)
    panel.compute_now()
    panel.field.value = "intensity"
    inten = panel.result.fields["intensity"]
    shown = panel.source.data["image"][0]
    np.testing.assert_array_equal(shown[inten > 0], inten[inten > 0])
    assert np.isnan(shown[~(inten > 0)]).all()
    assert panel.color_bar.visible
    panel.field.value = "lyapunov"
    np.testing.assert_array_equal(panel.source.data["image"][0], panel.result.fields["lyapunov"])
    df = pd.read_csv(panel._csv())
    assert len(df) == 12 and list(df.columns[:3]) == ["lam", "phi2", "regime"]
    letters = {v: k for k, v in REGIME_CODES.items()}
    assert list(df["regime"]) == [letters[int(c)] for c in panel.result.fields["regime"].ravel()]


def test_second_run_comes_from_the_cache(panel):
    """The same map asked twice is read from the disk cache the second time, and says so."""
    small(panel, 5, 4)
    panel.compute_now()
    assert "computed on this server's cores" in panel.status.object
    first = panel.source.data["image"][0].copy()
    panel.compute_now()
    assert "read from the disk cache" in panel.status.object
    np.testing.assert_array_equal(panel.source.data["image"][0], first)


@pytest.mark.parametrize("setup, where, message", [
    ({"x_start": -1.0}, "x", "x axis lam: lam = -1.0 is outside the allowed range (1e-06, 10000]"),
    ({"y_axis": "r", "y_start": 0.5, "y_stop": 1.5}, "y",
     "y axis r: r = 1.5 is outside the allowed range [0, 1]"),
    ({"x_num": 1}, "x", "x points = 1 is outside the allowed range [2, 400]"),
    ({"x_num": 400, "y_num": 400}, "run", "the allowed range is up to 100,000 points"),
    ({"x_num": 300, "y_num": 300, "transient": 1000}, "run", "the allowed range is up to 2e+07"),
    ({"record": 0}, "run", "recorded periods = 0 is outside the allowed range [1, 10000]"),
    ({"x_start": 3.0, "x_stop": 1.0}, "x", "'from' (3) must be below 'to' (1)"),
    ({"y_axis": "lam"}, "x", "x axis and y axis must differ"),
])
def test_bad_inputs_show_a_message_naming_the_limit(panel, setup, where, message):
    """Out-of-range inputs and oversized grids are refused with a message beside the controls."""
    for name, value in setup.items():
        getattr(panel, name).value = value
    panel.compute_now()
    assert message in visible_messages(panel).get(where, ""), visible_messages(panel)
    assert panel.result is None and panel._job is None


def test_scheduler_field_messages(panel):
    """A malformed or unreachable Dask scheduler is a message beside the field, no map."""
    small(panel, 3, 3)
    panel.scheduler.value = "my-cluster"
    panel.compute_now()
    assert "is not understood" in visible_messages(panel)["scheduler"]
    panel.scheduler.value = "tcp://127.0.0.1:9"
    panel.compute_now()
    msg = visible_messages(panel)["scheduler"]
    assert "Dask scheduler 'tcp://127.0.0.1:9': cannot connect" in msg
    assert "Traceback" not in msg and panel.result is None


def test_click_sets_the_dashboard_parameters(panel, dash):
    """A click on a regime map sets Λ and φ₂ to the nearest grid point, and redraws."""
    small(panel, 6, 5)
    panel.compute_now()
    lams, phis = panel.result.x_values, panel.result.y_values
    panel.select_point(lams[2] + 0.01, phis[3] - 1.0)
    assert dash.state.lam == pytest.approx(lams[2], abs=1e-9)
    assert dash.state.phi2 == pytest.approx(phis[3], abs=1e-9)
    assert dash.tr.params.lam == pytest.approx(lams[2], abs=1e-9)
    assert "For other parameters" not in panel.status.object
    assert list(panel.marker.data["x"]) == [dash.state.lam]
    dash.widgets["r"].value = 0.5  # not an axis: the map no longer holds for these parameters
    assert "For other parameters" in panel.status.object


def test_basin_map_and_click_starts_the_gear_there(panel, dash):
    """Basins: the attractor image equals basin_map; a click starts the gear at (x₀, ẋ₀), t = 0."""
    dash.widgets["lam"].value = 1.16
    dash.widgets["h2"].value = 0.0
    panel.kind.value = "basin"
    p = dash.params
    y0 = float(excitation(0.0, p.h, p.phi))
    assert (panel.x_start.value, panel.x_stop.value) == pytest.approx((y0, y0 + p.j))
    small(panel, 6, 5, transient=150)
    panel.compute_now()
    assert visible_messages(panel) == {}
    ref = basin_map(p, np.linspace(y0, y0 + p.j, 6), np.linspace(-3, 3, 5), transient=150, record=30)
    np.testing.assert_array_equal(panel.source.data["image"][0], ref.fields["attractor"].astype(float))
    for i, a in enumerate(ref.attractors):
        assert f"<b>{i}</b>: regime {a['regime']}" in panel.legend.object
    xv, vv = panel.result.x_values, panel.result.y_values
    panel.select_point(xv[1], vv[4])
    assert float(dash.state.x0) == pytest.approx(xv[1], abs=1e-9)
    assert dash.state.v0 == pytest.approx(vv[4], abs=1e-9) and dash.state.t0 == 0.0
    assert dash.tr.settings["x0"] == pytest.approx(xv[1], abs=1e-9)


def test_background_compute_and_cancel(panel):
    """compute() runs on the maps worker; Cancel drops it, a new request replaces it."""
    import app.maps_panel as mp
    small(panel, 30, 30, transient=300, record=100)
    panel.compute()
    job = panel._job
    assert job is not None and not panel.cancel_button.disabled
    panel.cancel("Cancelled.")
    assert job.cancelled and panel._job is None and panel.status.object == "Cancelled."
    small(panel, 4, 4)
    panel.compute()
    panel._job.future.result(timeout=60)
    # outside a server the result lands at once (no document to schedule it on)
    assert panel.result is not None and panel.result.x_values.size == 4
    assert mp._EXECUTOR._max_workers == 1


def test_physical_axes_follow_the_units_mode(panel, dash):
    """rpm and drag torque are offered only in physical units, and map through the units."""
    from rattle_core.batch.plan import point_params
    from rattle_core.model.units import PhysicalParams
    assert "rpm" not in panel.x_axis.options.values()
    phys = PhysicalParams(inertia=2e-4, radius=0.04, drag_torque=0.02, backlash=160e-6,
                          rpm=1500.0, amplitudes=(400.0, 100.0), phases_deg=(0.0, 45.0),
                          excitation="acceleration")
    dash.physical = phys
    panel.on_redraw()
    assert {"rpm", "drag_torque"} <= set(panel.x_axis.options.values())
    panel.x_axis.value, panel.y_axis.value = "rpm", "drag_torque"
    small(panel, 3, 3)
    panel.compute_now()
    assert visible_messages(panel) == {}, visible_messages(panel)
    r = panel.result
    panel.select_point(r.x_values[2], r.y_values[1])
    want = point_params(phys.to_dimensionless(), phys, ("rpm", "drag_torque"),
                        (r.x_values[2], r.y_values[1]))
    assert dash.state.lam == pytest.approx(want.lam, rel=1e-9)
    assert dash.state.j == pytest.approx(want.j, rel=1e-9)
    dash.physical = None
    panel.on_redraw()
    assert "rpm" not in panel.x_axis.options.values() and panel.x_axis.value == "lam"


def test_serve_sets_the_scheduler_default(monkeypatch):
    """app.main.serve(scheduler=...) / (dask='local') set the field's default for new sessions."""
    import app.main
    import app.maps_panel as mp
    monkeypatch.setattr(app.main.pn, "serve", lambda *a, **k: None)
    monkeypatch.setattr(app.main, "warm_up", lambda: None)
    try:
        app.main.serve(port=5999, scheduler="tcp://10.1.2.3:8786")
        assert mp.default_scheduler() == "tcp://10.1.2.3:8786"
        app.main.serve(port=5999, dask="local")
        assert mp.default_scheduler() == "local"
        with pytest.raises(ValueError, match="not both"):
            app.main.serve(port=5999, scheduler="tcp://h:1", dask="local")
    finally:
        mp.set_default_scheduler("")


def test_local_dask_cluster_gives_the_same_map(panel):
    """Scheduler 'local' runs the map on the server's shared 2-worker LocalCluster, same values."""
    pytest.importorskip("dask.distributed")
    import app.maps_panel as mp
    small(panel, 5, 4)
    panel.compute_now()
    local = {k: v.copy() for k, v in panel.result.fields.items()}
    import rattle_core.store.cache as cache
    for f in cache.cache_dir().glob("map-*.npz"):  # computed again, this time on Dask
        f.unlink()
    panel.scheduler.value = "local"
    panel.compute_now()
    assert visible_messages(panel) == {}, visible_messages(panel)
    assert "computed on Dask (local)" in panel.status.object
    for k, v in local.items():
        np.testing.assert_array_equal(panel.result.fields[k], v)
    assert mp.dask_client("local") is mp.dask_client("local")
    assert len(mp.dask_client("local").scheduler_info()["workers"]) == 2


def test_click_on_a_physical_map_sets_the_physical_inputs(panel, dash):
    """Units on: a click on an rpm × drag-torque map puts that rpm and C in the inputs and table."""
    from html import escape

    from app.units_panel import UnitsPanel
    units = next(p for p in dash.panels if isinstance(p, UnitsPanel))
    units.set_mode(True)
    dash.refresh()
    panel.on_redraw()
    held = units.phys
    panel.x_axis.value, panel.y_axis.value = "rpm", "drag_torque"
    small(panel, 3, 3)
    panel.compute_now()
    assert visible_messages(panel) == {}, visible_messages(panel)
    r = panel.result
    rpm, torque = float(r.x_values[2]), float(r.y_values[1])
    assert rpm != held.rpm and torque != held.drag_torque
    panel.select_point(r.x_values[2] + 1e-3, r.y_values[1])
    want = held.replace(rpm=rpm, drag_torque=torque)
    assert dash.physical == want and units.phys == want
    assert dash.state.lam == want.lam and dash.state.j == want.to_dimensionless().j
    assert units.inputs["rpm"].value == float(f"{rpm:.6g}")
    assert units.inputs["drag_torque"].value == float(f"{torque:.6g}")
    assert escape(f"{rpm:.6g} rpm") in units.table.object
    assert escape(f"{torque:.6g} N·m") in units.table.object
    # a mixed map: the dimensionless axis is set too, the physical one stays as clicked
    panel.x_axis.value, panel.y_axis.value = "drag_torque", "r"
    small(panel, 3, 3)
    panel.compute_now()
    r = panel.result
    panel.select_point(r.x_values[0], r.y_values[2])
    assert dash.state.r == round(float(r.y_values[2]), 10)
    assert units.phys.drag_torque == float(r.x_values[0]) and units.phys.r == dash.state.r
    assert units.phys.to_dimensionless().lam == pytest.approx(dash.state.lam, rel=1e-12)
