"""A script payload in any one URL key reaches no place where the browser reads HTML.

Each key, alone, carries the payload into a session of its own, built as the server builds
one: the dashboard in a Bokeh document, with its Explorer, Maps and Gearbox tabs each drawn
in turn (the tabs are built when opened, so a browser that stays on the first one never sees
the other two). Every string the document holds for the browser is then read as the browser
would read it as HTML (Panel's HTML panes send their text escaped once, which the browser
undoes before setting it), and no ``<img>``, ``<script>``, ``<svg>`` or ``<iframe>`` tag, nor
any ``on…`` handler attribute, may appear in it. The payload may be shown, as text.

The browser tests (``test_ui_security.py``) open a page with every key holding a payload at
once and check there that no dialog opens and the messages show the payload as text.
"""
from __future__ import annotations

import html
import urllib.parse
from html.parser import HTMLParser

import numpy as np
import panel as pn
import pytest
from bokeh.document import Document

from app.dashboard import TABS
from conftest import new_dashboard
from app.state import URL_KEYS

#: Fifty sessions built and drawn in one process take minutes.
pytestmark = pytest.mark.long

#: Markup that runs script when a browser parses it as HTML (the browser tests use all three).
PAYLOADS = ("<img src=x onerror=alert(document.domain)>", "<script>alert(42)</script>",
            "\"><svg onload=alert(7)>")
PAYLOAD = PAYLOADS[0]
#: Every key of the Explorer's state, two of the other tabs' keys, and a key that is itself a
#: payload (an unknown key is named in the URL's message).
KEYS = [*URL_KEYS.values(), "map_x_axis", "gb_variant", "<img src=x onerror=alert(1)>"]


class _Markup(HTMLParser):
    """The tags and handler attributes that would run script, as the browser parses them."""

    ACTIVE = {"img", "script", "svg", "iframe", "object", "embed"}

    def __init__(self) -> None:
        super().__init__()
        self.active: list[str] = []

    def handle_starttag(self, tag, attrs):
        handlers = [a for a, _ in attrs if a.lower().startswith("on")]
        if tag in self.ACTIVE or handlers:
            self.active.append(f"<{tag} {' '.join(handlers)}>")


def _strings(value, path: str):
    if isinstance(value, str):
        yield path, value
    elif isinstance(value, np.ndarray) and value.dtype.kind in "OUS":
        for i, x in enumerate(value.ravel().tolist()):
            yield from _strings(x, f"{path}[{i}]")
    elif isinstance(value, (list, tuple)):
        for i, x in enumerate(value):
            yield from _strings(x, f"{path}[{i}]")
    elif isinstance(value, dict):
        for k, x in value.items():
            yield from _strings(k, f"{path} key")
            yield from _strings(x, f"{path}[{k!r}]")


def active_markup(doc: Document) -> list[str]:
    """Each property of ``doc``'s models that holds markup the browser would run."""
    found = []
    for model in list(doc.models):
        panel_model = type(model).__module__.startswith("panel.")
        for name, value in model.properties_with_values(include_defaults=False).items():
            for path, text in _strings(value, name):
                if "alert(" not in text:  # the payloads' own; the page's markup is not checked here
                    continue
                parser = _Markup()
                # Panel sends an HTML pane's text escaped, and its page unescapes it
                parser.feed(html.unescape(text) if panel_model else text)
                if parser.active:
                    found.append(f"{type(model).__name__}.{path}: {parser.active}")
    return found


@pytest.fixture(scope="module")
def built(job_pool):
    """A function: the session that ``search`` opens, in a document, with each tab drawn in
    turn; returns what :func:`active_markup` found."""
    def build(search: str) -> list[str]:
        doc = Document()
        dash = new_dashboard(job_pool, search, doc=doc)
        try:
            dash.shell.layout.server_doc(doc)
            found: list[str] = []
            for tab in TABS:
                dash.state.tab = tab
                found += active_markup(doc)
            return found
        finally:
            dash.destroy()
    return build


def test_the_check_finds_markup_that_would_run():
    """An HTML pane given the payload raw is found, and the same pane given it escaped is not."""
    for text, expected in ((PAYLOAD, 1), (html.escape(PAYLOAD), 0)):
        doc = Document()
        pn.Column(pn.pane.HTML(text), pn.widgets.TextInput(value="x")).server_doc(doc)
        assert len(active_markup(doc)) == expected, text


@pytest.mark.parametrize("key", KEYS)
def test_a_payload_in_any_one_key_reaches_no_html(built, key):
    assert built("?" + urllib.parse.urlencode({key: PAYLOAD})) == [], key
