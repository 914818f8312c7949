"""Browser tests of what a new user tripped on: each would have failed on the old dashboard.

The page is read back as the user sees it: pixel colours of a screenshot, the values in the
controls, the URL, the axes and legends of the plots in the page's Bokeh document.

Checks that can share a page run as steps of one test on one page (a page load is the costly
part of a browser test), in an order where no step spoils a later one. A diagram opened at
Λ = 0.6, a page opened with an invalid r, and ``rattle serve`` itself each have a page of their own.
"""
from __future__ import annotations

import io
import math
import os
import socket
import subprocess
import sys
import time
import urllib.request

import numpy as np
import pytest
from PIL import Image

from app import dashboard as dashboard_module
from conftest import free_port, wait_for
from test_ui import (READY, box, box_value, message, open_dashboard, painted, set_input, wait_bif,
                     wait_box)

pytestmark = [pytest.mark.ui, pytest.mark.timeout(600)]

#: The model named ``name`` that is on the page (a replaced plot may keep its name a moment).
BY_NAME = """(name) => {
  const all = [...Bokeh.documents[0]._all_models.values()].filter(m => m.name === name);
  return all.find(m => { const v = Bokeh.index.find_one(m); return v && v.el.isConnected; }) || null;
}"""
#: Screen position of data point (x, y) in the named figure, and the figure's ranges.
FIG = """([name, x, y]) => {
  const m = (""" + BY_NAME + """)(name);
  const v = Bokeh.index.find_one(m);
  v.el.scrollIntoView({block: 'center', inline: 'center'});  // below the fold on a tall page
  const r = v.el.getBoundingClientRect(), f = v.frame;
  const label = (side) => { const a = side.find(a => a.axis_label !== undefined); return a ? a.axis_label : null; };
  return {sx: r.left + f.x_scale.compute(x), sy: r.top + f.y_scale.compute(y),
          x0: m.x_range.start, x1: m.x_range.end, xlabel: label([...m.below, ...m.above]),
          ylabel: label([...m.left, ...m.right]), title: m.title.text};
}"""
#: The map's image glyph: its values, shape, placement and colour mapper.
MAP_IMAGE = """() => {
  const f = (""" + BY_NAME + """)('map_figure');
  if (f == null) return null;
  for (const r of f.renderers) {
    const g = r.glyph, s = r.data_source;
    if (g && g.color_mapper && s.data.image && s.data.image.length) {
      const img = s.data.image[0], cm = g.color_mapper;
      return {values: Array.from(img), shape: img.shape, x: s.data.x[0], y: s.data.y[0],
              dw: s.data.dw[0], dh: s.data.dh[0], low: cm.low, high: cm.high,
              palette: cm.palette, kind: cm.type};
    }
  }
  return null;
}"""


def fig(page, name: str, x: float = 0.0, y: float = 0.0) -> dict:
    return page.evaluate(FIG, [name, x, y])


def compute_map(page, nx: int, ny: int) -> None:
    page.locator(".bk-tab", has_text="Maps").first.click()
    page.locator(".map-compute button").first.wait_for(timeout=20_000)
    for css, value in ((".map-x-num", str(nx)), (".map-y-num", str(ny)), (".map-transient", "60"),
                       (".map-record", "30")):
        set_input(page, css, value)  # sent before the click, on the same socket
    page.locator(".map-compute button").first.click()
    page.locator(".map-status", has_text=f"{nx} × {ny} = {nx * ny} points").first.wait_for(timeout=180_000)
    page.wait_for_function(f"() => {{ const m = ({MAP_IMAGE})(); return m != null && m.shape[0] == {ny} "
                           f"&& m.shape[1] == {nx}; }}", timeout=60_000)
    page.locator(".map-plot").first.scroll_into_view_if_needed()  # where a click reaches it
    painted(page)


def settled(page) -> None:
    """Wait until the map's frame stops moving: the map takes the width its controls leave, so
    a colour bar that comes or goes re-lays it out over a few frames."""
    page.locator(".map-plot").first.scroll_into_view_if_needed()
    last = None
    for _ in range(600):  # a condition, polled frame by frame; 600 frames is ten seconds at 60/s
        painted(page)
        now = fig(page, "map_figure", 0.0, 0.0)
        if now == last:
            return
        last = now
    raise AssertionError(f"the map's frame kept moving: {last}")


def _live_dashboard():
    """The server's dashboard of the page the test opened last."""
    return max(dashboard_module.LIVE, key=lambda d: d.session.key)


def _step_a_slider_drag_runs_once(page):
    """Fix 9: dragging the Λ slider through many positions runs one simulation, on release."""
    dash = _live_dashboard()  # the session has run its first simulation
    runs = dash.session.runs
    h = page.locator(".ctl-lam .noUi-handle").first.bounding_box()
    x, y = h["x"] + h["width"] / 2, h["y"] + h["height"] / 2
    page.mouse.move(x, y)
    handle = page.locator(".ctl-lam .noUi-handle").first.element_handle()
    page.mouse.down()
    for k in range(1, 13):
        before = handle.get_attribute("aria-valuenow")
        page.mouse.move(x + 6 * k, y, steps=2)
        # as a hand drags: each position is on the slider before the next move
        page.wait_for_function("([h, v]) => h.getAttribute('aria-valuenow') !== v",
                               arg=[handle, before], timeout=20_000)
    page.mouse.up()
    page.wait_for_function("(el) => parseFloat(el.value) > 3.3", arg=box(page, "lam").element_handle(),
                           timeout=20_000)
    lam = box_value(page, "lam")
    wait_for(lambda: dash.state.result is not None and abs(dash.state.result.params.lam - lam) < 1e-12,
             timeout=30, what="the run at the released value")
    page.wait_for_function(f"() => Math.abs(parseFloat(new URLSearchParams(window.location.search)"
                           f".get('lam')) - {lam}) < 1e-12", timeout=20_000)
    assert dash.session.runs == runs + 1


def _type_lambda(page, lam: float) -> None:
    """Type Λ into its box and wait until the server has run it."""
    dash = _live_dashboard()
    set_input(page, ".ctl-lam", str(lam))
    wait_box(page, "lam", lam)
    wait_for(lambda: dash.state.result is not None and abs(dash.state.result.params.lam - lam) < 1e-12,
             timeout=60, what=f"the run at Λ = {lam}")


def _step_paper_45_degrees_gives_chaos_and_the_convention_is_in_the_url(page):
    """Fix 3: typing the paper's 45° at Λ = 3.3 gives chaos; the core switch shows −135° and
    goes into the URL; the φ₂ diagram runs over the paper's 0–360° of Figure 6."""
    wait_box(page, "phi2", 0.0)
    b = box(page, "phi2")
    b.fill("45")
    b.press("Enter")
    page.locator(".rattle-badge[data-regime='D']").wait_for(timeout=20_000)
    page.locator(".ctl-phases button", has_text="core").first.click()
    wait_box(page, "phi2", -135.0)
    page.wait_for_function("() => window.location.search.includes('phases=core')", timeout=10_000)
    assert "phi2=-135" in page.url
    page.locator(".rattle-badge[data-regime='D']").wait_for(timeout=20_000)
    page.locator(".ctl-phases button", has_text="paper").first.click()
    wait_box(page, "phi2", 45.0)
    page.locator(".ctl-bif button", has_text="φ₂").first.click()
    page.locator(".bif-status", has_text="φ₂ swept").first.wait_for(timeout=180_000)
    page.wait_for_function(f"() => ({FIG})(['bifurcation', 0, 0]).xlabel.includes('φ₂')", timeout=60_000)
    painted(page)
    f = fig(page, "bifurcation")
    assert (f["x0"], f["x1"]) == (pytest.approx(0.0, abs=1e-6), pytest.approx(360.0, abs=1e-6))
    assert "paper" in f["xlabel"] and "Figure 6" in f["xlabel"]


def _step_intensity_map_pixels_follow_its_colour_bar(page):
    """Fix 1: every cell of an intensity map is painted the colour bar's colour of its value."""
    compute_map(page, 8, 6)
    select = page.locator(".ctl-field select").first
    log_map = f"() => {{ const m = ({MAP_IMAGE})(); return m != null && m.kind === 'LogColorMapper'; }}"
    select.select_option(label="rattle intensity Σ Ĩ² per period")
    page.wait_for_function(log_map, timeout=30_000)
    settled(page)
    m = page.evaluate(MAP_IMAGE)
    ny, nx = m["shape"]
    values = np.array(m["values"], dtype=float).reshape(ny, nx)
    shot = Image.open(io.BytesIO(page.screenshot())).convert("RGB")
    lo, hi, pal = math.log(m["low"]), math.log(m["high"]), m["palette"]
    checked = 0
    for i in range(ny):
        for j in range(nx):
            v = values[i, j]
            if not (v > 0):
                continue
            p = fig(page, "map_figure", m["x"] + (j + 0.5) * m["dw"] / nx, m["y"] + (i + 0.5) * m["dh"] / ny)
            got = shot.getpixel((int(round(p["sx"])), int(round(p["sy"]))))
            k = min(len(pal) - 1, max(0, int((math.log(v) - lo) / (hi - lo) * len(pal))))
            want = tuple(int(pal[k][c:c + 2], 16) for c in (1, 3, 5))
            assert max(abs(a - b) for a, b in zip(got, want)) <= 8, (i, j, v, got, want)
            checked += 1
    assert checked >= 10


def _step_units_mode_draws_the_time_history_in_um_against_ms(page):
    """Fix 4: switching the units on puts the time history in µm against ms, SI metrics beside."""
    page.locator(".units-switch").first.click()
    page.wait_for_function(f"() => ({FIG})(['time_history', 0, 0]).ylabel.includes('µm')", timeout=20_000)
    f = fig(page, "time_history")
    assert f["xlabel"] == "t [ms]" and "rpm" in f["title"]
    assert "1/s" in page.locator(".rattle-metrics table").first.inner_text()
    # the units table is a view of its own, drawn on its own tick after the switch
    page.locator(".units-table table.units-params").first.wait_for(state="visible", timeout=20_000)


def _show_explorer(page) -> None:
    """Go back to the Explorer tab and wait until its plots are on the page again (a tab draws
    its content when it is shown)."""
    page.locator(".bk-tab", has_text="Explorer").first.click()
    page.wait_for_function(f"() => ['time_history', 'section', 'bifurcation']"
                           f".every(n => ({BY_NAME})(n) != null)", timeout=60_000)
    painted(page)


def test_drag_45_degrees_intensity_map_and_units_switch_on_one_page(page, dashboard_server):
    """Opened at Λ = 3.3, φ₂ = 0: a Λ slider drag runs once (fix 9); back at Λ = 3.3, the
    paper's 45° gives chaos and its convention is in the URL (fix 3); an intensity map's pixels
    follow its colour bar (fix 1); the units switch draws the time history in µm against ms
    (fix 4)."""
    open_dashboard(page, dashboard_server, "?lam=3.3&phi2=0")
    _step_a_slider_drag_runs_once(page)
    _type_lambda(page, 3.3)
    _step_paper_45_degrees_gives_chaos_and_the_convention_is_in_the_url(page)
    _step_intensity_map_pixels_follow_its_colour_bar(page)
    _show_explorer(page)
    _step_units_mode_draws_the_time_history_in_um_against_ms(page)


def _boxes(page, selector: str) -> list[dict]:
    loc = page.locator(selector)
    out = []
    for i in range(loc.count()):
        el = loc.nth(i)
        if el.is_visible():
            bb = el.bounding_box()
            if bb and bb["width"] > 0 and bb["height"] > 0:
                out.append(bb)
    return out


def _overlap(a: dict, b: dict) -> bool:
    return (a["x"] + 1 < b["x"] + b["width"] and b["x"] + 1 < a["x"] + a["width"]
            and a["y"] + 1 < b["y"] + b["height"] and b["y"] + 1 < a["y"] + a["height"])


def _step_sidebar_and_maps_controls_are_neither_clipped_nor_overlapping(page):
    """Fix 6: in units mode no sidebar label, box or button overlaps another or leaves the sidebar;
    the Maps tab's boxes are whole."""
    page.locator(".ctl-rpm input").first.wait_for(state="visible", timeout=20_000)
    page.evaluate("() => document.fonts.ready.then(() => true)")  # labels measured in their font
    painted(page)
    side = page.locator("#sidebar").first.bounding_box()
    inputs = _boxes(page, "#sidebar input.bk-input") + _boxes(page, "#sidebar button.bk-btn")
    labels = _boxes(page, "#sidebar div[style*='font-size:13px']")
    assert len(inputs) > 20 and len(labels) > 10
    for bb in inputs + labels:
        assert side["x"] - 1 <= bb["x"] and bb["x"] + bb["width"] <= side["x"] + side["width"] + 1, bb
    for i, a in enumerate(inputs):
        for b in inputs[i + 1:] + labels:
            assert not _overlap(a, b), (a, b)
    page.locator(".bk-tab", has_text="Maps").first.click()
    page.locator(".map-compute button").first.wait_for(timeout=20_000)
    for css in (".map-x-num", ".map-y-num", ".map-x-start", ".map-transient", ".map-record"):
        outer = page.locator(css).first.bounding_box()
        inner = page.locator(f"{css} input").first.bounding_box()
        assert inner["width"] >= 60 and inner["x"] + inner["width"] <= outer["x"] + outer["width"] + 1, css


def _step_click_on_the_rpm_drag_torque_map_lands_there_and_the_url_follows(page):
    """Fix 2: units, C = 0.05 N·m, 1500 rpm: a map click sets exactly that rpm and C, URL at once."""
    compute_map(page, 5, 4)
    rpm, torque = 4700.0, 0.075  # grid: 800…6000 rpm, C/4…4C
    p = fig(page, "map_figure", rpm, torque)
    page.mouse.click(p["sx"], p["sy"])
    page.wait_for_function("() => window.location.search.includes('rpm=4700')", timeout=20_000)
    assert "C=0.075" in page.url
    page.locator(".bk-tab", has_text="Explorer").first.click()
    wait_box(page, "rpm", rpm)
    wait_box(page, "drag_torque", torque)


def test_units_mode_sidebar_maps_tab_and_a_click_on_the_rpm_drag_torque_map(page, dashboard_server):
    """Opened in physical units at C = 0.05 N·m, 1500 rpm: the sidebar and the Maps tab's boxes
    are neither clipped nor overlapping (fix 6); a click on the rpm–drag torque map sets that
    rpm and C, and the URL follows (fix 2)."""
    open_dashboard(page, dashboard_server, "?units=1&C=0.05&rpm=1500")
    _step_sidebar_and_maps_controls_are_neither_clipped_nor_overlapping(page)
    _step_click_on_the_rpm_drag_torque_map_lands_there_and_the_url_follows(page)


def test_diagram_at_lambda_06_keeps_the_marker_on_a_full_range(page, dashboard_server):
    """Fix 5: at Λ = 0.6 the diagram spans the whole range with the marker in it, counted plainly."""
    open_dashboard(page, dashboard_server, "?lam=0.6&r=0.6")
    page.locator(".bif-status", has_text="400 values of Λ swept").first.wait_for(timeout=180_000)
    wait_bif(page)
    page.wait_for_function("() => Bokeh.documents[0].get_model_by_name('current_value') != null",
                           timeout=60_000)
    painted(page)
    f = fig(page, "bifurcation")
    assert f["x0"] == pytest.approx(0.5, abs=0.02) and f["x1"] == pytest.approx(4.0, abs=0.02)
    text = page.locator(".bif-status div").first.inner_text()
    assert "without impacts" in text and "rattle" in text
    marker = "() => Bokeh.documents[0].get_model_by_name('current_value').location"
    assert page.evaluate(marker) == pytest.approx(0.6)
    b = box(page, "lam")
    b.fill("0.7")
    b.press("Enter")
    page.wait_for_function(f"() => Math.abs(({marker})() - 0.7) < 1e-9", timeout=20_000)


def test_details_a_new_user_met(page, dashboard_server):
    """Fix 7: ?r=2 gets a message; r = −0.5 keeps the slider's range; one legend entry per flank,
    each in its colour; save tools named and titles captioned with the parameters; the sound's
    description follows the regime."""
    open_dashboard(page, dashboard_server, "?r=2&h2=0")
    page.locator(".msg-r").first.wait_for(state="visible", timeout=10_000)
    assert "r = 2" in message(page, "r") and "[0, 1]" in message(page, "r")
    b = box(page, "r")
    b.fill("-0.5")
    b.press("Enter")
    page.locator(".msg-r", has_text="-0.5").first.wait_for(timeout=10_000)
    wait_box(page, "r", 0.65)
    assert page.locator(".ctl-r .noUi-handle").first.get_attribute("aria-valuemin") in ("0", "0.0", "0.00")
    legend = page.evaluate("""() => { const f = Bokeh.documents[0].get_model_by_name('time_history');
      const l = f.center.find(x => x.type === 'Legend') || f.right.find(x => x.type === 'Legend');
      return l.items.map(i => [i.label.value, i.renderers.map(r => r.glyph.fill_color ? r.glyph.fill_color.value : null)]); }""")
    items = dict((k, v) for k, v in legend)
    assert items["impact, active flank"] != items["impact, reverse flank"]
    assert "impact (red active, blue reverse)" not in items
    wait_bif(page)
    for name in ("time_history", "bifurcation", "section"):
        names = page.evaluate(f"""() => Bokeh.documents[0].get_model_by_name('{name}').toolbar.tools
            .filter(t => t.type === 'SaveTool').map(t => t.filename)""")
        assert names and all(n and "lam3.3_r0.65_j8" in n for n in names), (name, names)
        title = fig(page, name)["title"]
        assert "r = 0.65 · j = 8" in title
        # the diagram runs over Λ, so its title leaves Λ out; the other plots name it
        assert ("Λ =" in title) == (name != "bifurcation"), (name, title)
    hear = page.locator(".sound-hear").first
    hear.filter(has_text="per second").wait_for(timeout=20_000)
    b = box(page, "lam")
    b.fill("0.8")
    b.press("Enter")
    page.locator(".rattle-badge[data-regime='A'], .rattle-badge[data-regime='B']").first.wait_for(timeout=20_000)
    page.locator(".sound-hear", has_text="ilence").first.wait_for(timeout=20_000)
    assert "per second" not in hear.inner_text() and "e+" not in page.locator(".badge-detail").first.inner_text()


def test_serve_prints_its_address_only_when_the_port_answers(browser, tmp_path):
    """Fix 8: `rattle serve` prints the address once the port answers; the page then draws."""
    port = free_port()
    env = {**os.environ, "PYTHONPATH": os.getcwd() + os.pathsep + os.environ.get("PYTHONPATH", "")}
    code = f"import sys; from rattle_cli.main import main; sys.exit(main(['serve', '--port', '{port}']))"
    proc = subprocess.Popen([sys.executable, "-u", "-c", code], stdout=subprocess.PIPE,
                            stderr=subprocess.DEVNULL, text=True, env=env)
    try:
        deadline = time.monotonic() + 240
        line = ""
        while "serving" not in line:
            assert time.monotonic() < deadline and proc.poll() is None, "serve never printed its address"
            line = proc.stdout.readline()
        with socket.create_connection(("127.0.0.1", port), timeout=1.0):
            pass
        assert f"http://localhost:{port}/" in line
        with urllib.request.urlopen(f"http://localhost:{port}/liveness", timeout=5) as resp:
            assert resp.status == 200
        page = browser.new_page()
        t0 = time.monotonic()
        page.goto(f"http://localhost:{port}/")
        page.wait_for_function(READY, timeout=60_000)
        print(f"first plot {time.monotonic() - t0:.1f} s after the page was asked for")
        page.close()
    finally:
        proc.terminate()
        proc.wait(timeout=30)
