"""The Gearbox tab: from a measurement to a verdict, with a what-if variant beside it.

1. **Measurement**: the card of :mod:`app.views.measurement` (given as ``measurement``).
2. **Gears**: edit them in a table, or upload a ``GEARBOX.toml`` (it fills the table and the
   excitation settings; a measurement it names is the one shown here, never a server file).
3. **Verdict**: every gear at every speed in the background (the session's ``gearbox`` job,
   :func:`app.work.gearbox.verdicts`, cached on disk), with progress and cancel; onsets and
   regimes, intensity and loudness against rpm, against a target (a line, the failing speeds
   shaded) and at an oil temperature; a second design dashed over the first, with a table of
   both side by side.  The second design is a variant (drag +x %, backlash ±y µm), or design B:
   an uploaded ``GEARBOX.toml`` or an edited copy of the gears, in its own table.
4. **Listen** to the whole gearbox at any speed; **export** the verdict as CSV and a
   self-contained HTML report (inputs, pictures, tables).

Uploads are parsed in the job pool's workers under the job limits (:mod:`app.work.gearbox`).
"""
from __future__ import annotations

import io
from typing import Any

import holoviews as hv
import numpy as np
import pandas as pd
import panel as pn
import param

from ..core import Excitation, Gearbox, Target, check_verdict_rpm, scaled_drag
from ..core import verdict_tables as vt
from ..state import ExplorerState, GearboxSettings
from ..ui.gearbox_plots import metric_plot, regime_plot
from ..ui.job_panel import JobPanel
from ..ui.labels import text_html
from ..ui.plots import HoloViewsPane
from ..ui.widgets import Field, message, set_value
from ..work import gearbox as work
from ..work.threads import plot_lock

COLUMNS = ["name", "inertia_kgm2", "base_radius_m", "drag_torque_Nm", "backlash_um",
           "restitution", "speed_ratio", "driver_radius_m"]
DEFAULT_GEARS = pd.DataFrame([
    ["5th idler", 4e-4, 0.035, 0.05, 80.0, 0.65, 1.0, np.nan],
    ["reverse idler", 2.5e-4, 0.030, 0.03, 120.0, 0.65, 0.8, np.nan],
    ["6th", 3e-4, 0.040, 0.08, 60.0, 0.65, 1.3, 0.030]], columns=COLUMNS)
MAX_GEARS = 12
PLOTS = ("regimes", "intensity", "loudness")
VARIANTS = {"no variant": "none", "drag torque +/- %": "drag", "backlash +/- µm": "backlash",
            "design B (its own gears)": "design"}


class GearboxView(pn.viewable.Viewer):
    """The Gearbox tab of one session (see the module docstring)."""

    state = param.ClassSelector(class_=ExplorerState)
    jobs = param.Parameter()
    #: The tab's request; the session's own (in the URL) on the page.
    settings = param.ClassSelector(class_=GearboxSettings)
    revision = param.Integer(0)
    #: The measurement card (:class:`app.views.measurement.MeasurementView`), sharing settings.
    measurement = param.Parameter()

    def __init__(self, **params: Any):
        super().__init__(**params)
        if self.measurement is None:
            raise TypeError("GearboxView needs its measurement view (measurement=...)")
        self.settings = self.measurement.settings
        self._on_measurement = self.measurement._on_upload  # an upload's event
        self.constant: Any = None  # constant orders from an uploaded gearbox file
        # an uploaded file's oil and its gears' drags that the table's one number cannot hold
        # (tables over speed or temperature, the oil model), kept by gear name
        self.oil: Any = None
        self.drags: dict = {}
        # the target text last shown from an uploaded file (replaced by the next file's)
        self.file_target = ""
        self.base: Any = None
        self.variant: Any = None
        self.variant_text = ""
        self.report = ""
        self.target: Any = None
        self.table_b = pn.widgets.Tabulator(DEFAULT_GEARS.copy(), show_index=False, height=170,
                                            sizing_mode="stretch_width", css_classes=["gb-gears-b"])
        self.copy_button = pn.widgets.Button(label="Edit a copy as design B",
                                             css_classes=["gb-copy"], sizing_mode="stretch_width")
        self.toml_b_input = pn.widgets.FileInput(accept=".toml", css_classes=["gb-toml-b"],
                                                 sizing_mode="stretch_width")
        self.target_input = pn.widgets.TextInput(
            value=self.settings.target, placeholder="1000:10,3000:20 sone; 1000:60,3000:70 dba",
            css_classes=["gb-target"], sizing_mode="stretch_width")
        self.side_by_side = pn.pane.HTML("", css_classes=["gb-side-by-side"],
                                         sizing_mode="stretch_width")
        self.table = pn.widgets.Tabulator(DEFAULT_GEARS.copy(), show_index=False, height=170,
                                          sizing_mode="stretch_width", css_classes=["gb-gears"])
        self.add_button = pn.widgets.Button(label="Add gear", css_classes=["gb-add"])
        self.remove_button = pn.widgets.Button(label="Remove last", css_classes=["gb-remove"])
        self.toml_input = pn.widgets.FileInput(accept=".toml", css_classes=["gb-toml"],
                                               sizing_mode="stretch_width")
        self.run_button = pn.widgets.Button(label="Run the verdict", color="primary",
                                            css_classes=["gb-run"], sizing_mode="stretch_width")
        # the verdict's job: progress, Cancel and status (``gb-progress``, ``gb-cancel``, ``gb-status``)
        self.run_panel = JobPanel(self.jobs, "gearbox", "gb")
        self.run_panel.say("No verdict yet.")
        self.cancel_button, self.progress, self.status = (
            self.run_panel.cancel_button, self.run_panel.progress, self.run_panel.status)
        self.listen_button = pn.widgets.Button(label="Listen", css_classes=["gb-listen"])
        self.audio = pn.pane.Audio(None, sample_rate=48_000, name="gearbox sound", volume=100,
                                   css_classes=["gb-audio"])  # volume set: see app.views.sound
        self.listen_status = pn.pane.HTML("", css_classes=["gb-listen-status"])
        self.csv_download = pn.widgets.FileDownload(callback=self.csv, filename="gearbox_verdict.csv",
                                                    label="Verdict as CSV", disabled=True,
                                                    css_classes=["gb-csv"], sizing_mode="stretch_width")
        self.report_download = pn.widgets.FileDownload(
            callback=lambda: io.StringIO(self.report), filename="gearbox_report.html",
            label="Report (HTML)", disabled=True, css_classes=["gb-report"], sizing_mode="stretch_width")
        self.toml_input.param.watch(self._on_toml, "value")
        self.toml_b_input.param.watch(self._on_toml_b, "value")
        self.copy_button.on_click(lambda e: self.copy_design())
        self.target_input.param.watch(lambda e: self.set_target(e.new), "value")
        self.settings.param.watch(lambda e: setattr(self.target_input, "value", e.new), "target")
        self.add_button.on_click(lambda e: self._add_gear())
        self.remove_button.on_click(lambda e: self._remove_gear())
        self.run_button.on_click(lambda e: self.run())
        self.cancel_button.on_click(lambda e: self.cancel("Cancelled."))
        self.listen_button.on_click(lambda e: self.listen())
        self.plots = {key: HoloViewsPane(self._plot(key), sizing_mode="stretch_width",
                                         css_classes=[f"gb-{key}-plot"]) for key in PLOTS}
        # a new measurement replaces the gearbox file's constant orders
        self.measurement.param.watch(lambda e: setattr(self, "constant", None), "revision")
        # a new verdict may bring other gears, hence other layers: each plot is built afresh
        self.param.watch(lambda e: self._redraw(), "revision")

    def _plot(self, key: str) -> hv.DynamicMap:
        """Plot ``key`` of :data:`PLOTS` as a DynamicMap following this view's results."""
        with plot_lock():
            draw = {"regimes": lambda: regime_plot(self.base, self.variant),
                    "intensity": lambda: metric_plot(self.base, self.variant, "intensity",
                                                     "intensity Σ I²/s [N²·s]", logy=True),
                    "loudness": lambda: metric_plot(self.base, self.variant, "loudness_sone",
                                                    "loudness N5 [sone]")}[key]
            return hv.DynamicMap(lambda revision: draw(), streams=[hv.streams.Params(self, ["revision"])])

    def _redraw(self) -> None:
        for key in PLOTS:
            self.plots[key].object = self._plot(key)

    def __panel__(self):
        s, st = self.settings, self.state

        def field(name: str, css: str) -> Field:
            return Field(s, name, slider=False, css=css)
        controls = pn.Column(
            self.measurement,
            pn.pane.Markdown("**2. Gears** (edit the table, or upload a GEARBOX.toml)"),
            self.table, pn.Row(self.add_button, self.remove_button), self.toml_input,
            message(st, "gearbox-gears"),
            pn.pane.Markdown("**3. Verdict**"),
            pn.Row(field("rpm_start", "gb-rpm-start"), field("rpm_stop", "gb-rpm-stop"),
                   field("rpm_num", "gb-rpm-num"), sizing_mode="stretch_width"),
            pn.Row(field("transient", "gb-transient"), field("record", "gb-record"),
                   field("transfer", "gb-transfer"), sizing_mode="stretch_width"),
            pn.pane.Markdown("Target (sone and/or dB(A) over rpm; empty: the file's)"),
            self.target_input, message(s, "target"),
            Field(s, "oil_temp", slider=False, css="gb-oil-temp", placeholder="the file's"),
            pn.widgets.Select.from_param(s.param.variant, options=VARIANTS, css_classes=["gb-variant"]),
            pn.Row(field("drag_pct", "gb-drag-pct"), field("backlash_change_um", "gb-backlash-change"),
                   sizing_mode="stretch_width"),
            pn.pane.Markdown("Design B's gears (edit a copy, or upload its GEARBOX.toml)"),
            self.copy_button, self.table_b, self.toml_b_input, message(st, "gearbox-design-b"),
            pn.Row(self.run_button, self.cancel_button, sizing_mode="stretch_width"),
            message(st, "gearbox-run"), self.progress, self.status,
            pn.Row(self.csv_download, self.report_download, sizing_mode="stretch_width"),
            pn.pane.Markdown("**4. Listen** to the whole gearbox"),
            pn.Row(field("listen_rpm", "gb-listen-rpm"), self.listen_button),
            message(st, "gearbox-listen"), self.listen_status, self.audio,
            width=460, margin=(0, 10))
        plots = pn.Column(self.measurement.plots(), *self.plots.values(), self.side_by_side,
                          sizing_mode="stretch_width")
        return pn.Row(controls, plots, sizing_mode="stretch_width")

    # ----- the measurement and the gears --------------------------------------------------

    @property
    def order_map(self) -> Any:
        """The measurement's order map shown (None before one)."""
        return self.measurement.order_map

    def measure(self, data: bytes | None) -> None:
        """Read and analyse a measurement (``None``: the sample) in the background."""
        self.measurement.measure(data)

    _file_error = staticmethod(work.file_error)

    def _on_toml(self, event) -> None:
        data = self.measurement.upload(event.new, "gearbox-gears", work.MAX_TOML_BYTES)
        if data is None:
            return
        self.jobs.submit("gearbox-toml", work.gearbox_text, (data, self.order_map),
                         time_limit=120.0, on_done=self._toml_read,
                         on_error=lambda m: self.state.say("gearbox-gears", m))

    def _toml_read(self, box: Any) -> None:
        self.oil = box.oil
        self.drags = {g.name: g.drag for g in box.gears if g.drag_torque_Nm is None}
        self.table.value = pd.DataFrame(work.gear_rows(box), columns=COLUMNS)
        if self.settings.target in ("", self.file_target):  # what the user typed stays
            self.file_target = "" if box.target is None else vt.target_text(box.target)
            self.set_target(self.file_target)
        exc = box.excitation
        self.settings.param.update(engine_order=exc.engine_order, harmonics=exc.harmonics,
                                   transfer=box.transfer_pa_per_ns)
        if exc.order_map is None:
            self.constant = exc
            self.measurement.say("Constant orders from the gearbox file.")
        elif exc.order_map is not self.order_map:
            self.measurement.campbell = None
            self.measurement.show(exc.order_map)

    def _on_toml_b(self, event) -> None:
        data = self.measurement.upload(event.new, "gearbox-design-b", work.MAX_TOML_BYTES)
        if data is None:
            return
        self.jobs.submit("gearbox-toml-b", work.gearbox_text, (data, self.order_map),
                         time_limit=120.0, on_done=self._toml_b_read,
                         on_error=lambda m: self.state.say("gearbox-design-b", m))

    def _toml_b_read(self, box: Any) -> None:
        self.table_b.value = pd.DataFrame(work.gear_rows(box), columns=COLUMNS)
        self.settings.variant = "design"

    def copy_design(self) -> None:
        """Design B starts as a copy of the gears, to be edited."""
        self.table_b.value = self.table.value.copy()
        self.settings.variant = "design"

    def set_target(self, text: str) -> bool:
        """Take the target text, or leave the reason beside it (plain text); True if taken."""
        text = str(text or "").strip()
        if set_value(self.settings, "target", text):
            self.settings.clear("target")
            return True
        return False

    def _add_gear(self) -> None:
        df = self.table.value
        if len(df) >= MAX_GEARS:
            self.state.say("gearbox-gears", f"a gearbox here has at most {MAX_GEARS} gears")
            return
        row = (df.iloc[-1:] if len(df) else DEFAULT_GEARS.iloc[:1]).copy()
        row["name"] = f"gear {len(df) + 1}"
        self.table.value = pd.concat([df, row], ignore_index=True)

    def _remove_gear(self) -> None:
        if len(self.table.value) > 1:
            self.table.value = self.table.value.iloc[:-1].reset_index(drop=True)

    def gearbox(self, table: Any = None) -> Gearbox:
        """The gearbox the tab describes (with the gears of ``table``, default the first);
        ``ValueError`` naming what is wrong."""
        s = self.settings
        gears = work.gears_of((self.table if table is None else table).value, COLUMNS, self.drags)
        if self.constant is not None:
            exc_ = self.constant
        elif self.order_map is None:
            raise ValueError("load a measurement or take the sample run-up first")
        else:
            exc_ = Excitation(engine_order=s.engine_order, harmonics=s.harmonics, order_map=self.order_map)
        needs_oil = any(g.drag.needs_oil for g in gears)
        return Gearbox(excitation=exc_, gears=tuple(gears), transfer_pa_per_ns=s.transfer,
                       oil=self.oil if needs_oil else None)

    def variant_of(self, box: Gearbox) -> tuple[Gearbox | None, str]:
        """The what-if gearbox the settings ask for, and its name."""
        s = self.settings
        if s.variant == "drag":
            return box.replace(gears=tuple(scaled_drag(g, 1 + s.drag_pct / 100) for g in box.gears)
                               ), f"drag torque {s.drag_pct:+g} %"
        if s.variant == "backlash":
            return box.replace(gears=tuple(g.replace(backlash_um=g.backlash_um + s.backlash_change_um)
                                           for g in box.gears)), f"backlash {s.backlash_change_um:+g} µm"
        if s.variant == "design":
            try:
                other = self.gearbox(self.table_b)
            except ValueError as exc:
                raise ValueError(f"design B, {exc}") from None
            return other.replace(target=box.target, oil_temp_C=box.oil_temp_C), "design B"
        return None, ""

    def with_settings(self, box: Gearbox) -> Gearbox:
        """``box`` with the tab's target and oil temperature (``ValueError`` naming them)."""
        s = self.settings
        if self.target is not None:
            box = box.replace(target=self.target)
        if s.oil_temp is not None:
            try:
                box = box.replace(oil_temp_C=float(s.oil_temp))
            except ValueError as exc:
                raise ValueError(f"oil temperature: {exc}") from None
        return box

    # ----- the verdict --------------------------------------------------------------------

    def run(self) -> bool:
        """Start the verdict (and its variant) in the background; False with a message if the
        request cannot run."""
        s, st = self.settings, self.state
        st.clear("gearbox-run", "gearbox-gears")
        try:
            box = self.gearbox()
        except ValueError as exc:
            st.say("gearbox-gears", str(exc))
            return False
        try:
            self.target = Target.parse(s.target) if s.target else None
            box = self.with_settings(box)
            variant, text = self.variant_of(box)
            if not s.rpm_start < s.rpm_stop:
                raise ValueError(f"rpm from ({s.rpm_start:g}) must be below rpm to ({s.rpm_stop:g})")
            rpm = np.linspace(s.rpm_start, s.rpm_stop, s.rpm_num)
            for b in (box, variant):
                if b is not None:
                    b.physical(0, float(rpm[0]))
                    b.physical(0, float(rpm[-1]))
            check_verdict_rpm(rpm, box)
        except ValueError as exc:
            st.say("gearbox-run", str(exc))
            return False
        self.variant_text = text
        self.run_panel.submit(
            object(), work.verdicts, (box, variant, rpm, s.transient, s.record, text,
                                      self.provenance()),
            f"Computing {len(box.gears)} gears × {rpm.size} speeds"
            f"{' and the variant' if variant is not None else ''}…", 600.0,
            on_done=self._done, on_error=self._error)
        return True

    def provenance(self) -> dict:
        """The measurement's name and hash, and the tab's settings, for the report."""
        s = self.settings
        out = dict(self.measurement.identity)
        out["campbell"] = self.measurement.campbell
        out["settings"] = {"target": s.target or "none", "what-if": self.variant_text or s.variant}
        if s.oil_temp is not None:
            out["settings"]["oil temperature [°C]"] = s.oil_temp
        return out

    @property
    def job(self) -> Any:
        """The running verdict's job, or None."""
        return self.run_panel.job

    def cancel(self, text: str | None = None) -> None:
        self.run_panel.stop(text)

    def _error(self, msg: str) -> None:
        self.run_panel.say("No verdict: see the message above.")
        self.state.say("gearbox-run", f"The verdict could not be computed: {msg}")

    def _done(self, result: tuple) -> None:
        self.base, self.variant, self.report = result
        how = "from the disk cache" if self.base.from_cache else "computed"
        text = f"Verdict ({how}) — {work.onsets_text(self.base.onsets)}."
        if self.variant is not None:
            text += f" Variant ({self.variant_text}): {work.onsets_text(self.variant.onsets)}."
        self.run_panel.say(text)
        self.csv_download.disabled = False
        self.report_download.disabled = not self.report
        self.side_by_side.object = self.side_by_side_html()
        self.revision += 1

    def side_by_side_frame(self) -> pd.DataFrame:
        """Per gear and for the gearbox: onset, ranges, loudness, dB(A) and pass of the first
        design and, if there is one, the second."""
        return work.side_by_side(self.base, self.variant)

    def side_by_side_html(self) -> str:
        if self.base is None:
            return ""
        df = self.side_by_side_frame()
        return "<b>Side by side</b>" + df.to_html(index=False, escape=True, float_format="%.4g",
                                                  na_rep="—")

    def csv(self) -> io.StringIO:
        """The verdict as CSV (:func:`app.work.gearbox.verdict_csv`)."""
        return io.StringIO(work.verdict_csv(self.base, self.variant, self.variant_text))

    # ----- listening ----------------------------------------------------------------------

    def listen(self) -> bool:
        """Render the whole gearbox at the chosen speed in the background."""
        st = self.state
        st.clear("gearbox-listen")
        try:
            box = self.gearbox()
            box.physical(0, self.settings.listen_rpm)
            check_verdict_rpm([self.settings.listen_rpm], box)
        except ValueError as exc:
            st.say("gearbox-listen", str(exc))
            return False
        self.listen_status.object = text_html(f"Rendering {work.LISTEN_SECONDS:g} s at "
                                              f"{self.settings.listen_rpm:g} rpm…")
        self.jobs.submit("gearbox-sound", work.sound, (box, self.settings.listen_rpm), time_limit=120.0,
                         on_done=self._heard, on_error=lambda m: st.say("gearbox-listen", m))
        return True

    def _heard(self, out: dict) -> None:
        self.audio.param.update(object=out["signal"], sample_rate=int(out["rate"]))
        self.listen_status.object = text_html(
            f"The gearbox at {out['rpm']:g} rpm: {out['sone']:.3g} sone, peak {out['peak_pa']:.3g} Pa "
            "(played normalised).")
