"""Browser tests of pinning a run: a link's pin drawn and unpinned, then Figure 4 pinned as A
and Figure 5 loaded as B, both drawn; a pin made in physical units drawn from its link.

The caption is read from the page, the overlays from the page's Bokeh document (the time
history's and the section's legends and data, the diagram's markers), and A's points are
compared with the core's run of Figure 4 made here. Unpinning and pinning share one page, the
link's, whose live run is Figure 4 (a page load is the costly part of a browser test).
"""
from __future__ import annotations

from urllib.parse import parse_qs, urlparse

import numpy as np
import pytest
from playwright.sync_api import expect

from app.pinning import parse_pin
from test_ui import open_dashboard, wait_bif
from test_ui_section import paper

pytestmark = [pytest.mark.ui, pytest.mark.timeout(600)]

FIG4 = "?lam=3.3&r=0.65&j=8&h2=0.25&phi2=45&phases=paper"

#: ``[label, visible, points]`` of each entry of the legend in the named figure.
LEGEND = """(name) => { const m = Bokeh.documents[0].get_model_by_name(name);
  if (m == null) return null;
  const legends = [...m.center, ...m.right].filter(l => l.type === 'Legend');
  return legends.flatMap(l => l.items.map(i => {
    const src = i.renderers[0].data_source;
    return [i.label.value, i.visible && l.visible, src.get_length() || 0]; })); }"""

#: The section's A points, as the page holds them.
PINNED_POINTS = """() => { const m = Bokeh.documents[0].get_model_by_name('section');
  const l = m.center.find(l => l.type === 'Legend');
  const item = l.items.find(i => i.label.value === 'A (pinned)');
  const d = item.renderers[0].data_source.data;
  return [Array.from(d.x), Array.from(d.y)]; }"""

MARKS = """() => { const d = Bokeh.documents[0];
  const [a, la, lb, b] = ['pinned_value', 'pinned_label', 'current_label', 'current_value']
    .map(n => d.get_model_by_name(n));
  return a == null ? null : {a: a.location, a_shown: a.visible, b: b.location,
                             names: [la.visible ? la.text : '', lb.visible ? lb.text : '']}; }"""


def legend(page, name: str) -> list:
    return page.evaluate(LEGEND, name) or []


@pytest.mark.timeout(1200)
def test_a_linked_pin_unpinned_then_fig4_pinned_and_fig5_shown_beside_it(page, dashboard_server):
    """Fig 4 opened with a pin (Λ = 2.5, H₂/H₁ = 0, φ₂ = 0) in its link: A is drawn and Unpin
    clears it; then Fig 4 pinned and the Fig 5 preset draw A beside B, and the URL carries the
    new pin."""
    errors = open_dashboard(page, dashboard_server, FIG4 + "&pin=lam%3A2.5%3Bh2%3A0%3Bphi2%3A0")
    _step_unpin_clears_a_from_the_page(page)
    _step_fig4_pinned_then_fig5_shows_both(page, dashboard_server, errors)


def _step_unpin_clears_a_from_the_page(page) -> None:
    """A link holding a pin opens A beside B; Unpin clears the caption's A, the overlays and
    the pin in the URL."""
    caption = page.locator(".pin-caption").first
    expect(caption).to_contain_text("A: Λ = 2.5, r = 0.65, j = 8, H₂/H₁ = 0, φ₂ = 0°",
                                    timeout=30_000)
    page.wait_for_function(f"""() => ({LEGEND})('time_history').some(
        i => i[0] === 'A (pinned): gear x(t)' && i[1] && i[2] > 100)""", timeout=30_000)
    page.locator(".unpin-run button").first.click()
    expect(caption).to_contain_text("Pin this run", timeout=20_000)
    page.wait_for_function(f"""() => ({LEGEND})('time_history').every(
        i => i[0] !== 'A (pinned): gear x(t)' || (!i[1] && i[2] == 0))""", timeout=30_000)
    page.wait_for_function("() => new URLSearchParams(window.location.search).get('pin') === ''",
                           timeout=20_000)


def _step_fig4_pinned_then_fig5_shows_both(page, dashboard_server, errors) -> None:
    """Fig 4 pinned, then the Fig 5 preset: the caption names A (φ₂ = 45°, chaotic) and B
    (φ₂ = 90°), the time history and the section draw A beside B with legend entries A and B,
    the diagram marks both, and the URL carries the pin."""
    caption = page.locator(".pin-caption").first
    expect(caption).to_contain_text("Pin this run", timeout=20_000)
    page.locator(".pin-run button").first.click()
    expect(caption).to_contain_text("A: Λ = 3.3, r = 0.65, j = 8, H₂/H₁ = 0.25, φ₂ = 45°",
                                    timeout=20_000)
    page.locator(".preset-Fig5 button").first.click()
    expect(caption).to_contain_text("B: Λ = 3.3, r = 0.65, j = 8, H₂/H₁ = 0.25, φ₂ = 90°",
                                    timeout=30_000)
    expect(caption).to_contain_text("A: Λ = 3.3, r = 0.65, j = 8, H₂/H₁ = 0.25, φ₂ = 45° (chaotic")
    expect(caption).to_contain_text("φ₂ = 90° (period 1")

    page.wait_for_function(f"""() => {{ const e = ({LEGEND})('time_history') || [];
        return e.some(i => i[0] === 'A (pinned): gear x(t)' && i[1] && i[2] > 100)
            && e.some(i => i[0] === 'B (live): gear x(t)' && i[1]); }}""", timeout=30_000)
    page.wait_for_function(f"""() => {{ const e = ({LEGEND})('section') || [];
        return e.some(i => i[0] === 'A (pinned)' && i[1] && i[2] == 200)
            && e.some(i => i[0] === 'B (live)' && i[1]); }}""", timeout=30_000)
    ax, av = page.evaluate(PINNED_POINTS)
    x, v = paper(3.3, 0.25, 45.0)
    np.testing.assert_allclose(ax, x, rtol=0, atol=1e-9)
    np.testing.assert_allclose(av, v, rtol=0, atol=1e-9)

    wait_bif(page)
    page.wait_for_function(f"() => {{ const m = ({MARKS})(); return m != null && m.a_shown; }}",
                           timeout=30_000)
    marks = page.evaluate(MARKS)
    assert marks["a"] == pytest.approx(3.3) and marks["b"] == pytest.approx(3.3)
    assert [t.strip() for t in marks["names"]] == ["A", "B"]

    pin = parse_pin(parse_qs(urlparse(page.url).query)["pin"][0])
    assert (pin["lam"], pin["h2"], pin["phi2"], pin["phases"]) == (3.3, 0.25, 45, "paper")
    assert errors == [] and dashboard_server["log"].tracebacks() == []


def test_a_physical_pin_from_a_link_is_drawn_in_ms(page, dashboard_server):
    """A link in physical units holding a pin made in that mode: the page draws A's time history
    on the ms axis beside B's, and marks A at its engine speed on the engine-speed diagram."""
    from urllib.parse import urlencode

    from test_pin import physical_pin
    text, a_in = physical_pin(lam=2.5)
    errors = open_dashboard(page, dashboard_server, "?" + urlencode({"units": 1, "lam": 3.3, "pin": text}))
    page.wait_for_function(f"""() => ({LEGEND})('time_history').some(
        i => i[0] === 'A (pinned): gear x(t)' && i[1] && i[2] > 100)""", timeout=30_000)
    label = page.evaluate("() => Bokeh.documents[0].get_model_by_name('time_history')"
                          ".below[0].axis_label")
    assert label == "t [ms]"
    wait_bif(page)
    page.wait_for_function(f"() => {{ const m = ({MARKS})(); return m != null && m.a_shown; }}",
                           timeout=30_000)
    assert page.evaluate(MARKS)["a"] == pytest.approx(a_in["rpm"], rel=1e-9)
    assert errors == [] and dashboard_server["log"].tracebacks() == []
