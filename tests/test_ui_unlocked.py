"""Browser test: a change Panel applies outside the document's lock still reaches the page.

Panel runs a click on the server's event loop without Bokeh's document lock when the click
arrives while a widget's debounced change is still pending (``Reactive._server_event``).
Every view that writes Bokeh models itself (the time history, the gear in motion, the
presented figures) must then still reach the page, and raise nothing on the server.
The test runs a preset and a change of view exactly there: on the loop, unlocked.
"""
from __future__ import annotations

import threading

import pytest

from app import dashboard as dashboard_module
from app.presets import PRESETS
from test_ui import CHECKSUM, open_dashboard, wait_box
from conftest import wait_for

pytestmark = [pytest.mark.ui, pytest.mark.timeout(600)]


def on_the_loop_unlocked(doc, fn) -> None:
    """Run ``fn`` on the server's event loop, as Panel runs a click there: no document lock."""
    from panel.io.state import set_curdoc, state
    done = threading.Event()
    errors: list[BaseException] = []

    def run() -> None:
        try:
            with set_curdoc(doc):
                fn()
        except BaseException as exc:  # handed to the test, which shows it
            errors.append(exc)
        finally:
            done.set()
    for bokeh_server, _, _ in list(state._servers.values()):
        bokeh_server.io_loop.asyncio_loop.call_soon_threadsafe(run)
        break
    assert done.wait(300), "the server's loop did not run the change"
    if errors:
        raise errors[0]


def test_a_preset_run_outside_the_lock_reaches_the_page(page, dashboard_server):
    """A preset, a pin and the presented motion, applied unlocked on the loop: the page shows
    the preset's Λ, a new time history, A's line on the diagram, the large motion view, and
    the server logged nothing."""
    open_dashboard(page, dashboard_server, "?lam=2.5")
    dash = max(dashboard_module.LIVE, key=lambda d: d.session.key)
    doc = dash.session.jobs.doc
    before = page.evaluate(CHECKSUM)
    lam = PRESETS["Fig 3D"][1]["lam"]

    on_the_loop_unlocked(doc, lambda: dash.controls.apply_preset("Fig 3D"))
    wait_for(lambda: dash.state.lam == pytest.approx(lam), 120, "the preset to be applied")
    wait_box(page, "lam", lam, timeout=60_000)
    page.wait_for_function(f"() => ({CHECKSUM})() !== {before!r}", timeout=60_000)

    # a pin of the run shown: A's line on the diagram and A's curve on the time history
    on_the_loop_unlocked(doc, dash.pin.pin)
    wait_for(lambda: dash.state.pinned_result is not None, 120, "the pin to be published")
    page.wait_for_function("() => { const d = Bokeh.documents[0];"
                           " const s = d.get_model_by_name('pinned_value');"
                           " return s != null && s.visible; }", timeout=60_000)

    on_the_loop_unlocked(doc, lambda: dash.state.param.update(present=True, stage="motion"))
    # the motion figure's ticks at presenting size: written by the view itself, not by Panel
    page.wait_for_function("() => { const f = Bokeh.documents[0].get_model_by_name('motion');"
                           " return f != null && parseFloat(f.below[0].major_label_text_font_size) === 17; }",
                           timeout=60_000)
    assert dashboard_server["log"].tracebacks() == []
