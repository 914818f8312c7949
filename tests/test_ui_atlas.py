"""Browser tests of the atlas: exact bifurcation curves reach the page's plots.

The curves' glyphs are found by name in the page's Bokeh document (``atlas-<kind>`` over the
map, ``curve-<kind>`` under the continued branch) and their coordinates read back, so a test
passes only if the curves travelled from the background job through the server and the
websocket into the browser, and are the closed forms there.
"""
from __future__ import annotations

import numpy as np
import pytest
from test_ui import open_dashboard, set_input, wait_bif, wait_box_leaves
from test_ui_maps import MAP_READY

pytestmark = [pytest.mark.ui, pytest.mark.timeout(300)]

PATHS = """(name) => {
  const m = Bokeh.documents[0].get_model_by_name(name);
  if (m == null) return null;
  const d = m.data_source.data;
  if (d.xs === undefined) return null;
  return {xs: Array.from(d.xs).map(a => Array.from(a)), ys: Array.from(d.ys).map(a => Array.from(a))};
}"""
FINITE = f"""(name) => {{ const p = ({PATHS})(name);
  return p == null ? 0 : p.xs.reduce((n, x) => n + x.filter(Number.isFinite).length, 0); }}"""


def lam_pd(r):
    return np.sqrt((2 * (1 + r**2) / (1 + r) ** 2) ** 2 + (np.pi * (1 - r) / (1 + r)) ** 2)


def finite_points(paths: dict) -> tuple[np.ndarray, np.ndarray]:
    x = np.concatenate([np.asarray(a, dtype=float) for a in paths["xs"]])
    y = np.concatenate([np.asarray(a, dtype=float) for a in paths["ys"]])
    ok = np.isfinite(x) & np.isfinite(y)
    return x[ok], y[ok]


def test_draw_the_atlas_over_a_regime_map(page, dashboard_server):
    """A Λ × r map (harmonic): "Draw the atlas" overlays the contact boundary at Λ = 1 and the
    C orbit's period doubling Λ_PD(r) to 1e-8, in their own line styles with a legend, and the
    URL keeps atlas=true."""
    page.set_default_navigation_timeout(120_000)  # a loaded machine builds the page slowly
    errors = open_dashboard(page, dashboard_server, "?lam=1.2&h2=0")
    page.locator(".bk-tab", has_text="Maps").first.click()
    page.locator(".map-compute button").first.wait_for(timeout=120_000)
    page.locator(".ctl-y_axis select").first.select_option(label="r")
    # the new axis brings its own range; typing before it arrives would be overwritten
    wait_box_leaves(page, ".map-y-stop", 360.0)
    for css, value in ((".map-x-start", "0.8"), (".map-x-stop", "2"), (".map-x-num", "10"),
                       (".map-y-start", "0.4"), (".map-y-stop", "0.8"), (".map-y-num", "6"),
                       (".map-transient", "40"), (".map-record", "20")):
        set_input(page, css, value)
    page.locator(".map-compute button").first.click()
    page.wait_for_function(MAP_READY, timeout=120_000)
    page.locator(".map-status", has_text="10 × 6 = 60 points").first.wait_for(timeout=60_000)
    assert page.evaluate(FINITE, "atlas-period_doubling") == 0
    page.locator(".atlas-draw button").first.click()
    page.locator(".atlas-status", has_text="codimension-two").first.wait_for(timeout=180_000)
    page.wait_for_function(f"() => ({FINITE})('atlas-period_doubling') > 0", timeout=60_000)
    x, y = finite_points(page.evaluate(PATHS, "atlas-contact"))
    assert len(x) >= 2 and np.allclose(x, 1.0, atol=1e-8) and y.min() <= 0.4 + 1e-9
    x, y = finite_points(page.evaluate(PATHS, "atlas-period_doubling"))
    on_c = np.abs(x - lam_pd(y)) < 1e-8  # the C orbit's doubling, among the others
    assert on_c.sum() >= 10
    assert abs(y[on_c].min() - 0.4) < 1e-9 and abs(y[on_c].max() - 0.8) < 1e-9
    dash = page.evaluate("""() => Bokeh.documents[0].get_model_by_name('atlas-fold')
                                  .glyph.line_dash""")
    assert dash != page.evaluate("""() => Bokeh.documents[0]
                                 .get_model_by_name('atlas-period_doubling').glyph.line_dash""")
    legend = " ".join(page.locator(".atlas-legend span").all_inner_texts())
    assert "period doubling" in legend and "contact boundary" in legend and "grazing" in legend
    page.wait_for_function("() => window.location.search.includes('atlas=true')", timeout=20_000)
    page.locator(".atlas-hide button").first.click()
    page.wait_for_function(f"() => ({FINITE})('atlas-period_doubling') == 0", timeout=30_000)
    assert errors == []
    assert dashboard_server["log"].tracebacks() == []


MARK_XY = """() => {
  const m = Bokeh.documents[0].get_model_by_name('cont-marks');
  const d = m.data_source.data;
  const i = Array.from(d.label).indexOf('PD');
  const f = Bokeh.documents[0].get_model_by_name('bifurcation');
  const v = Bokeh.index.find_one(f);
  v.el.scrollIntoView({block: 'center', inline: 'center'});  // below the fold on a tall page
  const r = v.el.getBoundingClientRect();
  const b = v.frame.bbox;
  const sx = v.frame.x_scale.compute(d.x[i]), sy = v.frame.y_scale.compute(d.y[i]);
  return {x: r.left + sx, y: r.top + sy, value: d.x[i]};
}"""


def test_a_click_on_a_marked_period_doubling_traces_its_curve(page, dashboard_server):
    """Regime C at Λ = 1.2, branch continued: a click on its PD mark traces the doubling in
    j (chosen from the list): the curve is Λ = Λ_PD to 1e-8 from j = 16 down to where the
    flight reaches the reverse flank (j = 5.75), and the URL holds it."""
    page.set_default_navigation_timeout(120_000)
    errors = open_dashboard(page, dashboard_server, "?lam=1.2&h2=0&cont=true&cont_from=1.2")
    wait_bif(page)
    page.locator(".cont-status div", has_text="Continued branch").first.wait_for(timeout=120_000)
    page.locator(".ctl-curve_param2 select").first.select_option(label="j")
    page.wait_for_function("() => Bokeh.documents[0].get_model_by_name('cont-marks') != null",
                           timeout=60_000)
    # the mark must be on screen for the click: the diagram scrolled into view, the layout
    # settled (the same position twice)
    page.locator(".diagram").first.scroll_into_view_if_needed()
    page.wait_for_function(f"""() => {{ const a = ({MARK_XY})(); const prev = window._markAt;
        window._markAt = a; return prev !== undefined && Math.abs(prev.x - a.x) < 0.5 &&
        Math.abs(prev.y - a.y) < 0.5 && a.y > 0 && a.y < window.innerHeight; }}""",
                           timeout=30_000, polling=500)
    target = page.evaluate(MARK_XY)
    assert abs(target["value"] - 1.2394) < 1e-3
    page.mouse.click(target["x"], target["y"])
    page.wait_for_function("() => window.location.search.includes('lam=1.2394')",
                           timeout=30_000)
    page.locator(".curve-status", has_text="Traced in j").first.wait_for(timeout=180_000)
    page.wait_for_function(f"() => ({FINITE})('curve-period_doubling') > 0", timeout=60_000)
    x, y = finite_points(page.evaluate(PATHS, "curve-period_doubling"))
    assert len(x) >= 5 and np.max(np.abs(x - lam_pd(0.65))) < 1e-8
    assert abs(y.min() - 5.752988199) < 1e-6 and abs(y.max() - 16.0) < 1e-9
    search = page.evaluate("() => window.location.search")
    assert "curve=period_doubling" in search and "curve_in=j" in search
    assert errors == []
