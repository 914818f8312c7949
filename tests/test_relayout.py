"""The page is given the script that lays it out once per frame of server changes (app.ui.relayout).

What the script does in the browser, fewer layouts of the page, is checked in a browser by
``test_ui_present_this.py``, which counts the page's layouts while a view is presented.
"""
from __future__ import annotations

from bokeh.document import Document

from app.ui import relayout


def test_the_page_is_given_the_one_layout_script_when_its_document_is_ready():
    doc = Document()
    relayout.install(doc)
    sent = dict(doc.to_json(deferred=False)["callbacks"]["entries"])  # what the page receives
    assert [cb["attributes"]["code"] for cb in sent["document_ready"]] == [relayout.ONE_LAYOUT_JS]
