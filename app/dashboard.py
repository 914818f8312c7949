"""One dashboard session: widgets, views and the wiring between them and the state.

Data flows one way: widgets, presets, plot clicks and the URL write the
:class:`~app.state.DashboardState` (always through validation); a change of state runs
:meth:`Dashboard.refresh`, which simulates once and redraws every view from that one
trajectory. A rejected value leaves a message beside its control and the last good state,
so the views never show a half-applied change.

Every callback is guarded: an exception becomes a message in this session and one log line,
never a traceback, and never touches another session.
"""
from __future__ import annotations

import functools
import io
import json
import logging
import math
import re
import time
import urllib.parse
from typing import Any, Callable

import numpy as np
import panel as pn
from bokeh.events import RangesUpdate, Reset, Tap

from rattle_core import SolverError, classify, simulate, units
from rattle_core import contact_boundary
from rattle_core.model.excitation import excitation

from . import background, maps_panel, sound_panel, units_panel, views
from .panel_base import guard
from .state import (FIELDS, PRESETS, URL_KEYS, DashboardState, apply_values, format_harmonics,
                    initial_x, parse_harmonics, rattle_params, validate_field)

log = logging.getLogger(__name__)

#: Main sliders, in display order.
SLIDERS = ("lam", "r", "j", "h2", "phi2")
#: Controls inside the collapsible "Advanced" card, which opens to show their messages.
ADVANCED = ("periods", "shown", "transient", "v_stick", "x0", "v0", "t0", "harmonics", "strobe")
#: Points per diagram computed in the background (whole range, then each zoomed region).
BIF_VALUES = {"lam": 400, "phi2": 361, "rpm": 400}
ZOOM_VALUES = 300
BIF_RANGES = {"lam": (0.5, 4.0), "phi2": (-180.0, 180.0), "rpm": (500.0, 6000.0)}
BIF_PERIODS = {"transient": 300, "record": 100}
BIF_AXIS = {"lam": "Λ", "phi2": "φ₂ (degrees, core convention)", "rpm": "engine speed (rpm)"}
#: Diagram choices; "Ĩ vs rpm" joins them while the physical-units mode is on.
BIF_OPTIONS = {"Ĩ vs Λ": "lam", "Ĩ vs φ₂": "phi2"}


#: Callbacks of the dashboard: an exception becomes the page-level message.
guarded = guard(None)


class Dashboard:
    """Everything one browser session sees; build with :func:`app.main.create_app`."""

    def __init__(self, sync_url: bool = True, location: Any = None):
        self.doc = pn.state.curdoc
        self.state = DashboardState()
        self.tr = None
        self.classification = None
        self._syncing = False
        self._last_good: dict[str, Any] | None = None
        self._job: background.Job | None = None
        self._bif_key: tuple | None = None
        self._bif: background.Diagram | None = None
        self._bif_view: tuple[float, float, float, float] | None = None
        self._section_view: tuple[float, float, float, float] | None = None
        self._section_xy: tuple[np.ndarray, np.ndarray] | None = None
        self._zoom_timer = None
        self._fine: list[tuple[float, float]] = []
        self._overlay_key: tuple | None = None
        self.last_update_ms = math.nan
        # the physical-units panel sets this to its PhysicalParams while its mode is on
        self.physical: units.PhysicalParams | None = None
        # the page's URL (None without one); the physical-units keys last written to it
        self._location = (location if location is not None
                          else pn.state.location if sync_url else None)
        self._units_query: dict[str, str] | None = {}

        self._build_widgets()
        self._build_views()
        # Feature panels: each brings its own widgets and is told after every good redraw.
        self.panels = [units_panel.UnitsPanel(self), sound_panel.SoundPanel(self),
                       maps_panel.MapsPanel(self)]
        url_errors: dict[str, str] = {}
        if self._location is not None:
            url_errors = self._sync_url(self._location)
        if "global" in url_errors:
            self.show_error(None, f"URL: {url_errors['global']}")
        self.refresh()
        self._state_to_widgets()
        self.state.param.watch(self._on_state, list(URL_KEYS))
        self.layout = self._build_layout()
        if self.doc is not None and self.doc.session_context is not None:
            pn.state.on_session_destroyed(self._on_destroyed)
            pn.state.onload(self.settle)

    @guarded
    def settle(self) -> None:
        """Re-render the text panes once the page is live.

        A pane's first update after its document is attached swaps its stylesheet models,
        which makes Bokeh re-walk every model of the document (about 50 ms per pane). Doing it
        while the page loads keeps that cost off the user's first slider move.
        """
        for pane in (self.badge, self.metrics, self.timing, self.bif_status, self.harm_list):
            pane.param.trigger("object")

    # ----- construction -------------------------------------------------------------------

    def _build_widgets(self) -> None:
        s = self.state
        self.alerts = {name: pn.pane.Alert("", alert_type="danger", visible=False, margin=(0, 10),
                                           css_classes=[f"msg-{name}"], sizing_mode="stretch_width")
                       for name in list(URL_KEYS)}
        self.global_alert = pn.pane.Alert("", alert_type="danger", visible=False,
                                          css_classes=["msg-global"], sizing_mode="stretch_width")
        self.widgets: dict[str, Any] = {}
        for name in SLIDERS:
            f = FIELDS[name]
            self.widgets[name] = pn.widgets.EditableFloatSlider(
                label=f.label, value=getattr(s, name), start=f.start, end=f.end, step=f.step,
                format="0[.]00[00]", sizing_mode="stretch_width", css_classes=[f"ctl-{name}"])
        for name in ("periods", "shown", "transient"):
            f = FIELDS[name]
            self.widgets[name] = pn.widgets.IntInput(label=f.label, value=getattr(s, name),
                                                     step=1, css_classes=[f"ctl-{name}"],
                                                     sizing_mode="stretch_width")
        for name in ("v_stick", "v0", "t0"):
            f = FIELDS[name]
            self.widgets[name] = pn.widgets.FloatInput(label=f.label, value=getattr(s, name),
                                                       css_classes=[f"ctl-{name}"],
                                                       sizing_mode="stretch_width")
        self.widgets["x0"] = pn.widgets.FloatInput(label=FIELDS["x0"].label, value=None,
                                                   placeholder="middle of the backlash",
                                                   css_classes=["ctl-x0"], sizing_mode="stretch_width")
        f = FIELDS["strobe"]
        self.widgets["strobe"] = pn.widgets.EditableFloatSlider(
            label=f.label, value=s.strobe, start=f.start, end=f.end, step=f.step,
            css_classes=["ctl-strobe"], sizing_mode="stretch_width")
        self.widgets["section"] = pn.widgets.RadioButtonGroup(
            options={"Poincaré (x, ẋ)": "absolute", "relative (x−y, ẋ−ẏ)": "relative",
                     "impact map": "impact"}, value=s.section, css_classes=["ctl-section"],
            color="default", sizing_mode="stretch_width")
        self.widgets["bif"] = pn.widgets.RadioButtonGroup(
            options=dict(BIF_OPTIONS), value="lam" if s.bif == "rpm" else s.bif,
            css_classes=["ctl-bif"], sizing_mode="stretch_width")
        self.widgets["overlays"] = pn.widgets.Checkbox(
            label="overlays: contact boundary Λ_c and 2πn/Λ", value=s.overlays,
            css_classes=["ctl-overlays"])
        for name, w in self.widgets.items():
            w.param.watch(functools.partial(self._on_widget, name), "value")
        self.bif_si = pn.widgets.Checkbox(label="impulse in N·s", value=False, visible=False,
                                          css_classes=["ctl-bif-si"])
        self.bif_si.param.watch(self._on_bif_si, "value")

        # harmonics beyond the second: add or remove orders
        self.harm_order = pn.widgets.IntInput(label="order k", value=3, start=3, end=32, width=80)
        self.harm_amp = pn.widgets.FloatInput(label="H_k/H₁", value=0.1, width=90)
        self.harm_phase = pn.widgets.FloatInput(label="φ_k (°)", value=0.0, width=90)
        self.harm_add = pn.widgets.Button(label="add / set", color="primary", width=90,
                                          align="end", css_classes=["harm-add"])
        self.harm_remove = pn.widgets.Button(label="remove order k", width=120, align="end")
        self.harm_add.on_click(self._on_harm_add)
        self.harm_remove.on_click(self._on_harm_remove)
        self.harm_list = pn.pane.Markdown("", css_classes=["harm-list"], margin=(0, 10))

        self.preset_buttons = []
        for label, (desc, _) in PRESETS.items():
            b = pn.widgets.Button(label=label, description=desc, width=72, margin=(2, 3),
                                  css_classes=[f"preset-{label.replace(' ', '')}"])
            b.on_click(functools.partial(self._on_preset, label))
            self.preset_buttons.append(b)

        self.progress = pn.indicators.Progress(value=0, max=100, visible=False, bar_color="info",
                                               sizing_mode="stretch_width", height=14,
                                               css_classes=["bif-progress"])
        self.bif_status = pn.pane.Markdown("", css_classes=["bif-status"], margin=(0, 10))
        self.badge = pn.pane.HTML("", css_classes=["regime-badge"], sizing_mode="stretch_width")
        self.metrics = pn.pane.HTML("", css_classes=["rattle-metrics"])
        self.timing = pn.pane.Markdown("", css_classes=["timing"], margin=(0, 10),
                                       styles={"color": "#777", "font-size": "11px"})
        self.download = pn.widgets.FileDownload(callback=self._csv, filename="impacts.csv",
                                                label="Impacts as CSV", color="success",
                                                css_classes=["download-csv"])

    def _build_views(self) -> None:
        self.th_fig, self.th_src = views.time_history_figure()
        self.sec_fig, self.sec_src = views.section_figure()
        self.bif_fig, self.bif = views.bifurcation_figure()
        for key, src in self.th_src.items():
            src.name = f"th_{key}"
        self.sec_src["points"].name = "sec_points"
        self.sec_src["image"].name = "sec_image"
        self.bif["sources"]["image"].name = "bif_image"
        self.sec_fig.on_event(Tap, self._on_section_tap)
        self.sec_fig.on_event(RangesUpdate, self._on_section_range)
        self.sec_fig.on_event(Reset, self._on_section_reset)
        self.bif_fig.on_event(Tap, self._on_bif_tap)
        self.bif_fig.on_event(RangesUpdate, self._on_bif_range)
        self.bif_fig.on_event(Reset, self._on_bif_reset)

    def _build_layout(self) -> pn.template.BootstrapTemplate:
        def ctl(name: str) -> pn.Column:
            return pn.Column(self.widgets[name], self.alerts[name], sizing_mode="stretch_width",
                             margin=0)
        presets = pn.FlexBox(*self.preset_buttons, sizing_mode="stretch_width")
        self.advanced = advanced = pn.Card(
            ctl("periods"), ctl("shown"), ctl("transient"), ctl("v_stick"),
            pn.pane.Markdown("**Initial state** (a click on the Poincaré map sets it)", margin=(5, 10, 0, 10)),
            ctl("x0"), ctl("v0"), ctl("t0"),
            pn.pane.Markdown("**More harmonics** y = Σ h_k cos(k t − φ_k)", margin=(5, 10, 0, 10)),
            pn.Row(self.harm_order, self.harm_amp, self.harm_phase),
            pn.Row(self.harm_add, self.harm_remove), self.harm_list, self.alerts["harmonics"],
            ctl("strobe"),
            title="Advanced", sizing_mode="stretch_width", css_classes=["advanced"],
            collapsed=not any(self.alerts[n].visible for n in ADVANCED))
        sidebar = [
            pn.pane.Markdown("### Paper presets (Figures 2–8)", margin=(0, 10)), presets,
            pn.pane.Markdown("### Parameters", margin=(0, 10)),
            *[ctl(n) for n in SLIDERS],
            advanced,
            pn.pane.Markdown("### Export", margin=(0, 10)),
            self.download,
            pn.pane.Markdown("Plots: use the save tool (disk icon) in each plot's toolbar.",
                             margin=(0, 10), styles={"font-size": "12px"}),
            *[obj for panel in self.panels for obj in panel.sidebar],
        ]
        top = pn.Row(self.badge, self.metrics, sizing_mode="stretch_width")
        section = pn.Column(ctl("section"), self.sec_fig, sizing_mode="stretch_width")
        bif = pn.Column(pn.Row(self.widgets["bif"], self.widgets["overlays"], self.bif_si,
                               sizing_mode="stretch_width"),
                        self.alerts["bif"], self.progress, self.bif_status, self.bif_fig,
                        sizing_mode="stretch_width")
        # the plots stay where the eye lands first; the panels' extras follow them
        explorer = pn.Column(top, self.th_fig, pn.Row(section, bif, sizing_mode="stretch_width"),
                             *[obj for panel in self.panels for obj in panel.explorer],
                             self.timing, sizing_mode="stretch_width")
        self.tabs = pn.Tabs(("Explorer", explorer),
                            *[panel.tab for panel in self.panels if panel.tab is not None],
                            sizing_mode="stretch_width", css_classes=["main-tabs"])
        main = [self.global_alert, self.tabs]
        return pn.template.BootstrapTemplate(
            title="Rattle Explorer: gear rattle, exactly", sidebar=sidebar, main=main,
            sidebar_width=360, header_background="#2c3e50")

    # ----- URL ----------------------------------------------------------------------------

    def _sync_url(self, location) -> dict[str, str]:
        """Sync the state with the query string; return messages for rejected parameters.

        The query may also arrive after the session is built (the browser reports it), so
        rejections are shown, and the URL corrected to the state shown, from the callback too.
        """
        errors: dict[str, str] = {}

        def on_error(values: dict) -> None:
            # the location applies a batch at once; retry one by one so good values still land
            rejected = apply_values(self.state, values)
            errors.update(rejected)
            for name, msg in rejected.items():
                self.show_error(name if name in URL_KEYS else None, f"URL: {msg}")
            fix = {k: self._url_value(k) for k in rejected if k in URL_KEYS}
            if fix:
                location.update_query(**fix)

        location.sync(self.state, URL_KEYS, on_error=on_error)
        for key in location.query_params:
            if key not in URL_KEYS and key not in units_panel.URL_KEYS:
                errors.setdefault("global", f"unknown URL parameter {key!r} ignored")
        # the physical-units mode after the state, so its inputs win over Λ, j, h₂, φ₂
        rejected = self._restore_units(location.search)
        if "units" in rejected:
            errors.setdefault("global", rejected["units"])
        # the browser reports the link's query again once connected: after the state has
        # taken it (Panel's watcher runs first), the physical inputs win again
        location.param.watch(self._on_search, "search")
        return errors

    def _restore_units(self, search: str) -> dict[str, str]:
        """Restore the physical-units mode from a query string; return its rejected keys."""
        raw = dict(urllib.parse.parse_qsl(search[1:], keep_blank_values=True))
        panel = self._units_panel()
        rejected = panel.restore_url(raw) if panel is not None else {}
        if any(key in raw for key in units_panel.URL_KEYS):
            self._units_query = None  # correct the link to the inputs shown
        self.write_units_url()
        return rejected

    @guarded
    def _on_search(self, event) -> None:
        raw = urllib.parse.parse_qsl(event.new[1:], keep_blank_values=True)
        linked = {k: v for k, v in raw if k in units_panel.URL_KEYS}
        if not linked or linked == self._units_query:
            return  # no physical-units key, or the ones this session wrote
        rejected = self._restore_units(event.new)
        if "units" in rejected:
            self.show_error(None, f"URL: {rejected['units']}")

    def write_units_url(self) -> None:
        """Put the physical-units mode and its inputs in the URL while it is on, and only then."""
        location, panel = self._location, self._units_panel()
        if location is None or panel is None:
            return
        want = panel.url_values()
        if want == self._units_query:
            return
        self._units_query = want
        query = {k: v for k, v in urllib.parse.parse_qsl(location.search[1:], keep_blank_values=True)
                 if k not in units_panel.URL_KEYS}
        query.update(want)
        location.search = "?" + urllib.parse.urlencode(query) if query else ""

    def _url_value(self, name: str) -> str:
        """The state's value of ``name`` as the URL carries it."""
        v = getattr(self.state, name)
        return v if isinstance(v, str) else json.dumps(v)

    # ----- messages -----------------------------------------------------------------------

    def show_error(self, name: str | None, message: str) -> None:
        alert = self.alerts.get(name) if name else None
        alert = alert or self.global_alert
        alert.object = message
        alert.visible = True
        if name in ADVANCED and getattr(self, "advanced", None) is not None:
            self.advanced.collapsed = False

    def clear_error(self, name: str | None) -> None:
        alert = self.alerts.get(name) if name else None
        alert = alert or self.global_alert
        if alert.visible:
            alert.visible = False
            alert.object = ""

    @staticmethod
    def field_of_error(message: str) -> str | None:
        """Which control a core ``ValueError`` is about, from the name it starts with."""
        m = re.match(r"\s*([A-Za-z_0-9θΛφ]+)(\[(\d+)\])?", message)
        if not m:
            return None
        word, idx = m.group(1), m.group(3)
        if word in ("amplitudes", "phases_deg") and idx is not None:
            if int(idx) == 1:
                return "h2" if word == "amplitudes" else "phi2"
            return "harmonics"
        return {"lam": "lam", "Λ": "lam", "r": "r", "j": "j", "v_stick": "v_stick", "x0": "x0",
                "v0": "v0", "t0": "t0", "periods": "periods", "transient": "transient",
                "strobe_phase": "strobe"}.get(word)

    # ----- state changes --------------------------------------------------------------------

    @guarded
    def _on_widget(self, name: str, event) -> None:
        if self._syncing:
            return
        value = event.new
        if name == "x0" and value is None:
            value = ""
        try:
            clean = validate_field(name, value)
        except ValueError as exc:
            self.show_error(name, f"{exc}. Kept {self._display(name)}.")
            self._state_to_widgets([name])
            return
        self.clear_error(name)
        if getattr(self.state, name) != clean:
            setattr(self.state, name, clean)

    def _display(self, name: str) -> str:
        f = FIELDS.get(name)
        v = getattr(self.state, name)
        if name == "x0" and v == "":
            return "x₀ = middle of the backlash"
        return f"{f.symbol} = {v:g}" if f and isinstance(v, (int, float)) else f"{name} = {v!r}"

    @guarded
    def _on_state(self, *events) -> None:
        if self._syncing:
            return
        self._state_to_widgets([e.name for e in events])
        if self.global_alert.visible and not self.global_alert.object.startswith("URL"):
            self.clear_error(None)
        if self.refresh() is None:
            # only user-driven redraws: the first one pays for building the session
            self.timing.object = f"last redraw: {self.last_update_ms:.0f} ms server time"

    def _state_to_widgets(self, names=None) -> None:
        self._syncing = True
        try:
            for name in names or self.widgets:
                if name not in self.widgets:
                    continue
                w, v = self.widgets[name], getattr(self.state, name)
                if name == "x0":
                    v = None if v == "" else float(v)
                if isinstance(w, pn.widgets.EditableFloatSlider):
                    f = FIELDS[name]
                    # reset a range stretched by a typed value, then stretch it to fit this one
                    want = {"start": min(f.start, v), "end": max(f.end, v), "value": v}
                    changes = {k: x for k, x in want.items() if getattr(w, k) != x}
                    if changes:
                        w.param.update(**changes)
                elif w.value != v:
                    w.value = v
            self.harm_list.object = self._harmonics_text()
        finally:
            self._syncing = False

    def _harmonics_text(self) -> str:
        harm = parse_harmonics(self.state.harmonics)
        if not harm:
            return "*no harmonic beyond the second*"
        return "  \n".join(f"k = {k}: H_k/H₁ = {h:g}, φ_k = {p:g}°" for k, (h, p) in harm.items())

    @guarded
    def _on_preset(self, label: str, event=None) -> None:
        self.apply_preset(label)

    def apply_preset(self, label: str) -> None:
        """Load a paper preset: every parameter it names, in one redraw."""
        _, values = PRESETS[label]
        for name in values:
            self.clear_error(name)
        self.clear_error(None)
        errors = apply_values(self.state, values)
        for name, msg in errors.items():
            self.show_error(name, msg)

    @guarded
    def _on_harm_add(self, event=None) -> None:
        harm = parse_harmonics(self.state.harmonics)
        try:
            k = self.harm_order.value
            text = format_harmonics({**harm, int(k): (self.harm_amp.value, self.harm_phase.value)})
            clean = validate_field("harmonics", text)
        except (TypeError, ValueError) as exc:
            self.show_error("harmonics", f"{exc}. Kept the harmonics as they were.")
            return
        self.clear_error("harmonics")
        self.state.harmonics = clean

    @guarded
    def _on_harm_remove(self, event=None) -> None:
        harm = parse_harmonics(self.state.harmonics)
        k = self.harm_order.value
        if k not in harm:
            self.show_error("harmonics", f"order {k} is not among the extra harmonics")
            return
        del harm[k]
        self.clear_error("harmonics")
        self.state.harmonics = format_harmonics(harm)

    # ----- the update path ----------------------------------------------------------------

    def refresh(self) -> str | None:
        """Simulate once and redraw every view; return the name of a rejected field, or None.

        When the state cannot run, the field at fault (or, if unknown, the whole state) goes
        back to its last good value (its default before the first good draw), its message
        stays beside its control, and the views show the last good trajectory.
        """
        rejected = None
        for _ in range(len(URL_KEYS) + 1):
            failed = self._redraw()
            if failed is None:
                return rejected
            rejected = rejected or failed
            good = self._last_good or {k: DashboardState.param[k].default for k in URL_KEYS}
            if failed in URL_KEYS and getattr(self.state, failed) != good[failed]:
                names = [failed]
            else:
                names = list(URL_KEYS)
            self._set_quietly({k: good[k] for k in names})
        return rejected

    def _set_quietly(self, values: dict[str, Any]) -> None:
        """Change the state without triggering a redraw; the widgets follow."""
        changed = {k: v for k, v in values.items() if getattr(self.state, k) != v}
        if not changed:
            return
        self._syncing = True
        try:
            self.state.param.update(**changed)
        finally:
            self._syncing = False
        self._state_to_widgets(list(changed))

    def _redraw(self) -> str | None:
        t_start = time.perf_counter()
        s = self.state
        try:
            params = rattle_params(s)
            tr = simulate(params, periods=s.periods, x0=initial_x(s), v0=s.v0,
                          strobe_phase=math.radians(s.strobe), t0=s.t0, transient=s.transient,
                          lyapunov=True)
        except (ValueError, SolverError) as exc:
            field = self.field_of_error(str(exc)) if isinstance(exc, ValueError) else None
            self.show_error(field, f"{exc}. Showing the last good view.")
            return field or "global"
        self.tr, self.params = tr, params
        self.classification = classify(tr)
        self._draw_time_history()
        self._draw_section()
        self._draw_badge()
        self._update_bifurcation()
        self.download.filename = f"impacts_lam{s.lam:g}_r{s.r:g}_j{s.j:g}.csv"
        self._last_good = {k: getattr(s, k) for k in URL_KEYS}
        for panel in getattr(self, "panels", ()):
            panel.on_redraw()
        self.last_update_ms = 1e3 * (time.perf_counter() - t_start)
        return None

    def _draw_time_history(self) -> None:
        data = views.time_history_data(self.tr, min(self.state.shown, self.state.periods))
        views.update_time_history(self.th_src, data)

    def _draw_badge(self) -> None:
        self.badge.object = views.badge_html(self.classification)
        self.metrics.object = views.metrics_html(self.classification, self.tr)

    # ----- Poincaré / impact map --------------------------------------------------------------

    def _draw_section(self) -> None:
        mode = self.state.section
        x, y, xl, yl = views.section_points(self.tr, mode)
        self._section_xy = (x, y)
        self.sec_fig.xaxis.axis_label = xl
        self.sec_fig.yaxis.axis_label = yl
        theta = f"θ = {self.state.strobe:g}°"
        self.sec_fig.title.text = {"absolute": f"Poincaré map (x, ẋ) at {theta}",
                                   "relative": f"Relative Poincaré map at {theta}",
                                   "impact": "Impact map: impulse against impact phase"}[mode]
        xr, yr = views.padded_range(x), views.padded_range(y)
        self.sec_src["extent"].data = {"x": [xr[0], xr[1]], "y": [yr[0], yr[1]]}
        if len(x) > views.RASTER_THRESHOLD:
            self.sec_src["points"].data = {"x": [], "y": []}
            self._raster_section()
        else:
            self.sec_src["image"].data = dict(views.EMPTY_IMAGE)
            self.sec_src["points"].data = {"x": x, "y": y}
        if mode != "impact" and self.state.x0 != "":
            t0 = self.state.t0
            sx, sv = float(self.state.x0), self.state.v0
            if mode == "relative":
                p = self.params
                sx -= float(excitation(t0, p.h, p.phi))
                sv -= float(excitation(t0, p.h, p.phi, 1))
            self.sec_src["start"].data = {"x": [sx], "y": [sv]}
        else:
            self.sec_src["start"].data = {"x": [], "y": []}

    def _raster_section(self) -> None:
        if self._section_xy is None or len(self._section_xy[0]) <= views.RASTER_THRESHOLD:
            return
        x, y = self._section_xy
        if self._section_view is not None:
            xr, yr = self._section_view[:2], self._section_view[2:]
        else:
            xr, yr = views.padded_range(x), views.padded_range(y)
        w, h = self._pixels(self.sec_fig)
        self.sec_src["image"].data = views.rasterize(x, y, xr, yr, w, h, spread=1)

    @staticmethod
    def _pixels(fig) -> tuple[int, int]:
        def size(attr: str, default: int) -> int:
            try:  # known only once a browser has laid the plot out
                v = getattr(fig, attr)
            except Exception:
                return default
            return v if isinstance(v, int) and v > 0 else default
        # the browser does not report the frame size back; this matches the default layout
        return size("inner_width", 480), size("inner_height", 300)

    @guarded
    def _on_section_range(self, event) -> None:
        self._section_view = (event.x0, event.x1, event.y0, event.y1)
        self._raster_section()

    @guarded
    def _on_section_reset(self, event) -> None:
        self._section_view = None
        self._raster_section()

    @guarded
    def _on_section_tap(self, event) -> None:
        self.start_from_section(event.x, event.y)

    def start_from_section(self, x: float, y: float) -> None:
        """Start the gear at the clicked section point: (x₀, ẋ₀) at t₀ = the strobe phase."""
        mode = self.state.section
        if mode == "impact":
            self.show_error("section", "Switch to a Poincaré map to start the gear from a clicked point.")
            return
        t0 = math.radians(self.state.strobe)
        x0, v0 = float(x), float(y)
        if mode == "relative":
            p = self.params
            x0 += float(excitation(t0, p.h, p.phi))
            v0 += float(excitation(t0, p.h, p.phi, 1))
        y0 = float(excitation(t0, self.params.h, self.params.phi))
        if not y0 <= x0 <= y0 + self.params.j:
            self.show_error("x0", f"x₀ = {x0:.4g} is outside the backlash [{y0:.4g}, {y0 + self.params.j:.4g}] "
                                  f"at t₀ = {t0:.4g}; click between the teeth. Kept {self._display('x0')}.")
            return
        self.clear_error("section")
        apply_values(self.state, {"x0": repr(round(x0, 10)), "v0": round(v0, 10), "t0": round(t0, 12)})

    # ----- bifurcation diagram ------------------------------------------------------------------

    def _bif_request_key(self) -> tuple:
        name = self.state.bif
        if name == "rpm":
            # the dimensionless parameter an engine-speed sweep moves (Λ, or j with accelerations
            # held), and the physical constants that map it to rpm
            swept, _ = units.rpm_sweep(self.physical, self.physical.rpm)
            base = self.params.with_value(swept, 1.0)
            return (name, swept, repr(base.canonical()), repr(self.physical.with_rpm(1.0)))
        base = self.params.with_value(name, 1.0)
        return (name, repr(base.canonical()))

    def _units_panel(self) -> units_panel.UnitsPanel | None:
        return next((p for p in getattr(self, "panels", ()) if isinstance(p, units_panel.UnitsPanel)),
                    None)

    def units_changed(self) -> None:
        """The physical-units mode or its inputs changed: offer, update or withdraw "Ĩ vs rpm"."""
        on = self.physical is not None
        if not on and self.state.bif == "rpm":
            self.clear_error("bif")
            apply_values(self.state, {"bif": "lam"})
        options = {**BIF_OPTIONS, "Ĩ vs rpm": "rpm"} if on else dict(BIF_OPTIONS)
        if self.widgets["bif"].options != options:
            self._syncing = True
            try:
                self.widgets["bif"].options = options
            finally:
                self._syncing = False
        if on and self.state.bif == "rpm" and self.tr is not None:
            self._update_bifurcation()
        self.write_units_url()

    def _update_bifurcation(self) -> None:
        name = self.state.bif
        if name == "rpm":
            panel = self._units_panel()
            self.physical = panel.sync() if panel is not None else None
            if self.physical is None:  # units mode off: the engine-speed axis has no meaning
                self._set_quietly({"bif": "lam"})
                name = "lam"
        self.bif_si.visible = name == "rpm"
        self.bif_fig.xaxis.axis_label = BIF_AXIS[name]
        self.bif_fig.yaxis.axis_label = self._bif_y_label(name)
        value = self.physical.rpm if name == "rpm" else getattr(self.state, name)
        self.bif["marker"].location = value
        key = self._bif_request_key()
        if key != self._bif_key:
            self._bif_key = key
            self._fine = []
            self._start_base_diagram(name, value)
        self._draw_overlays()
        self.alerts["bif"].visible = False

    def _start_base_diagram(self, name: str, value: float) -> None:
        self._cancel_job()
        self._bif_view = None
        shipped = None if name == "rpm" else background.find_shipped(self.params, name)
        if shipped is not None:
            self._set_diagram(shipped, self._bif_key)
            return
        lo, hi = BIF_RANGES[name]
        if name in ("lam", "rpm"):
            lo, hi = min(lo, 0.8 * value), max(hi, 1.25 * value)
        values = np.linspace(lo, hi, BIF_VALUES[name])
        self._bif = None
        self.bif["sources"]["image"].data = dict(views.EMPTY_IMAGE)
        self.bif["sources"]["extent"].data = {"x": [lo, hi], "y": [0.0, 1.0]}
        self._submit(self._sweep_request(name, values), merge=False)

    def _sweep_request(self, name: str, values: np.ndarray) -> background.SweepRequest:
        """The background sweep behind diagram ``name`` at ``values`` (engine speeds for rpm)."""
        if name == "rpm":
            name, values = units.rpm_sweep(self.physical, values)
        return background.SweepRequest(self.params, name, tuple(float(v) for v in values),
                                       **BIF_PERIODS)

    def rpm_diagram(self, diagram: background.Diagram) -> background.Diagram:
        """A sweep of Λ (or j) along an engine-speed sweep, redrawn against rpm."""
        rpm = units.rpm_from_sweep(self.physical, diagram.name, diagram.value)
        return background.Diagram(name="rpm", value=np.asarray(rpm, dtype=np.float64),
                                  impulse=diagram.impulse, flank=diagram.flank,
                                  source=diagram.source, cancelled=diagram.cancelled)

    def _bif_y_label(self, name: str) -> str:
        if name == "rpm" and self.bif_si.value:
            return "impulse I (N·s, along the line of action)"
        return "impulse Ĩ (dimensionless)" if name == "rpm" else "impulse Ĩ"

    def _bif_points(self) -> tuple[np.ndarray, np.ndarray]:
        """The diagram's (x, impulse) as drawn: impulses in N·s when asked, against rpm."""
        d = self._bif
        if d.name == "rpm" and self.bif_si.value and self.physical is not None and d.value.size:
            return d.value, d.impulse * units.impulse_scale_from_rpm(self.physical, d.value)
        return d.value, d.impulse

    @guarded
    def _on_bif_si(self, event) -> None:
        self._bif_view = None
        self._overlay_key = None
        if self._bif is not None:
            self._set_diagram(self._bif, self._bif_key)
        else:
            self._draw_overlays()
        if self.state.bif == "rpm":
            self.bif_fig.yaxis.axis_label = self._bif_y_label("rpm")

    def _submit(self, req: background.SweepRequest, merge: bool) -> None:
        key = self._bif_key
        self._cancel_job()
        self.progress.param.update(value=0, visible=True)
        what = "the zoomed region" if merge else "the diagram"
        self.bif_status.object = f"Computing {what}: {len(req.values)} values in the background…"
        self._job = background.submit(
            req,
            on_progress=lambda frac: self._in_session(lambda: self._on_bif_progress(key, frac)),
            on_done=lambda d: self._in_session(lambda: self._on_bif_done(key, d, merge)),
            on_error=lambda msg: self._in_session(lambda: self._on_bif_error(key, msg)))

    def _cancel_job(self) -> None:
        if self._job is not None:
            self._job.cancel()
            self._job = None
        self.progress.visible = False

    def _in_session(self, fn: Callable[[], None]) -> None:
        """Run ``fn`` in this session's document (from the worker thread, on the next tick)."""
        doc = self.doc
        if doc is None or doc.session_context is None:
            fn()
            return
        from panel.io.state import set_curdoc

        def cb() -> None:
            with set_curdoc(doc):
                try:
                    fn()
                except Exception as exc:
                    log.warning("bifurcation update failed: %s: %s", type(exc).__name__, exc)
        try:
            doc.add_next_tick_callback(cb)
        except Exception:
            pass  # the session closed while the sweep ran; nothing left to update

    def _on_bif_progress(self, key: tuple, frac: float) -> None:
        if key == self._bif_key and self._job is not None:
            self.progress.value = int(100 * frac)

    def _on_bif_error(self, key: tuple, msg: str) -> None:
        if key != self._bif_key:
            return
        self.progress.visible = False
        self.bif_status.object = ""
        self.show_error("bif", f"The diagram could not be computed: {msg}")

    def _on_bif_done(self, key: tuple, diagram: background.Diagram, merge: bool) -> None:
        if key != self._bif_key:
            return
        self._job = None
        self.progress.visible = False
        if key[0] == "rpm":
            diagram = self.rpm_diagram(diagram)
        if merge and self._bif is not None:
            lo, hi = diagram.span
            keep = (self._bif.value < lo) | (self._bif.value > hi)
            self._fine.append((lo, hi))
            diagram = background.Diagram(
                name=diagram.name, value=np.concatenate([self._bif.value[keep], diagram.value]),
                impulse=np.concatenate([self._bif.impulse[keep], diagram.impulse]),
                flank=np.concatenate([self._bif.flank[keep], diagram.flank]),
                source=f"{self._bif.source}; Λ∈[{lo:.4g}, {hi:.4g}] refined" if diagram.name == "lam"
                else f"{self._bif.source}; [{lo:.4g}, {hi:.4g}] refined")
        self._set_diagram(diagram, key)

    def _set_diagram(self, diagram: background.Diagram, key: tuple) -> None:
        self._bif = diagram
        x, y = self._bif_points()
        xr = views.padded_range(x, 0.01)
        yr = views.padded_range(y)
        self.bif["sources"]["extent"].data = {"x": list(xr), "y": list(yr)}
        n_vals = len(np.unique(diagram.value))
        self.bif_status.object = f"{n_vals} values, {len(diagram.value)} impacts · {diagram.source}"
        self._raster_bif()
        self._draw_overlays()

    def _raster_bif(self) -> None:
        d = self._bif
        if d is None or len(d.value) == 0:
            self.bif["sources"]["image"].data = dict(views.EMPTY_IMAGE)
            return
        x, y = self._bif_points()
        if self._bif_view is not None:
            xr, yr = self._bif_view[:2], self._bif_view[2:]
        else:
            xr, yr = views.padded_range(x, 0.01), views.padded_range(y)
        w, h = self._pixels(self.bif_fig)
        self.bif["sources"]["image"].data = views.rasterize(
            x, y, xr, yr, w, h, category=d.flank,
            colors={1: views.ACTIVE_COLOR, -1: views.REVERSE_COLOR})

    def _draw_overlays(self) -> None:
        on = self.state.overlays
        name = self.state.bif
        if self._bif_view is not None:
            xr = self._bif_view[:2]
        elif self._bif is not None:
            xr = views.padded_range(self._bif.value, 0.01)
        else:
            xr = BIF_RANGES[name]
        key = (on, name, tuple(xr), self._bif_key, self.state.lam if name == "phi2" else None,
               self.bif_si.value)
        if key == self._overlay_key:
            return
        self._overlay_key = key
        lam_c = contact_boundary(self.params) if name in ("lam", "rpm") else None
        if name == "rpm":
            ov = views.rpm_overlay_lines(self.physical, xr, lam_c, self.bif_si.value)
        else:
            ov = views.overlay_lines(name, self.state.lam, xr, lam_c)
        self.bif["sources"]["curves"].data = ov["curves"] if on else {"xs": [], "ys": [], "n": []}
        b = self.bif["boundary"]
        if on and ov["boundary"] is not None:
            b.location = ov["boundary"]
            b.visible = True
        else:
            b.visible = False

    @guarded
    def _on_bif_tap(self, event) -> None:
        self.set_from_diagram(event.x)

    def set_from_diagram(self, x: float) -> None:
        """A click on the diagram sets the swept parameter to the clicked value."""
        name = self.state.bif
        if name == "rpm":
            panel = self._units_panel()
            msg = panel.set_rpm(round(float(x), 1)) if panel is not None else "units mode is off"
            if msg:
                self.show_error("bif", msg)
            else:
                self.clear_error("bif")
            return
        value = round(float(x), 4 if name == "lam" else 2)
        errors = apply_values(self.state, {name: value})
        if errors:
            self.show_error(name, f"{errors[name]}. Kept {self._display(name)}.")
        else:
            self.clear_error(name)

    @guarded
    def _on_bif_range(self, event) -> None:
        if None in (event.x0, event.x1, event.y0, event.y1):
            return
        self._bif_view = (float(event.x0), float(event.x1), float(event.y0), float(event.y1))
        self._raster_bif()
        self._draw_overlays()
        self._schedule_zoom()

    @guarded
    def _on_bif_reset(self, event) -> None:
        self._bif_view = None
        self._raster_bif()
        self._draw_overlays()

    def _schedule_zoom(self) -> None:
        """Refine the visible region once the user stops zooming (debounced)."""
        doc = self.doc
        if doc is None or doc.session_context is None:
            self.refine_visible()
            return
        if self._zoom_timer is not None:
            try:
                doc.remove_timeout_callback(self._zoom_timer)
            except ValueError:
                pass
        self._zoom_timer = doc.add_timeout_callback(self._zoom_fire, 600)

    @guarded
    def _zoom_fire(self) -> None:
        self._zoom_timer = None
        self.refine_visible()

    def refine_visible(self) -> bool:
        """Recompute the visible part of the diagram finer, if zoomed in enough to need it."""
        d, view = self._bif, self._bif_view
        if d is None or view is None:
            return False
        name = self.state.bif
        full_lo, full_hi = d.span
        lo, hi = max(view[0], full_lo), min(view[1], full_hi)
        if name in ("lam", "rpm"):
            lo = max(lo, 1e-3)
        if hi <= lo or (hi - lo) > 0.6 * (full_hi - full_lo):
            return False
        if any(a <= lo and hi <= b for a, b in self._fine):
            return False
        shown = np.unique(d.value[(d.value >= lo) & (d.value <= hi)])
        if len(shown) >= ZOOM_VALUES * 0.8:
            return False
        values = np.linspace(lo, hi, ZOOM_VALUES)
        self._submit(self._sweep_request(name, values), merge=True)
        return True

    # ----- export and teardown ------------------------------------------------------------

    def _csv(self) -> io.StringIO:
        if self.tr is None:
            return io.StringIO("")
        return io.StringIO(views.impacts_csv(self.tr))

    def _on_destroyed(self, session_context) -> None:
        self._cancel_job()
        for panel in self.panels:
            panel.on_destroyed()
