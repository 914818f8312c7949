"""The Gearbox tab without a browser: the sample's orders, a verdict and its variant in the
background, the exports (CSV, an HTML report that escapes what users typed), listening, and
uploads refused by size or content."""
from __future__ import annotations

import html

import numpy as np
import pandas as pd
import pytest
from conftest import wait_for
from gearboxes import OIL_ONE_GEAR

from app.work import gearbox as work

pytestmark = pytest.mark.timeout(600)


@pytest.fixture()
def view(dash, tmp_path, monkeypatch):
    monkeypatch.setenv("RATTLE_CACHE_DIR", str(tmp_path))
    v = dash.gearbox
    v.settings.param.update(rpm_num=5, transient=80, record=30)
    return v


def test_sample_verdict_variant_and_exports(view):
    """The sample's orders arrive; a verdict with a drag +50 % variant arrives with its onsets;
    the variant never rattles earlier than the baseline; the CSV holds both cases; the report
    is one HTML file with its pictures inside and the gear names escaped."""
    view.measure(None)
    wait_for(lambda: view.order_map is not None, 120, "the sample's orders")
    assert list(view.order_map.orders) == [2.0, 4.0, 6.0]
    df = view.table.value.copy()
    df.loc[0, "name"] = "<script>alert(1)</script>"
    view.table.value = df
    view.settings.param.update(variant="drag", drag_pct=50.0)
    assert view.set_target("1000:0.1,3000:0.1 sone")
    assert view.run()
    wait_for(lambda: view.revision == 1, 300, "the verdict")  # set last, after the results
    assert view.base is not None and view.variant is not None
    for name, onset in view.base.onsets.items():
        later = view.variant.onsets[name]
        assert not (later < onset), (name, onset, later)  # more drag: contact holds longer
    csv = pd.read_csv(view.csv())
    assert set(csv["design"]) == {"baseline", "drag torque +50 %", "B - A"}
    assert len(csv) == 3 * 5 * 4
    a = csv[csv["design"] == "baseline"]
    assert (a["margin_sone"] - (0.1 - a["loudness_sone"])).abs().max() < 1e-9
    side = view.side_by_side_frame()
    assert list(side["design"]).count("A") == list(side["design"]).count("B") == 4
    assert set(side["pass"]) <= {"pass", "fail"} and "&lt;script&gt;" in view.side_by_side.object
    from app.ui.gearbox_plots import metric_plot
    import holoviews as hv
    plot = metric_plot(view.base, view.variant, "loudness_sone", "loudness")
    labels = [el.label for el in plot]
    assert "target" in labels and ("fail" not in set(a["pass"].astype(str)) or any(
        isinstance(el, hv.VSpan) for el in plot))
    html = view.report
    assert html.startswith("<!DOCTYPE html>") and html.count("data:image/png;base64,") >= 3
    assert "<script>alert(1)</script>" not in html and "&lt;script&gt;alert(1)&lt;/script&gt;" in html
    assert view.listen()
    wait_for(lambda: view.audio.object is not None, 120, "the gearbox sound")
    assert len(view.audio.object) == int(work.LISTEN_SECONDS * 48_000)


def test_bad_requests_are_refused_with_messages(view):
    """No measurement: the run is refused; a bad measurement upload names its line; a bad
    gear value names its row; an oversized upload is refused before any work."""
    assert not view.run()
    assert "measurement" in view.state.messages["gearbox-gears"]
    view.measure(b"time_s,speed_rpm\n0,1000\n0.001,1000\n0.0005,1000\n" + b"0.1,1000\n" * 50)
    wait_for(lambda: "gearbox-measure" in view.state.messages, 120, "the refusal")
    assert "the uploaded file" in view.state.messages["gearbox-measure"]
    assert "line 4" in view.state.messages["gearbox-measure"]
    view._on_measurement(type("E", (), {"new": b"x" * (work.MAX_MEASUREMENT_BYTES + 1)})())
    assert "allowed size" in view.state.messages["gearbox-measure"]
    view.measure(None)
    wait_for(lambda: view.order_map is not None, 120, "the sample's orders")
    df = view.table.value.copy()
    df.loc[1, "inertia_kgm2"] = -1.0
    view.table.value = df
    assert not view.run()
    assert "row 2" in view.state.messages["gearbox-gears"]


def test_an_uploaded_gearbox_file_fills_the_table_and_opens_no_file(view):
    """A TOML upload fills the gear table and the excitation settings; a measurement path in it
    is never opened on the server."""
    text = (b'[excitation]\nmeasurement = "/etc/passwd"\nengine_order = 2\nharmonics = 2\n'
            b'[[gear]]\nname = "only"\ninertia_kgm2 = 1e-4\nbase_radius_m = 0.03\n'
            b'drag_torque_Nm = 0.02\nbacklash_um = 50\n')
    view._on_toml(type("E", (), {"new": text})())
    wait_for(lambda: "gearbox-gears" in view.state.messages, 120, "the refusal")
    assert "names no file" in view.state.messages["gearbox-gears"]
    view.measure(None)
    wait_for(lambda: view.order_map is not None, 120, "the sample's orders")
    view.state.clear("gearbox-gears")
    view._on_toml(type("E", (), {"new": text})())
    wait_for(lambda: list(view.table.value["name"]) == ["only"], 120, "the table")
    assert view.settings.harmonics == 2


def test_cancel_drops_the_running_verdict(view):
    """Cancel stops the verdict: its job is cancelled, nothing it computed is shown, and the
    next request's verdict is the one that arrives."""
    view.measure(None)
    wait_for(lambda: view.order_map is not None, 120, "the sample's orders")
    view.settings.param.update(rpm_num=60, transient=400, record=200)
    assert view.run()
    job = view.job
    view.cancel("Cancelled.")
    assert job.cancelled and view.job is None and not view.progress.visible
    assert "Cancelled." in view.status.object
    view.settings.param.update(rpm_num=3, transient=60, record=30)
    assert view.run()
    wait_for(lambda: view.revision == 1, 300, "the second verdict")
    assert view.base.rpm.size == 3


def test_target_text_and_oil_temperature_are_checked(view):
    """A target that does not read is refused with its reason as plain text, the last good one
    kept; a good one is taken; an oil temperature outside −40…150 °C is refused with the range;
    design B starts as a copy of the gears."""
    assert view.set_target("1000:10,3000:20 sone; 1000:60,3000:70 dba")
    assert view.settings.target == "1000:10,3000:20 sone; 1000:60,3000:70 dba"
    assert not view.set_target("1000:10,<b>3000</b> sone")
    msg = view.settings.messages["target"]
    assert "is not RPM:VALUE" in msg and "Kept 1000:10,3000:20 sone; 1000:60,3000:70 dba" in msg
    assert view.settings.target == "1000:10,3000:20 sone; 1000:60,3000:70 dba"
    from app.ui.widgets import set_value
    assert not set_value(view.settings, "oil_temp", 151.0)
    assert "[-40, 150]" in view.settings.messages["oil_temp"]
    assert set_value(view.settings, "oil_temp", -40.0)
    view.copy_design()
    assert view.settings.variant == "design"
    assert view.table_b.value.equals(view.table.value)


#: The oil gearbox of the tests with a target of its own.
OIL_BOX = OIL_ONE_GEAR.replace(
    "[[gear]]", "[target]\nrpm = [1000, 3000]\nsone = [0.1, 0.3]\n\n[[gear]]").encode()


def test_drag_what_if_scales_an_oil_drag_and_the_file_target_is_shown(view):
    """An uploaded gearbox with [oil], an oil-drag gear and a [target]: the target field shows
    the file's target in the CLI's form (and keeps what the user types over the next upload);
    the verdict's drag is the oil model's 0.01 + 0.02·rpm/2000 N·m at 40 °C, the drag +50 %
    what-if's is 1.5 times it at every speed, and the what-if rattles no earlier."""
    view._on_toml(type("E", (), {"new": OIL_BOX})())
    wait_for(lambda: list(view.table.value["name"]) == ["idler"], 120, "the table")
    assert view.settings.target == "1000:0.1,3000:0.3 sone"
    assert view.target_input.value == "1000:0.1,3000:0.3 sone"
    view.settings.param.update(rpm_start=600.0, rpm_stop=3000.0, rpm_num=5, variant="drag",
                               drag_pct=50.0, transient=150, record=40)
    assert view.run(), view.state.messages
    wait_for(lambda: view.revision == 1, 300, "the verdict")
    base, what_if = view.base.gear("idler"), view.variant.gear("idler")
    rpm = base["rpm"].to_numpy()
    np.testing.assert_allclose(base["drag_Nm"], 0.01 + 0.02 * rpm / 2000, rtol=1e-9)
    np.testing.assert_allclose(what_if["drag_Nm"], 1.5 * (0.01 + 0.02 * rpm / 2000), rtol=1e-9)
    assert not (view.variant.onsets["idler"] < view.base.onsets["idler"])
    assert view.base.gearbox.target.limits["sone"] == (0.1, 0.3)
    assert view.set_target("1000:5,3000:5 sone")
    view._toml_read(work.gearbox_text(OIL_BOX, view.order_map))  # the upload's callback
    assert view.settings.target == "1000:5,3000:5 sone"


DAQ = __import__("pathlib").Path(__file__).parent / "data" / "daq_semicolon_decimal_comma.csv"


def test_a_semicolon_decimal_comma_upload_shows_what_was_read_and_draws_its_orders(view):
    """A DAQ export with ``;``, decimal commas and a units row: the card says so in plain
    text (semicolon, decimal mark ',', its columns, the unit 1/min read as rpm, the rows), the
    orders and the Campbell view are drawn, and the analysed orders are the ones asked for."""
    view.measurement.input.filename = "<b>daq</b>.csv"
    view._on_measurement(type("E", (), {"new": DAQ.read_bytes()})())
    # the job's thread sets the orders, then draws the Campbell view
    wait_for(lambda: view.order_map is not None and view.measurement.revision == 1, 180,
             "the upload's orders and their Campbell view")
    text = view.measurement.detected.object
    assert "semicolon-separated" in text and "decimal mark &#x27;,&#x27;" in text
    assert "Zeit" in text and "Drehzahl" in text and "4000 samples" in text
    assert "<b>" not in text and "<b>daq" not in view.measurement.status.object
    assert list(view.order_map.orders) == [2.0, 4.0, 6.0]
    notices = view.measurement.notices.object  # orders 4 and 6 are beyond the 2 kHz sampling
    assert view.order_map.notices and all(html.escape(n, quote=True) in notices
                                          for n in view.order_map.notices)
    assert view.measurement.revision == 1 and view.measurement.campbell is not None
    np.testing.assert_array_equal(view.measurement.campbell.analysed_orders, [2.0, 4.0, 6.0])
    overlay = view.measurement.orders_pane.object[()]
    assert len(overlay) == 3 and overlay.get(0).data.shape[0] == view.order_map.rpm.size
    mesh = view.measurement.campbell_pane.object[()]
    assert mesh.get(0).dimension_values(2, flat=False).shape == \
        view.measurement.campbell.level_db.shape


def test_a_corrected_speed_unit_reads_the_same_bytes_again(view):
    """The DAQ file's speed written in rad/s under a bare ``speed`` header reads as 157 rpm
    with a warning naming rad/s; choosing rad/s reads the same bytes again: 1500 rpm, the
    value in the file times 60/(2π), and the card says rad/s converted to rpm."""
    import math
    rows = [line.replace(",", ".").split(";") for line in
            DAQ.read_text(encoding="utf-8-sig").splitlines()[3:] if line.strip()]
    data = ("time_s,speed\n" + "".join(f"{t},{float(v) * 2 * math.pi / 60:.6f}\n"
                                        for t, v in rows)).encode()
    view.settings.harmonics = 1
    view._on_measurement(type("E", (), {"new": data})())
    wait_for(lambda: view.measurement.revision == 1, 180, "the upload's orders")
    assert view.order_map.rpm[0] < 160 and "as rad/s it would be 1500 rpm" in \
        view.measurement.detected.object
    assert view.measurement.options() == {}
    view.measurement.speed_unit.value = "rad/s"
    wait_for(lambda: view.measurement.revision == 2, 180, "the re-read")
    assert view.measurement.options() == {"speed_unit": "rad/s"}
    assert "[rad/s] converted to rpm" in view.measurement.detected.object
    mean = np.mean([float(v) for _, v in rows])
    assert abs(view.order_map.rpm[0] - mean) < 1e-3 * mean


def test_the_report_holds_the_campbell_view_and_how_the_file_was_read(view):
    """With a measurement, the verdict's report holds a Campbell image and the reading's facts
    (separator, decimal mark); without the Campbell data it holds none."""
    view.settings.harmonics = 1  # the file's 2 kHz resolves order 2 only at its speeds
    view._on_measurement(type("E", (), {"new": DAQ.read_bytes()})())
    wait_for(lambda: view.measurement.revision == 1, 180, "the upload's orders")
    view.settings.param.update(rpm_start=1460.0, rpm_stop=1540.0, rpm_num=2, transient=40,
                               record=20)  # the file is one bin, about 1500 rpm
    assert view.run(), view.state.messages
    wait_for(lambda: view.revision == 1, 300, "the verdict")
    html = view.report
    assert "<h2>Campbell view</h2>" in html
    campbell = html.split("<h2>Campbell view</h2>", 1)[1]
    assert campbell.lstrip().startswith('<img alt="" style="max-width:100%" src="data:image/png')
    assert "semicolon-separated" in html and "measurement read as" in html
    assert work.campbell_html(None) == ""
