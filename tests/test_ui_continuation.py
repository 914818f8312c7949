"""Browser test: "Continue this orbit" draws the branch on the bifurcation diagram of the page.

The branch's glyphs are found by name in the page's Bokeh document (``cont-stable``,
``cont-unstable``, ``cont-marks``; counted in finite coordinates), so the test passes only if the branch travelled from the
background job through the server and the websocket into the browser's plot.
"""
from __future__ import annotations

import pytest
from test_ui import open_dashboard, wait_bif

pytestmark = [pytest.mark.ui, pytest.mark.timeout(300)]

GLYPH_SIZE = """(name) => {
  const m = Bokeh.documents[0].get_model_by_name(name);
  if (m == null) return -1;
  const d = m.data_source.data;
  const finite = (x) => Array.from(x).filter(Number.isFinite).length;
  if (d.xs !== undefined) return Array.from(d.xs).reduce((n, x) => n + finite(x), 0);
  return d.x === undefined ? 0 : finite(d.x);
}"""


LEGEND = """() => { const l = Bokeh.documents[0].get_model_by_name('cont-legend');
  return l == null ? [] : l.items.filter((i) => i.visible).map((i) => i.label.value); }"""


def test_continue_this_orbit_overlays_the_branch_and_keeps_it_in_the_url(page, dashboard_server):
    """Regime C at Λ = 1.2: the button draws stable and unstable lines and the PD mark, the
    status names the period doubling, the branches of the cascade are drawn with their legend,
    and the URL carries cont=true and cont_from=1.2."""
    errors = open_dashboard(page, dashboard_server, "?lam=1.2&h2=0")
    wait_bif(page)
    button = page.locator(".cont-button button").first
    button.wait_for(timeout=30_000)
    assert page.evaluate(GLYPH_SIZE, "cont-stable") <= 0
    button.click()
    status = page.locator(".cont-status div").filter(has_text="Continued branch").first
    status.wait_for(timeout=120_000)
    assert "PD at 1.2394" in status.inner_text()
    page.wait_for_function(f"() => ({GLYPH_SIZE})('cont-stable') > 0", timeout=60_000)
    assert page.evaluate(GLYPH_SIZE, "cont-unstable") > 0
    assert page.evaluate(GLYPH_SIZE, "cont-marks") >= 2
    # the cascade: the branches started at period doublings, each with its legend entry
    page.wait_for_function(f"() => ({LEGEND})().length >= 3", timeout=60_000)
    labels = page.evaluate(LEGEND)
    assert labels[:3] == ["period 1, from 1.2", "period 2, PD at 1.2394", "period 4, PD at 1.3764"]
    assert page.evaluate(GLYPH_SIZE, "cont-unstable-1") > 0
    page.wait_for_function("() => window.location.search.includes('cont=true')", timeout=20_000)
    assert "cont_from=1.2" in page.evaluate("() => window.location.search")
    assert errors == []
