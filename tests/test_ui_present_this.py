"""Browser tests: each "Present this" button presents its view alone, large, on a projector.

The diagram (with continuation), the gear in motion (beside the time history), the pinned
comparison and the Maps tab's map each carry the button. A click puts ``present=true`` and
``stage=<view>`` in the URL, hides the sidebar, and at 1280×720 the view's figure fills most of
the window below the header, with presenting fonts, and nothing scrolls either way. Sizes and
fonts are read from the page: the figures' boxes from their Bokeh views, the tick fonts from
their models. One page presents each view in turn, leaving each presentation before the next.
"""
from __future__ import annotations

import pytest
from playwright.sync_api import expect

from test_ui import open_dashboard, painted

pytestmark = [pytest.mark.ui, pytest.mark.timeout(300)]

PROJECTOR = {"width": 1280, "height": 720}
#: A short run: the layout does not depend on the run's length.
SHORT = "?periods=20&transient=20"

#: The presented figure's box and tick font, the page's scroll sizes, the header's bottom.
LOOK = """(name) => {
  const d = Bokeh.documents[0];
  const fig = [...d._all_models.values()].find(m => m.name === name);
  const view = fig && Bokeh.index.find_one(fig);
  const r = view ? view.el.getBoundingClientRect() : null;
  const main = document.getElementById('main');
  return {
    box: r && {left: r.left, top: r.top, right: r.right, bottom: r.bottom, width: r.width, height: r.height},
    ticks: fig ? parseFloat(fig.below[0].major_label_text_font_size) : null,
    width: document.scrollingElement.scrollWidth, height: document.scrollingElement.scrollHeight,
    mainScroll: main.scrollHeight, mainClient: main.clientHeight,
    mainScrollW: main.scrollWidth, mainClientW: main.clientWidth,
    header: document.getElementById('header').getBoundingClientRect().bottom,
    vw: window.innerWidth, vh: window.innerHeight,
  };
}"""

#: Counts the page's layouts (BokehJS lays a page out from its root, in ``compute_layout``).
COUNT_LAYOUTS = """() => {
  const view = Bokeh.require("models/layouts/layout_dom").LayoutDOMView.prototype;
  if (!view.__counted) {
    const compute = view.compute_layout;
    view.compute_layout = function (...args) { window.__layouts += 1; return compute.apply(this, args); };
    view.__counted = true;
  }
  window.__layouts = 0;
}"""
#: Layouts of the page that presenting the diagram may take. It changes about 45 layout
#: properties; laid out once per property (Bokeh's own way) that was 57 layouts and 11 s of the
#: browser's time; once per frame of the server's messages (app.ui.relayout) it is about 20,
#: most of them the browser's own as the plots resize.
MOST_LAYOUTS = 40

#: stage → (the figure's Bokeh name, least share of the height below the header, least share
#: of the window's width).
STAGES = {"diagram": ("bifurcation", 0.6, 0.6),
          "motion": ("motion", 0.6, 0.45),
          "pin": ("section", 0.5, 0.4),
          "maps": ("map_figure", 0.6, 0.7)}


def present(page, stage: str) -> None:
    """Click ``stage``'s "Present this" and check that the view fills the window alone."""
    name, tall, wide = STAGES[stage]
    button = page.locator(f".present-{stage} button").first
    expect(button).to_have_text("Present this")
    button.click()
    page.wait_for_function(
        "(st) => { const q = new URLSearchParams(window.location.search);"
        " return q.get('present') === 'true' && q.get('stage') === st; }", arg=stage, timeout=60_000)
    expect(page.get_by_role("button", name="Exit presentation")).to_be_visible(timeout=60_000)
    page.wait_for_function("() => document.getElementById('sidebar').getBoundingClientRect().width === 0",
                           timeout=60_000)
    page.wait_for_function(f"() => ({LOOK})('{name}').ticks === 17", timeout=60_000)
    # the browser lays the stretching figure out after the server's last change
    page.wait_for_function(
        f"([h, w]) => {{ const l = ({LOOK})('{name}'); return l.box != null &&"
        " l.box.height >= h * (l.vh - l.header) && l.box.width >= w * l.vw; }",
        arg=[tall, wide], timeout=60_000)
    painted(page)
    look = page.evaluate(LOOK, name)
    b = look["box"]
    assert look["width"] <= look["vw"] and look["height"] <= look["vh"], (stage, look)
    assert look["mainScroll"] <= look["mainClient"], (stage, look)
    assert look["mainScrollW"] <= look["mainClientW"], (stage, look)
    assert look["header"] <= b["top"] and b["bottom"] <= look["vh"] + 1, (stage, look)
    assert 0 <= b["left"] and b["right"] <= look["vw"], (stage, look)
    expect(button).to_be_hidden()


def leave(page, stage: str) -> None:
    """Exit the presentation: the URL says so, the sidebar and the view's button are back."""
    page.get_by_role("button", name="Exit presentation").click()
    page.wait_for_function(
        "() => new URLSearchParams(window.location.search).get('present') !== 'true'",
        timeout=60_000)
    page.wait_for_function("() => document.getElementById('sidebar').getBoundingClientRect().width > 100",
                           timeout=60_000)
    expect(page.locator(f".present-{stage} button").first).to_be_visible(timeout=60_000)


def test_present_this_fills_a_projector_with_each_view_in_turn(page, dashboard_server):
    """Each view's "Present this" button presents it, in one page: the URL says so, the sidebar
    is gone, the figure fills most of a 1280×720 window at presenting fonts, and nothing
    scrolls; "Exit presentation" brings the page back for the next one. The page is laid out
    once per frame of the server's messages, not once per property a presentation changes."""
    page.set_viewport_size(PROJECTOR)
    open_dashboard(page, dashboard_server, SHORT)
    page.evaluate(COUNT_LAYOUTS)  # from here: the diagram is presented first
    for stage in ("diagram", "motion", "pin", "maps"):
        if stage == "pin":
            page.locator(".pin-run button").first.click()
            page.wait_for_function("() => /[?&]pin=[^&]/.test(window.location.search)",
                                   timeout=60_000)
        if stage == "maps":
            page.locator(".bk-tab", has_text="Maps").first.click()
        present(page, stage)
        if stage == "diagram":
            assert page.evaluate("() => window.__layouts") <= MOST_LAYOUTS
        leave(page, stage)
