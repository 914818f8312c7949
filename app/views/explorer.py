"""The Explorer tab's views of the current run: the section, the regime badge and the metrics.

Each is a ``pn.viewable.Viewer`` that draws ``state.result`` (and the view settings it
needs) and writes only to the state: a click on the section starts the gear there by setting
``x0``, ``v0``, ``t0``. The plots are HoloViews ``DynamicMap``s whose layers keep their
structure from one run to the next, so an update replaces glyph data and nothing else. The
section's dense clouds are rasterised and spread with datashader (HoloViews ``datashade``
and ``dynspread``) over the range shown, which follows the data until the user zooms
(:class:`app.ui.plots.Zoom`); a zoom re-rasterises at the new range. The time history is in
:mod:`app.views.time_history`. A pinned run (``state.pinned_result``, A) has its section
drawn beside the live run's (B), in its own colour and marker, and the legend names both.
"""
from __future__ import annotations

import html
import math
from typing import Any

import holoviews as hv
import numpy as np
import panel as pn
import param
from holoviews.operation.datashader import datashade, dynspread

from ..core import batch_means, excitation
from ..ui.help import HELP, tooltip
from ..ui.labels import (MARK_COLOR, PIN_COLOR, badge_html, metrics_rows, regime_legend_html, table_html,
                         what_you_see)
from ..ui.present import PANE_CSS, figure_fonts, mark, presents, stretch
from ..ui.plots import (TOOLS, HoloViewsPane, Zoom, caption, file_stem, padded, save_as,
                    section_points, weak_hook)
from ..state import ExplorerState
from ..work.threads import later
from ..ui.widgets import Choice, deferred, message

SECTION_OPTIONS = {"Poincaré (x, ẋ)": "absolute", "relative (x−y, ẋ−ẏ)": "relative",
                   "impact map": "impact"}
SECTION_PIXELS = (480, 320)
#: Words of the diagrams explained on hover beside the legend (keys of :data:`app.ui.help.HELP`).
WORDS = ("multipliers", "pd", "grazing", "sticking")
#: The section figure's height, and its least; while presenting it fills its cell of the
#: Explorer's grid.
SECTION_HEIGHT = 380
#: Above this many points the section is rasterised instead of drawn as glyphs.
DENSE = 5000
#: Legend entries of the live run's and the pinned run's points.
LIVE_LABEL, PINNED_LABEL = "B (live)", "A (pinned)"


class SectionView(pn.viewable.Viewer):
    """Poincaré (absolute or relative) or impact map; a click starts the gear at that point.

    Three layers: a datashader raster of dense clouds (re-rasterised at the range shown after
    a zoom), the points as glyphs (up to :data:`DENSE` of them) and the start point. The raster
    is a ``DynamicMap`` of its own, redrawn only when a dense cloud changes or the view zooms.
    """

    state = param.ClassSelector(class_=ExplorerState)
    revision = param.Integer(0)
    dense_revision = param.Integer(0)

    def __init__(self, **params: Any):
        super().__init__(**params)
        self._xy = (np.zeros(0), np.zeros(0))
        self._pinned_xy = (np.zeros(0), np.zeros(0))
        self._dense: tuple[np.ndarray, np.ndarray] | None = None
        self._kdims = [hv.Dimension("x"), hv.Dimension("y", label="ẋ")]
        self._lims = ((-1.0, 1.0), (-1.0, 1.0))
        self._stem, self._title = "rattle_section", "Poincaré map"
        self.zoom = Zoom(on_reset=self._redraw)
        self.range = hv.streams.RangeXY()
        self.sparse = hv.DynamicMap(self._sparse, streams=[hv.streams.Params(self, ["revision"])])
        self.dense = hv.DynamicMap(self._raster, streams=[hv.streams.Params(self, ["dense_revision"]),
                                                          self.range])
        self.range.add_subscriber(self.zoom._ranged, precedence=-1)
        plot = (self.dense * self.sparse).opts(
            hv.opts.Overlay(responsive=True, height=SECTION_HEIGHT, hooks=[weak_hook(self._name_plot)]),
            hv.opts.Points(tools=[*TOOLS, "tap"], active_tools=["wheel_zoom"]))
        # HoloViews links a stream to the figure through the overlay's first layer (a source
        # on the glyph layer, whose output is an overlay, is never linked: clicks were lost)
        hv.streams.PlotReset(source=self.dense).add_subscriber(self.zoom._reset)
        self.tap = hv.streams.Tap(source=self.dense)
        self.tap.add_subscriber(self._on_tap)
        self.mode = Choice(self.state, "section", SECTION_OPTIONS, sizing_mode="stretch_width")
        self.msg = message(self.state, "start")
        self.pane = HoloViewsPane(plot, sizing_mode="stretch_width", min_height=SECTION_HEIGHT,
                                  css_classes=["section"])
        self.state.param.watch(self._update, ["result", "section", "pinned_result"])
        # drawn once the page has loaded, so the first plot (the time history) comes sooner
        self.layout = pn.Column(self.mode, self.msg, deferred(self.pane), sizing_mode="stretch_width")
        self.state.param.watch(self._present, ["present", "stage"])
        self._update()
        self._present()

    def __panel__(self):
        return self.layout

    def _present(self, *_: Any) -> None:
        """While presenting, the section and what holds it are as high as their cell in the
        Explorer's grid; the figure follows from the hook (:meth:`_name_plot`)."""
        mode = "stretch_both" if presents(self.state, "section") else "stretch_width"
        for part in (self.layout, self.layout[2], self.pane):
            part.sizing_mode = mode
        self._redraw()

    @property
    def points(self) -> tuple[np.ndarray, np.ndarray]:
        """The section's points as drawn (glyphs, or the raster's cloud)."""
        return self._dense if self._dense is not None else self._xy

    def _update(self, *_: Any) -> None:
        run = self.state.result
        if run is None:
            return
        section = self.state.section
        x, y, xl, yl = section_points(run.tr, section)
        self._kdims = [hv.Dimension("x", label=xl), hv.Dimension("y", label=yl)]
        self._pinned_xy = self.pinned_points(section)
        ax, ay = self._pinned_xy
        self._lims = (padded(np.concatenate([x, ax])), padded(np.concatenate([y, ay])))
        self.zoom.user = False  # a new run frames its data; a zoom holds only while it stays
        theta = f"θ = {self.state.strobe:g}°"
        title = {"absolute": f"Poincaré map (x, ẋ) at {theta}",
                 "relative": f"Relative Poincaré map at {theta}",
                 "impact": "Impact map: impulse against impact phase"}[section]
        self._title = f"{title} · {caption(run)}"
        self._stem = file_stem(run, f"section-{section}")
        dense = len(x) > DENSE
        if dense or self._dense is not None:
            self._dense = (x, y) if dense else None
            self.dense_revision += 1
        self._xy = (np.zeros(0), np.zeros(0)) if dense else (x, y)
        self.revision += 1

    def pinned_points(self, section: str | None = None) -> tuple[np.ndarray, np.ndarray]:
        """A's section points as drawn: its last :data:`DENSE` points (glyphs, not a raster, so
        they stay a legend entry of their own), none without a pin."""
        a = self.state.pinned_result
        if a is None:
            return np.zeros(0), np.zeros(0)
        x, y, _, _ = section_points(a.tr, section or self.state.section)
        return np.asarray(x)[-DENSE:], np.asarray(y)[-DENSE:]

    def _redraw(self) -> None:
        self.revision += 1
        self.dense_revision += 1

    def _sparse(self, revision: int = 0) -> hv.Overlay:
        """The points as glyphs, and the start point (both follow every run)."""
        s, run = self.state, self.state.result
        point = None if run is None else self._start_point(run, s.section, s.x0, s.v0, s.t0)
        marker = hv.Points([point] if point else [], self._kdims).opts(
            marker="x", size=14, line_width=3, color=MARK_COLOR)
        cloud = hv.Points(self._xy, self._kdims, label=LIVE_LABEL).opts(
            size=7 if presents(s, "section") else 4, color="#1f5fa8", alpha=0.8)
        pinned = hv.Points(self._pinned_xy, self._kdims, label=PINNED_LABEL).opts(
            marker="triangle", size=9 if presents(s, "section") else 6, color=PIN_COLOR, alpha=0.75)
        return self.zoom.apply(pinned * cloud * marker, *self._lims)

    def _raster(self, dense_revision: int = 0, x_range: Any = None, y_range: Any = None) -> hv.RGB:
        xr, yr = self._lims
        if self.zoom.user and x_range is not None and y_range is not None and None not in (*x_range, *y_range):
            xr, yr = tuple(x_range), tuple(y_range)
        x, y = self._dense if self._dense is not None else (np.zeros(0), np.zeros(0))
        w, h = SECTION_PIXELS
        rgb = dynspread(datashade(hv.Points((x, y), self._kdims), cmap=["#4a90c8", "#08306b"],
                                  cnorm="eq_hist", min_alpha=140, x_range=xr, y_range=yr,
                                  width=w, height=h, dynamic=False),
                        max_px=2, threshold=0.6, dynamic=False)
        return self.zoom.apply(rgb, *self._lims)

    def _name_plot(self, plot: Any, element: Any) -> None:
        """Title (the parameters, so a saved PNG carries them) and the save tool's file name."""
        plot.state.name = "section"
        shown = self.state.pinned_result is not None  # the legend names A and B, with a pin only
        corner = free_corner(np.concatenate([self.points[0], self._pinned_xy[0]]),
                             np.concatenate([self.points[1], self._pinned_xy[1]]), *self._lims)
        for legend in plot.state.legend:
            if legend.visible != shown:
                legend.visible = shown
            if legend.location != corner:  # where it hides none of the points, or the fewest
                legend.location = corner
        if not self.zoom.user:
            # HoloViews keeps an overlay's first ranges when its layers' limits change
            # (and Bokeh's reset tool returns to the ranges a figure was built with)
            fig, ((x0, x1), (y0, y1)) = plot.state, self._lims
            if (fig.x_range.start, fig.x_range.end, fig.y_range.start, fig.y_range.end) != (x0, x1, y0, y1):
                fig.x_range.update(start=x0, end=x1, reset_start=x0, reset_end=x1)
                fig.y_range.update(start=y0, end=y1, reset_start=y0, reset_end=y1)
        if plot.state.title.text != self._title:
            plot.state.title.text = self._title
        figure_fonts(plot.state, presents(self.state, "section"), title="9pt")
        stretch(plot.state, presents(self.state, "section"))
        save_as(lambda: self._stem)(plot, element)

    @staticmethod
    def _start_point(run: Any, section: str, x0: Any, v0: float, t0: float):
        if section == "impact" or x0 is None:
            return None
        sx, sv = float(x0), float(v0)
        if section == "relative":
            p = run.params
            sx -= float(excitation(t0, p.h, p.phi))
            sv -= float(excitation(t0, p.h, p.phi, 1))
        return (sx, sv)

    def _on_tap(self, x: float | None = None, y: float | None = None, **_: Any) -> None:
        if x is not None and y is not None:
            later(start_from_section, self.state, x, y)


def free_corner(x: np.ndarray, y: np.ndarray, xlim: tuple[float, float],
                ylim: tuple[float, float]) -> str:
    """The corner of the view (Bokeh's ``"top_right"``, …) whose third of each axis holds the
    fewest of the points ``x, y``; the top right on a tie."""
    (x0, x1), (y0, y1) = xlim, ylim
    fx = (np.asarray(x, float) - x0) / max(x1 - x0, 1e-300)
    fy = (np.asarray(y, float) - y0) / max(y1 - y0, 1e-300)
    count = {f"{v}_{h}": int(np.sum((fy > 2 / 3 if v == "top" else fy < 1 / 3)
                                    & (fx > 2 / 3 if h == "right" else fx < 1 / 3)))
             for v in ("top", "bottom") for h in ("right", "left")}
    return min(count, key=lambda k: count[k])  # dicts keep order: top_right wins a tie


def start_from_section(state: ExplorerState, x: float, y: float) -> bool:
    """Start the gear at a clicked section point: (x₀, ẋ₀) at t₀ = the strobe phase; with the
    twin trajectory on and a start already clicked, the twin's start."""
    run = state.result
    if run is None:
        return False
    if state.section == "impact":
        state.say("start", "Switch to a Poincaré map to start the gear from a clicked point.")
        return False
    t0 = math.radians(state.strobe)
    p = run.params
    y0 = float(excitation(t0, p.h, p.phi))
    x0, v0 = float(x), float(y)
    if state.section == "relative":
        x0 += y0
        v0 += float(excitation(t0, p.h, p.phi, 1))
    if not y0 <= x0 <= y0 + p.j:
        state.say("start", f"x₀ = {x0:.4g} is outside the backlash [{y0:.4g}, {y0 + p.j:.4g}] "
                           f"at t₀ = {t0:.4g}: click between the teeth.")
        return False
    state.clear("start")
    if state.twin and state.x0 is not None and abs(state.t0 - round(t0, 12)) < 1e-9:
        # a second click, with the twin on: the twin starts there, beside the first gear
        state.param.update(twin_x0=round(x0, 10), twin_v0=round(v0, 10))
        return True
    state.param.update(x0=round(x0, 10), v0=round(v0, 10), t0=round(t0, 12))
    return True


class RegimeView(pn.viewable.Viewer):
    """The regime badge, what the regime looks like, the legend of every regime, hover help
    for the words of the diagrams, and the rattle metrics (in SI units in physical-units
    mode)."""

    state = param.ClassSelector(class_=ExplorerState)

    def __init__(self, **params: Any):
        super().__init__(**params)
        self.badge = pn.pane.HTML("", css_classes=["regime-badge"], sizing_mode="stretch_width",
                                  min_width=260, stylesheets=[PANE_CSS])
        self.seen = pn.pane.HTML("", css_classes=["regime-seen-pane"], sizing_mode="stretch_width",
                                 stylesheets=[PANE_CSS], margin=(0, 10))
        self.legend = pn.pane.HTML(regime_legend_html(), css_classes=["regime-legend-pane"],
                                   sizing_mode="stretch_width", stylesheets=[PANE_CSS],
                                   margin=(0, 10))
        self.words = pn.Row(*[part for key in WORDS for part in (
            pn.pane.HTML(f"<span style='font-size:12px'>{html.escape(HELP[key][0])}</span>",
                         margin=(0, 0, 0, 10)), tooltip(key))], css_classes=["help-words"])
        # a fixed width, so a long value (an interval, SI units) wraps instead of squeezing the
        # badge beside it
        self.metrics = pn.pane.HTML("", css_classes=["rattle-metrics"], width=430,
                                    styles={"white-space": "normal"}, stylesheets=[PANE_CSS])
        self.state.param.watch(self._draw, "result")
        self.state.param.watch(self._present, "present")
        self._draw()
        self._present()

    def __panel__(self):
        return pn.Row(pn.Column(self.badge, self.seen, self.legend, self.words,
                                sizing_mode="stretch_width", margin=0),
                      self.metrics, sizing_mode="stretch_width")

    def _draw(self, *_: Any) -> None:
        run = self.state.result
        if run is None:
            return
        self.badge.object = badge_html(run.cls)
        self.seen.object = (f'<div class="regime-seen" style="font-size:13px">'
                            f'{html.escape(what_you_see(run.cls))}</div>')
        self.metrics.object = table_html(
            metrics_rows(run.cls, run.tr, run.phys, batch_means(run.tr, run.cls)), "rattle-metrics")

    def _present(self, *_: Any) -> None:
        on = self.state.present
        mark([self.badge, self.seen, self.legend, self.metrics], on)
        # a lecture needs the regime and its legend; the metrics and word help stay on the page
        self.metrics.visible = self.words.visible = not on
