"""Browser tests of the Poincaré map: its axes frame each run, and a click starts the gear there.

The figure's ranges and the page's URL are read from the browser (the page's Bokeh document),
and compared with the section's points computed here by the core for the same parameters.

The checks share one page (a page load is the costly part of a browser test), opened at
``?lam=1.2&h2=0``: the Reset tool, then the framing of new runs (Fig 7, then H₂/H₁ = 5), then,
with the values the next check starts from typed in, a click on the map at Λ = 2.5, H₂/H₁ = 0,
and last the twin, on Fig 7 again (its preset also puts the initial state back).
"""
from __future__ import annotations

from urllib.parse import parse_qs, urlparse

import numpy as np
import pytest

from rattle_core import RattleParams, simulate
from rattle_core.model.phases import paper_to_core_phases
from test_ui import box, open_dashboard, wait_box
from test_ui_fixes import fig

pytestmark = [pytest.mark.ui, pytest.mark.timeout(600)]

SECTION_RANGE = """() => { const m = Bokeh.documents[0].get_model_by_name('section');
  return m == null ? null : [m.x_range.start, m.x_range.end, m.y_range.start, m.y_range.end]; }"""


def wait_framed(page, x, y, timeout: float = 60_000) -> list[float]:
    """Wait until the section's ranges hold every point (x, y) and are at most about twice the
    points' spread (plus the unit margin around a single point); return the ranges."""
    lo_x, hi_x, lo_y, hi_y = (float(v) for v in (x.min(), x.max(), y.min(), y.max()))
    wx, wy = (2 * max(float(np.ptp(v)), 1e-3) + 1.0 for v in (x, y))
    page.wait_for_function(f"""() => {{ const r = ({SECTION_RANGE})(); if (r == null) return false;
        return r[0] <= {lo_x} && {hi_x} <= r[1] && r[2] <= {lo_y} && {hi_y} <= r[3]
            && r[1] - r[0] <= {wx} && r[3] - r[2] <= {wy}; }}""", timeout=timeout)
    return page.evaluate(SECTION_RANGE)


def paper(lam: float, h2: float, phi2: float = 0.0, periods: int = 200) -> tuple[np.ndarray, np.ndarray]:
    """The absolute Poincaré section (x, ẋ) at strobe 0 with the page's default run settings,
    computed by the core (phases in the paper's convention, as the page takes them)."""
    p = RattleParams(lam=lam, r=0.65, j=8.0, amplitudes=(1.0, h2),
                     phases_deg=tuple(paper_to_core_phases([0.0, phi2])))
    tr = simulate(p, periods=periods, transient=300)
    return tr.strobe_x, tr.strobe_v


def _step_reset_returns_to_the_current_runs_frame(page) -> None:
    """After a run changes the frame, a wheel zoom and the Reset tool come back to the new frame,
    not to the page's first ranges; the next run frames its own data again."""
    b = box(page, "lam")
    b.fill("2.5")
    b.press("Enter")
    x, y = paper(2.5, 0.0)
    framed = wait_framed(page, x, y)
    page.locator(".section").first.scroll_into_view_if_needed()
    c = fig(page, "section", 0.5 * (framed[0] + framed[1]), 0.5 * (framed[2] + framed[3]))
    page.mouse.move(c["sx"], c["sy"])
    page.mouse.wheel(0, -400)
    page.wait_for_function(f"() => ({SECTION_RANGE})()[1] - ({SECTION_RANGE})()[0] < {0.9 * (framed[1] - framed[0])!r}",
                           timeout=20_000)
    page.evaluate("""() => { const m = Bokeh.documents[0].get_model_by_name('section');
        m.toolbar.tools.find(t => t.type === 'ResetTool').do.emit(); }""")
    page.wait_for_function(f"""() => {{ const r = ({SECTION_RANGE})();
        return [{framed[0]!r}, {framed[1]!r}, {framed[2]!r}, {framed[3]!r}]
            .every((v, i) => Math.abs(v - r[i]) < 1e-9 * (1 + Math.abs(v))); }}""", timeout=20_000)
    b.fill("1.2")
    b.press("Enter")
    x, y = paper(1.2, 0.0)
    wait_framed(page, x, y)


def _step_frames_each_new_run(page) -> None:
    """Fig 7 from Λ = 1.2, H₂/H₁ = 0, then H₂/H₁ = 5: each time the axes hold every point, tightly."""
    page.locator(".preset-Fig7 button").first.click()
    x, y = paper(3.3, 0.25, 45.0, periods=5000)
    r = wait_framed(page, x, y)
    assert r[1] - r[0] > 3.0  # the strange attractor, not the first run's 1-wide box
    wait_box(page, "h2", 0.25)
    b = box(page, "h2")
    b.fill("5")
    b.press("Enter")
    x, y = paper(3.3, 5.0, 45.0, periods=5000)
    assert y.max() < -10  # the points lie near ẋ ≈ −13.9, far outside the last view
    wait_framed(page, x, y)


def _step_a_click_between_the_teeth_starts_the_gear_there(page) -> None:
    """At Λ = 2.5, H₂/H₁ = 0, a click on the map sets x₀ and ẋ₀ to the clicked point, in the URL too."""
    x, y = paper(2.5, 0.0)
    r = wait_framed(page, x, y)
    page.locator(".section").first.scroll_into_view_if_needed()
    gx, gy = r[0] + 0.3 * (r[1] - r[0]), r[2] + 0.7 * (r[3] - r[2])
    assert 0.0 < gx < 8.0  # between the teeth: y(0) = 0 and y(0) + j = 8
    assert "x0" not in parse_qs(urlparse(page.url).query), page.url  # not set before the click
    p = fig(page, "section", gx, gy)
    page.mouse.click(p["sx"], p["sy"])
    page.wait_for_function("() => /[?&]x0=[-0-9]/.test(window.location.search)", timeout=20_000)
    q = parse_qs(urlparse(page.url).query)
    assert float(q["x0"][0]) == pytest.approx(gx, abs=0.02 * (r[1] - r[0]))
    assert float(q["v0"][0]) == pytest.approx(gy, abs=0.02 * (r[3] - r[2]))
    wait_box(page, "x0", float(q["x0"][0]), tol=1e-6)


def _step_a_twin_drifts_away_on_chaos(page) -> None:
    """Fig 7, the twin turned on once the page is drawn (its plots join the page only then):
    the page draws the separation, which grows from the 1e-6 nudge by more than a thousandfold."""
    assert page.evaluate("() => Bokeh.documents[0].get_model_by_name('twin_gap') == null")
    page.locator(".ctl-twin input[type=checkbox]").first.check()
    page.wait_for_function("() => /[?&]twin=(true|1)/.test(window.location.search)", timeout=60_000)
    gap = """() => { const r = Bokeh.documents[0].get_model_by_name('twin_gap');
      if (r == null) return null; const y = r.data_source.data.separation || r.data_source.data.y;
      return y == null ? null : Array.from(y); }"""
    page.wait_for_function(f"() => {{ const y = ({gap})(); return y != null && y.length > 100; }}",
                           timeout=60_000)
    y = np.array(page.evaluate(gap))
    assert y[0] == pytest.approx(1e-6, rel=1e-6) and np.median(y[-100:]) > 1e3 * y[0]


#: x₀ is unset (the middle of the backlash): the URL gives it no value.
X0_DEFAULT = "() => /[?&]x0=(&|$)/.test(window.location.search)"


def _type(page, name: str, value: float) -> None:
    """Type ``value`` into the entry box of ``name`` and wait until the page shows it."""
    b = box(page, name)
    b.fill(f"{value:g}")
    b.press("Enter")
    wait_box(page, name, value)


def _set_for_the_click(page) -> None:
    """Type in the values the click is checked at: N = 200 (in the Advanced card), H₂/H₁ = 0,
    Λ = 2.5, the page's other values as at ``?lam=2.5&h2=0``."""
    if not box(page, "periods").is_visible():
        page.locator(".advanced .card-header").first.click()
        box(page, "periods").wait_for(state="visible", timeout=20_000)
    for name, value in (("periods", 200), ("h2", 0.0), ("lam", 2.5)):
        _type(page, name, value)
    wait_box(page, "phi2", 45.0)
    page.wait_for_function(X0_DEFAULT, timeout=20_000)
    wait_box(page, "v0", 0.0)


def _fig7_again(page) -> None:
    """The Fig 7 preset: the page's values as at ``?lam=3.3&h2=0.25&phi2=45&periods=5000``
    (the initial state back to its default), its section framed."""
    page.locator(".preset-Fig7 button").first.click()
    for name, value in (("lam", 3.3), ("h2", 0.25), ("phi2", 45.0), ("periods", 5000), ("v0", 0.0)):
        wait_box(page, name, value)
    page.wait_for_function(X0_DEFAULT, timeout=20_000)
    wait_framed(page, *paper(3.3, 0.25, 45.0, periods=5000))


@pytest.mark.timeout(1200)
def test_the_poincare_map_frames_each_run_resets_and_starts_the_gear_at_a_click(page, dashboard_server):
    """From ?lam=1.2&h2=0: after a run changes the frame, a wheel zoom and Reset come back to
    the new frame; Fig 7, then H₂/H₁ = 5, are each framed tightly; at Λ = 2.5, H₂/H₁ = 0, a
    click on the map sets x₀ and ẋ₀ there, in the URL too; on Fig 7 a twin started next to the
    gear drifts away by more than a thousandfold."""
    open_dashboard(page, dashboard_server, "?lam=1.2&h2=0")
    page.wait_for_function(f"() => ({SECTION_RANGE})() != null", timeout=60_000)
    _step_reset_returns_to_the_current_runs_frame(page)
    _step_frames_each_new_run(page)
    _set_for_the_click(page)
    _step_a_click_between_the_teeth_starts_the_gear_there(page)
    _fig7_again(page)
    _step_a_twin_drifts_away_on_chaos(page)
