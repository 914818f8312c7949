"""The explorer's state: one ``param.Parameterized`` per session, and the rules it validates by.

:class:`ExplorerState` holds everything a session can set (model parameters, run settings,
view settings, the physical-units inputs) and, below them, what the session computed from
them (``result``) and the messages shown beside the controls (``messages``). Every number
carries its allowed range as param bounds (``softbounds`` give the sliders' range), so a
value outside it is refused by param itself, whoever sets it: a widget, the URL, a click,
a preset. :func:`rejection` turns such a refusal into the message shown beside the control,
naming it, the value (escaped when shown) and the allowed range.

Phases are stored in the convention the page shows (``phases``): the paper's
``y = Σ h_k sin(k t + φ_k)`` by default, or the core's ``Σ h_k cos(k t − φ_k)``.
:meth:`ExplorerState.set_phase_convention` converts ``phi2`` and the extra harmonics when the
user switches, so the model does not change; :func:`rattle_params` converts to the core.

The URL keys are the parameter names (physical inputs have short keys, :data:`URL_KEYS`);
the Maps tab's :class:`MapSettings` are URL keys too, each with a ``map_`` prefix
(:data:`MAP_URL_KEYS`), and so are the Gearbox tab's :class:`GearboxSettings`, with ``gb_``
(:data:`GEARBOX_URL_KEYS`; the gears and the measurement are files, not in the URL).
A pinned run (``pinned``, URL key ``pin``) is checked and run by :mod:`app.pinning`.
"""
from __future__ import annotations

import dataclasses
import math
import re
from typing import Any

import param

from rattle_core import RattleParams

from .core import (AMPLITUDE_RANGE, J_RANGE, LAM_RANGE, MAX_HARMONICS, NOISE_DEFAULT,
                   NOISE_RANGE, PHASE_RANGE_DEG, R_RANGE, V_STICK_RANGE,
                   MAX_T0, check_range, core_to_paper_phases, paper_to_core_phases)
from .core import units as U

_EX = U.example()
#: Physical ranges, open at their lower end.
OPEN = (False, True)


def parse_harmonics(text: Any) -> dict[int, tuple[float, float]]:
    """Parse ``'3:0.1:30, 5:0.05:-20'`` into ``{3: (0.1, 30.0), 5: (0.05, -20.0)}``.

    Orders run from 3 to ``MAX_HARMONICS`` (1 and 2 have their own controls); amplitudes and
    phases obey the core's ranges. Raises ``ValueError`` naming the item at fault.
    """
    if text is None:
        return {}
    if not isinstance(text, str):
        raise ValueError(f"harmonics must be text like '3:0.1:30', got {type(text).__name__}")
    out: dict[int, tuple[float, float]] = {}
    for item in filter(None, (s.strip() for s in text.split(","))):
        parts = item.split(":")
        if len(parts) != 3:
            raise ValueError(f"harmonic {item[:30]!r} must be 'order:amplitude:phase', e.g. '3:0.1:30'")
        try:
            k = float(parts[0])
        except ValueError:
            k = math.nan
        if not (math.isfinite(k) and k == int(k) and 3 <= k <= MAX_HARMONICS):
            raise ValueError(f"harmonic order {parts[0][:20]!r} must be a whole number in [3, {MAX_HARMONICS}]")
        h = check_range(f"H{int(k)}/H₁", parts[1], *AMPLITUDE_RANGE, text_ok=True)
        phi = check_range(f"φ{int(k)}", parts[2], *PHASE_RANGE_DEG, text_ok=True)
        out[int(k)] = (h, phi)
    return dict(sorted(out.items()))


def format_harmonics(harm: dict[int, tuple[float, float]]) -> str:
    """Inverse of :func:`parse_harmonics` (sorted by order, shortest exact floats)."""
    return ",".join(f"{k}:{h!r}:{phi!r}" for k, (h, phi) in sorted(harm.items()))


class Harmonics(param.String):
    """Extra harmonics as ``'k:h:φ'`` items; param refuses text that does not parse."""

    def _validate_value(self, val, allow_None):
        super()._validate_value(val, allow_None)
        parse_harmonics(val)


class OptionalNumber(param.Number):
    """A number or None; the URL writes None as an empty value and reads it back."""

    @classmethod
    def serialize(cls, value):
        return "" if value is None else value

    @classmethod
    def deserialize(cls, value):
        return None if value in (None, "", "null") else value


class TargetText(param.String):
    """A rattle target in the CLI's text form (``"1000:10,3000:20 sone; 1000:60,3000:70 dba"``),
    or empty; a text that does not read as one is refused with the reason."""

    MAX_CHARS = 4000

    def _validate_value(self, value, allow_None):
        super()._validate_value(value, allow_None)
        if value:
            if len(value) > self.MAX_CHARS:
                raise ValueError(f"the target has {len(value)} characters; the allowed length is "
                                 f"up to {self.MAX_CHARS}")
            from .core import Target
            Target.parse(value)


class Flag(param.Boolean):
    """A switch the URL may also give as 1/0, on/off or yes/no."""

    @classmethod
    def deserialize(cls, value):
        text = str(value).strip().lower()
        if text in ("1", "true", "on", "yes"):
            return True
        if text in ("0", "false", "off", "no"):
            return False
        return value


def convert_phase(phi: float, k: int) -> float:
    """Harmonic ``k``'s phase from one convention to the other (the mapping is its own inverse)."""
    phases = [0.0] * k
    phases[k - 1] = phi
    return paper_to_core_phases(phases)[k - 1]


class Said(param.Parameterized):
    """A parameterized object whose controls show messages (``messages``: name → text)."""

    messages = param.Dict({}, precedence=-1, doc="control name → message shown beside it")

    def say(self, name: str, text: str) -> None:
        """Show ``text`` beside control ``name`` (``global``/``url``: above the tabs)."""
        if self.messages.get(name) != text:
            self.messages = {**self.messages, name: text}

    def clear(self, *names: str) -> None:
        """Take the messages of ``names`` away."""
        if any(n in self.messages for n in names):
            self.messages = {k: v for k, v in self.messages.items() if k not in names}


class ExplorerState(Said):
    """Everything one session can set, with its allowed range; and what it computed."""

    # ----- model ---------------------------------------------------------------------------
    lam = param.Number(3.3, bounds=LAM_RANGE, inclusive_bounds=OPEN, softbounds=(0.2, 6.0),
                       step=0.01, label="Λ", doc="inertia ÷ drag, m H₁ω²/F")
    r = param.Number(0.65, bounds=R_RANGE, softbounds=R_RANGE, step=0.01, label="r",
                     doc="restitution coefficient")
    j = param.Number(8.0, bounds=J_RANGE, inclusive_bounds=OPEN, softbounds=(0.5, 20.0), step=0.1,
                     label="j", doc="backlash ÷ H₁")
    h2 = param.Number(0.25, bounds=AMPLITUDE_RANGE, softbounds=(0.0, 1.0), step=0.01,
                      label="H₂/H₁", doc="2nd-harmonic amplitude ratio")
    phi2 = param.Number(45.0, bounds=PHASE_RANGE_DEG, softbounds=(-180.0, 360.0), step=1.0,
                        label="φ₂", doc="2nd-harmonic phase, degrees")
    phases = param.Selector(default="paper", objects=["paper", "core"], label="phase convention",
                            doc="paper: y = Σ h_k sin(k t + φ_k); core: y = Σ h_k cos(k t − φ_k)")
    harmonics = Harmonics("", label="harmonics", doc="extra harmonics k ≥ 3 as 'k:h:φ' items")
    v_stick = param.Number(1e-6, bounds=V_STICK_RANGE, label="v_stick",
                           doc="limit impact velocity (ends chatter)")
    noise = param.Number(NOISE_DEFAULT, bounds=NOISE_RANGE, label="noise ε",
                         doc="restitution scatter: each impact rebounds with r·(1 ± ε), drawn "
                             "uniformly; 0 is the strict deterministic model")
    # ----- run -------------------------------------------------------------------------------
    periods = param.Integer(200, bounds=(1, 20_000), label="N", doc="periods recorded (map, metrics)")
    shown = param.Integer(12, bounds=(1, 2_000), label="Nₜ", doc="periods shown in the time history")
    transient = param.Integer(300, bounds=(0, 100_000), label="Nₜᵣ", doc="transient periods, not recorded")
    x0 = OptionalNumber(None, allow_None=True, bounds=(-1e6, 1e6), label="x₀",
                        doc="initial position (empty: middle of the backlash)")
    v0 = param.Number(0.0, bounds=(-1e6, 1e6), label="ẋ₀", doc="initial velocity")
    t0 = param.Number(0.0, bounds=(-MAX_T0, MAX_T0), label="t₀", doc="start time (phase of the forcing)")
    strobe = param.Number(0.0, bounds=(0.0, 360.0), softbounds=(0.0, 360.0), step=1.0, label="θ",
                          doc="strobe phase of the Poincaré map, degrees")
    # ----- view ------------------------------------------------------------------------------
    section = param.Selector(default="absolute", objects=["absolute", "relative", "impact"],
                             label="section")
    bif = param.Selector(default="lam", objects=["lam", "phi2", "rpm"], label="diagram",
                         doc="bifurcation diagram against Λ, φ₂ or (physical units) engine speed")
    overlays = Flag(True, label="overlays", doc="contact boundary Λ_c and 2πn/Λ")
    tab = param.Selector(default="explorer", objects=["explorer", "maps", "gearbox"], label="tab",
                         doc="the page's main tab, so that a shared link opens on it")
    present = Flag(False, label="presentation mode",
                   doc="large fonts, the time history and the section side by side, no sidebar")
    stage = param.Selector(default="plots", objects=["plots", "diagram", "motion", "pin", "maps"],
                           label="presented view",
                           doc="what presentation mode shows: the time history and the section "
                               "(plots), the bifurcation diagram, the gear in motion, the pinned "
                               "comparison or the maps")
    # ----- physical units --------------------------------------------------------------------
    units = Flag(False, label="physical units")
    inertia = param.Number(_EX.inertia, bounds=U.INERTIA_RANGE, inclusive_bounds=OPEN,
                           label="J", doc="idle-gear inertia [kg·m²]")
    radius = param.Number(_EX.radius, bounds=U.RADIUS_RANGE, inclusive_bounds=OPEN,
                          label="R_b", doc="idle-gear base radius [m]")
    drag_torque = param.Number(_EX.drag_torque, bounds=U.DRAG_TORQUE_RANGE,
                               inclusive_bounds=OPEN, label="C", doc="drag torque on the idle gear [N·m]")
    backlash_um = param.Number(_EX.backlash_um, bounds=tuple(v * 1e6 for v in U.BACKLASH_RANGE),
                               inclusive_bounds=OPEN, label="b", doc="backlash along the line of action [µm]")
    backlash_unit = param.Selector(default="um", objects=["um", "deg"], label="backlash shown in")
    rpm = param.Number(_EX.rpm, bounds=U.RPM_RANGE, inclusive_bounds=OPEN, label="engine speed [rpm]")
    order = param.Number(_EX.order, bounds=U.ORDER_RANGE, inclusive_bounds=OPEN,
                         label="order", doc="engine order of the fundamental")
    excitation = param.Selector(default="displacement", objects=["displacement", "acceleration"],
                                label="excitation")
    amp1 = param.Number(_EX.amplitudes[0], bounds=U.ALPHA_RANGE, inclusive_bounds=OPEN,
                        label="harmonic-1 amplitude", doc="θ₁ [rad] or α₁ [rad/s²]")
    amp2 = param.Number(_EX.amplitudes[1], bounds=U.ALPHA_RANGE, label="harmonic-2 amplitude",
                        doc="θ₂ [rad] or α₂ [rad/s²]")
    phase2 = param.Number(convert_phase(_EX.phases_deg[1], 2), bounds=PHASE_RANGE_DEG,
                          label="φ₂ (physical)",
                          doc="harmonic-2 phase [°] in the page's convention (``phases``), like φ₂")
    solve_for = param.Selector(default="rpm", objects=list(U.SOLVE_FOR), label="a change of Λ moves")
    # ----- continuation ----------------------------------------------------------------------
    continuation = Flag(False, label="continued branch",
                        doc="the orbit found at cont_from, continued over the diagram's range")
    cont_from = OptionalNumber(None, allow_None=True, bounds=(-1e6, 1e6), label="continued from",
                               doc="the diagram parameter's value (axis units) where the continued "
                                   "orbit was found (empty: the current value)")
    # ----- bifurcation curves ------------------------------------------------------------------
    atlas = Flag(False, label="atlas", doc="the exact bifurcation curves drawn over the map")
    curve_kind = param.Selector(default="", objects=["", "fold", "period_doubling", "grazing",
                                                     "stick_onset", "stick_end"],
                                label="curve of",
                                doc="the kind of the branch's bifurcation whose curve is traced")
    curve_at = OptionalNumber(None, allow_None=True, bounds=(-1e6, 1e6), label="curve from",
                              doc="where that bifurcation is (the diagram's units)")
    curve_param2 = param.Selector(default="r", objects=["lam", "r", "j", "h2", "phi2"],
                                  label="second parameter",
                                  doc="the parameter the bifurcation's curve is traced in")
    # ----- sensitivity: a twin trajectory ------------------------------------------------------
    twin = Flag(False, label="twin trajectory",
                doc="a second gear started next to the first; their separation against time")
    nudge = param.Number(1e-6, bounds=(1e-12, 1.0), label="nudge",
                         doc="how far the twin starts from the first gear, in x (H₁)")
    twin_x0 = OptionalNumber(None, allow_None=True, bounds=(-1e6, 1e6), label="twin x₀",
                             doc="the twin's clicked start (empty: the first gear's, nudged)")
    twin_v0 = param.Number(0.0, bounds=(-1e6, 1e6), label="twin ẋ₀", doc="the twin's start velocity")
    # ----- a pinned run, compared with the live one ----------------------------------------------
    pinned = param.String("", label="pinned run A",
                          doc="run A's settings 'key:value;…', kept while the live run (B) changes")
    # ----- computed, never in the URL ----------------------------------------------------------
    result = param.Parameter(None, precedence=-1, doc="the last good Run")
    pinned_result = param.Parameter(None, precedence=-1, doc="the Run of ``pinned`` (A), or None")
    branch = param.Parameter(None, precedence=-1, doc="the continued branch shown (app.branch.Branch)")

    def set_phase_convention(self, convention: str) -> None:
        """Show phases in ``convention`` ('paper' or 'core'); the model stays the same."""
        if convention == self.phases:
            return
        self.param["phases"]._validate(convention)
        harm = {k: (h, convert_phase(p, k)) for k, (h, p) in parse_harmonics(self.harmonics).items()}
        self.param.update(phases=convention, phi2=convert_phase(self.phi2, 2),
                          phase2=convert_phase(self.phase2, 2), harmonics=format_harmonics(harm))


#: Axes and fields a map can have (dimensionless, physical, or the start state for basins).
MAP_AXES = ["lam", "r", "j", "h2", "phi2", "rpm", "drag_torque", "x0", "v0"]
MAP_FIELDS = ["regime", "intensity", "period", "lyapunov", "stick_fraction", "attractor"]


#: How far a map's axis may reach either way (the model's own ranges are checked per axis).
MAP_RANGE = (-1e6, 1e6)


class MapSettings(Said):
    """The Maps tab's request: axes, ranges, points, periods and the field shown, with bounds.

    Its parameters are URL keys too (:data:`MAP_URL_KEYS`), so a shared link reopens the map."""

    kind = param.Selector(default="regime", objects=["regime", "basin"], label="map kind")
    x_axis = param.Selector(default="lam", objects=MAP_AXES, label="x axis")
    y_axis = param.Selector(default="phi2", objects=MAP_AXES, label="y axis")
    x_start = param.Number(0.5, bounds=MAP_RANGE, label="x from")
    x_stop = param.Number(4.0, bounds=MAP_RANGE, label="x to")
    x_num = param.Integer(60, bounds=(2, 400), label="x points")
    y_start = param.Number(0.0, bounds=MAP_RANGE, label="y from")
    y_stop = param.Number(360.0, bounds=MAP_RANGE, label="y to")
    y_num = param.Integer(60, bounds=(2, 400), label="y points")
    transient = param.Integer(200, bounds=(0, 100_000), label="transient periods")
    record = param.Integer(60, bounds=(1, 10_000), label="recorded periods")
    field = param.Selector(default="regime", objects=MAP_FIELDS, label="shown")


class GearboxSettings(Said):
    """The Gearbox tab's request: the excitation's orders, the speeds, the sound's level, the
    run's periods, and the what-if variant, with bounds.

    Its parameters are URL keys too (:data:`GEARBOX_URL_KEYS`), so a shared link reopens them."""

    engine_order = param.Number(2.0, bounds=(0.5, 50.0), label="engine order of the fundamental")
    harmonics = param.Integer(3, bounds=(1, 6), label="harmonics")
    rpm_step = param.Number(100.0, bounds=(10.0, 1000.0), label="rpm bins of the order analysis")
    rpm_start = param.Number(1000.0, bounds=(1.0, 1e5), label="rpm from")
    rpm_stop = param.Number(3000.0, bounds=(1.0, 1e5), label="rpm to")
    rpm_num = param.Integer(21, bounds=(2, 200), label="speeds")
    transfer = param.Number(5.0, bounds=(1e-3, 1e4), label="Pa per N·s")
    transient = param.Integer(200, bounds=(10, 5000), label="transient periods")
    record = param.Integer(100, bounds=(10, 5000), label="recorded periods")
    variant = param.Selector(default="none", objects=["none", "drag", "backlash", "design"],
                             label="what-if variant")
    target = TargetText("", label="target",
                        doc="limit curves 'RPM:VALUE,... sone; RPM:VALUE,... dba' (empty: the file's)")
    oil_temp = OptionalNumber(None, allow_None=True, bounds=(-40.0, 150.0),
                              label="oil temperature [°C]")
    drag_pct = param.Number(20.0, bounds=(-90.0, 500.0), label="drag change [%]")
    backlash_change_um = param.Number(-10.0, bounds=(-1000.0, 1000.0), label="backlash change [µm]")
    listen_rpm = param.Number(2000.0, bounds=(1.0, 1e5), label="listen at [rpm]")


#: State parameters → URL query keys.
URL_KEYS = {n: n for n in ExplorerState.param
            if n not in ("name", "result", "messages", "branch", "pinned_result")}
URL_KEYS.update(inertia="J", radius="Rb", drag_torque="C", backlash_um="b_um", backlash_unit="b_unit",
                excitation="exc", amp1="a1", amp2="a2", phase2="p2", solve_for="solve",
                continuation="cont", curve_kind="curve", curve_at="curve_at",
                curve_param2="curve_in", pinned="pin")
#: Map settings → URL query keys (``map_`` and the setting: ``map_x_axis``, ``map_x_num``, …).
MAP_URL_KEYS = {n: f"map_{n}" for n in MapSettings.param if n not in ("name", "messages")}
#: Gearbox settings → URL query keys (``gb_`` and the setting: ``gb_rpm_start``, …).
GEARBOX_URL_KEYS = {n: f"gb_{n}" for n in GearboxSettings.param if n not in ("name", "messages")}
#: Parameters that change the trajectory.
RUN_KEYS = ("lam", "r", "j", "h2", "phi2", "phases", "harmonics", "v_stick", "noise", "periods",
            "transient",
            "x0", "v0", "t0", "strobe")
#: Physical inputs that determine Λ, j, h₂, φ₂ while the units mode is on.
PHYSICAL_KEYS = ("inertia", "radius", "drag_torque", "backlash_um", "rpm", "order", "excitation",
                 "amp1", "amp2", "phase2")


@dataclasses.dataclass(frozen=True)
class Run:
    """One good simulation of the state: what every view draws."""

    params: RattleParams
    tr: Any
    cls: Any
    phys: Any  # PhysicalParams while the units mode is on, else None
    phases: str
    ms: float


def rattle_params(state: ExplorerState) -> RattleParams:
    """The core's parameter object for this state (phases converted to the core convention)."""
    extra = parse_harmonics(state.harmonics)
    n = max([2, *extra])
    amps = [1.0, state.h2] + [0.0] * (n - 2)
    phases = [0.0, state.phi2] + [0.0] * (n - 2)
    for k, (h, phi) in extra.items():
        amps[k - 1], phases[k - 1] = h, phi
    if state.phases == "paper":
        phases = list(paper_to_core_phases(phases))
    return RattleParams(lam=state.lam, r=state.r, j=state.j, amplitudes=tuple(amps),
                        phases_deg=tuple(phases), v_stick=state.v_stick, noise=state.noise)


def display_phases(params: RattleParams, convention: str) -> tuple[float, ...]:
    """The core parameters' phases as the page shows them."""
    return core_to_paper_phases(params.phases_deg) if convention == "paper" else params.phases_deg


#: Core parameter names in error messages → state parameters.
_CORE_NAMES = {"lam": "lam", "Λ": "lam", "r": "r", "j": "j", "v_stick": "v_stick", "x0": "x0",
               "v0": "v0", "t0": "t0", "periods": "periods", "transient": "transient",
               "strobe_phase": "strobe", "noise": "noise"}


def field_of_error(message: str) -> str | None:
    """Which state parameter a core ``ValueError`` is about, from the name it starts with."""
    m = re.match(r"\s*([A-Za-z_0-9θΛφ]+)(\[(\d+)\])?", message)
    if not m:
        return None
    word, idx = m.group(1), m.group(3)
    if word in ("amplitudes", "phases_deg") and idx is not None:
        if int(idx) == 1:
            return "h2" if word == "amplitudes" else "phi2"
        return "harmonics"
    return _CORE_NAMES.get(word)
