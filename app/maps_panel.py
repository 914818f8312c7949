"""The Maps tab: 2-D regime/intensity maps and basins of attraction for the current parameters.

An NVH engineer picks two axes (Λ, r, j, H₂/H₁, φ₂; engine speed and drag torque when the
dashboard works in physical units) or the start state (basins), a range and a number of points
per axis, and presses Compute. The map runs through :func:`rattle_core.store.requests.run_map`:

* on this panel's own worker thread, never on the server's event loop, so sliders stay live
  (parallel kernel launches are serialised in ``rattle_core.batch.chunks``, so a map may run while a
  bifurcation diagram does); progress and the result come back through the session's document;
* cancelled by Cancel, by a new request, and when the session closes;
* from the disk cache when the same map ran before (the status line says so, and how long it
  took);
* on local cores, or on Dask when the "Dask scheduler" field holds ``tcp://host:port`` (a
  shared ``Client`` per address) or ``local`` (one 2-worker ``LocalCluster`` per server
  process, closed at exit; :mod:`rattle_core.batch.executor`). ``rattle serve --scheduler``/
  ``--dask local`` set the field's default through :func:`set_default_scheduler`.

The map is a Bokeh image whose data source (``map_image``) also holds, per cell, the values the
hover tool shows. A click on a regime map sets the dashboard's parameters to that point (through
the state's validation; on a physical axis, through the physical-units inputs, which then show
the clicked engine speed or drag torque); a click on a basin map starts the gear there at
t = 0. Slider moves only mark the map as computed for other parameters: a map is recomputed
only on request.
"""
from __future__ import annotations

import contextlib
import functools
import io
import logging
import math
import time
from concurrent.futures import ThreadPoolExecutor
from typing import Any, Callable

import numpy as np
import panel as pn
from bokeh.events import Tap
from bokeh.models import (ColorBar, ColumnDataSource, HoverTool, LinearColorMapper, LogColorMapper,
                          Range1d)
from bokeh.palettes import Category20, Magma256, Viridis256
from bokeh.plotting import figure

from rattle_core.analysis.vocabulary import REGIME_CODES, REGIME_COLOURS, REGIME_MEANING
from rattle_core.batch.executor import check_scheduler
from rattle_core.batch.executor import shared_client as dask_client
from rattle_core.batch.plan import PHYSICAL_AXES as MAP_PHYSICAL_AXES
from rattle_core.batch.plan import plan_map, point_params
from rattle_core.model.excitation import excitation
from rattle_core.store.requests import run_map

from .background import CancellableJob
from .panel_base import FeaturePanel
from .state import apply_values
from .units_panel import UnitsPanel

log = logging.getLogger(__name__)

_EXECUTOR = ThreadPoolExecutor(max_workers=1, thread_name_prefix="rattle-map")

#: Axis name → (label, default range). Physical ranges follow the current physical values.
DIMENSIONLESS_AXES = {"lam": ("Λ", (0.5, 4.0)), "r": ("r", (0.3, 0.95)), "j": ("j", (2.0, 16.0)),
                      "h2": ("H₂/H₁", (0.0, 1.0)), "phi2": ("φ₂ (°)", (-180.0, 180.0))}
PHYSICAL_AXES = {"rpm": "engine speed (rpm)", "drag_torque": "drag torque (N·m)"}
BASIN_LABELS = {"x0": "x₀ at t = 0", "v0": "ẋ₀ at t = 0"}
BASIN_V_RANGE = (-3.0, 3.0)

#: Limits of a map requested from the dashboard (the library allows more, from the CLI).
AXIS_POINTS = (2, 400)
MAX_POINTS = 100_000
MAX_WORK = 2e7  # points × (transient + record): about a minute on two cores
TRANSIENT_RANGE = (0, 100_000)
RECORD_RANGE = (1, 10_000)
DEFAULTS = {"num": 60, "transient": 200, "record": 60}

FIELDS = {"regime": "regime", "intensity": "rattle intensity Σ Ĩ² per period",
          "period": "period (forcing periods)", "lyapunov": "Lyapunov exponent",
          "stick_fraction": "stick fraction"}
BASIN_FIELDS = {"attractor": "attractor reached", **FIELDS}

# ----- Dask: one client per address and one local cluster per server process ---------------

_default_scheduler = ""


def set_default_scheduler(address: str | None) -> None:
    """The scheduler field's default for every new session (``rattle serve --scheduler``)."""
    global _default_scheduler
    _default_scheduler = check_scheduler(address)


def default_scheduler() -> str:
    return _default_scheduler


# ----- the background job -----------------------------------------------------------------

class MapJob(CancellableJob):
    """One map request, run on the maps worker thread (or in the caller's, for tests).

    ``on_done(result, seconds)``; ``on_error(control, message)`` names the control at fault.
    """

    def run(self) -> None:
        if self.cancelled:
            return
        req = self.request
        t_start = time.perf_counter()
        try:
            executor = dask_client(req["scheduler"])
        except (ConnectionError, ValueError) as exc:
            if not self.cancelled:
                self._on_error("scheduler", str(exc))
            return
        kwargs = {"transient": req["transient"], "record": req["record"]}
        if executor is not None:
            kwargs["executor"] = executor
        try:
            # the shared clients are nobody's default; Dask's as_completed needs a current one
            with (executor.as_current() if executor is not None else contextlib.nullcontext()):
                result = run_map(req["params"], req["phys"], req["x_name"], req["x_values"],
                                      req["y_name"], req["y_values"], use_cache=True,
                                      progress=self._progress, cancel=self._cancel.is_set, **kwargs)
        except Exception as exc:  # reported to its own session only, as a message
            if not self.cancelled:
                log.warning("map failed: %s: %s", type(exc).__name__, exc)
                text = str(exc) if isinstance(exc, ValueError) else f"{type(exc).__name__}: {exc}"
                self._on_error("run", f"The map could not be computed: {text}")
            return
        if not self.cancelled and not result.cancelled:
            self._on_done(result, time.perf_counter() - t_start)


# ----- pure helpers -----------------------------------------------------------------------

def _edges(values: np.ndarray) -> tuple[float, float]:
    """Left edge and width of an image whose pixel centres are the (evenly spaced) values."""
    step = (values[-1] - values[0]) / (len(values) - 1) if len(values) > 1 else 1.0
    return float(values[0] - step / 2), float(values[-1] - values[0] + step)


def image_data(result: Any, field: str) -> dict:
    """The image source's data: the shown field, and per cell what the hover tool shows."""
    letters = {v: k for k, v in REGIME_CODES.items()}
    f = result.fields
    shown = np.asarray(f[field], dtype=np.float64).copy()
    if field in ("regime", "attractor"):
        shown[shown < 0] = np.nan
    elif field == "intensity":
        shown[~(shown > 0)] = np.nan  # no impacts: blank, as the log colour scale needs
    gx, gy = np.meshgrid(result.x_values, result.y_values)
    x0, dw = _edges(result.x_values)
    y0, dh = _edges(result.y_values)
    reg = np.asarray(f["regime"])
    data = {"image": [shown], "x": [x0], "y": [y0], "dw": [dw], "dh": [dh],
            "xv": [gx], "yv": [gy],
            "regime": [[[letters.get(int(c), "–") for c in row] for row in reg]],
            "period": [np.asarray(f["period"], dtype=np.float64)],
            "intensity": [np.asarray(f["intensity"], dtype=np.float64)],
            "lyapunov": [np.asarray(f["lyapunov"], dtype=np.float64)],
            "stick": [np.asarray(f["stick_fraction"], dtype=np.float64)]}
    if "attractor" in f:
        data["attractor"] = [np.asarray(f["attractor"], dtype=np.float64)]
    return data


EMPTY = {k: [] for k in ("image", "x", "y", "dw", "dh", "xv", "yv", "regime", "period",
                         "intensity", "lyapunov", "stick", "attractor")}


def map_csv(result: Any) -> str:
    """One row per grid point: the two axes, then every field (regime as its letter)."""
    return result.table().to_csv(index=False)


class MapsPanel(FeaturePanel):
    """The Maps tab of one session."""

    def __init__(self, dashboard):
        super().__init__(dashboard)
        self.result = None
        self._job: MapJob | None = None
        self._token = 0
        self._result_key: str | None = None
        self._request: dict | None = None
        self._elapsed = math.nan
        self._stale = False
        self._phys_mode = getattr(dashboard, "physical", None) is not None
        self._build_widgets()
        self._build_figure()
        self.tab = ("Maps", self._build_layout())

    # ----- construction -------------------------------------------------------------------

    def _build_widgets(self) -> None:
        self.kind = pn.widgets.RadioButtonGroup(
            options={"Regimes over two parameters": "regime",
                     "Basins over (x₀, ẋ₀)": "basin"},
            value="regime", css_classes=["map-kind"], width=400)
        opts = self._axis_options(self._phys_mode)
        self.x_axis = pn.widgets.Select(label="x axis", options=opts, value="lam", width=120,
                                        css_classes=["map-x-axis"])
        self.y_axis = pn.widgets.Select(label="y axis", options=opts, value="phi2", width=120,
                                        css_classes=["map-y-axis"])
        self.x_start, self.x_stop, self.x_num = self._range_widgets("x", DIMENSIONLESS_AXES["lam"][1])
        self.y_start, self.y_stop, self.y_num = self._range_widgets("y", DIMENSIONLESS_AXES["phi2"][1])
        self.transient = pn.widgets.IntInput(label="transient periods", value=DEFAULTS["transient"],
                                             width=125, css_classes=["map-transient"])
        self.record = pn.widgets.IntInput(label="recorded periods", value=DEFAULTS["record"],
                                          width=125, css_classes=["map-record"])
        self.field = pn.widgets.Select(label="shown", options={v: k for k, v in FIELDS.items()},
                                       value="regime", width=260, css_classes=["map-field"])
        self.compute_button = pn.widgets.Button(label="Compute", color="primary", width=110,
                                                css_classes=["map-compute"])
        self.cancel_button = pn.widgets.Button(label="Cancel", width=90, disabled=True,
                                               css_classes=["map-cancel"])
        self.scheduler = pn.widgets.TextInput(
            label="Dask scheduler", value=_default_scheduler, width=300,
            placeholder="empty: this server's cores; 'local'; tcp://host:port",
            css_classes=["map-scheduler"])
        self.alerts = {name: pn.pane.Alert("", alert_type="danger", visible=False, margin=(0, 5),
                                           css_classes=[f"msg-map-{name}"], sizing_mode="stretch_width")
                       for name in ("x", "y", "run", "scheduler")}
        self.progress = pn.indicators.Progress(value=0, max=100, visible=False, bar_color="info",
                                               height=14, sizing_mode="stretch_width",
                                               css_classes=["map-progress"])
        self.status = pn.pane.Markdown("No map yet: choose the axes and press Compute.",
                                       css_classes=["map-status"], margin=(0, 5),
                                       sizing_mode="stretch_width")
        self.legend = pn.pane.HTML("", css_classes=["map-legend"], width=400)
        self.download = pn.widgets.FileDownload(callback=self._csv, filename="map.csv",
                                                label="Map as CSV", color="success",
                                                disabled=True, css_classes=["map-download"])
        self.kind.param.watch(self._guard(self._on_kind), "value")
        self.x_axis.param.watch(self._guard(functools.partial(self._on_axis, "x")), "value")
        self.y_axis.param.watch(self._guard(functools.partial(self._on_axis, "y")), "value")
        self.field.param.watch(self._guard(lambda e: self._draw()), "value")
        self.compute_button.on_click(self._guard(lambda e: self.compute()))
        self.cancel_button.on_click(self._guard(lambda e: self.cancel("Cancelled.")))

    def _range_widgets(self, axis: str, rng: tuple[float, float]):
        start = pn.widgets.FloatInput(label="from", value=rng[0], width=85,
                                      css_classes=[f"map-{axis}-start"])
        stop = pn.widgets.FloatInput(label="to", value=rng[1], width=85,
                                     css_classes=[f"map-{axis}-stop"])
        num = pn.widgets.IntInput(label="points", value=DEFAULTS["num"], width=70,
                                  css_classes=[f"map-{axis}-num"])
        return start, stop, num

    def _build_figure(self) -> None:
        self.source = ColumnDataSource(dict(EMPTY), name="map_image")
        self.marker = ColumnDataSource({"x": [], "y": []}, name="map_marker")
        self.x_range, self.y_range = Range1d(0, 1), Range1d(0, 1)
        self.fig = figure(width=620, height=500, x_range=self.x_range, y_range=self.y_range,
                          tools="pan,wheel_zoom,box_zoom,reset,save,tap", active_scroll="wheel_zoom",
                          name="map_figure", title="2-D map")
        self.mappers = {
            "regime": LinearColorMapper(palette=list(REGIME_COLOURS.values()), low=-0.5,
                                        high=len(REGIME_COLOURS) - 0.5, nan_color=(0, 0, 0, 0)),
            "attractor": LinearColorMapper(palette=list(Category20[20]), low=-0.5, high=19.5,
                                           nan_color=(0, 0, 0, 0)),
            "intensity": LogColorMapper(palette=Magma256, low=1e-4, high=1.0, nan_color=(0, 0, 0, 0)),
            "linear": LinearColorMapper(palette=Viridis256, low=0.0, high=1.0, nan_color=(0, 0, 0, 0)),
        }
        self.renderer = self.fig.image(image="image", x="x", y="y", dw="dw", dh="dh",
                                       source=self.source, color_mapper=self.mappers["regime"])
        self.fig.scatter("x", "y", source=self.marker, marker="circle_cross", size=14,
                         fill_color=None, line_color="white", line_width=2)
        self.color_bar = ColorBar(color_mapper=self.mappers["linear"], visible=False, width=12)
        self.fig.add_layout(self.color_bar, "right")
        self.hover = HoverTool(renderers=[self.renderer], tooltips=self._tooltips("x", "y", False))
        self.fig.add_tools(self.hover)
        self.fig.on_event(Tap, self._guard(lambda e: self.select_point(e.x, e.y)))

    def _build_layout(self) -> pn.Row:
        controls = pn.Column(
            self.kind,
            pn.Row(self.x_axis, self.x_start, self.x_stop, self.x_num), self.alerts["x"],
            pn.Row(self.y_axis, self.y_start, self.y_stop, self.y_num), self.alerts["y"],
            pn.Row(self.transient, self.record),
            pn.Row(self.compute_button, self.cancel_button), self.alerts["run"],
            self.progress, self.status,
            self.scheduler, self.alerts["scheduler"],
            self.download, self.legend, width=420)
        # two columns fit beside the sidebar on a 1400-px screen; the legend sits under the controls
        return pn.Row(controls, pn.Column(self.field, self.fig), sizing_mode="stretch_width")

    @staticmethod
    def _axis_options(physical: bool) -> dict[str, str]:
        opts = {label: name for name, (label, _) in DIMENSIONLESS_AXES.items()}
        if physical:
            opts.update({label: name for name, label in PHYSICAL_AXES.items()})
        return opts

    def _tooltips(self, x_label: str, y_label: str, basin: bool) -> list[tuple[str, str]]:
        tips = [(x_label, "@xv{0.[0000]}"), (y_label, "@yv{0.[0000]}"), ("regime", "@regime"),
                ("period", "@period"), ("intensity", "@intensity{0.[0000]}"),
                ("Lyapunov", "@lyapunov{0.[0000]}")]
        if basin:
            tips.insert(2, ("attractor", "@attractor"))
        return tips

    def _guard(self, fn: Callable) -> Callable:
        """A widget callback that turns any exception into a message here, never a traceback."""
        def wrapper(*args: Any) -> None:
            try:
                fn(*args)
            except Exception as exc:
                log.warning("maps callback failed: %s: %s", type(exc).__name__, exc)
                self._show("run", f"{type(exc).__name__}: {exc}")
        return wrapper

    # ----- messages -----------------------------------------------------------------------

    def _show(self, name: str, message: str) -> None:
        alert = self.alerts[name]
        alert.object = message
        alert.visible = True

    def _clear(self, *names: str) -> None:
        for name in names or tuple(self.alerts):
            if self.alerts[name].visible:
                self.alerts[name].param.update(visible=False, object="")

    # ----- axes ---------------------------------------------------------------------------

    def _physical(self) -> Any:
        return getattr(self.dashboard, "physical", None)

    def _default_range(self, name: str) -> tuple[float, float]:
        phys = self._physical()
        if name in DIMENSIONLESS_AXES:
            return DIMENSIONLESS_AXES[name][1]
        if name == "rpm":
            return (800.0, 6000.0)
        if name == "drag_torque" and phys is not None:
            return (float(f"{phys.drag_torque / 4:.3g}"), float(f"{phys.drag_torque * 4:.3g}"))
        if name == "x0":
            p = self.dashboard.params
            y0 = float(excitation(0.0, p.h, p.phi))
            return (round(y0, 10), round(y0 + p.j, 10))
        if name == "v0":
            return BASIN_V_RANGE
        return (0.0, 1.0)

    def _on_axis(self, axis: str, event) -> None:
        if event.new is None:
            return
        lo, hi = self._default_range(event.new)
        start, stop = (self.x_start, self.x_stop) if axis == "x" else (self.y_start, self.y_stop)
        start.value, stop.value = lo, hi
        self._clear(axis)

    def _on_kind(self, event) -> None:
        basin = event.new == "basin"
        if basin:
            self.x_axis.param.update(options={BASIN_LABELS["x0"]: "x0"}, value="x0", disabled=True)
            self.y_axis.param.update(options={BASIN_LABELS["v0"]: "v0"}, value="v0", disabled=True)
        else:
            opts = self._axis_options(self._phys_mode)
            self.x_axis.param.update(options=opts, value="lam", disabled=False)
            self.y_axis.param.update(options=opts, value="phi2", disabled=False)
        fields = BASIN_FIELDS if basin else FIELDS
        self.field.param.update(options={v: k for k, v in fields.items()},
                                value="attractor" if basin else "regime")
        self._clear()

    def _set_physical_mode(self, physical: bool) -> None:
        self._phys_mode = physical
        if self.kind.value != "regime":
            return
        opts = self._axis_options(physical)
        for sel, fallback in ((self.x_axis, "lam"), (self.y_axis, "phi2")):
            value = sel.value if sel.value in opts.values() else fallback
            sel.param.update(options=opts, value=value)

    # ----- requests -----------------------------------------------------------------------

    def _int(self, widget, what: str, lo: int, hi: int, alert: str) -> int | None:
        v = widget.value
        if v is None or not lo <= v <= hi:
            self._show(alert, f"{what} = {v} is outside the allowed range [{lo}, {hi}]")
            return None
        return int(v)

    def _axis_values(self, axis: str) -> np.ndarray | None:
        start, stop, num = ((self.x_start, self.x_stop, self.x_num) if axis == "x"
                            else (self.y_start, self.y_stop, self.y_num))
        name = (self.x_axis if axis == "x" else self.y_axis).value
        n = self._int(num, f"{axis} points", *AXIS_POINTS, alert=axis)
        if n is None:
            return None
        a, b = start.value, stop.value
        for v, what in ((a, "from"), (b, "to")):
            if v is None or not math.isfinite(v):
                self._show(axis, f"{name} {what} = {v} must be a finite number")
                return None
        if not a < b:
            self._show(axis, f"{name}: 'from' ({a:g}) must be below 'to' ({b:g})")
            return None
        return np.linspace(a, b, n)

    def request(self) -> dict | None:
        """The map the controls ask for, checked; None (with messages shown) when it cannot run."""
        self._clear()
        xv, yv = self._axis_values("x"), self._axis_values("y")
        transient = self._int(self.transient, "transient periods", *TRANSIENT_RANGE, alert="run")
        record = self._int(self.record, "recorded periods", *RECORD_RANGE, alert="run")
        try:
            scheduler = check_scheduler(self.scheduler.value)
        except ValueError as exc:
            self._show("scheduler", str(exc))
            return None
        if xv is None or yv is None or transient is None or record is None:
            return None
        points = xv.size * yv.size
        if points > MAX_POINTS:
            self._show("run", f"the grid has {xv.size} × {yv.size} = {points} points; the allowed "
                              f"range is up to {MAX_POINTS:,} points")
            return None
        work = points * (transient + record)
        if work > MAX_WORK:
            self._show("run", f"points × (transient + recorded periods) = {work:.3g}; the allowed "
                              f"range is up to {MAX_WORK:.0e} (fewer points or periods)")
            return None
        params = self.dashboard.params
        phys = self._physical()
        x_name, y_name = self.x_axis.value, self.y_axis.value
        try:
            plan = plan_map(params, phys, x_name, xv, y_name, yv)
        except ValueError as exc:
            text = str(exc)
            self._show("y" if text.startswith("y axis") else "x" if text.startswith("x axis")
                       else "run", text)
            return None
        if plan[0] == "basin":
            y0 = float(excitation(0.0, params.h, params.phi))
            if xv[0] < y0 - 1e-9 or xv[-1] > y0 + params.j + 1e-9:
                self._show("x", f"x₀ must lie in the backlash at t = 0, [{y0:.6g}, {y0 + params.j:.6g}]; "
                                f"got [{xv[0]:.6g}, {xv[-1]:.6g}]")
                return None
        return {"params": params, "phys": phys, "x_name": x_name, "y_name": y_name,
                "x_values": xv, "y_values": yv, "transient": transient, "record": record,
                "scheduler": scheduler, "plan": plan}

    @staticmethod
    def _key(params, plan: tuple) -> str:
        """What a map depends on besides its axes; a map is stale when this changes."""
        if plan[0] == "map":
            params = params.with_value(plan[1], 1.0).with_value(plan[3], 1.0)
        elif plan[0] == "flat":
            params = params.with_value(plan[1], 1.0)
        return repr(params.canonical())

    def _start(self, synchronous: bool) -> MapJob | None:
        req = self.request()
        if req is None:
            return None
        self.cancel(None)
        self._token += 1
        token = self._token
        session = self.dashboard._in_session
        job = MapJob(
            req,
            on_progress=lambda frac: session(lambda: self._on_progress(token, frac)),
            on_done=lambda res, dt: session(lambda: self._on_done(token, req, res, dt)),
            on_error=lambda where, msg: session(lambda: self._on_error(token, where, msg)))
        self._job = job
        self.progress.param.update(value=0, visible=True)
        self.cancel_button.disabled = False
        n = req["x_values"].size * req["y_values"].size
        where = f"on Dask ({req['scheduler']})" if req["scheduler"] else "on this server's cores"
        self.status.object = f"Computing {req['x_values'].size} × {req['y_values'].size} = {n} points {where}…"
        if synchronous:
            job.run()
        else:
            job.future = _EXECUTOR.submit(job.run)
        return job

    def compute(self) -> None:
        """Start the map the controls ask for, in the background (cancels the one running)."""
        self._start(synchronous=False)

    def compute_now(self) -> None:
        """The same as :meth:`compute`, run in the calling thread (for tests and scripts)."""
        self._start(synchronous=True)

    def cancel(self, message: str | None = None) -> None:
        if self._job is not None:
            self._job.cancel()
            self._job = None
            if message:
                self.status.object = message
        self._token += 1
        self.progress.visible = False
        self.cancel_button.disabled = True

    # ----- results (in the session's document) --------------------------------------------

    def _on_progress(self, token: int, frac: float) -> None:
        if token == self._token:
            self.progress.value = int(100 * frac)

    def _on_error(self, token: int, where: str, message: str) -> None:
        if token != self._token:
            return
        self._job = None
        self.progress.visible = False
        self.cancel_button.disabled = True
        self.status.object = "No new map: see the message above." if where == "run" else \
            "No new map: see the message below."
        self._show(where, message)

    def _on_done(self, token: int, req: dict, result: Any, elapsed: float) -> None:
        if token != self._token:
            return
        self._job = None
        self.progress.visible = False
        self.cancel_button.disabled = True
        self.result, self._request, self._elapsed = result, req, elapsed
        self._result_key = self._key(req["params"], req["plan"])
        self._stale = False
        basin = result.kind == "basin"
        labels = self._labels(result)
        self.hover.tooltips = self._tooltips(*labels, basin)
        self.fig.xaxis.axis_label, self.fig.yaxis.axis_label = labels
        x0, dw = _edges(result.x_values)
        y0, dh = _edges(result.y_values)
        self.x_range.update(start=x0, end=x0 + dw)
        self.y_range.update(start=y0, end=y0 + dh)
        self.download.param.update(disabled=False,
                                   filename=f"{'basins' if basin else 'map'}_{result.x_name}_{result.y_name}.csv")
        self._draw()
        self._draw_marker()
        self._show_status()

    def _labels(self, result: Any) -> tuple[str, str]:
        names = {**{k: v[0] for k, v in DIMENSIONLESS_AXES.items()}, **PHYSICAL_AXES, **BASIN_LABELS}
        return names.get(result.x_name, result.x_name), names.get(result.y_name, result.y_name)

    def _show_status(self) -> None:
        r = self.result
        if r is None:
            return
        n = r.x_values.size * r.y_values.size
        sched = self._request["scheduler"] if self._request else ""
        how = ("read from the disk cache" if r.from_cache
               else f"computed on Dask ({sched})" if sched else "computed on this server's cores")
        kind = "Basins" if r.kind == "basin" else "Map"
        took = (f"{1e3 * self._elapsed:.0f} ms" if self._elapsed < 1
                else f"{self._elapsed:.1f} s")
        text = f"{kind} of {r.x_values.size} × {r.y_values.size} = {n} points {how} in {took}."
        if self._stale:
            text += " **For other parameters than the current ones**: press Compute to update."
        self.status.object = text

    def _draw(self) -> None:
        r = self.result
        if r is None:
            return
        field = self.field.value
        if field not in r.fields:
            field = "attractor" if r.kind == "basin" else "regime"
        data = image_data(r, field)
        if field in ("regime", "attractor"):
            mapper = self.mappers[field]
            self.color_bar.visible = False
        else:
            vals = data["image"][0]
            finite = vals[np.isfinite(vals)]
            if field == "intensity":
                mapper = self.mappers["intensity"]
                hi = float(finite.max()) if finite.size else 1.0
                lo = max(float(finite.min()), 1e-4 * hi) if finite.size else 1e-4
                mapper.update(low=lo, high=max(hi, lo * (1 + 1e-9)))
            else:
                mapper = self.mappers["linear"]
                lo, hi = (float(finite.min()), float(finite.max())) if finite.size else (0.0, 1.0)
                mapper.update(low=lo, high=hi if hi > lo else lo + 1.0)
            self.color_bar.update(color_mapper=mapper, visible=True, title=FIELDS[field])
        self.renderer.glyph.color_mapper = mapper
        self.source.data = data
        self.fig.title.text = (f"{BASIN_FIELDS[field]} · "
                               + ("basins of attraction" if r.kind == "basin" else "regime map"))
        self.legend.object = self._legend_html(r, field)

    @staticmethod
    def _legend_html(result: Any, field: str) -> str:
        def swatch(colour: str) -> str:
            return (f"<span style='display:inline-block;width:14px;height:14px;background:{colour};"
                    "border:1px solid #555;margin-right:6px;vertical-align:middle'></span>")
        if result.kind == "basin":
            palette = Category20[20]
            rows = [f"<div class='map-attractor' data-regime='{a['regime']}'>"
                    f"{swatch(palette[i % 20])}<b>{i}</b>: regime {a['regime']}"
                    f"{', period ' + str(a['period']) if a['period'] else ''}, "
                    f"{100 * a['share']:.1f} %</div>"
                    for i, a in enumerate(result.attractors[:40])]
            more = len(result.attractors) - 40
            if more > 0:
                rows.append(f"<div>… and {more} more</div>")
            return "<div><b>Attractors</b> (regime, period, share of the grid)</div>" + "".join(rows)
        reg = np.asarray(result.fields["regime"])
        counts = {k: int((reg == c).sum()) for k, c in REGIME_CODES.items()}
        rows = [f"<div class='map-regime' data-regime='{k}'>{swatch(REGIME_COLOURS[k])}"
                f"<b>{k}</b> {REGIME_MEANING[k]} ({counts[k]})</div>"
                for k in REGIME_CODES]
        head = "<div><b>Regimes</b> (points)</div>"
        if field != "regime":
            head = f"<div>Colour: {FIELDS[field]}; regimes of this map:</div>"
        return head + "".join(rows)

    # ----- clicks, redraws, teardown -------------------------------------------------------

    def select_point(self, x: float, y: float) -> None:
        """A click on the map: set the dashboard to that grid point (basins: start there)."""
        r = self.result
        if r is None or x is None or y is None:
            return
        ix = int(np.argmin(np.abs(r.x_values - x)))
        iy = int(np.argmin(np.abs(r.y_values - y)))
        xv, yv = float(r.x_values[ix]), float(r.y_values[iy])
        if r.kind == "basin":
            values = {"x0": repr(round(xv if r.x_name == "x0" else yv, 10)),
                      "v0": round(yv if r.y_name == "v0" else xv, 10), "t0": 0.0}
        else:
            names = (r.x_name, r.y_name)
            if set(names) <= set(DIMENSIONLESS_AXES):
                values = {r.x_name: round(xv, 10), r.y_name: round(yv, 10)}
            elif self._units_on():
                # the physical inputs take the clicked values; Λ, j follow from them
                point = {n: v for n, v in zip(names, (xv, yv))}
                changes = {MAP_PHYSICAL_AXES[n][0]: point[n] * MAP_PHYSICAL_AXES[n][1]
                           for n in names if n in MAP_PHYSICAL_AXES}
                msg = self._units_panel().set_physical(**changes)
                if msg:
                    self._show("run", msg)
                    return
                values = {n: round(point[n], 10) for n in names if n in DIMENSIONLESS_AXES}
            else:
                phys = self._request["phys"] if self._request else None
                p = point_params(r.params, phys, names, (xv, yv))
                current = self.dashboard.params
                values = {n: float(f"{p.get(n):.10g}") for n in ("lam", "j")
                          if p.get(n) != current.get(n)}
                for n in names:
                    if n in DIMENSIONLESS_AXES:
                        values[n] = round(xv if n == r.x_name else yv, 10)
        errors = apply_values(self.dashboard.state, values)
        if errors:
            self._show("run", "; ".join(errors.values()))
        else:
            self._clear("run")

    def _units_panel(self) -> UnitsPanel | None:
        return next((p for p in getattr(self.dashboard, "panels", ()) if isinstance(p, UnitsPanel)),
                    None)

    def _units_on(self) -> bool:
        panel = self._units_panel()
        return panel is not None and panel.on

    def _draw_marker(self) -> None:
        r = self.result
        if r is None:
            return
        s = self.dashboard.state
        point: tuple[float, float] | None = None
        if r.kind == "basin":
            if s.x0 != "" and s.t0 == 0.0:
                point = (float(s.x0), s.v0) if r.x_name == "x0" else (s.v0, float(s.x0))
        elif r.x_name in DIMENSIONLESS_AXES and r.y_name in DIMENSIONLESS_AXES:
            point = (getattr(s, r.x_name), getattr(s, r.y_name))
        data = {"x": [point[0]], "y": [point[1]]} if point else {"x": [], "y": []}
        if data != dict(self.marker.data):
            self.marker.data = data

    def on_redraw(self) -> None:
        physical = self._physical() is not None
        if physical != self._phys_mode:
            self._set_physical_mode(physical)
        if self.result is None or self._request is None:
            return
        stale = self._key(self.dashboard.params, self._request["plan"]) != self._result_key
        if stale != self._stale:
            self._stale = stale
            self._show_status()
        self._draw_marker()

    def on_destroyed(self) -> None:
        self.cancel(None)

    def _csv(self) -> io.StringIO:
        return io.StringIO("" if self.result is None else map_csv(self.result))
