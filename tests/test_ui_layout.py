"""Browser tests: every tab fits its window, sideways, on a projector and on a full-HD screen.

The page's main area (``#main``, which scrolls on its own) and the document are measured
from the browser: a part wider than the area makes its ``scrollWidth`` exceed its
``clientWidth``. A short run (``periods``) keeps the page light.
"""
from __future__ import annotations

import pytest

from test_ui import DEEP, open_dashboard, painted

pytestmark = [pytest.mark.ui, pytest.mark.timeout(600)]

SIZES = ({"width": 1280, "height": 720}, {"width": 1920, "height": 1080})
#: Each tab, and what shows it has been drawn.
TABS = {"Explorer": "() => Bokeh.documents[0].get_model_by_name('section') != null",
        "Maps": "() => Bokeh.documents[0].get_model_by_name('map_figure') != null",
        "Gearbox": "() => {" + DEEP + " return deep(document, '.gb-gears') != null; }"}

WIDTHS = """() => { const m = document.getElementById('main'), d = document.scrollingElement;
  return {main: m.scrollWidth, mainClient: m.clientWidth, doc: d.scrollWidth,
          docClient: d.clientWidth,
          sidebar: document.getElementById('sidebar').getBoundingClientRect().width}; }"""


def test_no_tab_scrolls_sideways_at_either_size_with_the_sidebar_open_or_closed(page, dashboard_server):
    """At 1280×720 and 1920×1080, with the sidebar open and closed, the Explorer, Maps and
    Gearbox tabs are no wider than the main area, and the document no wider than the window
    (the motion's controls, the continuation's plot and the map once ran past the edge)."""
    page.set_viewport_size(SIZES[0])
    open_dashboard(page, dashboard_server, "?periods=60&lam=1.16")
    wide = []
    for size in SIZES:
        page.set_viewport_size(size)
        for sidebar in ("open", "closed"):
            if sidebar == "closed":
                page.locator("#sidebar-toggle").first.click()
                page.wait_for_function("() => document.getElementById('sidebar')"
                                       ".getBoundingClientRect().width < 5", timeout=20_000)
            for tab, drawn in TABS.items():
                page.locator(".bk-tab", has_text=tab).first.click()
                page.wait_for_function(drawn, timeout=120_000)
                painted(page)
                w = page.evaluate(WIDTHS)
                if w["main"] > w["mainClient"] or w["doc"] > w["docClient"]:
                    wide.append((size["width"], sidebar, tab, w))
            if sidebar == "closed":
                page.locator("#sidebar-toggle").first.click()  # open again for the next size
                page.wait_for_function("() => document.getElementById('sidebar')"
                                       ".getBoundingClientRect().width > 100", timeout=20_000)
            page.locator(".bk-tab", has_text="Explorer").first.click()
    assert not wide, wide
