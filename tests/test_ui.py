"""Browser tests: headless Chromium drives the real dashboard served by ``app.main.serve``.

The page's state is read back from the browser itself: the values shown in the controls'
entry boxes, the alerts beside them, and the data the plots hold (``Bokeh.documents``), so a
test passes only if the change travelled server → websocket → page.
"""
from __future__ import annotations

import math
import re
from urllib.parse import urlparse

import pytest
from conftest import patient_context

pytestmark = [pytest.mark.ui, pytest.mark.timeout(300)]

READY = """() => {
  const d = window.Bokeh && Bokeh.documents && Bokeh.documents[0];
  if (!d) return false;
  const m = d.get_model_by_name('th_motion');
  return m != null && m.get_length() > 0;
}"""

#: The deferred plots (section, diagram) are in the page: it has finished loading.
LOADED = """() => ['section', 'bifurcation'].every(n => Bokeh.documents[0].get_model_by_name(n) != null)"""

CHECKSUM = """() => {
  const x = Bokeh.documents[0].get_model_by_name('th_motion').get_column('x');
  let s = 0;
  for (let i = 0; i < x.length; i++) s += x[i] * ((i % 7) + 1);
  return s;
}"""

BIF_POINT = """(frac) => {
  const m = Bokeh.documents[0].get_model_by_name('bifurcation');
  const v = Bokeh.index.find_one(m);
  v.el.scrollIntoView({block: 'center', inline: 'center'});  // below the fold on a tall page
  const r = v.el.getBoundingClientRect();
  const b = v.frame.bbox;
  const sx = b.left + frac * b.width;
  return {x: r.left + sx, y: r.top + b.top + 0.5 * b.height, value: v.frame.x_scale.invert(sx)};
}"""


def wait_bif(page, timeout: float = 120_000) -> None:
    """Wait until the bifurcation diagram is drawn (its status counts the values swept), and
    bring it into view, where a click or the wheel reaches it."""
    page.locator(".bif-status").filter(has_text="swept").first.wait_for(timeout=timeout)
    page.wait_for_function("() => Bokeh.documents[0].get_model_by_name('bifurcation') != null",
                           timeout=timeout)
    page.locator(".diagram").first.scroll_into_view_if_needed()


def painted(page) -> None:
    """Wait until the browser has painted what it last received (two animation frames)."""
    page.evaluate("() => new Promise(r => requestAnimationFrame(() => requestAnimationFrame(r)))")


def open_dashboard(page, server, query: str = "") -> list[str]:
    """Load the dashboard and wait for its first time history; return the console errors."""
    errors: list[str] = []
    page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.goto(f"{server['url']}/{query}", timeout=120_000)  # a loaded machine serves slowly
    page.wait_for_function(READY, timeout=60_000)
    # the deferred plots load after the first one; a value typed before they are in is lost
    page.wait_for_function(LOADED, timeout=60_000)
    return errors


def box(page, name: str):
    """The exact-value entry box of control ``name``."""
    return page.locator(f".ctl-{name} input.bk-input").first


def message(page, name: str) -> str:
    """Text of the alert beside control ``name`` (empty when hidden)."""
    alert = page.locator(f".msg-{name}").first
    if not alert.is_visible():
        return ""
    return " ".join(alert.locator("p").all_inner_texts())


def box_value(page, name: str) -> float:
    return float(box(page, name).input_value())


#: A JavaScript function ``deep(root, selector)``: the first match, searched into shadow roots
#: too (Panel draws its widgets in shadow roots).
DEEP = """  const deep = (root, sel) => {
    const hit = root.querySelector(sel);
    if (hit) return hit;
    for (const el of root.querySelectorAll('*')) {
      if (el.shadowRoot) { const f = deep(el.shadowRoot, sel); if (f) return f; }
    }
    return null;
  };
"""

#: The number in the first input box inside ``css`` (null when empty), and whether it shows
#: ``want`` within ``tol``. Panel draws its widgets in shadow roots, so the search walks into them.
BOX_VALUE = """(css) => {
""" + DEEP + """  const field = deep(document, css);
  const box = field && (deep(field.shadowRoot || field, 'input.bk-input') || deep(field, 'input.bk-input'));
  return box == null || box.value === '' ? null : Number(box.value);
}"""
BOX_SHOWS = ("([css, want, tol]) => { const v = (" + BOX_VALUE + ")(css); "
             "return v !== null && Math.abs(v - want) <= tol; }")


def wait_box(page, name: str, expected: float, tol: float = 1e-9, timeout: float = 20_000) -> None:
    """Wait until the entry box of ``name`` shows ``expected`` (within ``tol``)."""
    try:
        page.wait_for_function(BOX_SHOWS, arg=[f".ctl-{name}", expected, tol], timeout=timeout)
    except Exception:
        raise AssertionError(f"{name} box shows {box(page, name).input_value()!r}, "
                             f"expected {expected}") from None


def wait_box_leaves(page, css: str, old: float, timeout: float = 60_000) -> None:
    """Wait until the input box inside ``css`` shows a number other than ``old`` (the server
    has pushed its new value)."""
    page.wait_for_function("([css, old]) => { const v = (" + BOX_VALUE + ")(css); "
                           "return v !== null && v !== old; }", arg=[css, old], timeout=timeout)


def set_input(page, css: str, value: str) -> None:
    """Type ``value`` into the input inside ``css`` and send it (Enter)."""
    b = page.locator(f"{css} input").first
    b.fill(value)
    b.press("Enter")


def test_page_loads_without_console_errors(page, dashboard_server):
    """The dashboard loads, draws its views and badge, with no browser console error."""
    errors = open_dashboard(page, dashboard_server)
    badge = page.locator(".rattle-badge")
    badge.wait_for(timeout=30_000)
    assert re.match(r"^[A-EPQ]$", badge.get_attribute("data-regime"))
    assert box_value(page, "lam") == pytest.approx(3.3)
    assert box_value(page, "r") == pytest.approx(0.65)
    assert box_value(page, "j") == pytest.approx(8.0)
    wait_bif(page)  # every view drawn: the deferred plots load last
    page.wait_for_function("() => Bokeh.documents[0].get_model_by_name('section') != null",
                           timeout=60_000)
    painted(page)
    assert errors == []


def test_lambda_slider_changes_time_history(page, dashboard_server):
    """Focusing the Λ slider handle and pressing ArrowRight moves Λ and redraws x(t)."""
    open_dashboard(page, dashboard_server)
    before = page.evaluate(CHECKSUM)
    handle = page.locator(".ctl-lam .noUi-handle").first
    handle.focus()
    for _ in range(5):
        page.keyboard.press("ArrowRight")
    wait_box(page, "lam", 3.35, tol=1e-6)
    page.wait_for_function(f"() => Math.abs(({CHECKSUM})() - {before!r}) > 1e-6", timeout=20_000)
    assert "lam=3.35" in page.url


TH_RANGE = """() => { const m = Bokeh.documents[0].get_model_by_name('time_history');
  return [m.x_range.start, m.x_range.end, m.y_range.start, m.y_range.end]; }"""


def test_time_history_zoom_survives_a_parameter_change(page, dashboard_server):
    """After the user zooms the time history, a Λ change redraws x(t) inside the same zoom."""
    open_dashboard(page, dashboard_server)
    painted(page)
    m = page.evaluate("""() => { const v = Bokeh.index.find_one(
        Bokeh.documents[0].get_model_by_name('time_history'));
      v.el.scrollIntoView({block: 'center', inline: 'center'});  // below the fold on a tall page
      const r = v.el.getBoundingClientRect(), b = v.frame.bbox;
      return {x: r.left + b.left + 0.5 * b.width, y: r.top + b.top + 0.5 * b.height}; }""")
    full = page.evaluate(TH_RANGE)
    page.mouse.move(m["x"], m["y"])
    for _ in range(4):
        page.mouse.wheel(0, -300)
    page.wait_for_function(f"() => {{ const r = ({TH_RANGE})(); return r[1] - r[0] < {0.8 * (full[1] - full[0])}; }}",
                           timeout=20_000)
    painted(page)
    zoomed = page.evaluate(TH_RANGE)
    before = page.evaluate(CHECKSUM)
    b = box(page, "lam")
    b.fill("3.1")
    b.press("Enter")
    page.wait_for_function(f"() => Math.abs(({CHECKSUM})() - {before!r}) > 1e-6", timeout=20_000)
    painted(page)  # a data range would re-fit itself on this paint
    assert page.evaluate(TH_RANGE) == pytest.approx(zoomed)


def test_preset_loads_its_parameters(page, dashboard_server):
    """One click on the Fig 8 preset sets Λ = 3.3, H₂/H₁ = 0.25 and the paper's φ₂ = 90°."""
    open_dashboard(page, dashboard_server, "?lam=1.5&h2=0.1&phi2=10")
    wait_box(page, "lam", 1.5)
    before = page.evaluate(CHECKSUM)
    page.locator(".preset-Fig8 button").first.click()
    wait_box(page, "lam", 3.3)
    wait_box(page, "h2", 0.25)
    wait_box(page, "phi2", 90.0)
    page.wait_for_function(f"() => Math.abs(({CHECKSUM})() - {before!r}) > 1e-6", timeout=20_000)
    page.locator(".rattle-badge[data-regime='E']").wait_for(timeout=20_000)
    page.wait_for_function("() => window.location.search.includes('phi2=90')", timeout=10_000)
    assert "phases=core" not in page.url


def test_click_on_bifurcation_diagram_sets_lambda(page, dashboard_server):
    """Clicking the bifurcation diagram at some Λ moves the Λ control (and the views) there."""
    open_dashboard(page, dashboard_server)
    wait_bif(page)
    target = page.evaluate(BIF_POINT, 0.3)
    assert abs(target["value"] - 3.3) > 0.2
    before = page.evaluate(CHECKSUM)
    page.mouse.click(target["x"], target["y"])
    wait_box(page, "lam", round(target["value"], 4), tol=0.02)
    page.wait_for_function(f"() => Math.abs(({CHECKSUM})() - {before!r}) > 1e-6", timeout=20_000)


def test_zooming_the_bifurcation_diagram_refines_the_visible_region(page, dashboard_server):
    """Wheel-zooming into the Ĩ–Λ diagram triggers a finer background sweep of the visible Λ range."""
    open_dashboard(page, dashboard_server)
    wait_bif(page)
    status = page.locator(".bif-status div").first
    assert "refined" not in status.inner_text()
    target = page.evaluate(BIF_POINT, 0.5)
    page.mouse.move(target["x"], target["y"])
    for _ in range(6):
        page.mouse.wheel(0, -300)
    page.locator(".bif-status div", has_text="refined").first.wait_for(timeout=120_000)


def test_url_parameters_restore_the_view(page, dashboard_server):
    """A link with parameters opens with exactly those values in the controls."""
    open_dashboard(page, dashboard_server, "?lam=2.2&r=0.5&j=6&h2=0.1&phi2=30&strobe=45")
    wait_box(page, "lam", 2.2)
    wait_box(page, "r", 0.5)
    wait_box(page, "j", 6.0)
    wait_box(page, "h2", 0.1)
    wait_box(page, "phi2", 30.0)
    wait_box(page, "strobe", 45.0)
    assert page.locator(".msg-global").first.is_hidden()


def test_garbage_url_parameters_show_messages_and_keep_defaults(page, dashboard_server):
    """Garbage URL values leave a message beside their control and the default view; no traceback."""
    errors = open_dashboard(page, dashboard_server, "?lam=abc&j=-3&r=0.4&harmonics=zz&x0=1e5")
    wait_box(page, "r", 0.4)
    assert box_value(page, "lam") == pytest.approx(3.3)
    assert box_value(page, "j") == pytest.approx(8.0)
    page.locator(".msg-lam").first.wait_for(state="visible", timeout=10_000)
    assert "Λ must be a number" in message(page, "lam")
    assert "outside the allowed range" in message(page, "j")
    assert "harmonic 'zz'" in message(page, "harmonics")
    assert "x0" in message(page, "x0")
    page.wait_for_function("() => !window.location.search.includes('abc')", timeout=10_000)
    assert "lam=3.3" in page.url and "r=0.4" in page.url
    assert errors == []
    assert dashboard_server["log"].tracebacks() == []


def test_out_of_range_typed_value_is_rejected_beside_the_control(page, dashboard_server):
    """Typing Λ = −5 shows a message beside Λ, keeps Λ = 3.3 and leaves the time history as it was."""
    open_dashboard(page, dashboard_server)
    before = page.evaluate(CHECKSUM)
    b = box(page, "lam")
    b.fill("-5")
    b.press("Enter")
    page.locator(".msg-lam").first.wait_for(state="visible", timeout=10_000)
    assert "outside the allowed range" in message(page, "lam")
    wait_box(page, "lam", 3.3)
    assert page.evaluate(CHECKSUM) == pytest.approx(before)
    assert dashboard_server["log"].tracebacks() == []


def test_impacts_download_as_csv(page, dashboard_server):
    """The export button downloads the current impacts as CSV, one row per impact."""
    open_dashboard(page, dashboard_server, "?lam=3.3&h2=0&periods=50")
    wait_box(page, "h2", 0.0)
    with page.expect_download(timeout=30_000) as info:
        page.locator(".download-csv button, .download-csv a").first.click()
    text = open(info.value.path(), encoding="utf-8").read().splitlines()
    assert text[0] == "t,phase,impulse,flank,w"
    assert len(text) - 1 == 100  # regime E: one impact per flank per period, 50 periods
    assert info.value.suggested_filename.startswith("rattle_impacts_lam3.3_r0.65_j8_h2-0_")


def test_no_request_leaves_localhost(page, dashboard_server):
    """Loading and using the dashboard requests nothing from any host but the local server."""
    urls: list[str] = []
    page.on("request", lambda r: urls.append(r.url))
    open_dashboard(page, dashboard_server)
    page.locator(".preset-Fig7 button").first.click()
    wait_box(page, "lam", 3.3)
    page.locator(".rattle-badge[data-regime='D']").wait_for(timeout=30_000)  # Fig 7 drawn
    wait_bif(page)
    painted(page)
    hosts = {urlparse(u).hostname for u in urls if not u.startswith(("data:", "blob:"))}
    assert len(urls) > 5
    assert hosts <= {"localhost", "127.0.0.1"}, hosts


def test_three_sessions_keep_their_own_state(browser, dashboard_server):
    """Three concurrent sessions changed differently each keep their own parameters and plots."""
    contexts = [patient_context(browser) for _ in range(3)]
    try:
        pages = [c.new_page() for c in contexts]
        for p in pages:
            open_dashboard(p, dashboard_server)
        first = [p.evaluate(CHECKSUM) for p in pages]
        pages[0].locator(".preset-Fig8 button").first.click()
        b = box(pages[1], "lam")
        b.fill("2")
        b.press("Enter")
        wait_box(pages[0], "phi2", 90.0)
        wait_box(pages[1], "lam", 2.0)
        for p, old in zip(pages[:2], first):  # both changed sessions redrew
            p.wait_for_function(f"() => Math.abs(({CHECKSUM})() - {old!r}) > 1e-6", timeout=20_000)
        sums = [p.evaluate(CHECKSUM) for p in pages]
        assert box_value(pages[0], "lam") == pytest.approx(3.3)
        assert box_value(pages[1], "phi2") == pytest.approx(45.0)
        assert box_value(pages[2], "lam") == pytest.approx(3.3)
        assert box_value(pages[2], "phi2") == pytest.approx(45.0)
        assert len({round(s, 6) for s in sums}) == 3
        assert all(math.isfinite(s) for s in sums)
    finally:
        for c in contexts:
            c.close()
