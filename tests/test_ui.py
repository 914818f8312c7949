"""Browser tests: headless Chromium drives the real dashboard served by ``app.main.serve``.

The page's state is read back from the browser itself: the values shown in the controls'
entry boxes, the alerts beside them, and the data the plots hold (``Bokeh.documents``), so a
test passes only if the change travelled server → websocket → page.

What the file shows: the explorer loads with no console error, exports its impacts as CSV,
refuses an out-of-range Λ, follows a click on the bifurcation diagram and the Λ slider, keeps
the time history's zoom through a change, refines a zoomed diagram, and requests nothing from
any other host; a link restores its values and a preset replaces them; garbage in a link is
named beside its control; three sessions keep their own state. Checks that need no page of
their own share one, step after step (one page for these checks: a page load is the costly
part of a browser test), in an order that leaves each step the state it reads; a value an
earlier step changed is typed back, and waited for, where a later one needs it.

This module also holds the helpers the other browser-test files use (``open_dashboard``,
``READY``, ``box``, ``wait_box``, ...).
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


#: The time history's x and y ranges.
TH_RANGE = """() => { const m = Bokeh.documents[0].get_model_by_name('time_history');
  return [m.x_range.start, m.x_range.end, m.y_range.start, m.y_range.end]; }"""

#: The link of the page the explorer's checks share: Λ, r and j at their defaults, H₂/H₁ = 0
#: (regime E, one impact on each flank per period) and 50 periods recorded.
EXPLORER = "?lam=3.3&h2=0&periods=50"

#: A link naming six values, Λ, H₂/H₁ and φ₂ all unlike those of the Fig 8 preset.
LINK = "?lam=2.2&r=0.5&j=6&h2=0.1&phi2=30&strobe=45"


def redrawn(page, before: float, timeout: float = 60_000) -> None:
    """Wait until x(t) differs from the one whose checksum was ``before``."""
    page.wait_for_function(f"() => Math.abs(({CHECKSUM})() - {before!r}) > 1e-6", timeout=timeout)


#: Whether the Λ slider stands at ``want``: the server moves it once the box's value has come
#: back (before it redraws the views).
LAM_SLIDER_AT = """(want) => {
  const slider = [...Bokeh.documents[0].all_models].find(
    m => Array.isArray(m.css_classes) && m.css_classes.includes('slider-lam'));
  return slider != null && Math.abs(slider.value - want) < 1e-9;
}"""


def type_lam(page, value: float) -> None:
    """Type Λ = ``value`` into its box and wait until the page shows it, in the box and on the
    slider, and has redrawn x(t)."""
    before = page.evaluate(CHECKSUM)
    b = box(page, "lam")
    b.fill(f"{value:g}")
    b.press("Enter")
    wait_box(page, "lam", value, timeout=60_000)
    redrawn(page, before)
    page.wait_for_function(LAM_SLIDER_AT, arg=value, timeout=60_000)


def _step_page_loads_without_console_errors(page, errors: list[str]) -> None:
    """The dashboard loads, draws its views and badge, with no browser console error."""
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


def _step_impacts_download_as_csv(page) -> None:
    """The export button downloads the current impacts as CSV, one row per impact."""
    wait_box(page, "h2", 0.0)
    with page.expect_download(timeout=60_000) as info:
        page.locator(".download-csv button, .download-csv a").first.click()
    text = open(info.value.path(), encoding="utf-8").read().splitlines()
    assert text[0] == "t,phase,impulse,flank,w"
    assert len(text) - 1 == 100  # regime E: one impact per flank per period, 50 periods
    assert info.value.suggested_filename.startswith("rattle_impacts_lam3.3_r0.65_j8_h2-0_")


def _step_out_of_range_typed_value_is_rejected_beside_the_control(page, server) -> None:
    """Typing Λ = −5 shows a message beside Λ, keeps Λ = 3.3 and leaves the time history as it was."""
    before = page.evaluate(CHECKSUM)
    b = box(page, "lam")
    b.fill("-5")
    b.press("Enter")
    page.locator(".msg-lam").first.wait_for(state="visible", timeout=10_000)
    assert "outside the allowed range" in message(page, "lam")
    wait_box(page, "lam", 3.3)
    assert page.evaluate(CHECKSUM) == pytest.approx(before)
    assert server["log"].tracebacks() == []


def _step_click_on_bifurcation_diagram_sets_lambda(page) -> None:
    """Clicking the bifurcation diagram at some Λ moves the Λ control (and the views) there."""
    wait_bif(page)
    target = page.evaluate(BIF_POINT, 0.3)
    assert abs(target["value"] - 3.3) > 0.2
    before = page.evaluate(CHECKSUM)
    page.mouse.click(target["x"], target["y"])
    wait_box(page, "lam", round(target["value"], 4), tol=0.02, timeout=60_000)
    redrawn(page, before)


def _step_time_history_zoom_survives_a_parameter_change(page) -> None:
    """After the user zooms the time history, a Λ change redraws x(t) inside the same zoom."""
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
    redrawn(page, before)
    painted(page)  # a data range would re-fit itself on this paint
    assert page.evaluate(TH_RANGE) == pytest.approx(zoomed)


def _step_lambda_slider_changes_time_history(page) -> None:
    """Focusing the Λ slider handle and pressing ArrowRight moves Λ and redraws x(t)."""
    before = page.evaluate(CHECKSUM)
    handle = page.locator(".ctl-lam .noUi-handle").first
    handle.focus()
    for _ in range(5):
        page.keyboard.press("ArrowRight")
    wait_box(page, "lam", 3.35, tol=1e-6, timeout=60_000)
    redrawn(page, before)
    assert "lam=3.35" in page.url


def _step_zooming_the_bifurcation_diagram_refines_the_visible_region(page) -> None:
    """Wheel-zooming into the Ĩ–Λ diagram triggers a finer background sweep of the visible Λ range."""
    wait_bif(page)
    status = page.locator(".bif-status div").first
    assert "refined" not in status.inner_text()
    target = page.evaluate(BIF_POINT, 0.5)
    page.mouse.move(target["x"], target["y"])
    for _ in range(6):
        page.mouse.wheel(0, -300)
    page.locator(".bif-status div", has_text="refined").first.wait_for(timeout=120_000)


def _step_no_request_leaves_localhost(page, urls: list[str]) -> None:
    """Loading and using the dashboard requests nothing from any host but the local server."""
    page.locator(".preset-Fig7 button").first.click()
    wait_box(page, "lam", 3.3, timeout=60_000)
    page.locator(".rattle-badge[data-regime='D']").wait_for(timeout=120_000)  # Fig 7 drawn
    wait_bif(page)
    painted(page)
    hosts = {urlparse(u).hostname for u in urls if not u.startswith(("data:", "blob:"))}
    assert len(urls) > 5
    assert hosts <= {"localhost", "127.0.0.1"}, hosts


@pytest.mark.timeout(900)
def test_explorer_draws_exports_and_follows_its_controls(page, dashboard_server):
    """On one page, in turn: the dashboard loads with every view and no console error; it exports
    its impacts as CSV; it refuses an out-of-range Λ beside the control; a click on the
    bifurcation diagram sets Λ; the time history keeps its zoom through a Λ change; the Λ slider
    moves Λ (from 3.3, typed back); zooming the diagram refines it; and nothing the page requests,
    from its load to a preset's redraw, leaves the local server."""
    urls: list[str] = []
    page.on("request", lambda r: urls.append(r.url))
    errors = open_dashboard(page, dashboard_server, EXPLORER)
    _step_page_loads_without_console_errors(page, errors)
    _step_impacts_download_as_csv(page)
    _step_out_of_range_typed_value_is_rejected_beside_the_control(page, dashboard_server)
    _step_click_on_bifurcation_diagram_sets_lambda(page)
    _step_time_history_zoom_survives_a_parameter_change(page)
    type_lam(page, 3.3)
    _step_lambda_slider_changes_time_history(page)
    _step_zooming_the_bifurcation_diagram_refines_the_visible_region(page)
    _step_no_request_leaves_localhost(page, urls)


def _step_url_parameters_restore_the_view(page) -> None:
    """A link with parameters opens with exactly those values in the controls."""
    wait_box(page, "lam", 2.2)
    wait_box(page, "r", 0.5)
    wait_box(page, "j", 6.0)
    wait_box(page, "h2", 0.1)
    wait_box(page, "phi2", 30.0)
    wait_box(page, "strobe", 45.0)
    assert page.locator(".msg-global").first.is_hidden()


def _step_preset_loads_its_parameters(page) -> None:
    """One click on the Fig 8 preset sets Λ = 3.3, H₂/H₁ = 0.25 and the paper's φ₂ = 90°."""
    before = page.evaluate(CHECKSUM)
    page.locator(".preset-Fig8 button").first.click()
    wait_box(page, "lam", 3.3, timeout=60_000)
    wait_box(page, "h2", 0.25, timeout=60_000)
    wait_box(page, "phi2", 90.0, timeout=60_000)
    redrawn(page, before)
    page.locator(".rattle-badge[data-regime='E']").wait_for(timeout=60_000)
    page.wait_for_function("() => window.location.search.includes('phi2=90')", timeout=10_000)
    assert "phases=core" not in page.url


def test_link_restores_its_values_and_a_preset_replaces_them(page, dashboard_server):
    """A link's values are in the controls when its page opens; one click on the Fig 8 preset
    then sets the figure's Λ, H₂/H₁ and φ₂ in place of the link's."""
    open_dashboard(page, dashboard_server, LINK)
    _step_url_parameters_restore_the_view(page)
    _step_preset_loads_its_parameters(page)


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
        wait_box(pages[0], "phi2", 90.0, timeout=60_000)
        wait_box(pages[1], "lam", 2.0, timeout=60_000)
        for p, old in zip(pages[:2], first):  # both changed sessions redrew
            redrawn(p, old)
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
