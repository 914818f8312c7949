"""Browser test of the physical-units mode: switch it on, type an engine speed, see Λ follow.

The expected Λ comes from ``rattle_core.model.units`` (``PhysicalParams.lam`` at the typed speed), and
the value is read back from the Λ control's entry box in the page.
"""
from __future__ import annotations

import pytest

from rattle_core import units
from test_ui import box_value, message, open_dashboard, wait_box

expect = pytest.importorskip("playwright.sync_api").expect

pytestmark = [pytest.mark.ui, pytest.mark.timeout(300)]


def test_engine_speed_typed_in_physical_units_sets_lambda(page, dashboard_server):
    """Units on, 2000 rpm typed: the Λ box shows the example gear's Λ at 2000 rpm; -5 rpm is refused."""
    errors = open_dashboard(page, dashboard_server)
    rpm_box = page.locator(".ctl-rpm input.bk-input").first
    assert not rpm_box.is_visible()
    page.locator(".units-switch").first.click()
    rpm_box.wait_for(state="visible", timeout=20_000)
    # switching on keeps the view: the inputs are solved for the current Λ
    wait_box(page, "lam", 3.3)
    rpm_box.fill("2000")
    rpm_box.press("Enter")
    expected = units.example().with_rpm(2000.0).lam
    wait_box(page, "lam", expected, tol=1e-4)
    table = page.locator(".units-table table.units-params").first
    expect(table).to_contain_text("2000 rpm", timeout=20_000)
    expect(table).to_contain_text(f"{expected:.6g}")

    rpm_box.fill("-5")
    rpm_box.press("Enter")
    page.locator(".msg-rpm").first.wait_for(state="visible", timeout=20_000)
    text = message(page, "rpm")
    assert "rpm" in text and "(0, 100000]" in text
    assert abs(box_value(page, "lam") - expected) <= 1e-4
    assert not [e for e in errors if "Error" in e]
