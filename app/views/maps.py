"""The Maps tab: regime and intensity maps over two parameters, and basins of attraction.

A ``pn.viewable.Viewer`` over the state and the session's map request (:class:`MapSettings`:
axes, ranges, points, periods, the field shown), whose bounds validate them; the request is
in the URL beside the state, so a link opened on the Maps tab reopens its map
(:meth:`MapsView.open_link`). Compute runs :func:`rattle_core.store.requests.run_map` as this
session's ``map`` job (:mod:`app.work.jobs`): in a worker process, bounded in time, cancelled
by Cancel, by a new request and when the session ends, from the disk cache when it ran before. Maps run on the server's cores, or on the
Dask scheduler given on the server's command line (``rattle serve --scheduler``,
:func:`app.work.map_plan.set_scheduler`); no page can choose where the server connects.

The map is a HoloViews ``Image`` whose colours follow the field shown: the regime colours for
regimes, a log colour bar for the rattle intensity, a linear one for the other quantities.
It takes the width the controls leave, and goes below them where that is too little.
A click (``Tap`` stream) sets the state to the clicked grid point (on physical axes, the
engine speed and drag torque themselves, so Λ and j follow exactly); on a basin map it starts
the gear there at t = 0. In physical units the default axes are engine speed and drag torque.
"""
from __future__ import annotations

import functools
import io
import math
import weakref
from typing import Any

import holoviews as hv
import numpy as np
import panel as pn
import param

from ..work import tasks
from ..core import excitation, paper_phi2_to_core, plan_map
from ..state import ExplorerState, MapSettings
from ..work.map_plan import (AXES, FIELDS, PHYSICAL, RANGES, axis_label, grid_refusal,
                             request_key, scheduler)
from ..work.threads import later, plot_lock
from ..ui.job_panel import JobPanel
from ..ui.labels import map_colours, map_key, map_legend, text_html
from ..ui.plots import TOOLS, HoloViewsPane, caption, file_stem, key_legend, save_as
from ..ui.present import figure_fonts, presents, stretch
from ..ui.widgets import Choice, Field, message
from .present import present_button

MAP_HEIGHT, MAP_MIN_WIDTH = 520, 420  # its width: what the controls leave, or below them

class MapsView(pn.viewable.Viewer):
    """The Maps tab of one session."""

    state = param.ClassSelector(class_=ExplorerState)
    jobs = param.Parameter()
    settings = param.ClassSelector(class_=MapSettings, default=None,
                                   doc="the request (the session's, in the URL; a new one if None)")
    revision = param.Integer(0)

    def __init__(self, **params: Any):
        super().__init__(**params)
        if self.settings is None:
            self.settings = MapSettings()
        m = self.settings
        self.result: Any = None
        self._figure = lambda: None
        self._generation = 0
        self._stem, self.overlays = "rattle_map", []  # overlays: other views' (add_overlay)
        m.param.watch(self._on_axis, ["x_axis", "y_axis"])
        m.param.watch(self._on_kind, "kind")
        self.state.param.watch(self._on_units, "units")
        self.state.param.watch(self._on_result, "result")
        self.compute_button = pn.widgets.Button(label="Compute", color="primary",
                                                css_classes=["map-compute"], sizing_mode="stretch_width")
        # the map's job: its progress, Cancel and status (``map-progress``, ``-cancel``, ``-status``)
        self.run = JobPanel(self.jobs, "map", "map")
        self.cancel_button, self.progress, self.status = (self.run.cancel_button, self.run.progress,
                                                          self.run.status)
        self.cancel_button.sizing_mode = "stretch_width"
        self.compute_button.on_click(lambda e: self.compute())
        self.cancel_button.on_click(lambda e: self.cancel("Cancelled."))
        self.run.say("No map yet: choose the axes and press Compute.")
        self.legend = pn.pane.HTML("", css_classes=["map-legend"], sizing_mode="stretch_width")
        self.download = pn.widgets.FileDownload(callback=self.csv, filename="map.csv", label="Map as CSV",
                                                color="success", disabled=True,
                                                css_classes=["map-download"], sizing_mode="stretch_width")
        self.pane = HoloViewsPane(self._plot(), css_classes=["map-plot"], sizing_mode="stretch_width")
        # a new colour scale (regimes, log intensity, linear) needs a plot of its own
        m.param.watch(lambda e: setattr(self.pane, "object", self._plot()), "field")
        self._choices = {n: Choice(m, n, {axis_label(a): a for a in self._axes()}, select=True,
                                   sizing_mode="stretch_width") for n in ("x_axis", "y_axis")}
        self._field = Choice(m, "field", self._fields(), select=True, width=300)
        self.layout = None
        self.present_button = present_button(self.state, "maps")
        self.state.param.watch(self._present, ["present", "stage"])
        default = (m.param.x_axis.default, m.param.y_axis.default)
        if self.state.units and m.kind == "regime" and (m.x_axis, m.y_axis) == default:
            # in physical units: engine speed and drag torque (unless the link chose other axes)
            self._set_axes("rpm", "drag_torque")
        for a in ("x", "y"):  # a link naming an axis but not its range: the axis's own range
            start, stop = f"{a}_start", f"{a}_stop"
            if ((getattr(m, f"{a}_axis") != m.param[f"{a}_axis"].default)
                    and (getattr(m, start), getattr(m, stop)) == (m.param[start].default, m.param[stop].default)):
                lo, hi = self._range(getattr(m, f"{a}_axis"))
                m.param.update({start: lo, stop: hi})

    def __panel__(self):
        m = self.settings

        def axis(a: str) -> pn.Column:
            return pn.Column(self._choices[f"{a}_axis"],
                             pn.Row(Field(m, f"{a}_start", label="from", slider=False, css=f"map-{a}-start"),
                                    Field(m, f"{a}_stop", label="to", slider=False, css=f"map-{a}-stop"),
                                    Field(m, f"{a}_num", label="points", slider=False, css=f"map-{a}-num"),
                                    sizing_mode="stretch_width"),
                             message(self.state, f"map-{a}"), sizing_mode="stretch_width", margin=0)
        where = (f"Maps run on the Dask scheduler {scheduler()} (set when the server started)."
                 if scheduler() else "Maps run on this server's cores.")
        controls = pn.Column(
            Choice(m, "kind", {"Regimes over two parameters": "regime", "Basins over (x₀, ẋ₀)": "basin"},
                   sizing_mode="stretch_width"),
            axis("x"), axis("y"),
            pn.Row(Field(m, "transient", slider=False, css="map-transient"),
                   Field(m, "record", slider=False, css="map-record"),
                   sizing_mode="stretch_width"),
            pn.Row(self.compute_button, self.cancel_button, sizing_mode="stretch_width"),
            message(self.state, "map-run"), self.progress, self.status,
            pn.pane.HTML(text_html(where, "font-size:12px;color:#555"), css_classes=["map-where"]),
            self.download, self.legend, width=440, margin=(0, 10))
        self.controls, self.map_column = controls, pn.Column(
            pn.Row(self._field, self.present_button), self.pane, sizing_mode="stretch_width",
            min_width=MAP_MIN_WIDTH)
        self.layout = pn.FlexBox(controls, self.map_column, flex_wrap="wrap", sizing_mode="stretch_width")
        self._present()
        return self.layout

    def _present(self, *_: Any) -> None:
        """Presented, the map alone takes the window below the header, with larger fonts."""
        if getattr(self, "layout", None) is None:
            return
        on = presents(self.state, "maps")
        self.controls.visible = not on
        for part in (self.layout, self.map_column, self.pane):
            part.sizing_mode = "stretch_both" if on else "stretch_width"
        self.revision += 1  # the hook sets the figure's fonts and sizing

    # ----- axes -------------------------------------------------------------------------------

    def _axes(self) -> list[str]:
        if self.settings.kind == "basin":
            return ["x0", "v0"]
        return [a for a in AXES if self.state.units or a not in PHYSICAL]

    def _range(self, name: str) -> tuple[float, float]:
        s = self.state
        if name == "phi2" and s.phases == "core":
            return (-180.0, 180.0)
        if name == "drag_torque":
            return (float(f"{s.drag_torque / 4:.3g}"), float(f"{s.drag_torque * 4:.3g}"))
        if name == "x0" and s.result is not None:
            p = s.result.params
            y0 = float(excitation(0.0, p.h, p.phi))
            return (round(y0, 10), round(y0 + p.j, 10))
        return RANGES.get(name, (0.0, 1.0))

    def _on_axis(self, *events) -> None:
        for event in events:
            a = event.name[0]
            lo, hi = self._range(event.new)
            self.settings.param.update({f"{a}_start": lo, f"{a}_stop": hi})
            self.state.clear(f"map-{a}")

    def _set_axes(self, x: str, y: str) -> None:
        for n, v in (("x_axis", x), ("y_axis", y)):
            self._choices[n].widget.options = {axis_label(a): a for a in self._axes()}
        self.settings.param.update(x_axis=x, y_axis=y)

    def _on_kind(self, event) -> None:
        basin = event.new == "basin"
        self._set_axes(*(("x0", "v0") if basin else ("lam", "phi2")))
        self._field.widget.options = self._fields()
        self.settings.field = "attractor" if basin else "regime"

    def _fields(self) -> dict[str, str]:
        """The fields a map of the settings' kind can show (label → field)."""
        fields = {v: k for k, v in FIELDS.items()}
        return {"attractor reached": "attractor", **fields} if self.settings.kind == "basin" else fields

    def _on_units(self, event) -> None:
        if self.settings.kind == "regime":
            self._set_axes(*(("rpm", "drag_torque") if event.new else ("lam", "phi2")))

    # ----- requests -----------------------------------------------------------------------------

    def request(self) -> dict | None:
        """The map the settings ask for, checked; None (with messages shown) if it cannot run."""
        m, s = self.settings, self.state
        s.clear("map-x", "map-y", "map-run")
        axes = {}
        for a in ("x", "y"):
            lo, hi, n = getattr(m, f"{a}_start"), getattr(m, f"{a}_stop"), getattr(m, f"{a}_num")
            if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
                s.say(f"map-{a}", f"{a} axis: 'from' ({lo:g}) must be below 'to' ({hi:g}).")
                return None
            # grid values people read (and a click puts in the URL): 12 significant digits
            axes[a] = np.array([float(f"{v:.12g}") for v in np.linspace(lo, hi, n)])
        xv, yv = axes["x"], axes["y"]
        refusal = grid_refusal(xv.size, yv.size, m.transient + m.record)
        if refusal:
            s.say("map-run", refusal)
            return None
        run = s.result
        core = {a: (paper_phi2_to_core(v) if name == "phi2" and s.phases == "paper" else v)
                for a, name, v in (("x", m.x_axis, xv), ("y", m.y_axis, yv))}
        try:
            plan = plan_map(run.params, run.phys, m.x_axis, core["x"], m.y_axis, core["y"])
        except ValueError as exc:
            text = str(exc)
            s.say("map-y" if text.startswith("y axis") else "map-x" if text.startswith("x axis")
                  else "map-run", text)
            return None
        return {"run": run, "params": run.params, "phys": run.phys, "x_name": m.x_axis, "y_name": m.y_axis,
                "x_values": xv, "y_values": yv, "core": core, "plan": plan,
                "transient": m.transient, "record": m.record, "key": request_key(run.params, plan)}

    def compute(self, req: dict | None = None, cached_only: bool = False) -> bool:
        """Start the map the settings ask for (it replaces the one running); with
        ``cached_only``, only read it from the disk cache (``_not_cached`` says a miss)."""
        req = req or self.request()
        if req is None:
            return False
        n = req["x_values"].size * req["y_values"].size
        where = f"on Dask ({scheduler()})" if scheduler() else "on this server's cores"
        args = (req["params"], req["phys"], req["x_name"], req["core"]["x"], req["y_name"],
                req["core"]["y"], req["transient"], req["record"], scheduler(), cached_only)
        text = ("Looking for this map in the disk cache…" if cached_only else
                f"Computing {req['x_values'].size} × {req['y_values'].size} = {n} points {where}…")
        self.run.submit(req["key"], tasks.regime_map, args, text, 300.0,
                        on_done=lambda r: self._done(req, r) if r is not None else self._not_cached(req),
                        on_error=self._error)
        return self.run.key is not None

    @property
    def job(self) -> Any:
        """The map's job while it is queued or running."""
        return self.run.job

    def open_link(self) -> None:
        """The page opened on the Maps tab: compute the link's map if it is no heavier than the
        default map; a heavier one is only read from the disk cache, or waits for Compute, so
        that a link cannot make the server work minutes for each visitor."""
        if self.state.result is None:  # the first run is still in a worker: once it is in
            def once(event) -> None:
                if event.new is not None:
                    self.state.param.unwatch(watcher)
                    self.open_link()
            watcher = self.state.param.watch(once, "result")
            return
        req = self.request()
        if req is None:
            self.run.say("This link's map cannot run: see the message above.")
            return
        m = MapSettings
        light = (m.param.x_num.default * m.param.y_num.default
                 * (m.param.transient.default + m.param.record.default))
        nx, ny = req["x_values"].size, req["y_values"].size
        periods = req["transient"] + req["record"]
        self.compute(req, cached_only=nx * ny * periods > light)

    def _not_cached(self, req: dict) -> None:
        """A heavy link's map is not in the disk cache: it waits for Compute."""
        nx, ny = req["x_values"].size, req["y_values"].size
        self.run.say(
            f"This link asks for a map of {nx} × {ny} = {nx * ny} points over "
            f"{req['transient'] + req['record']} periods each, more than a link computes by itself "
            "and not in the disk cache: press Compute to run it.")

    def cancel(self, text: str | None = None) -> None:
        """Stop the map's job (``text``, if given, replaces the status)."""
        self.run.stop(text)

    def _error(self, msg: str) -> None:
        self.run.say("No new map: see the message above.")
        self.state.say("map-run", f"The map could not be computed: {msg}")

    def _done(self, req: dict, result: Any) -> None:
        result.x_values, result.y_values = req["x_values"], req["y_values"]
        self.result, self._shown = result, req
        self.download.param.update(disabled=False, filename=file_stem(self.state.result, f"map-{req['x_name']}-{req['y_name']}") + ".csv")
        self.revision += 1
        self._on_result()

    # ----- drawing ------------------------------------------------------------------------------

    def _plot(self) -> Any:
        """The map and the current point, with a click stream (one per colour scale)."""
        with plot_lock():
            return self._build_plot()

    def _build_plot(self) -> Any:
        self.image = hv.DynamicMap(self._image, streams=[hv.streams.Params(self, ["revision"])])
        self.marker = hv.DynamicMap(self._marker, streams=[hv.streams.Params(self.state, ["result"]),
                                                           hv.streams.Params(self, ["revision"])])
        ref = weakref.ref(self)
        self.tap = hv.streams.Tap(source=self.image)
        self.tap.add_subscriber(lambda x=None, y=None, **_: ref() and later(ref().select_point, x, y))
        old = self._figure()
        if old is not None:  # the page's map is the new plot's
            old.name = None
        self._generation += 1
        generation = self._generation

        def name_plot(plot: Any, element: Any) -> None:
            me = ref()
            if me is not None and me._generation == generation:
                plot.state.name = "map_figure"
                figure_fonts(plot.state, presents(me.state, "maps"), title="9pt")
                stretch(plot.state, presents(me.state, "maps"))
                me._figure = weakref.ref(plot.state)
                save_as(lambda: me._stem)(plot, element)
                key_legend(plot.state, map_key(me.result, me.settings.field))
        return functools.reduce(lambda a, b: a * b, self.overlays, self.image * self.marker).opts(
            hv.opts.Overlay(responsive=True, height=MAP_HEIGHT, hooks=[name_plot]))

    def add_overlay(self, element: Any) -> None:
        """Draw ``element`` (a DynamicMap of another view) over the map from now on."""
        self.overlays.append(element)
        self.pane.object = self._plot()

    def image_element(self, revision: int = 0) -> hv.Image:
        """The map as the page draws it, for the field shown."""
        return self._image(revision)

    def _image(self, revision: int = 0) -> hv.Image:
        r, field = self.result, self.settings.field
        if r is None:  # nothing yet: an invisible image (NaN ones warn at every range computed)
            return hv.Image(np.zeros((2, 2)), bounds=(0, 0, 1, 1)).opts(
                colorbar=False, framewise=True, alpha=0)
        if field not in r.fields:
            field = "attractor" if r.kind == "basin" else "regime"
        z = np.asarray(r.fields[field], dtype=np.float64).copy()
        if field in ("regime", "attractor"):
            z[z < 0] = np.nan
        if field == "intensity":
            z[~(z > 0)] = np.nan  # no impacts: blank, as the log colour scale needs
        f = r.fields
        vd = [hv.Dimension(field, label=FIELDS.get(field, "attractor")), "regime_code", "period",
              "intensity_", "lyapunov_"]
        img = hv.Image((r.x_values, r.y_values, z, np.asarray(f["regime"], dtype=np.float64),
                        f["period"], f["intensity"], f["lyapunov"]),
                       [hv.Dimension("x", label=AXES.get(r.x_name, r.x_name)),
                        hv.Dimension("y", label=AXES.get(r.y_name, r.y_name))], vd)
        run = self._shown["run"]
        self._stem = file_stem(run, f"map-{r.x_name}-{r.y_name}-{field}")
        title = f"{FIELDS.get(field, 'attractor reached')} · {caption(run)}"
        opts = {"clipping_colors": {"NaN": (0, 0, 0, 0)}, "tools": [*TOOLS, "tap", "hover"],
                "framewise": True, "title": title}
        return img.opts(**opts, **map_colours(field, z))

    def _marker(self, result: Any = None, revision: int = 0) -> hv.Points:
        r, s = self.result, self.state
        point = None
        if r is not None and result is not None:
            if r.kind == "basin":
                if s.x0 is not None and s.t0 == 0.0:
                    point = (s.x0, s.v0) if r.x_name == "x0" else (s.v0, s.x0)
            else:
                point = (getattr(s, r.x_name), getattr(s, r.y_name))
        return hv.Points([point] if point else []).opts(marker="circle_cross", size=14, fill_color=None,
                                                        line_color="white", line_width=2, framewise=True)

    def _on_result(self, *_: Any) -> None:
        r, req, run = self.result, getattr(self, "_shown", None), self.state.result
        if r is None or req is None or run is None:
            self.legend.object = ""
            return
        n = r.x_values.size * r.y_values.size
        how = "read from the disk cache" if r.from_cache else "computed"
        text = f"{'Basins' if r.kind == 'basin' else 'Map'} of {r.x_values.size} × {r.y_values.size} = {n} points, {how}."
        try:
            stale = request_key(run.params, req["plan"]) != req["key"]
        except ValueError:
            stale = True
        if stale:
            text += " For other parameters than the current ones: press Compute to update."
        self.run.say(text)
        self.legend.object = map_legend(r)

    # ----- clicks -------------------------------------------------------------------------------

    def select_point(self, x: float | None, y: float | None) -> None:
        """A click on the map: the state moves to that grid point (basins: the gear starts there)."""
        r, s = self.result, self.state
        if r is None or x is None or y is None:
            return
        xv = float(r.x_values[int(np.argmin(np.abs(r.x_values - x)))])
        yv = float(r.y_values[int(np.argmin(np.abs(r.y_values - y)))])
        point = {r.x_name: xv, r.y_name: yv}
        if r.kind == "basin":
            values = {"x0": point["x0"], "v0": point["v0"], "t0": 0.0}
        elif set(point) & set(PHYSICAL) and not s.units:
            s.say("map-run", "This map has physical axes: turn the physical units on to move there.")
            return
        else:
            values = point
        try:
            s.param.update(**values)
            s.clear("map-run")
        except ValueError as exc:
            s.say("map-run", f"{exc}")

    def csv(self) -> io.StringIO:
        """The map as the CSV the page offers."""
        return io.StringIO("" if self.result is None else self.result.table().to_csv(index=False))
