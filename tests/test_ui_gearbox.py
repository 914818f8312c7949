"""Browser test of the Gearbox tab, on one page: the sample's orders, a verdict with a variant
computed in the background, its CSV downloaded, a bad upload refused with its line, the gearbox
heard; an upload just under the 20 MB limit analysed and drawn, one just over it refused; a DAQ
export with semicolons and decimal commas read, said how, and drawn.

The checks share one page, in turn (a page load is the costly part of a browser test); each
step starts from what the one before left, and the sample run-up the upload step ends on is
what the DAQ export replaces.
"""
from __future__ import annotations

from pathlib import Path

import pytest
from playwright.sync_api import expect
from test_ui import open_dashboard, set_input

pytestmark = [pytest.mark.ui, pytest.mark.timeout(600)]

REGIME_POINTS = """() => {
  const f = [...Bokeh.documents[0]._all_models.values()].filter(m => m.name === 'gb_regimes')
    .find(m => { const v = Bokeh.index.find_one(m); return v && v.el.isConnected; });
  if (f == null) return 0;
  let n = 0;
  for (const r of f.renderers) {
    const d = r.data_source && r.data_source.data;
    if (d && d.gear && d.color) n += d.color.length;
  }
  return n;
}"""

UPLOADED_ORDERS = """() => {
  const ms = [...Bokeh.documents[0]._all_models.values()];
  if (!ms.some(m => m.text === 'orders of the uploaded file')) return 0;
  let n = 0;
  for (const m of ms) {
    const d = m.data;
    if (d && d.accel && d.rpm) n = Math.max(n, d.accel.length);
  }
  return n;
}"""


def runup_file(path, size: int) -> None:
    """A run-up 1000 → 3000 rpm at 10 kHz (orders 2, 4, 6) of exactly ``size`` bytes: rows
    fill it to within one row, a comment line pads the rest."""
    import io
    import math

    import numpy as np
    rows = size // 18
    t = np.arange(rows) / 10_000.0
    w0, acc = 1000 * 2 * math.pi / 60, 2000 * 2 * math.pi / 60 / t[-1]
    psi, omega = w0 * t + 0.5 * acc * t * t, w0 + acc * t
    speed = omega - sum(a / (k * omega) * np.sin(k * psi - math.radians(p))
                        for k, a, p in ((2, 200.0, 20.0), (4, 70.0, -60.0), (6, 24.0, 150.0)))
    buf = io.BytesIO()
    np.savetxt(buf, np.column_stack([t, speed * 60 / (2 * math.pi)]), fmt=["%.5f", "%.3f"],
               delimiter=",")
    head = b"time_s,speed_rpm\n"
    body = buf.getvalue()
    body = body[:body.rfind(b"\n", 0, size - len(head) - 2) + 1]  # whole rows, room for "#\n"
    room = size - len(body) - len(head)
    path.write_bytes(b"#" + b" " * (room - 2) + b"\n" + head + body)
    assert path.stat().st_size == size


@pytest.mark.timeout(1800)
def test_gearbox_tab_verdict_uploads_and_a_daq_export(page, dashboard_server, tmp_path,
                                                      monkeypatch):
    """On one page: the sample's verdict with a variant, its CSV, a bad upload's line and the
    sound; a 19.9 MB upload drawn and a 20.1 MB one refused, the page still connected; a DAQ
    export read as text and drawn. Each step's console and server stay free of errors."""
    monkeypatch.setenv("RATTLE_CACHE_DIR", str(tmp_path / "cache"))
    errors = open_dashboard(page, dashboard_server)
    page.locator(".bk-tab", has_text="Gearbox").first.click()
    _step_sample_to_verdict(page, dashboard_server, tmp_path, errors)
    _step_upload_up_to_the_limit(page, dashboard_server, tmp_path, errors)
    _step_semicolon_decimal_comma_upload(page, dashboard_server, errors)


def _step_sample_to_verdict(page, dashboard_server, tmp_path, errors) -> None:
    """Sample → orders; 4 speeds with a drag +50 % variant → onsets in the status, the regime
    plot's 24 points and a CSV of 3 × 4 × 4 rows (both designs and B - A); a CSV with time going back → the message names the line; Listen → audio."""
    page.locator(".gb-sample button").first.click()
    expect(page.locator(".gb-measure-status").first).to_contain_text("rpm bins", timeout=120_000)
    for css, value in ((".gb-rpm-num", "4"), (".gb-transient", "60"), (".gb-record", "30")):
        set_input(page, css, value)
    page.locator(".gb-variant select").first.select_option(label="drag torque +/- %")
    set_input(page, ".gb-drag-pct", "50")  # sent before the click below, on the same socket
    page.locator(".gb-run button").first.click()
    expect(page.locator(".gb-status").first).to_contain_text("Variant (drag torque +50 %)",
                                                             timeout=300_000)
    expect(page.locator(".gb-status").first).to_contain_text("5th idler")
    # the regime plot drew every gear at every speed, baseline and variant (3 × 4 × 2)
    page.wait_for_function(f"() => ({REGIME_POINTS})() == 24", timeout=120_000)
    with page.expect_download(timeout=120_000) as dl:
        page.locator(".gb-csv button").first.click()
    text = open(dl.value.path(), encoding="utf-8").read().splitlines()
    assert text[0].startswith("design,gear,rpm,regime,impacts_per_s,intensity,loudness_sone")
    assert len(text) == 1 + 3 * 4 * 4
    bad = tmp_path / "bad.csv"
    bad.write_text("time_s,speed_rpm\n0,1000\n0.001,1000\n0.0005,1000\n" + "0.1,1000\n" * 50)
    page.locator(".gb-measurement input[type=file]").first.set_input_files(str(bad))
    expect(page.locator(".msg-gearbox-measure").first).to_contain_text("line 4", timeout=120_000)
    page.locator(".gb-listen button").first.click()
    expect(page.locator(".gb-listen-status").first).to_contain_text("sone", timeout=120_000)
    assert page.locator(".gb-audio audio").first.get_attribute("src")
    assert errors == []
    assert dashboard_server["log"].tracebacks() == []


def _step_upload_up_to_the_limit(page, dashboard_server, tmp_path, errors) -> None:
    """A 19.9 MB measurement goes through the page's connection (over Bokeh's default message
    limit once base64-encoded), is analysed and its orders drawn; a 20.1 MB one is refused at
    once, naming the 20 MB limit, and the page keeps its connection."""
    near, over = tmp_path / "near.csv", tmp_path / "over.csv"
    runup_file(near, 19_900_000)
    runup_file(over, 20_100_000)
    upload = page.locator(".gb-measurement input[type=file]").first
    upload.set_input_files(str(near))
    status = page.locator(".gb-measure-status").first
    expect(status).to_contain_text("the uploaded file:", timeout=300_000)
    expect(status).to_contain_text("rpm bins")
    page.wait_for_function(f"() => ({UPLOADED_ORDERS})() >= 15", timeout=120_000)
    upload.set_input_files(str(over))
    refusal = page.locator(".msg-gearbox-measure").first
    expect(refusal).to_contain_text("20100000 bytes", timeout=120_000)
    expect(refusal).to_contain_text("up to 20000000 bytes (20 MB)")
    # still connected: the page answers a new request
    page.locator(".gb-sample button").first.click()
    expect(status).to_contain_text("sample run-up", timeout=120_000)
    assert errors == []
    assert dashboard_server["log"].tracebacks() == []


def _step_semicolon_decimal_comma_upload(page, dashboard_server, errors) -> None:
    """A DAQ export (``;`` delimiter, decimal commas, a units row, German headers) uploaded
    through Chromium: the card says how it was read, as text, and the orders are drawn."""
    # the sample's orders have replaced the last upload's
    page.wait_for_function(f"() => ({UPLOADED_ORDERS})() == 0", timeout=120_000)
    daq = Path(__file__).parent / "data" / "daq_semicolon_decimal_comma.csv"
    page.locator(".gb-measurement input[type=file]").first.set_input_files(str(daq))
    detected = page.locator(".gb-detected").first
    expect(detected).to_contain_text("semicolon-separated", timeout=300_000)
    expect(detected).to_contain_text("decimal mark ','")
    expect(detected).to_contain_text("Drehzahl")
    page.wait_for_function(f"() => ({UPLOADED_ORDERS})() >= 1", timeout=120_000)
    assert errors == []
    assert dashboard_server["log"].tracebacks() == []
