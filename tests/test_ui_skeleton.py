"""Browser tests: a page shows its frame and a "computing…" note at once, before its first
plot; and the noise badge, seen in the page, names coexisting attractors.

The server sends the page's frame (:class:`app.dashboard.Shell`) without waiting for the first
run, and builds the dashboard into it once the browser has connected.
"""
from __future__ import annotations

import os
import time

import pytest
from test_ui import LOADED, READY

pytestmark = [pytest.mark.ui, pytest.mark.timeout(300)]

#: Whether the page has drawn its first plot (the time history holds data).
DRAWN = f"() => ({READY})()"


def allowed_s() -> float:
    """1 s, stretched by how far the machine's load exceeds its cores: the frame costs the
    server about 0.1–0.3 s of CPU, so on a machine shared beyond its cores its wall time
    grows with the queue in front of it."""
    cores = os.cpu_count() or 1
    return 1.0 * max(1.0, os.getloadavg()[0] / cores)


def test_a_page_shows_computing_within_a_second_then_its_plots(page, dashboard_server):
    """Opening the page: "computing…" is visible within 1 s (on a machine not loaded beyond its
    cores), while no plot is drawn yet; then
    the first plot arrives and the note gives way to the page."""
    url = dashboard_server["url"]
    page.goto(f"{url}/?lam=2.5", wait_until="commit")  # one warm-up page: the server's caches
    page.wait_for_function(READY, timeout=120_000)
    page.goto("about:blank")

    start = time.monotonic()
    page.goto(f"{url}/?lam=2.6", wait_until="commit")
    note = page.get_by_text("computing…").first
    note.wait_for(state="visible", timeout=30_000)
    seen = time.monotonic() - start
    assert not page.evaluate(DRAWN), "the first plot was drawn before the note was seen"
    limit = allowed_s()
    assert seen < limit, f"the note appeared after {seen:.2f} s (allowed {limit:.2f} s)"
    page.wait_for_function(READY, timeout=120_000)
    page.wait_for_function(LOADED, timeout=60_000)
    assert page.get_by_text("computing…").count() == 0


def test_the_noise_badge_in_the_page_names_the_coexisting_attractors(page, dashboard_server):
    """Fig 2's settings at Λ = 1.16 from a link: the badge the browser shows lists B, D and C
    with their runs and quotes D's own mean active impulse (≈ 8.53) for the chaotic run."""
    query = "?lam=1.16&r=0.65&j=8.0&h2=0.0&phi2=0.0&phases=paper&shown=12"
    page.goto(f"{dashboard_server['url']}/{query}", wait_until="commit")
    page.wait_for_function(READY, timeout=120_000)
    badge = page.locator(".noise-check").filter(has_text="attractors").first
    badge.wait_for(state="visible", timeout=240_000)
    text = badge.inner_text()
    assert "3 attractors at noise 1e-12: B (4 of 8 runs), D (3), C (1)." in text, text
    assert "The run on screen is on D: mean active impulse 8.5" in text, text
    assert "0.06218" not in text
