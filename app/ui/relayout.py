"""One layout of the page per frame of server updates, not one per changed property.

A redraw or a switch of presentation mode changes tens of properties (sizes, visibility,
fonts, data). Bokeh's server sends each change as a message of its own, and BokehJS lays out
and repaints the whole page for every layout property it applies: presenting the diagram took
57 layouts of the page, 11 s of the browser's time on a two-core machine, for one click.

:data:`ONE_LAYOUT_JS`, run in the page when its document is ready (:func:`install`), makes
BokehJS lay a page out once per animation frame for all the server's messages that arrived
before it: while a message is applied, a layout asked of a page's root is noted, and done at
the next frame, before the browser paints. Layouts asked for otherwise (a resize, a click in
the page) are done at once, as before. It leaves BokehJS as it is if the functions it wraps
are not there.

The server's messages stay one per change: a message that the page cannot apply (one that
names a model the page no longer holds, as a plot replaced meanwhile) fails alone, and the
changes after it still arrive.
"""
from __future__ import annotations

from typing import Any

#: Wraps ``Document.apply_json_patch``: a layout that a root view asks for while a message is
#: applied is done once, at the next animation frame.
ONE_LAYOUT_JS = """
let layout_dom, document_module;
try {
  layout_dom = Bokeh.require("models/layouts/layout_dom");
  document_module = Bokeh.require("document/document");
} catch (e) {
  return;
}
const LayoutDOMView = layout_dom.LayoutDOMView;
const Document = document_module.Document;
if (LayoutDOMView == null || Document == null) return;
const view = LayoutDOMView.prototype, doc = Document.prototype;
if (view.__one_layout_per_frame || typeof view.invalidate_layout !== "function"
    || typeof doc.apply_json_patch !== "function") return;
const invalidate = view.invalidate_layout, apply = doc.apply_json_patch;
let applying = false;
const due = new Set();  // the roots whose layout waits for the next frame
const lay_out = () => {
  const roots = [...due];
  due.clear();
  for (const root of roots) {
    if (root.el != null && root.el.isConnected) invalidate.call(root);
  }
};
view.invalidate_layout = function () {
  if (applying && !(this.parent instanceof LayoutDOMView)) {
    if (due.size == 0) requestAnimationFrame(lay_out);
    due.add(this);
    return;
  }
  return invalidate.call(this);
};
doc.apply_json_patch = function (...args) {
  const was = applying;
  applying = true;
  try {
    return apply.apply(this, args);
  } finally {
    applying = was;
  }
};
view.__one_layout_per_frame = true;
"""


def install(doc: Any) -> None:
    """Run :data:`ONE_LAYOUT_JS` in ``doc``'s page once the page has its document."""
    from bokeh.models import CustomJS

    doc.js_on_event("document_ready", CustomJS(code=ONE_LAYOUT_JS))
