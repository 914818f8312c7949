"""Browser test of "Replay the run-up": the sample's run-up replayed in the background, its
sound in a player, and the loudness plot's cursor following the player along the rpm axis.

The cursor is moved by the page alone (``CURSOR_JS``): seeking the player to a fraction of the
run puts it at that fraction of the way from "rpm from" to "rpm to", and while the player plays
it moves on. Both are read from the Bokeh model ``runup_cursor`` in the page.
"""
from __future__ import annotations

import pytest
from playwright.sync_api import expect

from test_ui import open_dashboard, set_input

pytestmark = [pytest.mark.ui, pytest.mark.timeout(600)]

#: The run-up's player, found in the page's shadow roots as the cursor's callback finds it.
PLAYER = """() => {
  const walk = (root) => {
    for (const el of root.querySelectorAll("*")) {
      if (el.shadowRoot) {
        if (el.classList.contains("gb-runup-audio")) {
          const a = el.shadowRoot.querySelector("audio");
          if (a) return a;
        }
        const a = walk(el.shadowRoot);
        if (a) return a;
      }
    }
    return null;
  };
  return walk(document);
}"""
CURSOR = ("() => { const c = Bokeh.documents[0].get_model_by_name('runup_cursor');"
          " return {location: c.location, visible: c.visible}; }")
RPM_FROM, RPM_TO, DURATION = 1500.0, 1700.0, 1.0


def test_the_replayed_run_up_plays_with_a_cursor_on_its_rpm_axis(page, dashboard_server, tmp_path,
                                                                  monkeypatch):
    """Sample → a 1 s run-up 1500 → 1700 rpm → its player holds 1 s of sound; seeking to 25 %
    and 75 % puts the cursor at 1550 and 1650 rpm; playing moves it."""
    monkeypatch.setenv("RATTLE_CACHE_DIR", str(tmp_path / "cache"))
    open_dashboard(page, dashboard_server)
    page.locator(".bk-tab", has_text="Gearbox").first.click()
    page.locator(".gb-sample button").first.click()
    expect(page.locator(".gb-measure-status").first).to_contain_text("rpm bins", timeout=120_000)
    for css, value in ((".gb-runup-from", RPM_FROM), (".gb-runup-to", RPM_TO),
                       (".gb-runup-duration", DURATION)):
        set_input(page, css, f"{value:g}")
    page.locator(".gb-runup-run button").first.click()
    status = page.locator(".gb-runup-status").first
    expect(status).to_contain_text(f"Run {RPM_FROM:g} → {RPM_TO:g} rpm in {DURATION:g} s",
                                   timeout=480_000)
    # the player has the run's sound: its duration is the run's
    page.wait_for_function(f"() => {{ const a = ({PLAYER})(); return a != null && "
                           f"Math.abs(a.duration - {DURATION}) < 0.01; }}", timeout=60_000)
    for fraction in (0.25, 0.75):
        page.evaluate(f"() => {{ ({PLAYER})().currentTime = {fraction * DURATION}; }}")
        want = RPM_FROM + fraction * (RPM_TO - RPM_FROM)
        page.wait_for_function(f"() => {{ const c = ({CURSOR})(); return c.visible && "
                               f"Math.abs(c.location - {want}) < 1; }}", timeout=30_000)
    page.evaluate(f"() => {{ const a = ({PLAYER})(); a.muted = true; a.currentTime = 0; }}")
    page.wait_for_function(f"() => Math.abs(({CURSOR})().location - {RPM_FROM}) < 1", timeout=30_000)
    page.evaluate(f"() => ({PLAYER})().play()")
    page.wait_for_function(f"() => ({CURSOR})().location > {RPM_FROM} + 20", timeout=60_000)
