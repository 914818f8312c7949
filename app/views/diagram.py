"""The bifurcation diagram: impulses against Λ, φ₂ or (physical units) engine speed.

A ``pn.viewable.Viewer`` over the state. The diagram's sweep comes from the shipped assets,
the disk cache, or a background job (:class:`app.session.SessionJobs`); it is recomputed
only when a parameter other than the swept one changes, while the current-value marker
follows every run. The x-range is the whole range asked for, stretched to hold the current
value, so the marker, the rattle-free range, the onset of rattle (Λ_c) and the first chaotic
value are on the plot, marked and labelled. Impacts are shaded by flank with datashader
(:mod:`app.ui.shading`, once for every session); a zoom recomputes the visible region finer
(a ``RangeXY`` stream), and a click (a ``Tap`` stream) sets the swept parameter. In physical units the
diagram runs against engine speed and shows impulses in N·s.

The current-value marker is hand-written Bokeh: a ``Span`` added to the HoloViews figure,
whose location each run sets. As a layer of the HoloViews overlay it cost a
redraw of the whole overlay (about 30 ms of server CPU: range computation over the raster and
option handling), a fifth of the slider budget, to move one line. A pinned run's value (A)
gets a dashed line beside it, both named A and B (:class:`app.ui.plots.PinMarkers`). The
continued branch is hand-written Bokeh too (:class:`app.ui.branch_glyphs.BranchGlyphs`),
so a page's plot build holds its lock for the raster and the marks only.
"""
from __future__ import annotations

import weakref
from typing import Any

import holoviews as hv
import numpy as np
import panel as pn
import param
from bokeh.models import Span, WheelZoomTool

from ..work import tasks
from ..work.diagram_data import (RECORD, TRANSIENT, ZOOM_VALUES, Diagram, current_value,
                                 diagram_key, from_work, marks, one_sided, request, run_value,
                                 shipped)
from ..ui.branch_glyphs import BranchGlyphs
from ..ui.labels import CHAOS_COLOR, MARK_COLOR, ONSET_COLOR, num
from ..ui.plots import (TOOLS, HoloViewsPane, PinMarkers, Zoom, caption, file_stem, padded,
                        save_as, weak_hook)
from ..state import ExplorerState
from ..work.threads import later, writes_bokeh
from ..ui.present import figure_fonts, presents, stretch
from ..ui.shading import PIXELS, shaded
from ..ui.widgets import Choice, deferred, message, set_value
from .present import present_button

OPTIONS = {"Ĩ vs Λ": "lam", "Ĩ vs φ₂": "phi2"}
UNITS_OPTIONS = {"I vs engine speed": "rpm", "Ĩ vs φ₂": "phi2"}
AXES = {"lam": "Λ", "phi2-paper": "φ₂ [°], the paper's convention (Figure 6)",
        "phi2-core": "φ₂ [°], the core's convention", "rpm": "engine speed [rpm]"}


class DiagramView(pn.viewable.Viewer):
    """Ĩ against the swept parameter, computed in the background; see the module docstring."""

    state = param.ClassSelector(class_=ExplorerState)
    jobs = param.Parameter()
    revision = param.Integer(0, doc="bumped when new diagram data arrive")
    marks_revision = param.Integer(0, doc="bumped when the marks move (new data, or Λ for φ₂)")

    def __init__(self, **params: Any):
        super().__init__(**params)
        self.diagram: Diagram | None = None
        self._key: tuple | None = None
        self._name = "lam"
        self._span_x = (0.5, 4.0)
        self._stem = "rattle_diagram"
        self._title = "Bifurcation diagram"
        self._timer = None
        self._lam = None
        self.zoom = Zoom(on_reset=self._redraw)
        self.range = hv.streams.RangeXY()
        self.points = hv.DynamicMap(self._points, streams=[hv.streams.Params(self, ["revision"]),
                                                           self.range])
        self.range.add_subscriber(self.zoom._ranged, precedence=-1)
        self.range.add_subscriber(self._on_range)
        hv.streams.PlotReset(source=self.points).add_subscriber(self.zoom._reset)
        self.marks = hv.DynamicMap(self._marks, streams=[
            hv.streams.Params(self.state, ["overlays"]), hv.streams.Params(self, ["marks_revision"])])
        self.branch = BranchGlyphs()
        self._span: Any = lambda: None
        self.pins = PinMarkers()
        self.tap = hv.streams.Tap(source=self.points)
        self.tap.add_subscriber(self._on_tap)
        s = self.state
        self.choice = Choice(s, "bif", UNITS_OPTIONS if s.units else OPTIONS, sizing_mode="stretch_width")
        self.overlays = Choice(s, "overlays", label="overlays: contact boundary Λ_c and 2πn/Λ")
        self.progress = pn.indicators.Progress(value=0, max=100, visible=False, bar_color="info",
                                               sizing_mode="stretch_width", height=14,
                                               css_classes=["bif-progress"])
        self.status = pn.pane.HTML("", css_classes=["bif-status"], margin=(0, 10),
                                   sizing_mode="stretch_width")
        plot = (self.points * self.marks).opts(
            hv.opts.Overlay(responsive=True, height=380, hooks=[weak_hook(self._name_plot)]),
            hv.opts.RGB(tools=[*TOOLS, "tap"], active_tools=["wheel_zoom"]))
        self.pane = HoloViewsPane(plot, sizing_mode="stretch_width", min_height=380,
                                      css_classes=["diagram"])
        self.present_button = present_button(s, "diagram")
        self.layout = pn.Column(
            pn.Row(self.choice, self.overlays, self.present_button, sizing_mode="stretch_width"),
            message(self.state, "bif"), self.progress, self.status, deferred(self.pane),
            sizing_mode="stretch_width")
        s.param.watch(self._present, ["present", "stage"])
        s.param.watch(self._update, ["result", "bif", "phases"])
        s.param.watch(self._move_marker, ["result", "pinned_result"])
        s.param.watch(self._draw_branch, "branch")
        self.param.watch(self._draw_branch, "marks_revision")
        s.param.watch(self._on_units, "units")
        if s.units and s.bif == "lam":  # in physical units Λ runs as engine speed
            s.bif = "rpm"
        self._update()
        self._present()

    def __panel__(self):
        return self.layout

    def _present(self, *_: Any) -> None:
        """Presented, the diagram is as high as its cell (the window's height below the badge);
        the figure's fonts and sizing follow in the hook (:meth:`_name_plot`)."""
        mode = "stretch_both" if presents(self.state, "diagram") else "stretch_width"
        for part in (self.layout, self.layout[-1], self.pane):
            part.sizing_mode = mode
        self.marks_revision += 1

    # ----- what to show -------------------------------------------------------------------------

    def swept(self) -> str:
        """The diagram shown: ``state.bif``, but Λ while the physical side is not available."""
        run = self.state.result
        return "lam" if self.state.bif == "rpm" and (run is None or run.phys is None) else self.state.bif

    def _update(self, *_: Any) -> None:
        run = self.state.result
        if run is None:
            return
        name = self.swept()
        key = diagram_key(name, self.state.phases, run.params, run.phys)
        value = current_value(name, self.state)
        lo, hi = self._span_x
        if key == self._key and lo <= value <= hi:
            if name == "phi2" and self._lam != run.params.lam:  # the 2πn/Λ lines move with Λ
                self._lam = run.params.lam
                self.marks_revision += 1
            return
        self._lam = run.params.lam
        self._key, self._name = key, name
        self.diagram = None
        self.zoom.user = False
        self._title = f"Bifurcation diagram · {caption(run, name)}"
        self._stem = file_stem(run, f"diagram-{name}")
        req = request(name, self.state, run)
        self._span_x = (min(req.axis), max(req.axis))
        self._start(req, merge=False)

    def _start(self, req: Any, merge: bool) -> None:
        found = None if merge else shipped(req)
        if found is not None:
            self._set(found)
            return
        if not merge:  # the old diagram is for other parameters: clear it
            self.revision += 1
            self.marks_revision += 1
        base, name, values = req.sweep_args()
        key = self._key
        what = "the zoomed region" if merge else "the diagram"
        self.status.object = _text(f"Computing {what}: {len(values)} values in the background…")
        self.progress.param.update(value=0, visible=True)
        try:
            self.jobs.submit("diagram", tasks.diagram, (base, name, values, TRANSIENT, RECORD),
                             time_limit=60.0,
                             on_progress=lambda f: self._progress(key, f),
                             on_done=lambda out: self._done(key, req, out, merge),
                             on_error=lambda msg: self._error(key, msg))
        except RuntimeError as exc:
            self._error(key, str(exc))

    def _progress(self, key: tuple, fraction: float) -> None:
        if key == self._key:
            self.progress.value = int(100 * fraction)

    def _done(self, key: tuple, req: Any, out: dict, merge: bool) -> None:
        if key != self._key:
            return
        self.progress.visible = False
        new = from_work(req, out, "read from the disk cache" if out.get("from_cache") else "computed")
        self._set(self.diagram.merge(new) if merge and self.diagram is not None else new)

    def _error(self, key: tuple, msg: str) -> None:
        if key != self._key:
            return
        self.progress.visible = False
        self.status.object = ""
        self.state.say("bif", f"The diagram could not be computed: {msg}")

    def _set(self, diagram: Diagram) -> None:
        self.state.clear("bif")
        self.status.object = _text(diagram.counts())
        self.diagram = diagram
        self.revision += 1
        self.marks_revision += 1

    # ----- elements -----------------------------------------------------------------------------

    @property
    def span(self) -> tuple[float, float]:
        """The x-range of the diagram asked for (axis units)."""
        return self._span_x

    @property
    def marker(self) -> float | None:
        """Where the current-value marker stands on the page (None before the plot is drawn)."""
        span = self._span()
        return None if span is None else span.location

    def axes(self) -> tuple[str, str]:
        """The axis labels of the diagram shown."""
        return self._axis()

    def _axis(self) -> tuple[str, str]:
        name = self._name
        x = AXES["phi2-" + self.state.phases] if name == "phi2" else AXES[name]
        y = "impulse I [N·s, along the line of action]" if name == "rpm" else "impulse Ĩ"
        return x, y

    def _limits(self) -> tuple[tuple[float, float], tuple[float, float]]:
        d = self.diagram
        y = padded(d.impulse) if d is not None and d.impulse.size else (-10.0, 10.0)
        return self._span_x, y

    def _points(self, revision: int = 0, x_range: Any = None, y_range: Any = None) -> hv.RGB:
        xlim, ylim = self._limits()
        xr, yr = xlim, ylim
        if self.zoom.user and x_range is not None and y_range is not None and None not in (*x_range, *y_range):
            xr, yr = tuple(x_range), tuple(y_range)
        xl, yl = self._axis()
        kdims = [hv.Dimension("x", label=xl), hv.Dimension("y", label=yl)]
        d = self.diagram
        w, h = PIXELS
        if d is None or not d.x.size:  # nothing to shade (yet): a transparent image
            rgb = hv.RGB(np.zeros((h, w, 4), dtype=np.uint8), kdims,
                         bounds=(xr[0], yr[0], xr[1], yr[1]))
            return self.zoom.apply(rgb, xlim, ylim)
        return self.zoom.apply(shaded(d, kdims, xr, yr), xlim, ylim)

    def _marker_at(self) -> float:
        return current_value(self._name, self.state) if self.state.result is not None else self._span_x[0]

    @writes_bokeh
    def _move_marker(self, *_: Any) -> None:
        """The current value moves with every run: one Bokeh property, not a HoloViews redraw."""
        span = self._span()
        if span is not None:
            span.location = self._marker_at()
        self.pins.place(self._pinned_at(), self._marker_at())

    def _pinned_at(self) -> float | None:
        """A's value on this diagram's axis (None without a pin, or A without rpm)."""
        a = self.state.pinned_result
        return None if a is None else run_value(self._name, a, self.state.phases)

    def _marks(self, overlays: bool = True, marks_revision: int = 0) -> hv.Overlay:
        """Where rattle starts and chaos first appears (labelled), and the 2πn/Λ curves."""
        result = self.state.result
        xlim, ylim = self._limits()
        name = self._name
        kdims = [hv.Dimension("x"), hv.Dimension("y")]
        m = marks(name, result, self.diagram) if result is not None else {"onset": None, "chaos": None}
        lines, labels = [], []
        for key, color, row in (("onset", ONSET_COLOR, 0.04), ("chaos", CHAOS_COLOR, 0.12)):
            x, shown = m[key], []
            if x is not None and (overlays or key == "chaos"):
                lines.append((x, ylim[0], x, ylim[1], color))
                shown = [mark_label(key, name, x, xlim, ylim[1] - row * (ylim[1] - ylim[0]))]
            # one label layer per mark, each in its own colour, always there: the overlay keeps
            # its structure, and no colour column is looked for in an empty label set
            align = shown[0][3] if shown else "left"
            labels.append(hv.Labels([r[:3] for r in shown], kdims, ["text"]).opts(
                text_color=color, text_align=align, text_baseline="middle",
                text_font_size="13pt" if presents(self.state, "diagram") else "9pt"))
        segs = hv.Segments(lines, kdims + ["x1", "y1"], ["color"]).opts(
            color="color", line_width=2, line_dash="dashed")
        text = labels[0] * labels[1]
        curves = one_sided(name, result, *xlim) if (overlays and result is not None) else []
        paths = hv.Path(curves or [np.empty((0, 2))], kdims).opts(
            color="#27ae60", line_width=1.5, line_dash="dotted")
        return self.zoom.apply(segs * text * paths, xlim, ylim)

    def _branch_drawn(self, *_: Any) -> None:
        """The continued branch (``state.branch``), drawn by :class:`~app.ui.branch_glyphs.BranchGlyphs`
        (as :meth:`_draw_branch` when a change of the branch or the marks calls it, outside
        HoloViews' own write of the figure)."""
        self.branch.draw(self.state.branch, self._name, self._limits(),
                         large=presents(self.state, "diagram"))

    _draw_branch = writes_bokeh(_branch_drawn)

    def _name_plot(self, plot: Any, element: Any) -> None:
        """Title (the parameters, so a saved PNG carries them) and the save tool's file name."""
        plot.state.name = "bifurcation"
        if self._span() is None or self._span() not in plot.state.center:
            span = Span(location=self._marker_at(), dimension="height", line_color=MARK_COLOR,
                        line_width=2, name="current_value")
            plot.state.add_layout(span)
            self._span = weakref.ref(span)
        self.pins.attach(plot.state, self._pinned_at(), self._marker_at())
        if self.branch.attach(plot.state):  # inside HoloViews' own write of the figure
            self._branch_drawn()
        if plot.state.title.text != self._title:
            plot.state.title.text = self._title
        figure_fonts(plot.state, presents(self.state, "diagram"), title="9pt")
        stretch(plot.state, presents(self.state, "diagram"))
        for tool in plot.state.toolbar.tools:
            if isinstance(tool, WheelZoomTool) and tool.dimensions != "width":
                tool.dimensions = "width"  # the swept axis only: a zoom in impulse soon shows nothing
        save_as(lambda: self._stem)(plot, element)

    def _redraw(self) -> None:
        self.revision += 1
        self.marks_revision += 1

    # ----- interaction --------------------------------------------------------------------------

    def _on_tap(self, x: float | None = None, y: float | None = None, **_: Any) -> None:
        if x is not None:
            later(self.set_swept, float(x))

    def set_swept(self, x: float) -> None:
        """Set the swept parameter to ``x`` (a click on the diagram)."""
        name = self._name
        if name == "rpm":
            set_value(self.state, "rpm", round(float(x), 1))
        elif name == "phi2":
            set_value(self.state, "phi2", round(float(x), 2))
        else:
            set_value(self.state, "lam", round(float(x), 4))

    def _on_range(self, x_range: Any = None, y_range: Any = None, **_: Any) -> None:
        if not self.zoom.user or x_range is None or None in x_range:
            return
        doc = pn.state.curdoc
        if doc is None or doc.session_context is None:
            self.refine(*x_range)
            return
        if self._timer is not None:
            try:
                doc.remove_timeout_callback(self._timer)
            except ValueError:
                pass
        lo, hi = x_range
        self._timer = doc.add_timeout_callback(lambda: self.refine(lo, hi), 600)

    def refine(self, lo: float, hi: float) -> bool:
        """Recompute the visible part ``[lo, hi]`` of the diagram finer, if zoomed in enough."""
        self._timer = None
        d, run = self.diagram, self.state.result
        if d is None or run is None:
            return False
        full_lo, full_hi = d.span
        lo, hi = max(lo, full_lo), min(hi, full_hi)
        if hi <= lo or (hi - lo) > 0.6 * (full_hi - full_lo):
            return False
        if any(a <= lo and hi <= b for a, b in d.refined):
            return False
        if np.count_nonzero((d.swept >= lo) & (d.swept <= hi)) >= 0.8 * ZOOM_VALUES:
            return False
        self._start(request(self._name, self.state, run, lo, hi, ZOOM_VALUES), merge=True)
        return True

    def _on_units(self, event) -> None:
        s = self.state
        if event.new and s.bif == "lam":
            s.bif = "rpm"
        elif not event.new and s.bif == "rpm":
            s.bif = "lam"
        self.choice.widget.options = UNITS_OPTIONS if event.new else OPTIONS


def _text(text: str) -> str:
    import html
    return f'<div style="font-size:12px;color:#444">{html.escape(text)}</div>'


def mark_label(key: str, name: str, x: float, xlim: tuple[float, float],
               y: float) -> tuple[float, float, str, str]:
    """``(x, y, text, align)`` of the label of a diagram mark at ``x``, inside the view.

    The text names the value in the axis's own unit; a mark near the right edge is labelled to
    its left, and a mark left of the view is labelled at the left edge, pointing to it.
    """
    what = "rattle starts" if key == "onset" else "first chaos"
    value = {"lam": f"Λ = {num(x, 4)}", "rpm": f"{num(x, 5)} rpm",
             "phi2": f"φ₂ = {num(x, 4)}°"}[name]
    if key == "onset" and name == "lam":
        value = f"Λ_c = {num(x, 4)}"
    lo, hi = xlim
    if x < lo:
        return lo, y, f" ← {what} ({value})", "left"
    if x > hi:
        return hi, y, f"{what} ({value}) → ", "right"
    if x > lo + 0.6 * (hi - lo):
        return x, y, f"{what} ({value}) ", "right"
    return x, y, f" {what} ({value})", "left"
