"""In the browser: a second session redraws while another opens the audit's worst link.

Before the page's run had a budget, the worst link simulated for minutes inside its session's
redraw while holding the lock every session's redraw takes: another session's redraw waited
115 s.  Here one page opens the worst link (twice: 300 and 100000 transient periods) while a
second page changes Λ twice per link; each of its redraws must arrive within seconds, and the
first page must draw with its run refused (the values in force, not the link's) and say
beside the periods that the run is over the budget.
"""
from __future__ import annotations

import time

import pytest

from conftest import patient_context
from test_ui import CHECKSUM, READY, box, message, open_dashboard, wait_box
from test_page_run import WORST

pytestmark = [pytest.mark.ui, pytest.mark.timeout(600)]


def test_a_second_session_redraws_while_the_worst_link_runs(browser, dashboard_server):
    """Session B's Λ changes redraw within 20 s each while session A loads the worst links."""
    ctx_a = patient_context(browser)
    ctx_b = patient_context(browser)
    try:
        a, b = ctx_a.new_page(), ctx_b.new_page()
        open_dashboard(b, dashboard_server)
        for link in (WORST, WORST.replace("transient=300", "transient=100000")):
            a.goto(f"{dashboard_server['url']}/{link}", wait_until="commit")
            for lam in (2.6, 2.9):
                before = b.evaluate(CHECKSUM)
                t0 = time.monotonic()
                field = box(b, "lam")
                field.fill(str(lam))
                field.press("Enter")
                wait_box(b, "lam", lam, tol=1e-9, timeout=20_000)
                b.wait_for_function(f"() => Math.abs(({CHECKSUM})() - {before!r}) > 1e-9",
                                    timeout=20_000)
                assert time.monotonic() - t0 < 20
            a.wait_for_function(READY, timeout=120_000)
            wait_box(a, "periods", 200.0, timeout=60_000)  # the worst run was refused
            a.locator(".msg-periods", has_text="budget").first.wait_for(timeout=60_000)
            assert "harmonics" in message(a, "periods")
        assert dashboard_server["log"].tracebacks() == []
    finally:
        ctx_a.close()
        ctx_b.close()
