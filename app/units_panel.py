"""The dashboard's physical-units mode: an NVH engineer's inputs beside the dimensionless model.

With the mode on, the sidebar card holds the idle gear's inertia, base radius and drag torque,
the backlash, the engine speed and order, and the driving gear's excitation (angular
displacement or acceleration, amplitude and phase per order). Editing one of them maps the
whole set to ``Λ, j, h₂, φ₂`` with :meth:`PhysicalParams.to_dimensionless` and writes them into
the dashboard's state through its validated path, so the views redraw once. A dimensionless
change (a slider, a preset, a click on a diagram) goes the other way with
:meth:`PhysicalParams.from_dimensionless`: every physical constant is held except the one chosen
to absorb Λ (the engine speed by default).

The physical values are held in one :class:`PhysicalParams`, never re-read from the rounded
numbers the inputs display, so repeated round trips do not drift. ``dashboard.physical`` is
that object while the mode is on, and None while it is off.

The Explorer tab shows both parameter sets side by side and the rattle metrics in SI units;
that table is all :meth:`UnitsPanel.on_redraw` updates, so a slider move stays cheap.

The URL carries the mode only while it is on: ``units=1`` and the inputs under short keys
(:data:`URL_KEYS`: ``J``, ``Rb``, ``C`` in SI units, ``b_um`` the backlash in µm whatever unit
it is shown in, ``b_unit``, ``rpm``, ``order``, ``exc``, ``a1``, ``a2`` and ``p2`` in the
excitation's own units, ``solve`` the quantity absorbing Λ), beside the dimensionless keys,
which always agree with them. Orders ≥ 3 travel as the dimensionless ``harmonics`` key, as
their physical amplitudes keep their ratio to order 1. When a URL holds both, **the physical
inputs win**: as soon as one numeric physical key is present, the physical set is built from
the URL (the example gear's value for each key missing or rejected; ``r`` and ``v_stick`` from
the dimensionless keys) and Λ, j, h₂, φ₂ follow from it. A URL with ``units=1`` and no numeric
physical key keeps its dimensionless values and solves the physical set from them, as turning
the switch on does. A rejected key leaves a message beside its input naming the value and the
allowed range, the example's value for it, and the URL corrected to the inputs shown; the
physical keys are ignored without ``units=1``.
"""
from __future__ import annotations

import functools
import html
import logging
import math
from typing import TYPE_CHECKING, Any

import panel as pn

from rattle_core import RattleParams, units
from rattle_core.model.params import check_range
from rattle_core.analysis.vocabulary import physical_table
from rattle_core.model.phases import wrap_deg
from rattle_core.model.units import PhysicalParams

from .panel_base import FeaturePanel
from .state import apply_values, parse_harmonics

if TYPE_CHECKING:
    from .dashboard import Dashboard

log = logging.getLogger(__name__)

#: Which physical quantity absorbs a change of Λ made in dimensionless terms.
SOLVE_FOR_OPTIONS = {"engine speed (rpm)": "rpm", "drag torque C": "drag_torque",
                     "idle-gear inertia J": "inertia", "excitation amplitude (order 1)": "amplitude"}
EXCITATION_OPTIONS = {"θ_k: displacement [rad]": "displacement",
                      "α_k: acceleration [rad/s²]": "acceleration"}
BACKLASH_OPTIONS = {"µm along the line of action": "um", "degrees of the idle gear": "deg"}
#: Numeric inputs: name → field of PhysicalParams they edit (amplitudes and phases by index).
NUMERIC = ("inertia", "radius", "drag_torque", "backlash", "rpm", "order", "amp1", "amp2",
           "phase2")
#: URL query key → the input whose message shows a rejected value (``units``: the page's own).
URL_KEYS = {"units": None, "J": "inertia", "Rb": "radius", "C": "drag_torque", "b_um": "backlash",
            "b_unit": "backlash", "rpm": "rpm", "order": "order", "exc": "amp1", "a1": "amp1",
            "a2": "amp2", "p2": "phase2", "solve": "solve_for"}
#: Numeric URL keys: their presence makes the physical inputs win over the dimensionless keys.
URL_NUMERIC = ("J", "Rb", "C", "b_um", "rpm", "order", "a1", "a2", "p2")


def _interval(lo: float, hi: float, lo_open: bool) -> str:
    return f"{'(' if lo_open else '['}{lo:g}, {hi:g}]"


def _show(v: float) -> float:
    """A value as the inputs display it: six significant digits."""
    return float(f"{v:.6g}")


def _url_number(v: float) -> str:
    """The shortest text that reads back as exactly ``v``."""
    text = repr(float(v))
    return text[:-2] if text.endswith(".0") else text


def _url_um(backlash: float) -> str:
    """Backlash in µm as the shortest text that maps back to exactly ``backlash`` metres."""
    um = backlash * 1e6
    for y in (um, math.nextafter(um, -math.inf), math.nextafter(um, math.inf)):
        for digits in range(1, 18):
            text = f"{y:.{digits}g}"
            if float(text) / 1e6 == backlash:
                return _url_number(float(text))
    return _url_number(um)


def same_model(a: RattleParams, b: RattleParams, rel: float = 1e-9) -> bool:
    """Whether two parameter sets describe the same model up to rounding (phases modulo 360°)."""
    if a.n_harmonics != b.n_harmonics:
        return False
    pairs = [(a.lam, b.lam), (a.r, b.r), (a.j, b.j), (a.v_stick, b.v_stick),
             *zip(a.amplitudes, b.amplitudes)]
    if not all(math.isclose(x, y, rel_tol=rel, abs_tol=1e-12) for x, y in pairs):
        return False
    return all(abs(wrap_deg(x - y)) <= 1e-9 for x, y in zip(a.phases_deg, b.phases_deg))


class UnitsPanel(FeaturePanel):
    """The "Physical units" sidebar card and its side-by-side table in the Explorer tab."""

    def __init__(self, dashboard: "Dashboard"):
        super().__init__(dashboard)
        self.phys: PhysicalParams = units.example()
        self._syncing = False
        self._applying = False
        self._unreachable = False
        self.switch = pn.widgets.Switch(value=False, width=50, margin=(12, 10, 0, 10),
                                        css_classes=["units-switch"])
        self.switch.param.watch(self._on_switch, "value")

        def num(key: str, **kw: Any) -> pn.widgets.FloatInput:
            return pn.widgets.FloatInput(css_classes=[f"units-{key}"], sizing_mode="stretch_width",
                                         **kw)
        self.inputs: dict[str, pn.widgets.FloatInput] = {
            "inertia": num("inertia", label="J · idle-gear inertia [kg·m²]"),
            "radius": num("radius", label="R_b · idle-gear base radius [m]"),
            "drag_torque": num("drag_torque", label="C · drag torque on the idle gear [N·m]"),
            "backlash": num("backlash"),
            "rpm": num("rpm", label="engine speed [rpm]"),
            "order": num("order", label="engine order of the fundamental"),
            "amp1": num("amp1"),
            "amp2": num("amp2"),
            "phase2": num("phase2", label="φ₂ · order-2 phase [°]"),
        }
        self.phase1 = pn.widgets.FloatInput(label="φ₁ [°] (time reference)", disabled=True,
                                            css_classes=["units-phase1"], sizing_mode="stretch_width",
                                            description="Order 1 sets the time origin: its displacement "
                                                        "phase is 0° (acceleration phase 180°).")
        self.alerts = {name: pn.pane.Alert("", alert_type="danger", visible=False, margin=(0, 10),
                                           css_classes=[f"msg-units-{name}"], sizing_mode="stretch_width")
                       for name in (*NUMERIC, "solve_for")}
        self.backlash_unit = pn.widgets.RadioButtonGroup(options=BACKLASH_OPTIONS, value="um",
                                                         css_classes=["units-backlash-unit"],
                                                         sizing_mode="stretch_width")
        self.excitation = pn.widgets.RadioButtonGroup(options=EXCITATION_OPTIONS, value="displacement",
                                                      css_classes=["units-excitation"],
                                                      sizing_mode="stretch_width")
        self.solve_for = pn.widgets.Select(label="a change of Λ (slider, preset, click) moves",
                                           options=SOLVE_FOR_OPTIONS, value="rpm",
                                           css_classes=["units-solve-for"], sizing_mode="stretch_width")
        for name, w in self.inputs.items():
            w.param.watch(functools.partial(self._on_input, name), "value")
        self.backlash_unit.param.watch(self._on_backlash_unit, "value")
        self.excitation.param.watch(self._on_excitation, "value")
        self.solve_for.param.watch(self._on_solve_for, "value")
        self._describe()
        self._to_widgets()

        def ctl(name: str) -> pn.Column:
            return pn.Column(self.inputs[name], self.alerts[name], margin=0,
                             sizing_mode="stretch_width")
        note = {"margin": (5, 10, 0, 10)}
        self.body = pn.Column(
            pn.pane.Markdown("**Idle gear**", **note), ctl("inertia"), ctl("radius"),
            ctl("drag_torque"),
            pn.pane.Markdown("**Backlash**", **note), self.backlash_unit, ctl("backlash"),
            pn.pane.Markdown("**Engine**", **note), ctl("rpm"), ctl("order"),
            pn.pane.Markdown("**Driving-gear excitation** Σ a_k cos(k ω t − φ_k)", **note),
            self.excitation, pn.Row(self.inputs["amp1"], self.phase1, margin=0), self.alerts["amp1"],
            ctl("amp2"), ctl("phase2"),
            pn.pane.Markdown("Orders ≥ 3 (Advanced) keep their ratio H_k/H₁.",
                             styles={"font-size": "12px"}, margin=(0, 10)),
            self.solve_for, self.alerts["solve_for"],
            visible=False, margin=0, sizing_mode="stretch_width")
        self.card = pn.Card(
            pn.Row(self.switch, pn.pane.Markdown("SI inputs ⇄ Λ, j, h₂, φ₂", margin=(8, 0))),
            self.body, title="Physical units", collapsed=False, sizing_mode="stretch_width",
            css_classes=["units-card"])
        self.sidebar = [self.card]
        # hidden while the mode is off, so it takes no room above the plots
        self.table = pn.pane.HTML("", css_classes=["units-table"], visible=False,
                                  sizing_mode="stretch_width")
        self.explorer = [self.table]

    # ----- labels and display ---------------------------------------------------------------

    def _ranges(self) -> dict[str, str]:
        """Allowed range of each numeric input, in the unit it is shown in."""
        p = self.phys
        if self.backlash_unit.value == "um":
            b = _interval(units.BACKLASH_RANGE[0] * 1e6, units.BACKLASH_RANGE[1] * 1e6, True) + " µm"
        else:
            b = _interval(0.0, math.degrees(units.BACKLASH_RANGE[1] / p.radius), True) + "°"
        disp = p.excitation == "displacement"
        lo, hi = units.THETA_RANGE if disp else units.ALPHA_RANGE
        unit = "rad" if disp else "rad/s²"
        return {
            "inertia": _interval(*units.INERTIA_RANGE, True) + " kg·m²",
            "radius": _interval(*units.RADIUS_RANGE, True) + " m",
            "drag_torque": _interval(*units.DRAG_TORQUE_RANGE, True) + " N·m",
            "backlash": b,
            "rpm": _interval(*units.RPM_RANGE, True) + " rpm",
            "order": _interval(*units.ORDER_RANGE, True) + " (2: four-cylinder four-stroke)",
            "amp1": _interval(lo, hi, True) + f" {unit}",
            "amp2": _interval(lo, hi, False) + f" {unit}",
            "phase2": "[-1e+06, 1e+06]°, cos(2ωt − φ₂)",
        }

    def _describe(self) -> None:
        """Labels and tooltips that depend on the excitation kind and backlash unit."""
        disp = self.excitation.value == "displacement"
        sym, unit = ("θ", "rad") if disp else ("α", "rad/s²")
        self.inputs["amp1"].label = f"{sym}₁ · order-1 amplitude [{unit}]"
        self.inputs["amp2"].label = f"{sym}₂ · order-2 amplitude [{unit}]"
        self.inputs["backlash"].label = ("b · backlash [µm]" if self.backlash_unit.value == "um"
                                        else "β · backlash angle of the idle gear [°]")
        for name, rng in self._ranges().items():
            self.inputs[name].description = f"allowed {rng}"

    def _shown(self) -> dict[str, float]:
        p = self.phys
        return {"inertia": p.inertia, "radius": p.radius, "drag_torque": p.drag_torque,
                "backlash": p.backlash_um if self.backlash_unit.value == "um" else p.backlash_deg,
                "rpm": p.rpm, "order": p.order, "amp1": p.amplitudes[0],
                "amp2": p.amplitudes[1] if len(p.amplitudes) > 1 else 0.0,
                "phase2": p.phases_deg[1] if len(p.phases_deg) > 1 else 0.0}

    def _to_widgets(self) -> None:
        self._syncing = True
        try:
            for name, v in self._shown().items():
                v = _show(v)
                if self.inputs[name].value != v:
                    self.inputs[name].value = v
            if self.phase1.value != self.phys.phases_deg[0]:
                self.phase1.value = self.phys.phases_deg[0]
            if self.excitation.value != self.phys.excitation:
                self.excitation.value = self.phys.excitation
        finally:
            self._syncing = False

    def _clear(self, name: str) -> None:
        a = self.alerts[name]
        if a.visible:
            a.visible = False
            a.object = ""

    def _error(self, name: str, message: str) -> None:
        self.alerts[name].object = message
        self.alerts[name].visible = True

    # ----- the mode -------------------------------------------------------------------------------

    @property
    def on(self) -> bool:
        return bool(self.switch.value)

    def _on_switch(self, event) -> None:
        try:
            self.set_mode(bool(event.new))
        except Exception as exc:  # a callback never raises into the page
            log.warning("units mode failed: %s: %s", type(exc).__name__, exc)
            self.dashboard.show_error(None, f"Physical units: {type(exc).__name__}: {exc}")

    def set_mode(self, on: bool) -> None:
        """Turn the physical-units mode on or off.

        Turning it on keeps the current view: the physical inputs are solved from the
        dashboard's dimensionless state (held constants from the last physical inputs, the
        example gear at first).
        """
        if self.switch.value != on:
            self.switch.value = on  # its watcher calls back here
            return
        self.body.visible = self.table.visible = on
        if on:
            self.sync(force=True)
            self.dashboard.physical = self.phys
            self._update_table()
        else:
            self.dashboard.physical = None
        self.dashboard.units_changed()

    def sync(self, force: bool = False) -> PhysicalParams | None:
        """Follow a dimensionless change of the dashboard's state; return the physical set.

        Cheap when nothing moved: one comparison. Returns None while the mode is off.
        """
        if not self.on and not force:
            return None
        if self._applying:
            return self.phys
        params = getattr(self.dashboard, "params", None)
        if params is None or same_model(params, self.phys.to_dimensionless()):
            return self.phys
        try:
            new = PhysicalParams.from_dimensionless(params, self.phys, solve_for=self.solve_for.value)
            new.to_dimensionless()
        except ValueError as exc:
            self._error("solve_for", f"Λ = {params.lam:g}, j = {params.j:g} cannot be reached by "
                                     f"moving the {self._solve_label()}: {exc}. The physical inputs "
                                     "show their last values.")
            self._unreachable = True
            return self.phys
        if self._unreachable:  # only its own message: a link's stays until the next edit
            self._unreachable = False
            self._clear("solve_for")
        self.phys = new
        self.dashboard.physical = new
        self._to_widgets()
        return new

    def _solve_label(self) -> str:
        return next(k for k, v in SOLVE_FOR_OPTIONS.items() if v == self.solve_for.value)

    # ----- edits --------------------------------------------------------------------------------

    def _on_input(self, name: str, event) -> None:
        if self._syncing:
            return
        try:
            self.edit(name, event.new)
        except Exception as exc:
            log.warning("units input failed: %s: %s", type(exc).__name__, exc)
            self._error(name, f"{type(exc).__name__}: {exc}")

    def _candidate(self, name: str, value: Any) -> PhysicalParams:
        """The physical set with input ``name`` changed (``ValueError`` naming it if refused)."""
        p = self.phys
        if value is None or isinstance(value, bool):
            raise ValueError(f"{name} must be a number, got {value!r}")
        value = float(value)
        if name == "backlash":
            if self.backlash_unit.value == "um":
                return p.replace(backlash=units.backlash_from_um(value))
            return p.replace(backlash=units.backlash_from_angle(value, p.radius, "deg"))
        if name in ("amp1", "amp2"):
            amps = list(p.amplitudes)
            if name == "amp1":
                rng = units.THETA_RANGE if p.excitation == "displacement" else units.ALPHA_RANGE
                check_range("amplitudes[0]", value, *rng, lo_open=True, text_ok=True)
                # orders ≥ 3 have no physical input: they keep their ratio to order 1
                amps[2:] = [a * value / amps[0] for a in amps[2:]]
                amps[0] = value
            else:
                amps[1] = value
            return p.replace(amplitudes=tuple(amps))
        if name == "phase2":
            phases = list(p.phases_deg)
            phases[1] = value
            return p.replace(phases_deg=tuple(phases))
        return p.replace(**{name: value})

    def edit(self, name: str, value: Any) -> str | None:
        """Set physical input ``name`` and apply it; return the message shown if refused.

        A refused value (out of range, not a number, or mapping outside the model) leaves a
        message beside its input, the input back at its last good value, and the view as it was.
        """
        label = self.inputs[name].label
        old = self.phys
        try:
            cand = self._candidate(name, value)
            self._apply(cand)
        except ValueError as exc:
            self.phys = old
            self.dashboard.physical = old if self.on else None
            msg = f"{label}: {exc}. Kept {_show(self._shown()[name]):g}; allowed {self._ranges()[name]}."
            self._error(name, msg)
            self._to_widgets()
            return msg
        self._clear(name)
        self._to_widgets()
        return None

    def set_rpm(self, rpm: float) -> str | None:
        """Set the engine speed (a click on the rpm diagram); the message if refused."""
        return self.edit("rpm", rpm)

    def set_physical(self, **changes: float) -> str | None:
        """Set physical quantities at once (a click on a map with physical axes); the message if refused.

        ``changes`` name fields of :class:`PhysicalParams` (``rpm``, ``drag_torque``,
        ``inertia``, ``backlash`` in metres, ...). The inputs, the table and Λ, j follow in one
        redraw; a refused set leaves a message beside the first input named and changes nothing.
        """
        shown = [n for n in changes if n in self.inputs] or ["solve_for"]
        old = self.phys
        try:
            cand = old.replace(**{k: float(v) for k, v in changes.items()})
            self._apply(cand)
        except (TypeError, ValueError) as exc:
            self.phys = old
            self.dashboard.physical = old if self.on else None
            what = ", ".join(f"{k} = {v!r}" for k, v in changes.items())
            msg = f"{what}: {exc}. Kept the physical inputs as they were."
            self._error(shown[0], msg)
            self._to_widgets()
            return msg
        for name in shown:
            self._clear(name)
        self._to_widgets()
        return None

    # ----- the URL ------------------------------------------------------------------------------

    def url_values(self) -> dict[str, str]:
        """The mode and its inputs as URL query values (:data:`URL_KEYS`); empty while off."""
        if not self.on:
            return {}
        p = self.phys
        second = len(p.amplitudes) > 1
        return {"units": "1", "J": _url_number(p.inertia), "Rb": _url_number(p.radius),
                "C": _url_number(p.drag_torque), "b_um": _url_um(p.backlash),
                "b_unit": self.backlash_unit.value, "rpm": _url_number(p.rpm),
                "order": _url_number(p.order), "exc": p.excitation,
                "a1": _url_number(p.amplitudes[0]),
                "a2": _url_number(p.amplitudes[1] if second else 0.0),
                "p2": _url_number(p.phases_deg[1] if second else 0.0),
                "solve": self.solve_for.value}

    def restore_url(self, query: dict[str, str]) -> dict[str, str]:
        """Turn the mode on from URL query values (raw text) if ``units=1``; return rejections.

        Each rejected key gets a message beside its input and keeps the example's value; the
        returned ``{key: message}`` lists them. Never raises on any text.
        """
        errors: dict[str, str] = {}
        flag = query.get("units")
        if flag is None:
            return errors
        if str(flag).strip().lower() in ("0", "false", "off", ""):
            return errors
        if str(flag).strip().lower() not in ("1", "true", "on"):
            errors["units"] = f"units = {flag!r}; allowed: 1 (physical units on) or 0"
            return errors

        beside: dict[str, list[str]] = {}

        def reject(key: str, message: str) -> None:
            message = message.rstrip(".") + "."
            errors[key] = message
            name = URL_KEYS[key]
            if name is not None:  # the mode itself has no input: the page's message
                beside.setdefault(name, []).append(f"URL: {message}")
                self._error(name, " ".join(beside[name]))

        example = units.example().replace(r=self.phys.r, v_stick=self.phys.v_stick)
        kind = example.excitation
        if "exc" in query:
            if query["exc"] in EXCITATION_OPTIONS.values():
                kind = query["exc"]
            else:
                reject("exc", f"exc = {query['exc']!r}; allowed: displacement or acceleration. "
                              f"Kept {kind}")
        if "b_unit" in query:
            if query["b_unit"] in BACKLASH_OPTIONS.values():
                self.backlash_unit.value = query["b_unit"]
            else:
                reject("b_unit", f"b_unit = {query['b_unit']!r}; allowed: um or deg. "
                                 f"Kept {self.backlash_unit.value}")
        base = example.as_excitation(kind)
        amp_rng = units.THETA_RANGE if kind == "displacement" else units.ALPHA_RANGE
        amp_unit = "rad" if kind == "displacement" else "rad/s²"
        checks = {  # key: (field default, range, lo_open, unit)
            "J": (base.inertia, units.INERTIA_RANGE, True, "kg·m²"),
            "Rb": (base.radius, units.RADIUS_RANGE, True, "m"),
            "C": (base.drag_torque, units.DRAG_TORQUE_RANGE, True, "N·m"),
            "b_um": (base.backlash_um, tuple(v * 1e6 for v in units.BACKLASH_RANGE), True, "µm"),
            "rpm": (base.rpm, units.RPM_RANGE, True, "rpm"),
            "order": (base.order, units.ORDER_RANGE, True, ""),
            "a1": (base.amplitudes[0], amp_rng, True, amp_unit),
            "a2": (base.amplitudes[1] if len(base.amplitudes) > 1 else 0.0, amp_rng, False, amp_unit),
            "p2": (base.phases_deg[1] if len(base.phases_deg) > 1 else 0.0,
                   (-1e6, 1e6), False, "°"),
        }
        got = {}
        for key, (default, (lo, hi), lo_open, unit) in checks.items():
            if key not in query:
                got[key] = default
                continue
            try:
                got[key] = check_range(key, query[key], lo, hi, lo_open=lo_open, text_ok=True)
            except ValueError as exc:
                got[key] = default
                reject(key, f"{f'{exc} {unit}'.rstrip()}. Kept {default:g}")
        if "solve" in query:
            solve = query["solve"]
            if solve not in SOLVE_FOR_OPTIONS.values():
                reject("solve", f"solve = {solve!r}; allowed: {', '.join(SOLVE_FOR_OPTIONS.values())}. "
                                f"Kept {self.solve_for.value}")
            elif solve == "rpm" and kind == "acceleration":
                reject("solve", "solve = 'rpm' is not allowed with acceleration amplitudes: "
                                "Λ = m R_d α₁ / F does not depend on engine speed. Kept the amplitude")
            else:
                self.solve_for.value = solve
        if kind == "acceleration" and self.solve_for.value == "rpm":
            self.solve_for.value = "amplitude"

        physical_wins = any(key in query for key in URL_NUMERIC)
        cand = None
        if physical_wins:
            try:
                cand = self._url_candidate(base, got)
            except ValueError as exc:
                reject("units", f"the physical inputs of this link give no valid model: {exc}. "
                                "The physical inputs follow the dimensionless values instead")
        self.phys = base
        self._describe()
        self.set_mode(True)
        if cand is not None:
            try:
                self._apply(cand)
            except ValueError as exc:
                self.phys = base
                self.dashboard.physical = base
                reject("units", f"the physical inputs of this link give no valid model: {exc}. "
                                "The physical inputs follow the dimensionless values instead")
                self.sync(force=True)
        self._to_widgets()
        self._update_table()
        self.dashboard.units_changed()
        for name, messages in beside.items():  # solving for the state clears the solve_for message
            self._error(name, " ".join(messages))
        return errors

    def _url_candidate(self, base: PhysicalParams, got: dict[str, float]) -> PhysicalParams:
        """The physical set a link describes; orders ≥ 3 and r, v_stick from the state."""
        state = self.dashboard.state
        acc = base.excitation == "acceleration"
        extra = parse_harmonics(state.harmonics)
        n = max([2, *extra])
        a1 = got["a1"]
        amps = [a1, got["a2"]] + [0.0] * (n - 2)
        # as PhysicalParams.from_dimensionless maps the dimensionless phases of orders ≥ 3
        phases = [180.0 if acc else 0.0, got["p2"]] + [180.0 if acc else 0.0] * (n - 2)
        for k, (h, phi) in extra.items():
            amps[k - 1] = h * (k * k) * a1 if acc else h * a1
            phases[k - 1] = wrap_deg(phi - 180.0) if acc else phi
        return base.replace(inertia=got["J"], radius=got["Rb"], drag_torque=got["C"],
                            backlash=units.backlash_from_um(got["b_um"]), rpm=got["rpm"],
                            order=got["order"], amplitudes=tuple(amps), phases_deg=tuple(phases),
                            r=state.r, v_stick=state.v_stick)

    def _apply(self, cand: PhysicalParams) -> None:
        """Write the dimensionless image of ``cand`` into the dashboard's state, in one redraw."""
        params = cand.to_dimensionless()
        if not self.on:
            self.phys = cand
            return
        values = {"lam": params.lam, "j": params.j, "h2": params.amplitudes[1],
                  "phi2": params.phases_deg[1]}
        state = self.dashboard.state
        self.phys = cand
        self.dashboard.physical = cand
        self._applying = True
        try:
            errors = apply_values(state, values)
        finally:
            self._applying = False
        if errors or any(getattr(state, k) != v for k, v in values.items()):
            detail = "; ".join(errors.values()) if errors else "the model could not run with it"
            raise ValueError(f"{detail} (Λ = {params.lam:.6g}, j = {params.j:.6g})")
        self._update_table()
        self.dashboard.units_changed()

    def _on_backlash_unit(self, event) -> None:
        self._describe()
        self._clear("backlash")
        self._to_widgets()
        self._write_url()

    def _on_excitation(self, event) -> None:
        if self._syncing:
            return
        try:
            self.set_excitation(event.new)
        except Exception as exc:
            log.warning("units excitation failed: %s: %s", type(exc).__name__, exc)
            self._error("amp1", f"{type(exc).__name__}: {exc}")

    def set_excitation(self, kind: str) -> None:
        """Describe the same excitation by displacements or by accelerations (the model is unchanged)."""
        p = self.phys
        if kind == p.excitation:
            return
        try:
            cand = p.as_excitation(kind)
        except ValueError as exc:
            self._error("amp1", f"These amplitudes cannot be given as {kind}s: {exc}")
            self._to_widgets()
            return
        self._clear("amp1")
        self.phys = cand
        if kind == "acceleration" and self.solve_for.value == "rpm":
            # with accelerations held, Λ = m R_d α₁ / F does not depend on engine speed
            self.solve_for.value = "amplitude"
        self._describe()
        self._to_widgets()
        if self.on:
            self._apply(cand)

    def _on_solve_for(self, event) -> None:
        if event.new == "rpm" and self.phys.excitation == "acceleration":
            self.solve_for.value = event.old
            self._error("solve_for", "With acceleration amplitudes, Λ = m R_d α₁ / F does not depend "
                                     "on engine speed: choose the drag torque, the inertia or the "
                                     "amplitude, or give the excitation as displacements.")
            return
        self._clear("solve_for")
        self._write_url()

    # ----- the Explorer table -------------------------------------------------------------------

    def on_redraw(self) -> None:
        if not self.on:
            return
        self.sync()
        self.dashboard.physical = self.phys
        self._update_table()
        self._write_url()

    def _write_url(self) -> None:
        write = getattr(self.dashboard, "write_units_url", None)
        if write is not None:
            write()

    def _update_table(self) -> None:
        self.table.object = table_html(self.phys, getattr(self.dashboard, "classification", None))


def physical_metrics(phys: PhysicalParams, cls) -> list[tuple[str, str]]:
    """Rattle metrics in SI units: impact rate, mean and RMS impulse, frequency, period.

    One dimensionless period (2π) is one excitation period ``60 / (order × rpm)`` s, and an
    impulse ``Ĩ`` is ``Ĩ m ω H₁`` N·s along the line of action.
    """
    f, s = phys.frequency_hz, phys.impulse_scale

    def g(v: float | None, scale: float = 1.0) -> str:
        return "–" if v is None or not math.isfinite(v) else f"{v * scale:.4g}"
    rows = [("excitation frequency", f"{f:.6g} Hz"),
            ("excitation period", f"{1e3 * phys.period_s:.6g} ms")]
    if cls is not None:
        rows += [
            ("impact rate (active, reverse)",
             f"{g(cls.active_per_period, f)}, {g(cls.reverse_per_period, f)} 1/s"),
            ("mean |I| (active, reverse)",
             f"{g(cls.mean_impulse_active, s)}, {g(cls.mean_impulse_reverse, s)} N·s"),
            ("RMS I (active, reverse)",
             f"{g(cls.rms_impulse_active, s)}, {g(cls.rms_impulse_reverse, s)} N·s"),
        ]
    return rows


def table_html(phys: PhysicalParams, cls) -> str:
    """Physical and dimensionless parameters side by side, and the metrics in SI units."""
    e = html.escape
    head = ("<tr><th style='text-align:left;padding-right:10px'>quantity</th>"
            "<th style='text-align:left;padding-right:10px'>physical</th>"
            "<th style='text-align:left'>dimensionless</th></tr>")
    body = "".join(f"<tr><td style='padding-right:10px'>{e(q)}</td><td style='padding-right:10px'>"
                   f"<b>{e(a)}</b></td><td><b>{e(b)}</b></td></tr>" for q, a, b in physical_table(phys))
    metrics = "".join(f"<tr><td style='padding-right:10px'>{e(q)}</td><td><b>{e(v)}</b></td></tr>"
                      for q, v in physical_metrics(phys, cls))
    return ('<div class="units-tables" style="display:flex;gap:24px;flex-wrap:wrap;font-size:12px">'
            f'<table class="units-params">{head}{body}</table>'
            f'<table class="units-metrics"><tr><th colspan="2" style="text-align:left">'
            f'rattle in SI units</th></tr>{metrics}</table></div>')
