"""Browser tests of what a hostile link or a closed page can do to the server: nothing.

* Every URL key (and a key name) with script payloads at once: the page opens no dialog, each
  value is refused with a message that shows the payload as text, and the state stays good.
  Each key alone is checked without a browser, in every tab (``test_url_payloads.py``).
* No page can choose where the server connects (the Dask scheduler is the command line's).
* A closed session is freed: once the server has destroyed it, one garbage collection frees
  its dashboard, state and document, and its background work is cancelled.
"""
from __future__ import annotations

import gc
import sys
import threading
import urllib.parse
import warnings
import weakref

import pytest
from bokeh.document import Document

import holders
from app import dashboard as dashboard_module
from app import session as session_module
from app.state import URL_KEYS
from test_ui import READY, box_value, open_dashboard, painted
from conftest import patient_context, wait_for
from test_url_payloads import PAYLOADS

pytestmark = [pytest.mark.ui, pytest.mark.timeout(900)]

#: Keys whose control shows its message in the sidebar, while the Explorer tab is open.
SHOWN = ("lam", "r", "j", "h2", "phi2")


def watch_dialogs(page) -> list[str]:
    dialogs: list[str] = []

    def on_dialog(d) -> None:
        dialogs.append(d.message)
        d.dismiss()
    page.on("dialog", on_dialog)
    return dialogs


@pytest.mark.parametrize("payload", PAYLOADS)
def test_every_url_key_with_a_script_payload_runs_nothing(page, dashboard_server, payload):
    """All keys (and one key name) carry the payload: no dialog, messages show it as text."""
    dialogs = watch_dialogs(page)
    query = urllib.parse.urlencode({**{k: payload for k in URL_KEYS.values()}, payload: "1"})
    open_dashboard(page, dashboard_server, "?" + query)
    assert box_value(page, "lam") == pytest.approx(3.3) and box_value(page, "r") == pytest.approx(0.65)
    for name in SHOWN:
        msg = page.locator(f".msg-{name} p").first
        msg.wait_for(state="visible", timeout=10_000)
        assert payload[:30] in msg.inner_text()  # as text: the browser did not parse it
    url_msg = page.locator(".msg-url p").first.inner_text()
    assert "unknown key" in url_msg and payload[:20] in url_msg
    assert page.locator(".msg-lam img, .msg-lam script, .msg-url img, .msg-url svg").count() == 0
    page.locator(".rattle-badge").first.wait_for(timeout=20_000)
    painted(page)  # every message and the badge drawn: any script among them would have run
    assert dialogs == []
    assert dashboard_server["log"].tracebacks() == []


def test_no_page_chooses_where_the_server_connects(page, dashboard_server):
    """The Maps tab has no scheduler field; a scheduler key in the URL is an unknown key."""
    open_dashboard(page, dashboard_server, "?scheduler=tcp%3A%2F%2F203.0.113.9%3A8786")
    page.locator(".msg-url p").first.wait_for(timeout=10_000)
    assert "'scheduler'" in page.locator(".msg-url p").first.inner_text()
    page.locator(".bk-tab", has_text="Maps").first.click()
    page.locator(".map-compute button").first.wait_for(timeout=20_000)
    assert page.locator(".map-scheduler").count() == 0
    assert "this server's cores" in page.locator(".map-where div").first.inner_text()


def _after_the_server_loop_turns() -> None:
    """Return once the server's event loop has run a callback posted now: whatever it was
    running (a session's destroy hooks, which run there in one go) has finished."""
    from panel.io.state import state
    done = threading.Event()
    for bokeh_server, _, _ in list(state._servers.values()):
        bokeh_server.io_loop.asyncio_loop.call_soon_threadsafe(done.set)
        assert done.wait(60), "the server's loop did not turn"
        done.clear()


def closed_session_survivors(browser, server, keep: list | None = None) -> list[str]:
    """Open a page, close it, wait until the server has destroyed its session, collect once:
    the types of the session's objects still alive (``keep`` receives the dashboard, to show
    that a reference kept is found)."""
    context = patient_context(browser)
    try:
        page = context.new_page()
        page.goto(f"{server['url']}/?lam=2.5")
        page.wait_for_function(READY, timeout=120_000)
        dash = max(dashboard_module.LIVE, key=lambda d: d.session.key)
        assert dash.state.lam == pytest.approx(2.5)
        doc = dash.session.jobs.doc
        jobs = weakref.ref(dash.session.jobs)
        objects = (dash, dash.session, dash.state, dash.layout, dash.time_history, doc)
        refs = [weakref.ref(o) for o in objects]
        if keep is not None:
            keep.append(dash)
        del dash, doc, objects
        page.close()
    finally:
        context.close()
    wait_for(lambda: (j := jobs()) is None or j._closed, 120,
             "the server to destroy the closed page's session")
    _after_the_server_loop_turns()
    gc.collect()
    survivors = [r() for r in refs if r() is not None]
    if keep is None and [type(o) for o in survivors] == [Document]:
        # the app's objects are gone and Panel has emptied the document; once in a few loaded
        # runs it outlived the collection, held outside the app: that is reported, and held
        # by the app it is a survivor like the others
        doc = survivors.pop()
        assert doc.session_context is None, "the closed page's document was not emptied"
        found = holders.roots(doc)
        warnings.warn("the closed page's emptied Bokeh document outlived the collection; held by: "
                      + " | ".join(found))
        if holders.through(found, "app"):
            survivors.append(doc)
        del doc
    if keep is None:
        for obj in survivors:  # in the failing test's output: what holds each survivor
            print(f"{type(obj).__name__} survived; held by:", *holders.roots(obj), sep="\n  ",
                  file=sys.stderr)
    return [type(obj).__name__ for obj in survivors]


def test_a_closed_session_is_collected_at_the_next_collection(browser, dashboard_server):
    """Once the server has destroyed a closed page's session, one ``gc.collect()`` frees its
    dashboard, session, state, template, a view and its Bokeh document: nothing of the app holds
    them (a reference kept here is found, so the check can fail)."""
    assert closed_session_survivors(browser, dashboard_server) == []
    kept: list = []
    assert closed_session_survivors(browser, dashboard_server, keep=kept) != []
    kept.clear()
    gc.collect()
    assert dashboard_server["log"].tracebacks() == []


def test_closing_the_page_cancels_its_background_work(browser, dashboard_server):
    """A session's running map is cancelled when its page closes."""
    from app.work import jobs
    context = patient_context(browser)
    p = context.new_page()
    open_dashboard(p, dashboard_server)
    key = max(s.key for s in session_module.LIVE)
    p.locator(".bk-tab", has_text="Maps").first.click()
    for css, value in ((".map-x-num", "200"), (".map-y-num", "200"), (".map-transient", "400")):
        box = p.locator(f"{css} input").first
        box.fill(value)
        box.press("Enter")  # sent before the click, on the same socket
    p.locator(".map-compute button").first.click()
    wait_for(lambda: jobs.pool().pending(key), 60, "the map to start")
    context.close()
    wait_for(lambda: not jobs.pool().pending(key), 60, "the closed page's map to be cancelled")
    assert jobs.pool().pending(key) == []
