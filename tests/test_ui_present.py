"""Browser tests: presentation mode on a 1280×720 projector, the regime legend and hover help.

Sizes and fonts are read from the page itself: the figures' boxes from their Bokeh views, the
fonts from the computed styles and the figures' models, whether the page scrolls from the
document and from the template's main area (which scrolls on its own).
"""
from __future__ import annotations

import pytest
from playwright.sync_api import expect

from rattle_core.analysis.vocabulary import CLASS_LETTERS

from test_ui import DEEP, open_dashboard, painted

pytestmark = [pytest.mark.ui, pytest.mark.timeout(300)]

PROJECTOR = {"width": 1280, "height": 720}

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
  };
}"""

TICKS_ARE = ("(px) => parseFloat(Bokeh.documents[0].get_model_by_name('time_history')"
             ".below[0].major_label_text_font_size) === px")


def test_presentation_mode_fits_1280x720_and_exit_restores_the_page(page, dashboard_server):
    """present=true at 1280×720: no scrolling, the time history and the section side by side,
    taller and larger than normally, larger fonts, no sidebar; "Exit presentation" restores the
    normal page and the URL says present=false."""
    page.set_viewport_size(PROJECTOR)
    open_dashboard(page, dashboard_server, "?present=true")
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


def test_the_present_button_turns_the_mode_on(page, dashboard_server):
    """A click on "Present" in the header puts present=true in the URL and hides the sidebar."""
    page.set_viewport_size(PROJECTOR)
    open_dashboard(page, dashboard_server)
    page.get_by_role("button", name="Present", exact=True).click()
    page.wait_for_function("() => window.location.search.includes('present=true')", timeout=30_000)
    page.wait_for_function("() => document.getElementById('sidebar').getBoundingClientRect().width === 0",
                           timeout=30_000)
    page.wait_for_function(TICKS_ARE, arg=17, timeout=30_000)


def test_the_legend_is_shown_and_the_lambda_help_appears_on_hover(page, dashboard_server):
    """The regime legend names every letter of the vocabulary; hovering Λ's "?" shows the
    words of docs/model.md."""
    open_dashboard(page, dashboard_server)
    legend = page.locator(".regime-legend")
    expect(legend).to_be_visible()
    letters = [e.get_attribute("data-regime") for e in legend.locator(".legend-regime").all()]
    assert letters == list(CLASS_LETTERS)
    tip = page.get_by_text("inertia over drag")
    expect(tip).to_have_count(0)
    page.locator(".help-lam").first.hover()
    expect(tip).to_be_visible(timeout=10_000)
