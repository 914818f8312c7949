"""The time history x(t) between the teeth: the one view drawn with Bokeh directly, not HoloViews.

Why Bokeh here: every slider move redraws this plot, and its picture needs eight layers (two
teeth, two walls, the gear, impacts on each flank, stick phases). As a HoloViews
``DynamicMap`` overlay, one redraw cost about 80 ms of server CPU on the project's 2-core
machine (about 10 ms per layer: element construction, option lookup, range computation,
glyph update), which with the section, the diagram marker and the badge took a slider move
to about 290 ms, twice the 150 ms budget (``benchmarks/bench_app.py``). Here the figure is
built once per session and a redraw replaces the data of its ``ColumnDataSource``s: about
8 ms. The section and the diagram stay HoloViews elements.

The ranges are ``DataRange1d``: they follow the data until the user zooms, and the reset tool
returns to the data. A zoom is kept across redraws while the axes keep their meaning, so a
Λ sweep can be watched inside one window of time; when the time span of the data changes
(an engine-speed change in physical units rescales the forcing period, or the periods shown
change) or the units change, the old window means nothing and the plot frames the new data. In physical-units mode the axes
are ms and µm (or degrees of the idle gear). The title holds the parameters, so a saved PNG
carries them, and the save tool's file name does too. Each flank's impacts are a legend
entry of their own, in their own colour.

A pinned run (``state.pinned_result``, A) is drawn as its gear's trace alone, dashed in a
muted colour, over the live run (B); the legend then names the two gears A and B. In physical
units A is drawn only when it has a physical side of its own (a run pinned in that mode, on the
page or from its link); on a dimensionless page A is drawn dimensionless.
"""
from __future__ import annotations

from typing import Any

import numpy as np
import panel as pn
import param
from bokeh.core.properties import value
from bokeh.models import (ColumnDataSource, DataRange1d, HoverTool, Legend, LegendItem, SaveTool,
                          Span)
from bokeh.plotting import figure

from ..state import ExplorerState
from ..ui.labels import (ACTIVE_COLOR, GEAR_COLOR, MARK_COLOR, PIN_COLOR, REVERSE_COLOR,
                         STICK_COLOR, TOOTH_COLOR)
from ..ui.present import figure_fonts, presents, stretch
from ..work.threads import writes_bokeh
from ..ui.plots import caption, file_stem, full_screen, name_saved_png, time_history_data

#: The figure's height; while presenting it fills its cell of the Explorer's grid.
HEIGHT = 330
MOTION = ("t", "x", "y", "yj", "tooth_lo", "tooth_hi")
IMPACTS = ("t", "x", "impulse")
#: The gear's legend entry, alone and beside a pinned run; and the pinned run's.
GEAR_LABEL, GEAR_LABEL_B, PINNED_LABEL = "gear x(t)", "B (live): gear x(t)", "A (pinned): gear x(t)"


def time_history_figure() -> tuple[Any, dict[str, ColumnDataSource]]:
    """The figure and its data sources (``motion``, ``active``, ``reverse``, ``stick``,
    ``pinned``)."""
    src = {"motion": ColumnDataSource({k: [] for k in MOTION}, name="th_motion"),
           "active": ColumnDataSource({k: [] for k in IMPACTS}, name="th_active"),
           "reverse": ColumnDataSource({k: [] for k in IMPACTS}, name="th_reverse"),
           "stick": ColumnDataSource({"xs": [], "ys": []}, name="th_stick"),
           "pinned": ColumnDataSource({"t": [], "x": []}, name="th_pinned")}
    p = figure(height=HEIGHT, sizing_mode="stretch_width", tools="pan,wheel_zoom,box_zoom,reset",
               active_scroll="wheel_zoom", x_range=DataRange1d(), y_range=DataRange1d(),
               output_backend="canvas", name="time_history")
    p.add_tools(SaveTool(filename="rattle_time.png"))
    full_screen(p)
    m = src["motion"]
    teeth_a = p.varea(x="t", y1="tooth_lo", y2="y", source=m, fill_color=TOOTH_COLOR, fill_alpha=0.55)
    teeth_r = p.varea(x="t", y1="yj", y2="tooth_hi", source=m, fill_color=TOOTH_COLOR, fill_alpha=0.55)
    wall_a = p.line("t", "y", source=m, color="#5d6d7e", line_width=1.5)
    wall_r = p.line("t", "yj", source=m, color="#5d6d7e", line_width=1.5, line_dash="dashed")
    pinned = p.line("t", "x", source=src["pinned"], color=PIN_COLOR, line_width=1.8,
                    line_dash="dashed", line_alpha=0.9, name="th_pinned_gear")
    gear = p.line("t", "x", source=m, color=GEAR_COLOR, line_width=1.8)
    stick = p.multi_line("xs", "ys", source=src["stick"], color=STICK_COLOR, line_width=6,
                         line_alpha=0.8)
    act = p.scatter("t", "x", source=src["active"], color=ACTIVE_COLOR, size=7, line_color="white")
    rev = p.scatter("t", "x", source=src["reverse"], color=REVERSE_COLOR, size=7, line_color="white")
    p.add_tools(HoverTool(renderers=[act, rev], tooltips=[("t", "@t{0.000}"), ("impulse", "@impulse{0.0000}")]))
    legend = Legend(items=[LegendItem(label=GEAR_LABEL, renderers=[gear], name="th_legend_gear"),
                           LegendItem(label=PINNED_LABEL, renderers=[pinned], visible=False,
                                      name="th_legend_pinned"),
                           LegendItem(label="active tooth y(t)", renderers=[wall_a, teeth_a]),
                           LegendItem(label="reverse tooth y(t) + j", renderers=[wall_r, teeth_r]),
                           LegendItem(label="impact, active flank", renderers=[act]),
                           LegendItem(label="impact, reverse flank", renderers=[rev]),
                           LegendItem(label="permanent contact", renderers=[stick])],
                    location="top_left", click_policy="hide", background_fill_alpha=0.7)
    p.add_layout(legend, "right")
    # the gear-in-motion view's clock moves it in the page (app.views.motion); on the overlay
    # layer, a move repaints the cursor alone, not the plot's thousands of points
    p.add_layout(Span(location=None, dimension="height", line_color=MARK_COLOR, line_width=2,
                      line_alpha=0.8, name="th_cursor", visible=False,
                      level="overlay"))
    return p, src


class TimeHistoryView(pn.viewable.Viewer):
    """x(t) between the teeth of the current run (see the module docstring)."""

    state = param.ClassSelector(class_=ExplorerState)

    def __init__(self, **params: Any):
        super().__init__(**params)
        self.fig, self.sources = time_history_figure()
        self.pane = pn.pane.Bokeh(self.fig, sizing_mode="stretch_width", css_classes=["time-history"])
        #: What the current ranges were framed for: the axis labels and the data's time span.
        self._frame: tuple | None = None
        self.state.param.watch(self.draw, ["result", "shown", "backlash_unit", "pinned_result"])
        self.state.param.watch(self._present, ["present", "stage"])
        self.draw()
        self._present()

    def __panel__(self):
        return self.pane

    @writes_bokeh
    def _present(self, *_: Any) -> None:
        """Presentation mode: a figure as large as its cell, larger fonts."""
        on = presents(self.state, "time_history")
        figure_fonts(self.fig, on)
        # beside a figure half the page wide, the legend goes below it, in two columns
        legend = self.fig.legend[0]
        side, other = ("below", "right") if on else ("right", "below")
        if legend not in getattr(self.fig, side):
            setattr(self.fig, other, [m for m in getattr(self.fig, other) if m is not legend])
            setattr(self.fig, side, [*getattr(self.fig, side), legend])
            legend.ncols = 2 if on else 1
        # while presenting, as high as its cell in the Explorer's grid (the window's height);
        # set on the figure, not the pane: the pane would copy the figure's stylesheets back
        # into its own parameters, which take only strings
        stretch(self.fig, on)

    @writes_bokeh
    def draw(self, *_: Any) -> None:
        run = self.state.result
        if run is None:
            return
        tr = run.tr
        data = time_history_data(tr, min(self.state.shown, int(tr.periods)), run.phys,
                                 angle=self.state.backlash_unit == "deg")
        self.sources["motion"].data = data["motion"]
        imp = data["impacts"]
        for key, sel in (("active", imp["flank"] > 0), ("reverse", imp["flank"] < 0)):
            self.sources[key].data = {k: np.asarray(imp[k])[sel] for k in IMPACTS}
        self.sources["stick"].data = {"xs": [s[0] for s in data["stick"]],
                                      "ys": [s[1] for s in data["stick"]]}
        self._draw_pinned(run)
        xl, yl, _ = data["labels"]
        t = np.asarray(data["motion"]["t"])
        # the span to 9 digits: a Λ change at fixed speed redraws the same times
        span = (float(f"{t[0]:.9g}"), float(f"{t[-1]:.9g}")) if t.size else (0.0, 0.0)
        frame = (xl, yl, span)
        if self._frame != frame:
            if self._frame is not None:
                self.fig.x_range, self.fig.y_range = DataRange1d(), DataRange1d()
            self._frame = frame
            self.fig.xaxis.axis_label, self.fig.yaxis.axis_label = xl, yl
        title = f"Time history · {caption(run)}"
        if self.fig.title.text != title:
            self.fig.title.text = title
        name_saved_png(self.fig, file_stem(run, "time"))

    def pinned_trace(self, run: Any) -> dict[str, np.ndarray] | None:
        """A's gear trace ``{t, x}`` in the axes of the live run ``run``, or None when there is
        no pin (or, in physical units, A has no physical side to scale it by)."""
        a = self.state.pinned_result
        if a is None or (run.phys is not None and a.phys is None):
            return None
        phys = a.phys if run.phys is not None else None
        data = time_history_data(a.tr, min(self.state.shown, int(a.tr.periods)), phys,
                                 angle=self.state.backlash_unit == "deg")
        return {"t": data["motion"]["t"], "x": data["motion"]["x"]}

    def _draw_pinned(self, run: Any) -> None:
        trace = self.pinned_trace(run)
        self.sources["pinned"].data = trace or {"t": [], "x": []}
        gear, pinned = self.fig.legend[0].items[:2]
        label = GEAR_LABEL if trace is None else GEAR_LABEL_B
        if gear.label != value(label):  # a plain string would be read as a column's name
            gear.label = value(label)
        pinned.visible = trace is not None
