"""The Gearbox tab's measurement card: a measured shaft speed in, its orders and its Campbell
view out.

* **Upload** a measurement (any DAQ export: the delimiter, decimal mark, units row and columns
  are sniffed; a size limit) or take the shipped synthetic run-up.  It is read and analysed in
  the job pool's workers (:func:`app.work.gearbox.measurement`), with progress and cancel.
* **What was read** is shown as plain text (delimiter, decimal mark, columns and their units,
  rows, duration, sample rate, resampling, warnings), and so are the orders the sampling
  resolves only at some speeds (their notices).
* **Corrections**: the time column, the speed column and its unit (rpm, rad/s, Hz), a pulse
  column with its pulses per revolution, and a time window; changing one reads the same bytes
  again with it.
* **Plots**: each order against rpm, and the Campbell view (order spectrum against rpm in dB,
  the analysed orders marked).

The Gearbox view (:mod:`app.views.gearbox`) is given this view and composes it; the map it
shows is :attr:`MeasurementView.order_map`, new ones announced by :attr:`revision`; the
time and speed it was analysed from are kept beside it (:attr:`MeasurementView.samples`).
"""
from __future__ import annotations

import math
from typing import Any

import holoviews as hv
import panel as pn
import param

from ..core import SPEED_UNITS
from ..state import ExplorerState, GearboxSettings
from ..ui.gearbox_plots import campbell_plot, orders_plot
from ..ui.job_panel import JobPanel
from ..ui.labels import text_html
from ..ui.plots import HoloViewsPane
from ..ui.widgets import Field, message
from ..work import gearbox as work
from ..work.threads import plot_lock

#: The speed unit choices: "" reads the unit from the file.
UNITS = {"as detected": "", **{u: u for u in SPEED_UNITS}}
DETECTED, NONE = "(as detected)", "(none)"
TEXT_STYLE = "font-size:12px;color:#333;white-space:pre-wrap"
NOTICE_STYLE = "font-size:12px;color:#8a5a00;white-space:pre-wrap"


class MeasurementView(pn.viewable.Viewer):
    """The measurement card of the Gearbox tab (see the module docstring)."""

    state = param.ClassSelector(class_=ExplorerState)
    jobs = param.Parameter()
    settings = param.ClassSelector(class_=GearboxSettings)
    #: Counts the maps shown; a new one is :attr:`order_map`.
    revision = param.Integer(0)

    def __init__(self, **params: Any):
        super().__init__(**params)
        if self.settings is None:
            self.settings = GearboxSettings()
        self.order_map: Any = None
        self.campbell: Any = None
        self.identity: dict = {}
        #: the bytes last read (``None``: the sample) and their name, read again on a correction
        self.data: bytes | None = None
        self.file_name = ""
        # the time [s] and speed [rpm] read, and the map they were analysed into: the run-up
        # replay's measured angle is built from them (:attr:`samples`)
        self._samples: tuple | None = None
        self._samples_map: Any = None
        self.loaded = False
        self._quiet = False
        self.input = pn.widgets.FileInput(accept=".csv,.gz,.txt,.tsv", css_classes=["gb-measurement"],
                                          sizing_mode="stretch_width")
        self.sample_button = pn.widgets.Button(label="Use the sample run-up (synthetic)",
                                               css_classes=["gb-sample"], sizing_mode="stretch_width")
        # the measurement's job: progress, Cancel and status (``gb-measure-progress``, ...)
        self.panel = JobPanel(self.jobs, "gearbox-measure", "gb-measure")
        self.panel.say("No measurement yet.")
        self.status = self.panel.status
        self.detected = pn.pane.HTML("", css_classes=["gb-detected"], sizing_mode="stretch_width")
        self.notices = pn.pane.HTML("", css_classes=["gb-notices"], sizing_mode="stretch_width")
        column = dict(options=[DETECTED], value=DETECTED, sizing_mode="stretch_width")
        self.time_column = pn.widgets.Select(label="time column", css_classes=["gb-time-column"],
                                             **column)
        self.speed_column = pn.widgets.Select(label="speed column", css_classes=["gb-speed-column"],
                                              **column)
        self.speed_unit = pn.widgets.Select(label="speed unit", options=UNITS, value="",
                                            css_classes=["gb-speed-unit"], sizing_mode="stretch_width")
        self.pulse_column = pn.widgets.Select(label="pulse column", options=[NONE], value=NONE,
                                              css_classes=["gb-pulse-column"],
                                              sizing_mode="stretch_width")
        self.pulses_per_rev = pn.widgets.IntInput(label="pulses per rev", value=1, start=1,
                                                  end=10_000, css_classes=["gb-ppr"],
                                                  sizing_mode="stretch_width")
        # a RangeSlider: Panel's EditableRangeSlider kept a closed page's whole session alive
        self.window = pn.widgets.RangeSlider(label="analyse from / to [s]", start=0.0,
                                                     end=1.0, value=(0.0, 1.0), step=1e-3,
                                                     disabled=True, css_classes=["gb-window"],
                                                     sizing_mode="stretch_width")
        self.span: tuple[float, float] | None = None
        self.input.param.watch(self._on_upload, "value")
        self.sample_button.on_click(lambda e: self.measure(None))
        self.panel.cancel_button.on_click(
            lambda e: self.panel.stop("Analysis cancelled: the measurement shown is kept."))
        for w in (self.time_column, self.speed_column, self.speed_unit, self.pulse_column,
                  self.pulses_per_rev):
            w.param.watch(self._on_option, "value")
        self.window.param.watch(self._on_option, "value_throttled")
        with plot_lock():
            self.orders_pane = HoloViewsPane(self._plot(orders_plot, lambda: self.order_map),
                                             sizing_mode="stretch_width",
                                             css_classes=["gb-orders-plot"])
            self.campbell_pane = HoloViewsPane(self._plot(campbell_plot, lambda: self.campbell),
                                               sizing_mode="stretch_width",
                                               css_classes=["gb-campbell-plot"])
        self.param.watch(lambda e: self._redraw(), "revision")

    def _plot(self, draw, what) -> hv.DynamicMap:
        return hv.DynamicMap(lambda revision: draw(what()),
                             streams=[hv.streams.Params(self, ["revision"])])

    def _redraw(self) -> None:
        # another file may bring other orders: each plot is built afresh
        with plot_lock():
            self.orders_pane.object = self._plot(orders_plot, lambda: self.order_map)
            self.campbell_pane.object = self._plot(campbell_plot, lambda: self.campbell)

    def __panel__(self):
        s = self.settings

        def field(name: str, css: str) -> Field:
            return Field(s, name, slider=False, css=css)
        return pn.Column(
            pn.pane.Markdown("**1. Measurement** (time and speed, or tachometer pulses; any "
                             f"delimiter and decimal mark; up to "
                             f"{work.MAX_MEASUREMENT_BYTES // 1_000_000} MB)"),
            self.input, self.sample_button, message(self.state, "gearbox-measure"),
            pn.Row(self.panel.progress, self.panel.cancel_button, sizing_mode="stretch_width"),
            self.status, self.detected, self.notices,
            pn.Row(self.time_column, self.speed_column, self.speed_unit,
                   sizing_mode="stretch_width"),
            pn.Row(self.pulse_column, self.pulses_per_rev, sizing_mode="stretch_width"),
            self.window,
            pn.Row(field("engine_order", "gb-order"), field("harmonics", "gb-harmonics"),
                   field("rpm_step", "gb-rpm-step"), sizing_mode="stretch_width"),
            sizing_mode="stretch_width", margin=0)

    def plots(self) -> pn.Column:
        """The orders against rpm and the Campbell view."""
        return pn.Column(self.orders_pane, self.campbell_pane, sizing_mode="stretch_width")

    # ----- reading ------------------------------------------------------------------------

    def orders(self) -> tuple:
        s = self.settings
        return tuple(s.engine_order * n for n in range(1, s.harmonics + 1))

    def upload(self, data: Any, where: str, limit: int) -> bytes | None:
        """An upload's bytes, or None (with a message beside ``where``) when over ``limit``."""
        if data is None:
            return None
        if len(data) > limit:
            self.state.say(where, f"the file has {len(data)} bytes; the allowed size is up to "
                                  f"{limit} bytes ({limit / 1e6:g} MB)")
            return None
        self.state.clear(where)
        return bytes(data)

    def _on_upload(self, event) -> None:
        data = self.upload(event.new, "gearbox-measure", work.MAX_MEASUREMENT_BYTES)
        if data is not None:
            self.measure(data)

    @property
    def samples(self) -> tuple | None:
        """``(time_s, speed_rpm, source)`` of the measurement whose order map is shown, as read
        with the corrections; None when the map shown came otherwise (constant orders, none)."""
        if self._samples is None or self._samples_map is not self.order_map:
            return None
        return self._samples

    def options(self) -> dict:
        """The reading options the corrections ask for (none: what the file's layout says)."""
        out: dict[str, Any] = {}
        if self.pulse_column.value != NONE:
            out.update(pulse_column=self.pulse_column.value,
                       pulses_per_rev=int(self.pulses_per_rev.value))
        else:
            for key, w in (("time_column", self.time_column), ("speed_column", self.speed_column)):
                if w.value != DETECTED:
                    out[key] = w.value
            if self.speed_unit.value:
                out["speed_unit"] = self.speed_unit.value
        if self.span is not None and not self.window.disabled:
            lo, hi = self.window.value
            if lo > self.span[0]:
                out["from_s"] = float(lo)
            if hi < self.span[1]:
                out["to_s"] = float(hi)
        return out

    def measure(self, data: bytes | None, options: dict | None = None) -> None:
        """Read and analyse uploaded bytes (``None``: the sample) in a worker, with progress;
        ``options`` are the corrections (a new file starts without any)."""
        self.state.clear("gearbox-measure")
        if options is None:  # a new file: its own layout, its whole length
            self._reset_options()
            options = {}
        self.data, self.loaded = data, True
        what = "the sample run-up" if data is None else f"the uploaded file ({len(data)} bytes)"
        self.file_name = (self.input.filename or "the uploaded file") if data is not None \
            else "the sample run-up (synthetic)"
        self.panel.submit(object(), work.measurement,
                          (data, self.orders(), self.settings.rpm_step, self.file_name, options),
                          f"Reading and analysing {what}…", work.MEASUREMENT_JOB_LIMIT,
                          on_done=lambda out: self._measured(out, options),
                          on_error=lambda m: self._failed(work.file_error(m)))

    def reread(self) -> None:
        """Read the same bytes again with the corrections."""
        if self.loaded:
            self.measure(self.data, self.options())

    def _on_option(self, event) -> None:
        if not self._quiet:
            self.reread()

    def _reset_options(self) -> None:
        self._quiet = True
        try:
            self.time_column.value = self.speed_column.value = DETECTED
            self.pulse_column.value = NONE
            self.speed_unit.value = ""
            self.span = None
            self.window.disabled = True
        finally:
            self._quiet = False

    def _measured(self, out: Any, options: dict) -> None:
        if out is None:  # cancelled
            return
        omap, self.identity, extra = out
        self.campbell = extra["campbell"]
        t_w = extra.get("samples")
        self._samples = None if t_w is None else (*t_w, self.file_name)
        self._samples_map = omap
        det = omap.detected
        self._quiet = True
        try:
            if det is not None:
                for w, first in ((self.time_column, DETECTED), (self.speed_column, DETECTED),
                                 (self.pulse_column, NONE)):
                    w.options = [first, *det.columns]
            if extra["span"] is not None and "from_s" not in options and "to_s" not in options:
                lo, hi = self.span = extra["span"]
                step = 10.0 ** math.floor(math.log10(max(hi - lo, 1e-9))) / 1000
                self.window.param.update(start=lo, end=hi, value=(lo, hi), step=step,
                                         disabled=False)
        finally:
            self._quiet = False
        self.show(omap, extra["campbell_note"])

    def show(self, omap: Any, note: str = "") -> None:
        """Show ``omap``: its summary, how it was read, what it left out; new speeds to verdict."""
        self.order_map = omap
        self.status.object = text_html(
            f"{omap.source}: {omap.rpm.size} rpm bins from {omap.rpm[0]:.0f} to {omap.rpm[-1]:.0f} "
            f"rpm, orders {', '.join(f'{k:g}' for k in omap.orders)}.")
        det = omap.detected
        self.detected.object = "" if det is None else text_html(
            "Read as: " + "\n".join(det.describe()), TEXT_STYLE)
        told = [*omap.notices, *([note] if note else [])]
        self.notices.object = text_html("\n".join(told), NOTICE_STYLE) if told else ""
        lo, hi = omap.rpm_range
        step = self.settings.rpm_step  # round speeds, inside the measured range
        self.settings.param.update(rpm_start=float(math.ceil(lo / step) * step),
                                   rpm_stop=float(math.floor(hi / step) * step))
        self.revision += 1

    def say(self, text: str) -> None:
        """Replace what the card says about the measurement (constant orders, say)."""
        self.status.object = text_html(text)
        self.detected.object = self.notices.object = ""

    def _failed(self, msg: str) -> None:
        self.state.say("gearbox-measure", msg)
        self.status.object = text_html("No measurement taken: see the message above.")
