"""The atlas on the Maps tab: the exact bifurcation curves drawn over the regime map.

:class:`AtlasView` adds a DynamicMap to the map's plot (``MapsView.add_overlay``). "Draw the
atlas" sets ``state.atlas`` (in the URL); while it is set, each regime map shown gets its
curves for the map's two axes and window, physical ones included: the session's ``atlas``
job runs :func:`app.work.atlas.atlas_curves` in a worker process (progress, cancel, killed
with the session, disk-cached, so a reopened link redraws from the cache). Each kind of curve
has its own line style (``rattle_core``'s ``CURVE_STYLES``), listed in the legend below the
buttons; the codimension-two points are marked, their messages on hover.
"""
from __future__ import annotations

import html
from typing import Any

import holoviews as hv
import numpy as np
import panel as pn
import param

from ..core import CURVE_STYLES, axes_supported
from ..state import ExplorerState
from ..ui.job_panel import JobPanel
from ..ui.widgets import message
from ..work.atlas import Curves, atlas_curves, from_job, to_core
from .continuation import _named

#: A path of one blank point: Bokeh reports an error for a line glyph with no coordinates.
_BLANK = np.full((1, 2), np.nan)
_SVG_DASH = {"solid": "", "dashed": "6,4", "dotdash": "2,3,6,3", "dotted": "2,3"}


def curves_overlay(curves: Curves | None, prefix: str = "atlas") -> hv.Overlay:
    """One Path per kind of curve (blank when absent) and the codimension-two points; the
    glyphs are named ``{prefix}-{kind}`` and ``{prefix}-codim2``."""
    kdims = [hv.Dimension("x"), hv.Dimension("y")]
    items = []
    for kind, st in CURVE_STYLES.items():
        paths = curves.paths.get(kind, []) if curves is not None else []
        items.append(hv.Path(paths or [_BLANK], kdims).opts(
            color=st.colour, line_dash=st.dash, line_width=2.5, framewise=False,
            hooks=[_named(f"{prefix}-{kind}")]))
    marks = curves.codim2 if curves is not None and len(curves.codim2) else None
    data = (marks[["x", "y", "label", "message"]] if marks is not None else
            {"x": [np.nan], "y": [np.nan], "label": [""], "message": [""]})
    items.append(hv.Points(data, kdims, ["label", "message"]).opts(
        color="black", fill_color="white", size=9, marker="diamond", line_width=1.5,
        tools=["hover"], framewise=False, hooks=[_named(f"{prefix}-codim2")]))
    return hv.Overlay(items)


def legend_html() -> str:
    """The line style of each kind of curve, as small SVG samples and escaped labels."""
    rows = []
    for st in CURVE_STYLES.values():
        dash = _SVG_DASH.get(st.dash, "")
        rows.append(f'<span style="white-space:nowrap;margin-right:12px"><svg width="34" '
                    f'height="10"><line x1="0" y1="5" x2="34" y2="5" stroke="{st.colour}" '
                    f'stroke-width="3" stroke-dasharray="{dash}"/></svg> '
                    f'{html.escape(st.label)}</span>')
    rows.append('<span style="white-space:nowrap">◇ where two curves meet (hover for what)</span>')
    return f'<div style="font-size:12px;color:#333">{" ".join(rows)}</div>'


class AtlasView(pn.viewable.Viewer):
    """"Draw the atlas" over the Maps tab's regime map; see the module docstring."""

    state = param.ClassSelector(class_=ExplorerState)
    jobs = param.Parameter()
    maps = param.Parameter(doc="the Maps tab's view, whose plot the curves are drawn over")
    revision = param.Integer(0)

    def __init__(self, **params: Any):
        super().__init__(**params)
        self.curves: Curves | None = None
        self.run = JobPanel(self.jobs, "atlas", "atlas")
        self.draw_button = pn.widgets.Button(label="Draw the atlas", color="primary",
                                             css_classes=["atlas-draw"], width=150)
        self.hide_button = pn.widgets.Button(label="Hide the atlas", width=120,
                                             css_classes=["atlas-hide"])
        self.draw_button.on_click(lambda e: self.draw())
        self.hide_button.on_click(lambda e: self.state.param.update(atlas=False))
        self.run.cancel_button.on_click(lambda e: self.cancel("Atlas cancelled."))
        self.legend = pn.pane.HTML(legend_html(), css_classes=["atlas-legend"],
                                   sizing_mode="stretch_width")
        self.element = hv.DynamicMap(self._element, streams=[hv.streams.Params(self, ["revision"])])
        self.maps.add_overlay(self.element)
        self.maps.param.watch(self._update, "revision")
        self.state.param.watch(self._update, ["atlas"])
        self._update()

    def __panel__(self):
        return pn.Column(pn.Row(self.draw_button, self.hide_button, self.run.cancel_button),
                         message(self.state, "atlas"), self.run.progress, self.run.status,
                         self.legend, sizing_mode="stretch_width", css_classes=["atlas"])

    def draw(self) -> None:
        """The button: draw the atlas over the map shown (and over the maps to come)."""
        r = self.maps.result
        if r is None or r.kind != "regime":
            self.state.say("atlas", "The atlas is drawn over a regime map: compute one first.")
            return
        self.state.clear("atlas")
        if self.state.atlas:
            self._update()
        else:
            self.state.atlas = True

    def request(self) -> tuple | None:
        """What the atlas of the map shown depends on; None (with a message) if it cannot run."""
        s, r, run = self.state, self.maps.result, self.state.result
        if r is None or r.kind != "regime" or run is None:
            return None
        why = axes_supported(r.x_name, r.y_name)
        if why:
            s.say("atlas", why[0].upper() + why[1:] + ".")
            return None
        phys = run.phys if {r.x_name, r.y_name} & {"rpm", "drag_torque"} else None
        if phys is None and {r.x_name, r.y_name} & {"rpm", "drag_torque"}:
            s.say("atlas", "This map has physical axes: turn the physical units on.")
            return None
        xr = to_core(r.x_name, s.phases, float(np.min(r.x_values)), float(np.max(r.x_values)))
        yr = to_core(r.y_name, s.phases, float(np.min(r.y_values)), float(np.max(r.y_values)))
        return (r.params, phys, r.x_name, xr, r.y_name, yr, s.phases)

    def _update(self, *_: Any) -> None:
        s = self.state
        self.hide_button.visible = bool(s.atlas)
        if not s.atlas:
            if self.run.key is not None or self.curves is not None:
                self._drop()
            return
        req = self.request()
        if req is None:
            return
        key = (repr(req[0].canonical()), repr(req[1]), *req[2:])
        if key == self.run.key:
            return
        s.clear("atlas")
        self.run.submit(key, atlas_curves, req[:6],
                        f"Following the bifurcation curves over {req[2]} × {req[4]}…", 300.0,
                        lambda out: self._done(out, req), self._error)

    def _done(self, out: dict, req: tuple) -> None:
        self.curves = from_job(out, req[6], req[2], req[4])
        self.run.say("Atlas: " + self.curves.summary())
        self.revision += 1

    def _error(self, msg: str) -> None:
        self.state.say("atlas", f"The atlas could not be drawn: {msg}")

    def cancel(self, text: str | None = None) -> None:
        """Stop the running atlas job; what was drawn before stays hidden."""
        self._drop(text)
        self.state.param.update(atlas=False)

    def _drop(self, text: str | None = None) -> None:
        self.run.stop(text)
        self.curves = None
        self.revision += 1

    def _element(self, revision: int = 0) -> hv.Overlay:
        return curves_overlay(self.curves)
