"""The physical-units mode's controls and its table: an NVH engineer's inputs beside the model.

A ``pn.viewable.Viewer`` over the state. The sidebar card holds the switch and, while it is
on, the idle gear's inertia, base radius and drag torque, the backlash (µm, or degrees of the
idle gear), the engine speed and order, the driving gear's excitation (displacement or
acceleration amplitudes and the harmonic-2 phase) and which quantity absorbs a change of Λ.
Each input writes one state parameter; :mod:`app.physical` and the session carry it to
Λ, j, h₂, φ₂. The table shows both descriptions side by side; it sits beside the plots.
"""
from __future__ import annotations

import math
from typing import Any

import panel as pn
import param

from ..core import physical_table, units
from ..state import PHYSICAL_KEYS, ExplorerState
from ..ui.labels import table_html
from ..physical import SOLVE_LABELS, excitation_values
from ..ui.widgets import Choice, Field, _label_html, message, set_value

EXCITATION_OPTIONS = {"θ_k: displacement [rad]": "displacement",
                      "α_k: acceleration [rad/s²]": "acceleration"}
BACKLASH_OPTIONS = {"µm along the line of action": "um", "degrees of the idle gear": "deg"}
SOLVE_OPTIONS = {v: k for k, v in SOLVE_LABELS.items()}


class BacklashField(pn.viewable.Viewer):
    """The backlash in µm or in degrees of the idle gear; the state holds it in µm."""

    def __init__(self, state: ExplorerState):
        super().__init__()
        self.state = state
        self._syncing = False
        self.label = pn.pane.HTML("", margin=(4, 10, 0, 10), sizing_mode="stretch_width")
        self.box = pn.widgets.FloatInput(value=None, sizing_mode="stretch_width", margin=(0, 10),
                                         css_classes=["value-box"])
        self.box.param.watch(self._on_box, "value")
        state.param.watch(self._from_state, ["backlash_um", "backlash_unit", "radius"])
        self.layout = pn.Column(self.label, self.box, message(state, "backlash_um"),
                                css_classes=["ctl-backlash"], sizing_mode="stretch_width", margin=0)
        self._from_state()

    def __panel__(self):
        return self.layout

    def _deg(self) -> bool:
        return self.state.backlash_unit == "deg"

    def _from_state(self, *_: Any) -> None:
        s = self.state
        value = math.degrees(s.backlash_um * 1e-6 / s.radius) if self._deg() else s.backlash_um
        text = ("β · backlash angle of the idle gear [°]" if self._deg()
                else "b · backlash along the line of action [µm]")
        self.label.object = _label_html(text)
        self._syncing = True
        try:
            self.box.value = float(f"{value:.9g}")
        finally:
            self._syncing = False

    def _on_box(self, event) -> None:
        if self._syncing or event.new is None:
            return
        s = self.state
        um = units.backlash_from_angle(event.new, s.radius, "deg") * 1e6 if self._deg() else event.new
        set_value(s, "backlash_um", um) if math.isfinite(um) else s.say(
            "backlash_um", f"backlash must be a finite number, got {event.new!r}.")
        self._from_state()


class UnitsView(pn.viewable.Viewer):
    """The physical-units card (sidebar) and the side-by-side table (:attr:`table`)."""

    state = param.ClassSelector(class_=ExplorerState)

    def __init__(self, **params: Any):
        super().__init__(**params)
        s = self.state
        self.switch = pn.widgets.Switch(value=s.units, width=50, margin=(12, 10, 0, 10),
                                        css_classes=["units-switch"])
        self.switch.param.watch(lambda e: set_value(s, "units", e.new), "value")
        self.fields = {
            "inertia": Field(s, "inertia", "J · idle-gear inertia [kg·m²]"),
            "radius": Field(s, "radius", "R_b · idle-gear base radius [m]"),
            "drag_torque": Field(s, "drag_torque", "C · drag torque on the idle gear [N·m]"),
            "rpm": Field(s, "rpm", "engine speed [rpm]"),
            "order": Field(s, "order", "engine order of the fundamental (2: four-cylinder four-stroke)"),
            "amp1": Field(s, "amp1", ""), "amp2": Field(s, "amp2", ""),
            "phase2": Field(s, "phase2", ""),
        }
        self.backlash = BacklashField(s)
        self.backlash_unit = Choice(s, "backlash_unit", BACKLASH_OPTIONS, sizing_mode="stretch_width",
                                    orientation="vertical")
        self.excitation = pn.widgets.RadioButtonGroup(options=EXCITATION_OPTIONS, value=s.excitation,
                                                      css_classes=["ctl-excitation"], orientation="vertical",
                                                      sizing_mode="stretch_width")
        self.excitation.param.watch(self._on_excitation, "value")
        self.solve_for = Choice(s, "solve_for", SOLVE_OPTIONS, select=True, label="",
                                sizing_mode="stretch_width")
        note = {"margin": (6, 10, 0, 10)}
        self.heading = _bold("", **note)
        self.body = pn.Column(
            _bold("Idle gear", **note), self.fields["inertia"], self.fields["radius"],
            self.fields["drag_torque"],
            _bold("Backlash", **note), self.backlash_unit, self.backlash,
            _bold("Engine", **note), self.fields["rpm"], self.fields["order"],
            self.heading,
            self.excitation, message(s, "excitation"), self.fields["amp1"], self.fields["amp2"],
            self.fields["phase2"],
            _bold("Orders ≥ 3 (Advanced) keep their ratio H_k/H₁. A change of Λ (slider, preset, "
                  "click) moves:", **note),
            self.solve_for,
            visible=s.units or any(k in s.messages for k in PHYSICAL_KEYS), margin=0,
            sizing_mode="stretch_width")
        self.card = pn.Card(
            pn.Row(self.switch, pn.pane.HTML(_label_html("SI inputs ⇄ Λ, j, h₂, φ₂"), margin=(14, 0)),
                   sizing_mode="stretch_width"),
            message(s, "units"), self.body, title="Physical units", collapsed=False,
            sizing_mode="stretch_width", css_classes=["units-card"])
        # below the time history, as wide as it: each row reads on one line
        self.table = pn.pane.HTML("", css_classes=["units-table"], visible=s.units,
                                  sizing_mode="stretch_width", styles={"overflow-x": "auto"})
        s.param.watch(self._on_units, "units")
        s.param.watch(self._show_messages, "messages")
        s.param.watch(self._on_kind, ["excitation", "order", "phases"])
        s.param.watch(self._draw_table, "result")
        self._on_kind()
        self._draw_table()

    def __panel__(self):
        return self.card

    def _on_units(self, event) -> None:
        self.switch.value = event.new
        self.body.visible = self.table.visible = event.new
        self._draw_table()

    def _show_messages(self, event) -> None:
        """A refused physical input (from a link, say) shows its message even while the mode is off."""
        if any(k in event.new for k in (*PHYSICAL_KEYS, "solve_for", "excitation")):
            self.body.visible = True

    def _on_kind(self, *_: Any) -> None:
        s = self.state
        if self.excitation.value != s.excitation:
            self.excitation.value = s.excitation
        sym, unit = ("θ", "rad") if s.excitation == "displacement" else ("α", "rad/s²")
        # the fundamental's harmonics, named by the engine order each one is
        for k, name in ((1, "amp1"), (2, "amp2")):
            self.fields[name].label.object = _label_html(
                f"{sym}{'₁₂'[k - 1]} · amplitude at engine order {k * s.order:g} [{unit}]")
        wave = "sin(k ω t + φ_k)" if s.phases == "paper" else "cos(k ω t − φ_k)"
        self.heading.object = _bold_html(f"Driving-gear excitation Σ a_k {wave} ({s.phases} "
                                         "phases); harmonic 1 sets the time origin")
        self.fields["phase2"].label.object = _label_html(
            f"φ₂ · phase at engine order {2 * s.order:g} [°], "
            + ("sin(2ωt + φ₂)" if s.phases == "paper" else "cos(2ωt − φ₂)"))

    def _on_excitation(self, event) -> None:
        s = self.state
        if event.new == s.excitation:
            return
        try:
            values = excitation_values(s, event.new)
            s.param.update(**values)
            s.clear("excitation")
        except ValueError as exc:
            s.say("excitation", f"These amplitudes cannot be given as {event.new}s: {exc}")
            self.excitation.value = s.excitation

    def _draw_table(self, *_: Any) -> None:
        run = self.state.result
        if not self.state.units or run is None or run.phys is None:
            if self.table.object:
                self.table.object = ""
            return
        rows = [tuple(r) for r in physical_table(run.phys, run.params.noise, run.phases)]
        self.table.object = table_html(rows, "units-params", ("quantity", "physical", "dimensionless"),
                                       nowrap=True)


def _bold_html(text: str) -> str:
    import html
    return f"<div style='font-size:13px'><b>{html.escape(text)}</b></div>"


def _bold(text: str, **kw: Any) -> pn.pane.HTML:
    return pn.pane.HTML(_bold_html(text), sizing_mode="stretch_width", **kw)
