"""The physical-units mode: the state's SI inputs and its dimensionless Λ, j, h₂, φ₂ kept in step.

While ``state.units`` is on, two descriptions of one model live in the state. A change on
one side is carried to the other:

* a physical input changed (or a link says the physical side wins): Λ, j, h₂ and φ₂ follow
  from :meth:`PhysicalParams.to_dimensionless`;
* a dimensionless value changed (a slider, a preset, a click, turning the mode on): the
  physical set follows from :meth:`PhysicalParams.from_dimensionless`, every constant held
  except ``state.solve_for`` (the engine speed by default).

Orders ≥ 3 have no physical inputs: they keep their ratio ``h_k`` (the ``harmonics`` key).
The physical φ₂ is held in the page's phase convention, as φ₂ is: one convention per screen.
Values equal to rounding (relative 1e-12) are left as they are, so round trips do not creep
in the last digit. Nothing here touches widgets; the session applies what :func:`link`
returns.
"""
from __future__ import annotations

import math
from typing import Any

from rattle_core import RattleParams

from .core import PhysicalParams, units
from .state import PHYSICAL_KEYS, convert_phase, rattle_params

#: Dimensionless values the physical side sets, and those whose change moves the physical side.
DIMENSIONLESS_SET = ("lam", "j", "h2", "phi2")
SOLVE_LABELS = {"rpm": "the engine speed", "drag_torque": "the drag torque C",
                "inertia": "the idle-gear inertia J", "amplitude": "the harmonic-1 amplitude"}
DIMENSIONLESS_MOVES = ("lam", "j", "h2", "phi2", "phases", "harmonics", "r", "v_stick", "units")


class LinkError(ValueError):
    """A physical input that gives no valid model; ``name`` is the input at fault."""

    def __init__(self, name: str, message: str):
        super().__init__(message)
        self.name = name


def physical_of(state: Any, params: RattleParams | None = None) -> PhysicalParams:
    """The physical set the state's inputs describe (``ValueError`` if they describe none).

    Orders ≥ 3, ``r`` and ``v_stick`` come from ``params`` (the state's, by default).
    """
    params = params if params is not None else rattle_params(state)
    acc = state.excitation == "acceleration"
    a1 = state.amp1
    amps = [a1, state.amp2]
    phase2 = state.phase2 if state.phases == "core" else convert_phase(state.phase2, 2)
    phases = [180.0 if acc else 0.0, phase2]
    for k in range(3, params.n_harmonics + 1):
        h, phi = params.amplitudes[k - 1], params.phases_deg[k - 1]
        amps.append(h * k * k * a1 if acc else h * a1)
        phases.append(units.wrap_deg(phi - 180.0) if acc else phi)
    return PhysicalParams(inertia=state.inertia, radius=state.radius, drag_torque=state.drag_torque,
                          backlash=units.backlash_from_um(state.backlash_um), rpm=state.rpm,
                          amplitudes=tuple(amps), phases_deg=tuple(phases), order=state.order,
                          excitation=state.excitation, r=params.r, v_stick=params.v_stick)


def inputs_of(phys: PhysicalParams, phases: str = "core") -> dict[str, Any]:
    """The state's physical inputs for a physical set (φ₂ in the convention ``phases``)."""
    phase2 = phys.phases_deg[1] if len(phys.phases_deg) > 1 else 0.0
    return {"inertia": phys.inertia, "radius": phys.radius, "drag_torque": phys.drag_torque,
            "backlash_um": phys.backlash_um, "rpm": phys.rpm, "order": phys.order,
            "excitation": phys.excitation, "amp1": phys.amplitudes[0],
            "amp2": phys.amplitudes[1] if len(phys.amplitudes) > 1 else 0.0,
            "phase2": phase2 if phases == "core" else convert_phase(phase2, 2)}


def _changed(state: Any, values: dict[str, Any]) -> dict[str, Any]:
    """The entries of ``values`` that differ from the state's by more than rounding."""
    out = {}
    for k, v in values.items():
        old = getattr(state, k)
        if isinstance(v, float) and isinstance(old, (int, float)) and not isinstance(old, bool):
            if math.isclose(v, old, rel_tol=1e-12, abs_tol=1e-300):
                continue
        elif v == old:
            continue
        out[k] = v
    return out


def dimensionless_of(state: Any, phys: PhysicalParams) -> dict[str, Any]:
    """Λ, j, h₂ and φ₂ (in the page's phase convention) of a physical set."""
    p = phys.to_dimensionless()
    phi2 = p.phases_deg[1] if p.n_harmonics > 1 else 0.0
    if state.phases == "paper":
        phi2 = convert_phase(phi2, 2)
    return {"lam": p.lam, "j": p.j, "h2": p.amplitudes[1] if p.n_harmonics > 1 else 0.0, "phi2": phi2}


def link(state: Any, names: set[str], physical_wins: bool = False) -> tuple[dict[str, Any], str]:
    """What makes the two sides agree after ``names`` changed: ``(values, warning)``.

    ``values`` are to be applied to the state. Raises :class:`LinkError` when the physical
    inputs describe no model; ``warning`` (else empty) says why the physical side could not
    follow a dimensionless change (the inputs then keep their values).
    """
    if not state.units:
        return {}, ""
    if physical_wins or names & set(PHYSICAL_KEYS):
        culprit = next((n for n in PHYSICAL_KEYS if n in names), "units")
        try:
            phys = physical_of(state)
            values = dimensionless_of(state, phys)
        except ValueError as exc:
            raise LinkError(culprit, str(exc)) from None
        return _changed(state, values), ""
    if not names & set(DIMENSIONLESS_MOVES):
        return {}, ""
    params = rattle_params(state)
    try:
        held = physical_of(state, params)
        new = PhysicalParams.from_dimensionless(params, held, solve_for=state.solve_for)
        new.to_dimensionless()
    except ValueError as exc:
        return {}, (f"Λ = {params.lam:.6g}, j = {params.j:.6g} cannot be reached by moving "
                    f"{SOLVE_LABELS[state.solve_for]}: {exc}. "
                    "The physical inputs keep their values.")
    return _changed(state, inputs_of(new, state.phases)), ""


def run_physical(state: Any, params: RattleParams) -> PhysicalParams | None:
    """The physical set of a good run, or None when the mode is off or the sides disagree."""
    if not state.units:
        return None
    try:
        phys = physical_of(state, params)
        q = phys.to_dimensionless()
    except ValueError:
        return None
    same = all(math.isclose(a, b, rel_tol=1e-9) for a, b in ((q.lam, params.lam), (q.j, params.j)))
    return phys if same else None


def excitation_values(state: Any, kind: str) -> dict[str, Any]:
    """Inputs describing the same excitation as ``kind`` (displacements or accelerations)."""
    if kind == state.excitation:
        return {}
    phys = physical_of(state).as_excitation(kind)
    values = {k: v for k, v in inputs_of(phys, state.phases).items() if k in ("excitation", "amp1", "amp2", "phase2")}
    if kind == "acceleration" and state.solve_for == "rpm":
        # with accelerations held, Λ = m R_d α₁ / F does not depend on engine speed
        values["solve_for"] = "amplitude"
    return values
