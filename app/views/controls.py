"""The sidebar: the paper's presets, the model's parameters, advanced settings and exports.

A ``pn.viewable.Viewer`` over the session's state: every control writes one state parameter
(:mod:`app.ui.widgets`), a preset writes several in one batch, and the phase-convention switch
converts φ₂ and the extra harmonics so the model stays the same
(:meth:`ExplorerState.set_phase_convention`). The impacts export is the CLI's table
(``rattle simulate --impacts``): the same columns, flank as +1/−1, SI columns in physical
units, and a file name that holds the parameters.
"""
from __future__ import annotations

import html
import io
from typing import Any

import pandas as pd
import panel as pn
import param

from ..core import impacts_frame
from ..presets import PRESETS, preset_values
from ..state import ExplorerState, format_harmonics, parse_harmonics
from ..ui.help import HELP
from ..ui.plots import file_stem
from ..ui.widgets import Field, _label_html, message

SLIDERS = ("lam", "r", "j", "h2", "phi2")
ADVANCED = ("periods", "shown", "transient", "v_stick", "noise", "x0", "v0", "t0", "harmonics",
            "strobe")
PHASE_OPTIONS = {"paper: sin(k t + φ_k)": "paper", "core: cos(k t − φ_k)": "core"}


def impacts_table(run: Any) -> pd.DataFrame:
    """Every recorded impact, as ``rattle simulate --impacts`` writes it (the same function)."""
    return impacts_frame(run.tr, run.phys)


class Controls(pn.viewable.Viewer):
    """The sidebar of one session."""

    state = param.ClassSelector(class_=ExplorerState)

    def __init__(self, **params: Any):
        super().__init__(**params)
        s = self.state
        self.fields = {n: Field(s, n, help=n if n in HELP else None) for n in SLIDERS}
        self.fields.update({n: Field(s, n) for n in ("periods", "shown", "transient", "v_stick",
                                                     "noise", "v0", "t0", "strobe")})
        self.fields["x0"] = Field(s, "x0", placeholder="middle of the backlash")
        self.phases = pn.widgets.RadioButtonGroup(options=PHASE_OPTIONS, value=s.phases,
                                                  css_classes=["ctl-phases"], color="default",
                                                  sizing_mode="stretch_width")
        self.phases.param.watch(self._on_phases, "value")
        s.param.watch(self._follow_phases, "phases")
        self.presets = []
        for label, (desc, _) in PRESETS.items():
            # what a preset shows is said under the buttons once loaded: a hover tooltip
            # stayed over the plots after the click
            b = pn.widgets.Button(label=label, width=70, margin=(2, 3),
                                  css_classes=[f"preset-{label.replace(' ', '')}"])
            b.on_click(lambda e, label=label: self.apply_preset(label))
            self.presets.append(b)
        self.preset_note = _note("Each loads the parameters of one of the paper's figures.")
        self.preset_note.css_classes = ["preset-note"]
        # harmonics beyond the second: add or remove orders
        self.harm_order = pn.widgets.IntInput(label="order k", value=3, start=3, end=32,
                                              sizing_mode="stretch_width")
        self.harm_amp = pn.widgets.FloatInput(label="H_k/H₁", value=0.1, sizing_mode="stretch_width")
        self.harm_phase = pn.widgets.FloatInput(label="φ_k (°)", value=0.0, sizing_mode="stretch_width")
        self.harm_add = pn.widgets.Button(label="add / set", color="primary",
                                          sizing_mode="stretch_width", css_classes=["harm-add"])
        self.harm_remove = pn.widgets.Button(label="remove order k", sizing_mode="stretch_width",
                                             css_classes=["harm-remove"])
        self.harm_add.on_click(lambda e: self.add_harmonic(self.harm_order.value, self.harm_amp.value,
                                                           self.harm_phase.value))
        self.harm_remove.on_click(lambda e: self.remove_harmonic(self.harm_order.value))
        self.harm_list = pn.pane.HTML("", css_classes=["harm-list"], margin=(0, 10))
        s.param.watch(self._list_harmonics, "harmonics")
        self._list_harmonics()
        self.download = pn.widgets.FileDownload(callback=self._csv, filename="impacts.csv",
                                                label="Impacts as CSV", color="success",
                                                css_classes=["download-csv"], sizing_mode="stretch_width")
        s.param.watch(self._name_download, "result")
        self._name_download()
        self.advanced = pn.Card(
            *[self.fields[n] for n in ("periods", "shown", "transient", "v_stick", "noise")],
            _note("ε: every impact rebounds with r·(1 ± ε); chaotic statistics may depend on "
                  "it (docs/model.md, 'Noise')"),
            _note("Initial state (a click on the Poincaré map sets it)"),
            *[self.fields[n] for n in ("x0", "v0", "t0")],
            _note("More harmonics, in the phase convention shown"),
            pn.Row(self.harm_order, self.harm_amp, self.harm_phase, sizing_mode="stretch_width"),
            pn.Row(self.harm_add, self.harm_remove, sizing_mode="stretch_width"),
            self.harm_list, message(s, "harmonics"), self.fields["strobe"],
            title="Advanced", sizing_mode="stretch_width", css_classes=["advanced"],
            collapsed=not any(n in s.messages for n in ADVANCED))
        s.param.watch(self._open_advanced, "messages")
        self._label_phi2()

    def __panel__(self):
        return pn.Column(
            _heading("Paper presets (Figures 2–8)"),
            pn.FlexBox(*self.presets, sizing_mode="stretch_width"),
            self.preset_note,
            _heading("Parameters"),
            *[self.fields[n] for n in SLIDERS],
            pn.Column(_note("Phases shown in the convention of"), self.phases, message(self.state, "phases"),
                      sizing_mode="stretch_width", margin=0),
            self.advanced,
            _heading("Export"),
            self.download,
            _note("Plots: the save tool (disk icon) in each plot's toolbar writes a PNG named "
                  "after the parameters, which its title shows."),
            sizing_mode="stretch_width", margin=0)

    # ----- actions ----------------------------------------------------------------------------

    def apply_preset(self, label: str) -> None:
        """Load a paper preset: every parameter it names, in one redraw."""
        s = self.state
        values = preset_values(s, label)
        s.clear(*values, "global")
        s.param.update(**values)
        self.preset_note.object = _note(f"{label}: {PRESETS[label][0]}").object

    def add_harmonic(self, k: Any, h: Any, phi: Any) -> bool:
        s = self.state
        try:
            harm = parse_harmonics(s.harmonics)
            harm[int(k)] = (float(h), float(phi))
            text = format_harmonics(harm)
            s.harmonics = text
        except (TypeError, ValueError) as exc:
            s.say("harmonics", f"{exc}. Kept the harmonics as they were.")
            return False
        s.clear("harmonics")
        return True

    def remove_harmonic(self, k: Any) -> bool:
        s = self.state
        harm = parse_harmonics(s.harmonics)
        if k not in harm:
            s.say("harmonics", f"order {k} is not among the extra harmonics.")
            return False
        del harm[k]
        s.clear("harmonics")
        s.harmonics = format_harmonics(harm)
        return True

    def _on_phases(self, event) -> None:
        if event.new != self.state.phases:
            self.state.set_phase_convention(event.new)

    def _follow_phases(self, *_: Any) -> None:
        if self.phases.value != self.state.phases:
            self.phases.value = self.state.phases
        self._label_phi2()

    def _label_phi2(self) -> None:
        conv = "the paper's sin(2t + φ₂)" if self.state.phases == "paper" else "the core's cos(2t − φ₂)"
        self.fields["phi2"].label.object = _label_html(f"φ₂ · 2nd-harmonic phase [°], {conv}")

    def _list_harmonics(self, *_: Any) -> None:
        harm = parse_harmonics(self.state.harmonics)
        text = ("no harmonic beyond the second" if not harm else
                "; ".join(f"k = {k}: H_k/H₁ = {h:g}, φ_k = {p:g}°" for k, (h, p) in harm.items()))
        self.harm_list.object = f'<div style="font-size:12px">{html.escape(text)}</div>'

    def _open_advanced(self, event) -> None:
        if any(n in event.new and n not in event.old for n in ADVANCED):
            self.advanced.collapsed = False

    def _name_download(self, *_: Any) -> None:
        run = self.state.result
        if run is not None:
            self.download.filename = file_stem(run, "impacts") + ".csv"

    def _csv(self) -> io.StringIO:
        run = self.state.result
        if run is None:
            return io.StringIO("")
        return io.StringIO(impacts_table(run).to_csv(index=False))


def _heading(text: str) -> pn.pane.HTML:
    return pn.pane.HTML(f"<h3 style='margin:6px 0 2px 0;font-size:16px'>{html.escape(text)}</h3>",
                        margin=(0, 10), sizing_mode="stretch_width")


def _note(text: str) -> pn.pane.HTML:
    return pn.pane.HTML(f"<div style='font-size:12px;color:#444'>{html.escape(text)}</div>",
                        margin=(4, 10, 0, 10), sizing_mode="stretch_width")
