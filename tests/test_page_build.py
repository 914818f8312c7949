"""The page factory: a frame with "computing…" at once, the dashboard built into it once the
browser has connected, and no dashboard at all for a client that has gone.

``app.main.create_app`` runs here in a document with a stand-in server session (the part of
Bokeh's ``BokehSessionContext`` it reads: ``destroyed`` and its session's open connections),
and Panel's own on-load dispatch plays the browser's "connected" message.
"""
from __future__ import annotations

import weakref
from types import SimpleNamespace

from bokeh.document import Document
from panel.io.state import set_curdoc, state

from app.dashboard import LIVE, SKELETON, Dashboard
from app.main import client_gone, create_app


class _Session:
    def __init__(self, connections: int):
        self.connection_count = connections


class _Context:
    """What the page factory reads of a server session: whether it is gone."""

    def __init__(self, connections: int):
        self.destroyed = False
        self._session = _Session(connections)
        self.id = f"stand-in-{id(self)}"
        # what Panel reads of the request: no arguments, cookies or headers; an empty link
        self.request = SimpleNamespace(arguments={}, cookies={}, headers={}, path="/", uri="/")


def _page(connections: int):
    ctx = _Context(connections)
    doc = Document()
    doc._session_context = weakref.ref(ctx)
    with set_curdoc(doc):
        layout = create_app()
    return doc, ctx, layout


def _built_in(layout) -> list[Dashboard]:
    return [d for d in list(LIVE) if d.layout is layout]


def test_a_client_that_has_gone_gets_a_frame_and_no_dashboard(job_pool):
    """The frame is sent with "computing…" and no dashboard; when the on-load message comes
    for a session with no open connection, nothing is built, and a destroyed session too."""
    for gone in ("no connection", "destroyed"):
        doc, ctx, layout = _page(0 if gone == "no connection" else 1)
        ctx.destroyed = gone == "destroyed"
        assert client_gone(doc)
        notes = layout.main[0]
        assert "computing…" in notes[0].object and notes[0].object == SKELETON
        assert not _built_in(layout) and len(layout.main[1]) == 0  # the tabs are empty
        state._on_load(doc)
        assert not _built_in(layout), gone
        assert "computing…" in notes[0].object


def test_a_connected_client_gets_its_dashboard_built_into_the_frame(job_pool):
    """With a connection open, the on-load message builds the dashboard into the frame sent:
    the same template, its tabs filled, the note replaced; a client leaving during the build
    (its session destroyed before the views are made) stops it, and frees its session."""
    doc, ctx, layout = _page(1)
    assert not client_gone(doc) and not _built_in(layout)
    state._on_load(doc)
    built = _built_in(layout)
    assert len(built) == 1
    dash = built[0]
    assert [t for t in dash.tabs._names] == ["Explorer", "Maps", "Gearbox"]
    assert all("computing…" not in getattr(o, "object", "") for o in layout.main[0])
    assert dash.present.header is layout.header[0]
    dash.destroy()

    doc, ctx, layout = _page(1)
    left = []

    def leave(*_):  # the client goes once the first run is done
        ctx._session.connection_count = 0
        left.append(True)
    from app import session as session_module
    original = session_module.Session.__init__

    def init(self, *a, **kw):
        original(self, *a, **kw)
        leave()
    session_module.Session.__init__ = init
    try:
        state._on_load(doc)
    finally:
        session_module.Session.__init__ = original
    assert left and not _built_in(layout) and len(layout.main[1]) == 0


def test_a_build_that_fails_says_so_where_computing_was(job_pool, monkeypatch):
    """A dashboard that raises while built leaves the page saying it could not be built, with
    the error, instead of "computing…" for ever."""
    import app.main as main

    def broken(*args, **kwargs):
        raise RuntimeError("no run")
    monkeypatch.setattr(main, "Dashboard", broken)
    doc, ctx, layout = _page(1)
    state._on_load(doc)
    text = layout.main[0][0].object
    assert "computing…" not in text and "could not be built" in text and "no run" in text


def test_a_build_that_fails_after_its_client_left_logs_no_error(job_pool, monkeypatch, caplog):
    """A build torn down under it (its client gone) is not a server error: it logs one line at
    info, and no traceback; with the client still there the same failure is logged as an error."""
    import logging

    import app.main as main
    for leaves in (True, False):
        doc, ctx, layout = _page(1)

        def broken(*args, **kwargs):
            if leaves:
                ctx._session.connection_count = 0
            raise RuntimeError("torn down")
        monkeypatch.setattr(main, "Dashboard", broken)
        caplog.clear()
        with caplog.at_level(logging.INFO, logger="app"):
            state._on_load(doc)
        errors = [r for r in caplog.records if r.levelno >= logging.ERROR or r.exc_info]
        if leaves:
            assert errors == []
            assert any("went away" in r.getMessage() and "torn down" in r.getMessage()
                       for r in caplog.records)
        else:
            assert [r.getMessage() for r in errors] == ["building a page failed"]
