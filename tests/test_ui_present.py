"""Browser tests: presentation mode on a projector of any size, the regime legend and hover help.

Sizes and fonts are read from the page itself: the figures' boxes from their Bokeh views, the
fonts from the computed styles and the figures' models, whether the page scrolls from the
document and from the template's main area (which scrolls on its own).

Checks that can share a page share one (a page load is the costly part of a browser test):
presentation mode opened at 1280×720 is checked as first drawn, then while the window is
resized, then on leaving it; the normal page shows the legend and the hover help, then its
"Present" button is clicked. Presentation mode opened at 1920×1080 has a page of its own,
since it is about the page as first drawn at that size.
"""
from __future__ import annotations

import pytest
from playwright.sync_api import TimeoutError as PlaywrightTimeout
from playwright.sync_api import expect

from rattle_core.analysis.vocabulary import CLASS_LETTERS

from test_ui import DEEP, open_dashboard, painted

#: A short run: these tests are about the page's layout, which the run's length does not
#: change, and a short run builds the page faster.
SHORT = "&periods=20&transient=20"

pytestmark = [pytest.mark.ui, pytest.mark.timeout(300)]

PROJECTOR = {"width": 1280, "height": 720}
FULL_HD = {"width": 1920, "height": 1080}
#: On a large screen each plot is at least this part of the height below the header, and the
#: two together at least this part of the width.
FILL_HEIGHT, FILL_WIDTH = 0.7, 0.85

#: What the page looks like: scroll sizes, the two figures' boxes, the fonts, the sidebar.
LOOK = """() => {
""" + DEEP + """  const d = Bokeh.documents[0];
  const box = (name) => {
    const r = Bokeh.index.find_one(d.get_model_by_name(name)).el.getBoundingClientRect();
    return {left: r.left, top: r.top, right: r.right, bottom: r.bottom, width: r.width, height: r.height};
  };
  const main = document.getElementById('main'), sidebar = document.getElementById('sidebar');
  const th = d.get_model_by_name('time_history');
  return {
    height: document.scrollingElement.scrollHeight, width: document.scrollingElement.scrollWidth,
    mainScroll: main.scrollHeight, mainClient: main.clientHeight,
    th: box('time_history'), section: box('section'),
    badgeFont: parseFloat(getComputedStyle(deep(document, '.rattle-badge')).fontSize),
    tickFont: parseFloat(th.below[0].major_label_text_font_size),
    sidebar: sidebar.getBoundingClientRect().width,
    vw: window.innerWidth, vh: window.innerHeight,
    header: document.getElementById('header').getBoundingClientRect().bottom,
  };
}"""

#: Both plots fill the window (the thresholds are the argument), and nothing scrolls.
FILLS = """([fh, fw]) => {
  const l = (""" + LOOK + """)(), below = l.vh - l.header;
  return l.th.height >= fh * below && l.section.height >= fh * below
         && l.th.width + l.section.width >= fw * l.vw
         && l.height <= l.vh && l.mainScroll <= l.mainClient;
}"""

TICKS_ARE = ("(px) => parseFloat(Bokeh.documents[0].get_model_by_name('time_history')"
             ".below[0].major_label_text_font_size) === px")


def _step_fits_1280x720(page) -> dict:
    """present=true at 1280×720: no scrolling, the time history and the section side by side,
    large, larger fonts, no sidebar; returns the page's look."""
    page.wait_for_function(TICKS_ARE, arg=17, timeout=30_000)
    page.wait_for_function("() => document.getElementById('sidebar').getBoundingClientRect().width === 0",
                           timeout=30_000)
    painted(page)
    on = page.evaluate(LOOK)
    assert on["height"] <= PROJECTOR["height"] and on["width"] <= PROJECTOR["width"]
    assert on["mainScroll"] <= on["mainClient"], on  # the main area does not scroll either
    for name in ("th", "section"):  # whole, inside the projector's picture
        b = on[name]
        assert b["width"] > 300 and b["height"] > 300, (name, b)
        assert 0 <= b["left"] and b["right"] <= PROJECTOR["width"], (name, b)
        assert 0 <= b["top"] and b["bottom"] <= PROJECTOR["height"] + 1, (name, b)
    assert on["th"]["right"] <= on["section"]["left"] + 1  # side by side
    expect(page.locator(".rattle-badge")).to_be_visible()
    expect(page.locator(".regime-legend")).to_be_visible()
    return on


def filled(page) -> dict:
    """The page's look once both plots fill the window (the browser lays them out after a
    resize without the server), asserted: what fails is named with its numbers."""
    try:
        page.wait_for_function(FILLS, arg=[FILL_HEIGHT, FILL_WIDTH], timeout=30_000)
    except PlaywrightTimeout:
        pass  # the assertions below say which size falls short
    painted(page)
    look = page.evaluate(LOOK)
    below = look["vh"] - look["header"]
    assert look["height"] <= look["vh"] and look["width"] <= look["vw"], look
    assert look["mainScroll"] <= look["mainClient"], look
    for name in ("th", "section"):
        b = look[name]
        assert b["height"] >= FILL_HEIGHT * below, (name, b["height"], below)
        assert look["header"] <= b["top"] and b["bottom"] <= look["vh"] + 1, (name, b)
        assert 0 <= b["left"] and b["right"] <= look["vw"], (name, b)
    assert look["th"]["width"] + look["section"]["width"] >= FILL_WIDTH * look["vw"], look
    assert look["th"]["right"] <= look["section"]["left"] + 1  # side by side
    return look


def _step_resizing_refits_the_plots(page) -> None:
    """Presenting at 1280×720, then 1920×1080, then 1600×900: the plots grow with the window
    and fill each large one, and nothing scrolls at any size."""
    page.wait_for_function(TICKS_ARE, arg=17, timeout=30_000)
    painted(page)
    small = page.evaluate(LOOK)
    assert small["height"] <= PROJECTOR["height"] and small["mainScroll"] <= small["mainClient"], small

    page.set_viewport_size(FULL_HD)
    large = filled(page)
    for name in ("th", "section"):
        assert large[name]["height"] > 1.3 * small[name]["height"], name
        assert large[name]["width"] > 1.3 * small[name]["width"], name

    page.set_viewport_size({"width": 1600, "height": 900})
    middle = filled(page)
    for name in ("th", "section"):
        assert small[name]["height"] < middle[name]["height"] < large[name]["height"], name


#: Whether the two figures' boxes are those of the argument's look, to the pixel.
SAME_BOXES = """(want) => { const l = (""" + LOOK + """)();
  return ['th', 'section'].every((n) => ['left', 'top', 'width', 'height']
      .every((k) => Math.abs(l[n][k] - want[n][k]) <= 1)); }"""


def _step_back_to_1280x720(page, on: dict) -> None:
    """Back at 1280×720, the figures take the boxes they had when the page was first drawn."""
    page.set_viewport_size(PROJECTOR)
    try:
        page.wait_for_function(SAME_BOXES, arg={"th": on["th"], "section": on["section"]},
                               timeout=30_000)
    except PlaywrightTimeout:
        pass  # the assertions below say which box differs
    painted(page)
    back = page.evaluate(LOOK)
    for name in ("th", "section"):
        for k in ("left", "top", "width", "height"):
            assert back[name][k] == pytest.approx(on[name][k], abs=1), (name, back[name], on[name])


def _step_exit_restores_the_page(page, on: dict) -> None:
    """"Exit presentation" restores the normal page and the URL says present=false; the plots
    and fonts of presentation mode (``on``) were taller and larger than the normal ones."""
    page.get_by_role("button", name="Exit presentation").click()
    page.wait_for_function("() => !window.location.search.includes('present=true')", timeout=30_000)
    page.wait_for_function(TICKS_ARE, arg=11, timeout=30_000)
    page.wait_for_function("() => document.getElementById('sidebar').getBoundingClientRect().width > 300",
                           timeout=30_000)
    expect(page.get_by_role("button", name="Present", exact=True)).to_be_visible()
    painted(page)
    off = page.evaluate(LOOK)
    assert "present=false" in page.url
    assert off["mainScroll"] > off["mainClient"]  # the whole normal page is back: it scrolls
    for name in ("th", "section"):
        assert on[name]["height"] > off[name]["height"], name
        assert (on[name]["width"] * on[name]["height"] > off[name]["width"] * off[name]["height"]), name
    assert on["tickFont"] >= 1.4 * off["tickFont"]
    assert on["badgeFont"] >= 1.4 * off["badgeFont"]


def test_presentation_mode_fits_1280x720_refits_on_resize_and_exit_restores_the_page(page, dashboard_server):
    """present=true opened at 1280×720 fits it (no scrolling, the plots side by side, large
    fonts, no sidebar); the plots refit as the window grows to 1920×1080 and 1600×900 and,
    back at 1280×720, return to their first boxes; "Exit presentation" restores the normal
    page, with smaller plots and fonts, and the URL says present=false."""
    page.set_viewport_size(PROJECTOR)
    open_dashboard(page, dashboard_server, "?present=true" + SHORT)
    on = _step_fits_1280x720(page)
    _step_resizing_refits_the_plots(page)
    _step_back_to_1280x720(page, on)
    _step_exit_restores_the_page(page, on)


def test_presentation_mode_fills_a_1920x1080_screen(page, dashboard_server):
    """present=true at 1920×1080: nothing scrolls, each plot is at least 70 % of the height below
    the header and the two together at least 85 % of the width, fonts as on a 1280×720 one."""
    page.set_viewport_size(FULL_HD)
    open_dashboard(page, dashboard_server, "?present=true" + SHORT)
    page.wait_for_function(TICKS_ARE, arg=17, timeout=30_000)
    page.wait_for_function("() => document.getElementById('sidebar').getBoundingClientRect().width === 0",
                           timeout=30_000)
    look = filled(page)
    assert look["sidebar"] == 0 and look["badgeFont"] >= 21


def _step_legend_and_lambda_help(page) -> None:
    """The regime legend names every letter of the vocabulary; hovering Λ's "?" shows the
    words of docs/model.md."""
    legend = page.locator(".regime-legend")
    expect(legend).to_be_visible()
    letters = [e.get_attribute("data-regime") for e in legend.locator(".legend-regime").all()]
    assert letters == list(CLASS_LETTERS)
    tip = page.get_by_text("inertia over drag")
    expect(tip).to_have_count(0)
    page.locator(".help-lam").first.hover()
    expect(tip).to_be_visible(timeout=10_000)


def _step_present_button_turns_the_mode_on(page) -> None:
    """At 1280×720, a click on "Present" in the header puts present=true in the URL and hides
    the sidebar."""
    page.set_viewport_size(PROJECTOR)
    page.get_by_role("button", name="Present", exact=True).click()
    page.wait_for_function("() => window.location.search.includes('present=true')", timeout=30_000)
    page.wait_for_function("() => document.getElementById('sidebar').getBoundingClientRect().width === 0",
                           timeout=30_000)
    page.wait_for_function(TICKS_ARE, arg=17, timeout=30_000)


def test_the_normal_page_shows_the_legend_and_help_and_its_present_button_turns_the_mode_on(
        page, dashboard_server):
    """On the normal page, the regime legend names every letter and hovering Λ's "?" shows its
    help; then a click on "Present" puts present=true in the URL and hides the sidebar."""
    open_dashboard(page, dashboard_server, "?" + SHORT[1:])
    _step_legend_and_lambda_help(page)
    _step_present_button_turns_the_mode_on(page)
