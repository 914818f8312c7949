"""Browser tests of the Maps tab: a small regime map computed in the background reaches the
page, and a click on a Λ × r map opened after the Explorer lands there; a shared link reopens
its map, and the URL follows the page.

The image data is read back from the page's Bokeh document (the ``map_image`` source), so a
check passes only if the map travelled worker thread → session → websocket → browser. The
small map and the click share one page, opened with a Λ × r map (a page load is the costly
part of a browser test); the link opens a page of its own.
"""
from __future__ import annotations

import re

import pytest
from playwright.sync_api import expect
from test_ui import open_dashboard, set_input

pytestmark = [pytest.mark.ui, pytest.mark.timeout(300)]

MAP_SOURCE = """() => {
  const f = [...Bokeh.documents[0]._all_models.values()].filter(m => m.name === 'map_figure')
    .find(m => { const v = Bokeh.index.find_one(m); return v && v.el.isConnected; });
  if (f == null) return null;
  for (const r of f.renderers) {
    const s = r.data_source;
    if (s && s.data && s.data.image && s.data.image.length && s.data.image[0].length > 4) return s;
  }
  return null;
}"""
MAP_READY = "() => (" + MAP_SOURCE + ")() != null"
MAP_SHAPE = """() => { const s = (""" + MAP_SOURCE + """)();
  const img = s.data.image[0];
  return {size: img.length, codes: [...new Set(Array.from(img).filter(v => !isNaN(v)))]}; }"""


@pytest.mark.timeout(600)
def test_maps_tab_computes_a_small_map_and_a_click_on_a_lambda_r_map_lands_there(
        page, dashboard_server):
    """?map_y_axis=r, the Explorer drawn: a 12 × 12 map arrives with the regimes' legend; then a
    5 × 4 map, and a click on it sets exactly that Λ and r."""
    errors = open_dashboard(page, dashboard_server, "?map_y_axis=r")
    _step_maps_tab_computes_a_small_map(page, dashboard_server, errors)
    _step_a_click_on_a_lambda_r_map_opened_from_the_explorer_lands_there(page, dashboard_server)


def _step_maps_tab_computes_a_small_map(page, dashboard_server, errors) -> None:
    """Switch to Maps, compute a 12 × 12 map: the image arrives and the legend shows the regimes."""
    page.locator(".bk-tab", has_text="Maps").first.click()
    page.locator(".map-compute button").first.wait_for(timeout=20_000)
    for css, value in ((".map-x-num", "12"), (".map-y-num", "12"), (".map-transient", "40"),
                       (".map-record", "20")):
        set_input(page, css, value)  # sent before the click, on the same socket
    page.locator(".map-compute button").first.click()
    page.wait_for_function(MAP_READY, timeout=120_000)
    shape = page.evaluate(MAP_SHAPE)
    assert shape["size"] == 144
    assert set(shape["codes"]) <= set(range(8))
    entries = page.locator(".map-legend .map-regime")
    expect(entries).to_have_count(8, timeout=20_000)
    letters = [entries.nth(i).get_attribute("data-regime") for i in range(8)]
    assert letters == ["A", "B", "C", "D", "E", "P", "Q", "error"]
    for i, letter in enumerate(letters[:7]):
        assert re.match(rf"^\s*{letter}\b", entries.nth(i).inner_text()), entries.nth(i).inner_text()
    expect(page.locator(".map-status").first).to_contain_text("12 × 12 = 144 points")
    assert errors == []
    assert dashboard_server["log"].tracebacks() == []


def _step_a_click_on_a_lambda_r_map_opened_from_the_explorer_lands_there(page,
                                                                         dashboard_server) -> None:
    """Explorer first (its plots drawn), then a Λ × r map: a click sets exactly that Λ and r.

    The Explorer's plots share the axis names "x" and "y" with the map; Panel linked their
    ranges, and the map's click stream then refused every click as out of its range.
    """
    from test_ui_fixes import compute_map, fig

    compute_map(page, 5, 4)
    p = fig(page, "map_figure", 3.125, 0.95)  # grid: Λ 0.5…4 in 5, r 0.3…0.95 in 4
    page.mouse.click(p["sx"], p["sy"])
    page.wait_for_function("() => window.location.search.includes('lam=3.125')", timeout=20_000)
    assert "r=0.95" in page.url
    assert dashboard_server["log"].tracebacks() == []


def test_a_shared_link_reopens_its_map_and_the_url_follows_the_page(page, dashboard_server):
    """/?tab=maps with an r × φ₂ map: the Maps tab opens with the link's settings and computes
    the map; a click on it sets r and φ₂, and a changed setting goes into the URL. The page
    logs no error: the Explorer tab, not shown, was not built (built and hidden, its plots
    went on sending changes the page could not place: "reference … isn't known")."""
    from test_ui import BOX_SHOWS, painted
    from test_ui_fixes import MAP_IMAGE, fig

    errors: list[str] = []
    page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.goto(f"{dashboard_server['url']}/?tab=maps&map_x_axis=r&map_x_start=0.4&map_x_stop=0.9"
              "&map_x_num=5&map_y_num=4&map_transient=40&map_record=20", timeout=120_000)
    page.locator(".map-compute button").first.wait_for(timeout=60_000)
    expect(page.locator(".bk-tab.bk-active").first).to_have_text("Maps")
    assert page.locator(".ctl-x_axis select").first.input_value() == "r"
    for css, want in ((".map-x-start", 0.4), (".map-x-stop", 0.9), (".map-x-num", 5),
                      (".map-y-num", 4), (".map-transient", 40), (".map-record", 20)):
        page.wait_for_function(BOX_SHOWS, arg=[css, want, 1e-9], timeout=20_000)
    # no Compute pressed: a link's light map runs by itself
    page.locator(".map-status", has_text="5 × 4 = 20 points").first.wait_for(timeout=120_000)
    page.wait_for_function(f"() => {{ const m = ({MAP_IMAGE})(); return m != null && m.shape[0] == 4 "
                           "&& m.shape[1] == 5; }", timeout=60_000)
    painted(page)
    p = fig(page, "map_figure", 0.775, 240.0)  # grid: r 0.4…0.9 in 5, φ₂ 0…360 in 4
    page.mouse.click(p["sx"], p["sy"])
    page.wait_for_function("() => window.location.search.includes('r=0.775')", timeout=20_000)
    assert "phi2=240" in page.url
    set_input(page, ".map-x-num", "6")
    assert errors == []
    page.wait_for_function("() => window.location.search.includes('map_x_num=6')", timeout=20_000)
    page.locator(".bk-tab", has_text="Gearbox").first.click()
    page.wait_for_function("() => window.location.search.includes('tab=gearbox')", timeout=20_000)
    assert dashboard_server["log"].tracebacks() == []
