"""Browser test of the physical-units mode in the URL: a link opens with the mode and its inputs.

The expected Λ comes from ``rattle_core.model.units`` (``PhysicalParams(...).lam`` for the linked
inputs), read back from the Λ control's entry box; a garbage key leaves its message beside its
input and the link corrected to the value shown.
"""
from __future__ import annotations

import pytest

from rattle_core import units
from test_ui import box_value, message, open_dashboard, wait_box

expect = pytest.importorskip("playwright.sync_api").expect

pytestmark = [pytest.mark.ui, pytest.mark.timeout(300)]


def test_link_with_physical_units_restores_the_mode(page, dashboard_server):
    """/?units=1&rpm=2000&J=3e-4&C=0.03&lam=1: switch on, inputs shown, Λ from the physical set."""
    errors = open_dashboard(page, dashboard_server, "?units=1&rpm=2000&J=3e-4&C=0.03&lam=1")
    expected = units.example().replace(rpm=2000.0, inertia=3e-4, drag_torque=0.03).lam
    wait_box(page, "lam", expected, tol=1e-4)
    expect(page.locator(".units-switch").first).to_have_attribute("aria-checked", "true")
    rpm_box = page.locator(".ctl-rpm input.bk-input").first
    rpm_box.wait_for(state="visible", timeout=20_000)
    assert float(rpm_box.input_value()) == 2000.0
    assert float(page.locator(".ctl-inertia input.bk-input").first.input_value()) == 3e-4
    expect(page.locator(".units-table table.units-params").first).to_contain_text("2000 rpm")
    # the page writes the state in force into the URL once the browser is connected: the
    # switch as the state serialises it (the link's 1 read as true)
    page.wait_for_function("() => /[?&]units=(1|true)(&|$)/.test(window.location.search)",
                           timeout=60_000)
    assert "rpm=2000" in page.url and "C=0.03" in page.url
    assert page.locator(".msg-global").first.is_hidden()
    assert not [e for e in errors if "Error" in e]
    assert dashboard_server["log"].tracebacks() == []


def test_garbage_physical_link_values_show_messages(page, dashboard_server):
    """rpm=abc: a message beside the engine speed naming its range, 1500 rpm kept, no traceback."""
    errors = open_dashboard(page, dashboard_server, "?units=1&rpm=abc&C=0.03")
    expected = units.example().replace(drag_torque=0.03).lam
    wait_box(page, "lam", expected, tol=1e-4)
    page.locator(".msg-rpm").first.wait_for(state="visible", timeout=20_000)
    text = message(page, "rpm")
    assert "rpm" in text and "(0, 100000]" in text and "Kept 1500" in text
    assert float(page.locator(".ctl-rpm input.bk-input").first.input_value()) == 1500.0
    page.wait_for_function("() => !window.location.search.includes('abc')", timeout=10_000)
    assert "rpm=1500" in page.url
    assert abs(box_value(page, "lam") - expected) <= 1e-4
    assert not [e for e in errors if "Error" in e]
    assert dashboard_server["log"].tracebacks() == []
