"""The dashboard's state: one ``param`` object per session, its validation, URL keys and presets.

Everything the views show is derived from :class:`DashboardState`. Widgets, the URL
(``pn.state.location.sync``), presets and clicks on the plots all write to it, and only through
:func:`validate_field`, so a bad value never reaches the solver: it is rejected with a message
naming the control, the value and the allowed range, and the last good state stays.

Phases typed in the dashboard follow the core's literal convention,
``y = Σ h_k cos(k t − φ_k)``. The paper's figures read the excitation as ``Σ h_k sin(k t + φ_k)``;
the presets come from the paper's cases (:func:`rattle_core.paper.cases.explorer_presets`), which
store core phases, so "Fig 7" (paper φ₂ = 45°) sets φ₂ = −135°.
"""
from __future__ import annotations

import dataclasses
import math
from typing import Any

import param

from rattle_core import RattleParams
from rattle_core.model.params import (AMPLITUDE_RANGE, J_RANGE, LAM_RANGE, MAX_HARMONICS,
                                      PHASE_RANGE_DEG, R_RANGE, V_STICK_RANGE, check_range)
from rattle_core.model.phases import paper_to_core
from rattle_core.paper.cases import explorer_presets

#: Largest window the dashboard simulates per redraw, to keep a slider move interactive.
MAX_PERIODS = 20_000
MAX_TRANSIENT = 100_000
MAX_SHOWN = 2_000


@dataclasses.dataclass(frozen=True)
class Field:
    """One user-editable quantity: its symbol, meaning, allowed range and slider range."""

    name: str
    symbol: str
    meaning: str
    lo: float
    hi: float
    lo_open: bool = False
    integer: bool = False
    start: float | None = None  # slider range, narrower than the allowed range
    end: float | None = None
    step: float | None = None

    @property
    def label(self) -> str:
        return f"{self.symbol} · {self.meaning}"

    def range_text(self) -> str:
        left = "(" if self.lo_open else "["
        return f"{left}{self.lo:g}, {self.hi:g}]"


FIELDS: dict[str, Field] = {f.name: f for f in [
    Field("lam", "Λ", "inertia ÷ drag, m H₁ω²/F", *LAM_RANGE, lo_open=True, start=0.2, end=6.0, step=0.01),
    Field("r", "r", "restitution coefficient", *R_RANGE, start=0.0, end=1.0, step=0.01),
    Field("j", "j", "backlash ÷ H₁", *J_RANGE, lo_open=True, start=0.5, end=20.0, step=0.1),
    Field("h2", "H₂/H₁", "2nd-harmonic amplitude ratio", *AMPLITUDE_RANGE, start=0.0, end=1.0, step=0.01),
    Field("phi2", "φ₂", "2nd-harmonic phase, degrees", *PHASE_RANGE_DEG, start=-180.0, end=180.0, step=1.0),
    Field("periods", "N", "periods recorded (Poincaré map, metrics)", 1, MAX_PERIODS, integer=True),
    Field("shown", "Nₜ", "periods shown in the time history", 1, MAX_SHOWN, integer=True),
    Field("transient", "Nₜᵣ", "transient periods, not recorded", 0, MAX_TRANSIENT, integer=True),
    Field("v_stick", "v_stick", "limit impact velocity (ends chatter)", *V_STICK_RANGE),
    Field("x0", "x₀", "initial position (empty: middle of the backlash)", -1e6, 1e6),
    Field("v0", "ẋ₀", "initial velocity", -1e6, 1e6),
    Field("t0", "t₀", "start time (phase of the forcing)", -1e9, 1e9),
    Field("strobe", "θ", "strobe phase of the Poincaré map, degrees", 0.0, 360.0, start=0.0, end=360.0, step=1.0),
]}

SECTIONS = ("absolute", "relative", "impact")
#: Bifurcation diagrams: Ĩ against Λ, φ₂, or engine speed (physical-units mode only).
BIF_PARAMS = ("lam", "phi2", "rpm")


class DashboardState(param.Parameterized):
    """Everything that defines the view; synced with the URL, one instance per session.

    Numbers carry their allowed range as hard bounds, so even a direct assignment (the URL
    sync does one) cannot store an out-of-range value.
    """

    lam = param.Number(3.3, bounds=LAM_RANGE, inclusive_bounds=(False, True))
    r = param.Number(0.65, bounds=R_RANGE)
    j = param.Number(8.0, bounds=J_RANGE, inclusive_bounds=(False, True))
    h2 = param.Number(0.25, bounds=AMPLITUDE_RANGE)
    phi2 = param.Number(paper_to_core(45.0), bounds=PHASE_RANGE_DEG)
    harmonics = param.String("", doc="Extra harmonics k ≥ 3 as 'k:h:φ' items, comma-separated.")
    periods = param.Integer(200, bounds=(1, MAX_PERIODS))
    shown = param.Integer(12, bounds=(1, MAX_SHOWN))
    transient = param.Integer(300, bounds=(0, MAX_TRANSIENT))
    v_stick = param.Number(1e-6, bounds=V_STICK_RANGE)
    x0 = param.String("", doc="Initial position; empty means the middle of the backlash.")
    v0 = param.Number(0.0, bounds=(-1e6, 1e6))
    t0 = param.Number(0.0, bounds=(-1e9, 1e9))
    strobe = param.Number(0.0, bounds=(0.0, 360.0))
    section = param.Selector(default="absolute", objects=list(SECTIONS))
    bif = param.Selector(default="lam", objects=list(BIF_PARAMS))
    overlays = param.Boolean(True)


#: Parameters that change the trajectory (and so every view).
DYNAMIC = ("lam", "r", "j", "h2", "phi2", "harmonics", "periods", "shown", "transient", "v_stick",
           "x0", "v0", "t0", "strobe", "section")
#: URL query keys, one per state parameter (short, stable names: links are shared).
URL_KEYS = {name: name for name in DashboardState.param if name != "name"}


def validate_field(name: str, value: Any) -> Any:
    """Return ``value`` cleaned for state parameter ``name``, or raise ``ValueError``.

    The message names the control's symbol, the value and the allowed range.
    """
    if name == "harmonics":
        return format_harmonics(parse_harmonics(value))
    if name == "x0":
        if value is None or (isinstance(value, str) and value.strip() == ""):
            return ""
        f = FIELDS["x0"]
        return repr(check_range(f.symbol, _number(f, value), f.lo, f.hi, text_ok=True))
    if name == "section":
        if value not in SECTIONS:
            raise ValueError(f"section = {value!r}; allowed: {', '.join(SECTIONS)}")
        return value
    if name == "bif":
        if value not in BIF_PARAMS:
            raise ValueError(f"bifurcation parameter = {value!r}; allowed: {', '.join(BIF_PARAMS)}")
        return value
    if name == "overlays":
        if isinstance(value, bool):
            return value
        if str(value).lower() in ("true", "1"):
            return True
        if str(value).lower() in ("false", "0"):
            return False
        raise ValueError(f"overlays = {value!r}; allowed: true or false")
    if name not in FIELDS:
        raise ValueError(f"unknown setting {name!r}")
    f = FIELDS[name]
    v = check_range(f.symbol, _number(f, value), f.lo, f.hi, lo_open=f.lo_open, text_ok=True)
    if f.integer:
        if v != int(v):
            raise ValueError(f"{f.symbol} = {value!r} must be a whole number in {f.range_text()}")
        return int(v)
    return v


def _number(f: Field, value: Any) -> float:
    if isinstance(value, bool):
        raise ValueError(f"{f.symbol} must be a number, got {value!r}")
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{f.symbol} must be a number, got {value!r}") from None
    if not math.isfinite(v):
        raise ValueError(f"{f.symbol} must be finite, got {value!r}")
    return v


def parse_harmonics(text: Any) -> dict[int, tuple[float, float]]:
    """Parse ``'3:0.1:30, 5:0.05:-20'`` into ``{3: (0.1, 30.0), 5: (0.05, -20.0)}``.

    Orders run from 3 to ``MAX_HARMONICS`` (1 and 2 have their own sliders); amplitudes and
    phases obey the core's ranges.
    """
    if text is None:
        return {}
    if not isinstance(text, str):
        raise ValueError(f"harmonics must be text like '3:0.1:30', got {text!r}")
    out: dict[int, tuple[float, float]] = {}
    for item in filter(None, (s.strip() for s in text.split(","))):
        parts = item.split(":")
        if len(parts) != 3:
            raise ValueError(f"harmonic {item!r} must be 'order:amplitude:phase', e.g. '3:0.1:30'")
        try:
            k = float(parts[0])
        except ValueError:
            raise ValueError(f"harmonic order {parts[0]!r} must be a whole number in [3, {MAX_HARMONICS}]") from None
        if k != int(k) or not 3 <= k <= MAX_HARMONICS:
            raise ValueError(f"harmonic order {parts[0]!r} must be a whole number in [3, {MAX_HARMONICS}]")
        h = check_range(f"H{int(k)}/H₁", parts[1], *AMPLITUDE_RANGE, text_ok=True)
        phi = check_range(f"φ{int(k)}", parts[2], *PHASE_RANGE_DEG, text_ok=True)
        out[int(k)] = (h, phi)
    return dict(sorted(out.items()))


def format_harmonics(harm: dict[int, tuple[float, float]]) -> str:
    """Inverse of :func:`parse_harmonics` (sorted by order, shortest exact floats)."""
    return ",".join(f"{k}:{h!r}:{phi!r}" for k, (h, phi) in sorted(harm.items()))


def rattle_params(state: DashboardState) -> RattleParams:
    """The core's parameter object for this state (``ValueError`` if the core rejects it)."""
    extra = parse_harmonics(state.harmonics)
    n = max([2, *extra])
    amps = [1.0, state.h2] + [0.0] * (n - 2)
    phases = [0.0, state.phi2] + [0.0] * (n - 2)
    for k, (h, phi) in extra.items():
        amps[k - 1] = h
        phases[k - 1] = phi
    return RattleParams(lam=state.lam, r=state.r, j=state.j, amplitudes=tuple(amps),
                        phases_deg=tuple(phases), v_stick=state.v_stick)


def initial_x(state: DashboardState) -> float | None:
    """``x0`` as the solver wants it: None (middle of the backlash) or a float."""
    return None if state.x0.strip() == "" else float(state.x0)


def apply_values(state: DashboardState, values: dict[str, Any]) -> dict[str, str]:
    """Validate and apply ``values`` in one batch; return ``{name: message}`` for the rejected ones.

    Valid entries are applied even when others are rejected, so one bad URL parameter does
    not cost the others.
    """
    good, errors = {}, {}
    for name, value in values.items():
        if name not in URL_KEYS:
            errors[name] = f"unknown setting {name!r} ignored"
            continue
        try:
            good[name] = validate_field(name, value)
        except ValueError as exc:
            errors[name] = str(exc)
    changed = {k: v for k, v in good.items() if getattr(state, k) != v}
    if changed:
        state.param.update(**changed)
    return errors


# ----- the paper's cases --------------------------------------------------------------------

def _state_values(p: RattleParams, **view: Any) -> dict[str, Any]:
    """The state values that show ``p`` (two harmonics at most) from a fresh start."""
    return {"lam": p.lam, "r": p.r, "j": p.j, "h2": p.get("h2"), "phi2": p.get("phi2"),
            "harmonics": "", "x0": "", "v0": 0.0, "t0": 0.0, **view}


#: One-click reproductions of the paper's figures: label → (description, state values).
PRESETS: dict[str, tuple[str, dict[str, Any]]] = {
    p.label: (p.description, _state_values(p.params, **p.view)) for p in explorer_presets()}
