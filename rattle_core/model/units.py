"""Physical units: an NVH engineer's inputs, mapped to the dimensionless model and back.

The rattle model (paper eq. 1-11, ``docs/model.md``) is solved in dimensionless form.  This module
is the one place where kg·m², N·m, µm and rpm are turned into ``Λ, j, h_k, φ_k`` and where
dimensionless results (times, positions, impulses) are turned back into seconds, metres and
newton-seconds.

Conventions
-----------
Idle gear (the rattling one)
    Inertia ``J`` [kg·m²] and base radius ``R_b`` [m].  Its rotation ``ψ`` becomes the
    displacement ``x = R_b ψ`` along the line of action, so its equivalent mass is
    ``m = J / R_b²`` [kg].  The drag torque ``C`` [N·m] becomes the force ``F = C / R_b`` [N].
Backlash
    ``b`` [m], measured along the line of action.  Given as an angle ``β`` of the idle gear
    (rad or degrees), ``b = R_b β``.
Engine speed and order
    The fundamental circular frequency of the excitation is
    ``ω = order × 2π × rpm / 60`` [rad/s].  ``order`` is the engine order of the fundamental:
    the number of excitation cycles per crankshaft revolution.  A four-stroke engine fires each
    cylinder once every two revolutions, so ``order = n_cylinders / 2``; for the paper's
    four-cylinder four-stroke, ``order = 2`` (the firing frequency, twice the rotation
    frequency).  Harmonic ``k`` of the model has circular frequency ``k ω``, i.e. engine order
    ``k × order``.
Driving gear excitation, harmonic ``k = 1..K``
    Either the angular displacement fluctuation of the driving gear,
    ``θ(t) = Σ θ_k cos(k ω t − φ_k)`` [rad], so that ``H_k = R_d θ_k``; or its angular
    acceleration fluctuation, ``α(t) = Σ α_k cos(k ω t − φ_k^α)`` [rad/s²].  Integrating twice,
    ``θ_k = α_k / (k ω)²`` and ``φ_k = φ_k^α + 180°``, so ``H_k = R_d α_k / (k ω)²``.
    ``R_d`` is the driving gear's base radius; it defaults to the idle gear's ``R_b``.
    Time is measured from the same reference as the phases (for example top dead centre of
    cylinder 1).
Dimensionless numbers (paper eq. 8-9)
    ``Λ = m H₁ ω² / F``, ``j = b / H₁``, ``h_k = H_k / H₁``, ``φ_k`` as above.  The restitution
    coefficient ``r`` is dimensionless in both systems, and ``v_stick`` is kept dimensionless
    (its physical value is ``v_stick ω H₁`` [m/s], see :attr:`PhysicalParams.v_stick_mps`).
Back to physical quantities
    Time ``t_phys = t / ω``; position ``x_phys = H₁ x``; velocity ``ẋ_phys = ω H₁ ẋ``;
    reaction ``R = F R̃``; impulse ``I = Ĩ m ω H₁`` [N·s] along the line of action (paper
    eq. 11), which is the angular impulse ``R_b I`` [N·m·s] on the idle gear.

With displacement amplitudes held fixed, ``Λ ∝ rpm²`` and ``j`` does not depend on speed.  With
acceleration amplitudes held fixed, ``H₁ ∝ 1/ω²``, so ``Λ = m R_d α₁ / F`` does not depend on
speed and ``j ∝ rpm²`` instead: an engine-speed sweep is then a sweep of ``j``
(:func:`rpm_sweep` picks the right one).
"""
from __future__ import annotations

import dataclasses
import math
from typing import Any, Literal

import numpy as np

from .params import (PHASE_RANGE_DEG, R_RANGE, V_STICK_RANGE, RattleParams, _as_tuple,
                     check_range)
from .engine import (ORDER_RANGE, RPM_RANGE, impulse_scale_from_rpm, j_from_rpm, lam_from_rpm,
                     omega_from_rpm, rpm_from_lam, rpm_from_omega, rpm_from_sweep, rpm_sweep)
from .phases import wrap_deg

#: Allowed ranges of the physical inputs (SI units), shared by validation, the CLI and the app.
INERTIA_RANGE = (0.0, 10.0)          # kg·m², open at 0
RADIUS_RANGE = (0.0, 2.0)            # m, open at 0
DRAG_TORQUE_RANGE = (0.0, 1.0e4)     # N·m, open at 0
BACKLASH_RANGE = (0.0, 0.1)          # m, open at 0
THETA_RANGE = (0.0, math.pi)         # rad, angular displacement amplitude
ALPHA_RANGE = (0.0, 1.0e9)           # rad/s², angular acceleration amplitude

ExcitationKind = Literal["displacement", "acceleration"]
_KINDS = ("displacement", "acceleration")
SOLVE_FOR = ("rpm", "drag_torque", "inertia", "amplitude")


def backlash_from_um(backlash_um: float) -> float:
    """Backlash along the line of action in metres, from micrometres: ``b = 10⁻⁶ b_µm``."""
    b_um = check_range("backlash_um", backlash_um, BACKLASH_RANGE[0] * 1e6,
                       BACKLASH_RANGE[1] * 1e6, lo_open=True)
    return b_um / 1e6  # division is correctly rounded: 160 µm gives exactly 160e-6


def backlash_from_angle(angle: float, radius: float, unit: Literal["rad", "deg"] = "rad") -> float:
    """Backlash along the line of action ``b = R_b β`` [m] from an angle ``β`` of the idle gear.

    Parameters
    ----------
    angle : float
        Angular backlash ``β`` of the idle gear, in ``unit``; > 0.
    radius : float
        Idle gear base radius ``R_b`` [m].
    unit : {"rad", "deg"}
        Unit of ``angle``.
    """
    if unit not in ("rad", "deg"):
        raise ValueError(f"unit = {unit!r} is not allowed; use 'rad' or 'deg'")
    radius = check_range("radius", radius, *RADIUS_RANGE, lo_open=True)
    hi = BACKLASH_RANGE[1] / radius
    if unit == "deg":
        beta = math.radians(check_range("backlash_deg", angle, 0.0, math.degrees(hi), lo_open=True))
    else:
        beta = check_range("backlash_rad", angle, 0.0, hi, lo_open=True)
    return radius * beta


@dataclasses.dataclass(frozen=True)
class PhysicalParams:
    """The rattle model in physical units (SI), equivalent to one :class:`RattleParams`.

    Parameters
    ----------
    inertia : float
        Idle gear moment of inertia ``J`` [kg·m²], in (0, 10].
    radius : float
        Idle gear base radius ``R_b`` [m], in (0, 2].  ``m = J / R_b²``.
    drag_torque : float
        Drag torque on the idle gear ``C`` [N·m], in (0, 1e4].  ``F = C / R_b``.
    backlash : float
        Backlash along the line of action ``b`` [m], in (0, 0.1].  See
        :func:`backlash_from_um` and :func:`backlash_from_angle`.
    rpm : float
        Engine speed [rev/min], in (0, 1e5].
    amplitudes : sequence of float
        Amplitudes of harmonics k = 1..K of the driving gear's fluctuation: angular
        displacement ``θ_k`` [rad], each in [0, π], or angular acceleration ``α_k`` [rad/s²],
        each in [0, 1e9], according to ``excitation``.  The first must be > 0.
    phases_deg : sequence of float, optional
        Phases of the same harmonics [degrees], in the convention
        ``cos(k ω t − φ_k)``; zeros by default.
    order : float
        Engine order of the fundamental, in (0, 100]; ``ω = order × 2π × rpm / 60``.
        Default 2 (four-cylinder four-stroke).
    excitation : {"displacement", "acceleration"}
        What ``amplitudes`` and ``phases_deg`` describe.
    r : float
        Coefficient of restitution, in [0, 1].
    v_stick : float
        Dimensionless limit impact velocity (as in :class:`RattleParams`), in [0, 10].
    driver_radius : float, optional
        Driving gear base radius ``R_d`` [m]; defaults to ``radius``.  ``H_k = R_d θ_k``.
    """

    inertia: float
    radius: float
    drag_torque: float
    backlash: float
    rpm: float
    amplitudes: tuple[float, ...]
    phases_deg: tuple[float, ...] | None = None
    order: float = 2.0
    excitation: ExcitationKind = "displacement"
    r: float = 0.65
    v_stick: float = 1e-6
    driver_radius: float | None = None

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        set_(self, "inertia", check_range("inertia", self.inertia, *INERTIA_RANGE, lo_open=True))
        set_(self, "radius", check_range("radius", self.radius, *RADIUS_RANGE, lo_open=True))
        set_(self, "drag_torque", check_range("drag_torque", self.drag_torque, *DRAG_TORQUE_RANGE,
                                              lo_open=True))
        set_(self, "backlash", check_range("backlash", self.backlash, *BACKLASH_RANGE, lo_open=True))
        set_(self, "rpm", check_range("rpm", self.rpm, *RPM_RANGE, lo_open=True))
        set_(self, "order", check_range("order", self.order, *ORDER_RANGE, lo_open=True))
        set_(self, "r", check_range("r", self.r, *R_RANGE))
        set_(self, "v_stick", check_range("v_stick", self.v_stick, *V_STICK_RANGE))
        if self.excitation not in _KINDS:
            raise ValueError(f"excitation = {self.excitation!r} is not allowed; "
                             f"use 'displacement' or 'acceleration'")
        if self.driver_radius is not None:
            set_(self, "driver_radius", check_range("driver_radius", self.driver_radius,
                                                    *RADIUS_RANGE, lo_open=True))
        amps = _as_tuple("amplitudes", self.amplitudes)
        if not amps:
            raise ValueError("amplitudes must hold at least one harmonic, got an empty list")
        rng = THETA_RANGE if self.excitation == "displacement" else ALPHA_RANGE
        unit = "rad" if self.excitation == "displacement" else "rad/s^2"
        amps = tuple(check_range(f"amplitudes[{i}] ({self.excitation} of harmonic {i + 1}, {unit})",
                                 a, *rng) for i, a in enumerate(amps))
        if amps[0] <= 0.0:
            raise ValueError(f"amplitudes[0] ({self.excitation} of harmonic 1, {unit}) = {amps[0]!r} "
                             f"is outside the allowed range ({rng[0]:g}, {rng[1]:g}]: the first "
                             "harmonic sets the length scale H1")
        if self.phases_deg is None:
            phases = (0.0,) * len(amps)
        else:
            phases = _as_tuple("phases_deg", self.phases_deg)
        if len(phases) != len(amps):
            raise ValueError(f"phases_deg has {len(phases)} entries but amplitudes has {len(amps)}; "
                             "they must have the same length")
        phases = tuple(check_range(f"phases_deg[{i}]", p, *PHASE_RANGE_DEG)
                       for i, p in enumerate(phases))
        set_(self, "amplitudes", amps)
        set_(self, "phases_deg", phases)

    # ----- derived physical quantities ----------------------------------------------------
    @property
    def mass(self) -> float:
        """Equivalent mass along the line of action ``m = J / R_b²`` [kg]."""
        return self.inertia / self.radius**2

    @property
    def force(self) -> float:
        """Drag force along the line of action ``F = C / R_b`` [N]."""
        return self.drag_torque / self.radius

    @property
    def omega(self) -> float:
        """Fundamental circular frequency ``ω = order × 2π × rpm / 60`` [rad/s]."""
        return self.order * 2.0 * math.pi * self.rpm / 60.0

    @property
    def frequency_hz(self) -> float:
        """Fundamental excitation frequency ``ω / 2π`` [Hz]."""
        return self.order * self.rpm / 60.0

    @property
    def period_s(self) -> float:
        """Fundamental excitation period ``2π / ω`` [s]; one dimensionless period 2π."""
        return 60.0 / (self.order * self.rpm)

    @property
    def drive_radius(self) -> float:
        """Driving gear base radius ``R_d`` [m] (``driver_radius``, or ``radius`` if unset)."""
        return self.radius if self.driver_radius is None else self.driver_radius

    @property
    def displacement_amplitudes(self) -> np.ndarray:
        """Angular displacement amplitudes ``θ_k`` [rad]; ``θ_k = α_k / (k ω)²`` from accelerations."""
        a = np.asarray(self.amplitudes, dtype=np.float64)
        if self.excitation == "displacement":
            return a
        k = np.arange(1, a.size + 1, dtype=np.float64)
        return a / (k * self.omega) ** 2

    @property
    def displacement_phases_deg(self) -> np.ndarray:
        """Phases ``φ_k`` [deg] of the displacement; ``φ_k = φ_k^α + 180°`` (wrapped) from accelerations."""
        p = np.asarray(self.phases_deg, dtype=np.float64)
        if self.excitation == "displacement":
            return p
        return np.array([wrap_deg(v + 180.0) for v in p])

    @property
    def H(self) -> np.ndarray:
        """Displacement amplitudes along the line of action ``H_k = R_d θ_k`` [m]."""
        return self.drive_radius * self.displacement_amplitudes

    @property
    def H1(self) -> float:
        """Length scale ``H₁`` [m]: amplitude of the first harmonic."""
        return float(self.H[0])

    @property
    def backlash_um(self) -> float:
        """Backlash along the line of action [µm]."""
        return self.backlash * 1e6

    @property
    def backlash_deg(self) -> float:
        """Backlash as an angle of the idle gear ``b / R_b`` [degrees]."""
        return math.degrees(self.backlash / self.radius)

    @property
    def v_stick_mps(self) -> float:
        """Limit impact velocity in physical units ``v_stick ω H₁`` [m/s]."""
        return self.v_stick * self.omega * self.H1

    @property
    def lam(self) -> float:
        """``Λ = m H₁ ω² / F`` (paper eq. 9)."""
        return self.mass * self.H1 * self.omega**2 / self.force

    # ----- the mapping ----------------------------------------------------------------
    def to_dimensionless(self) -> RattleParams:
        """The equivalent :class:`RattleParams`.

        Implements ``Λ = m H₁ ω² / F``, ``j = b / H₁``, ``h_k = H_k / H₁`` (``h₁ = 1`` exactly)
        and ``φ_k`` (displacement phases, see the module docstring); ``r`` and ``v_stick``
        pass through.

        Raises
        ------
        ValueError
            If a derived dimensionless number falls outside the model's range; the message
            names it and the physical inputs it came from.
        """
        H = self.H
        H1 = float(H[0])
        h = tuple([1.0] + [float(v) for v in H[1:] / H1])
        try:
            return RattleParams(lam=self.lam, r=self.r, j=self.backlash / H1, amplitudes=h,
                                phases_deg=tuple(float(p) for p in self.displacement_phases_deg),
                                v_stick=self.v_stick)
        except ValueError as exc:
            raise ValueError(f"{exc}; it derives from the physical inputs (H1 = {H1:.6g} m, "
                             f"omega = {self.omega:.6g} rad/s, m = {self.mass:.6g} kg, "
                             f"F = {self.force:.6g} N)") from None

    @classmethod
    def from_dimensionless(cls, params: RattleParams, held: "PhysicalParams",
                           solve_for: str = "rpm") -> "PhysicalParams":
        """Physical parameters that reproduce ``params``, holding the constants of ``held``.

        ``Λ = m H₁ ω² / F`` is solved for one quantity; every other physical constant is taken
        from ``held``.  Then, with ``H₁`` known:

        * backlash ``b = j H₁``;
        * displacement amplitudes ``θ_k = h_k θ₁`` with phases ``φ_k``, or acceleration
          amplitudes ``α_k = h_k k² α₁`` with phases ``φ_k − 180°`` (wrapped to (−180, 180]);
        * ``r`` and ``v_stick`` are copied.

        Parameters
        ----------
        params : RattleParams
            The dimensionless parameters.
        held : PhysicalParams
            Supplies the held constants: inertia, radius, driver radius, drag torque, engine
            speed and order, the first-harmonic amplitude and the excitation kind.
        solve_for : {"rpm", "drag_torque", "inertia", "amplitude"}
            Which quantity Λ determines:

            * ``"rpm"``: ``ω = sqrt(Λ F / (m H₁))`` (displacement excitation only: with
              acceleration amplitudes held, Λ does not depend on speed);
            * ``"drag_torque"``: ``C = R_b m H₁ ω² / Λ``;
            * ``"inertia"``: ``J = R_b² Λ F / (H₁ ω²)``;
            * ``"amplitude"``: ``H₁ = Λ F / (m ω²)``, so ``θ₁ = H₁ / R_d`` or
              ``α₁ = ω² H₁ / R_d``.

        Returns
        -------
        PhysicalParams
            ``result.to_dimensionless()`` equals ``params`` to rounding.
        """
        if not isinstance(params, RattleParams):
            raise ValueError(f"params must be a RattleParams, got {type(params).__name__}")
        if not isinstance(held, PhysicalParams):
            raise ValueError(f"held must be a PhysicalParams, got {type(held).__name__}")
        if solve_for not in SOLVE_FOR:
            raise ValueError(f"solve_for = {solve_for!r} is not allowed; use one of {', '.join(SOLVE_FOR)}")
        lam = params.lam
        m, F, Rb, Rd = held.mass, held.force, held.radius, held.drive_radius
        inertia, drag, rpm = held.inertia, held.drag_torque, held.rpm
        omega = held.omega
        a1 = held.amplitudes[0]
        H1 = held.H1
        if solve_for == "rpm":
            if held.excitation == "acceleration":
                raise ValueError("solve_for = 'rpm' is not allowed with acceleration amplitudes held: "
                                 "Λ = m R_d α1 / F does not depend on engine speed; solve for "
                                 "drag_torque, inertia or amplitude instead")
            omega = math.sqrt(lam * F / (m * H1))
            rpm = float(rpm_from_omega(omega, held.order))
        elif solve_for == "drag_torque":
            drag = Rb * m * H1 * omega**2 / lam
        elif solve_for == "inertia":
            inertia = Rb**2 * lam * F / (H1 * omega**2)
        else:
            H1 = lam * F / (m * omega**2)
            a1 = H1 / Rd if held.excitation == "displacement" else omega**2 * H1 / Rd
        h = params.amplitudes
        if held.excitation == "displacement":
            amps = tuple([a1] + [hk * a1 for hk in h[1:]])
            phases = tuple(params.phases_deg)
        else:
            amps = tuple([a1] + [hk * (k * k) * a1 for k, hk in enumerate(h[1:], start=2)])
            phases = tuple(wrap_deg(p - 180.0) for p in params.phases_deg)
        return cls(inertia=inertia, radius=Rb, drag_torque=drag, backlash=params.j * H1, rpm=rpm,
                   amplitudes=amps, phases_deg=phases, order=held.order, excitation=held.excitation,
                   r=params.r, v_stick=params.v_stick, driver_radius=held.driver_radius)

    def replace(self, **changes: Any) -> "PhysicalParams":
        """A validated copy with some fields changed."""
        return dataclasses.replace(self, **changes)

    def as_excitation(self, kind: ExcitationKind) -> "PhysicalParams":
        """The same excitation given as displacements or as accelerations
        (``α_k = θ_k (k ω)²``, ``φ_k^α = φ_k − 180°``): the dimensionless model is unchanged."""
        if kind not in _KINDS:
            raise ValueError(f"excitation = {kind!r}; allowed: {', '.join(_KINDS)}")
        if kind == self.excitation:
            return self
        if kind == "acceleration":
            k = np.arange(1, len(self.amplitudes) + 1, dtype=np.float64)
            amps = tuple(float(a) for a in np.asarray(self.amplitudes) * (k * self.omega) ** 2)
            phases = tuple(wrap_deg(v - 180.0) for v in self.phases_deg)
        else:
            amps = tuple(float(a) for a in self.displacement_amplitudes)
            phases = tuple(float(v) for v in self.displacement_phases_deg)
        return self.replace(excitation=kind, amplitudes=amps, phases_deg=phases)

    # ----- dimensionless results back to physical units --------------------------------
    def time(self, t: Any) -> np.ndarray | float:
        """Physical time ``t_phys = t / ω`` [s] of dimensionless times ``t``."""
        return _scale(t, 1.0 / self.omega)

    def position(self, x: Any) -> np.ndarray | float:
        """Physical displacement along the line of action ``x_phys = H₁ x`` [m]."""
        return _scale(x, self.H1)

    def velocity(self, v: Any) -> np.ndarray | float:
        """Physical velocity along the line of action ``ẋ_phys = ω H₁ ẋ`` [m/s]."""
        return _scale(v, self.omega * self.H1)

    def reaction(self, R: Any) -> np.ndarray | float:
        """Physical contact force ``R = F R̃`` [N] (paper eq. 4, 5, 8)."""
        return _scale(R, self.force)

    @property
    def impulse_scale(self) -> float:
        """``m ω H₁`` [N·s]: the physical impulse of ``Ĩ = 1`` (paper eq. 11)."""
        return self.mass * self.omega * self.H1

    def impulse(self, impulse: Any) -> np.ndarray | float:
        """Physical impulse along the line of action ``I = Ĩ m ω H₁`` [N·s] (paper eq. 11)."""
        return _scale(impulse, self.impulse_scale)

    def angular_impulse(self, impulse: Any) -> np.ndarray | float:
        """Angular impulse on the idle gear ``R_b I = R_b Ĩ m ω H₁`` [N·m·s]."""
        return _scale(impulse, self.radius * self.impulse_scale)

    def with_rpm(self, rpm: float) -> "PhysicalParams":
        """A copy at another engine speed (amplitudes of the declared kind held)."""
        return self.replace(rpm=rpm)


def _scale(values: Any, factor: float) -> np.ndarray | float:
    arr = np.asarray(values, dtype=np.float64) * factor
    return float(arr) if arr.ndim == 0 else arr


def example() -> PhysicalParams:
    """A small passenger-car idle gear at 1500 rpm, used in docs and tests.

    ``J = 2e-4 kg·m²``, ``R_b = 40 mm`` (``m = 0.125 kg``), ``C = 0.02 N·m`` (``F = 0.5 N``),
    backlash 160 µm, order 2 at 1500 rpm (``ω = 100π rad/s``, 50 Hz), ``θ₁ = 5e-4 rad``
    (``H₁ = 20 µm``), ``θ₂ = 1.25e-4 rad`` at 45°.  Hence ``Λ = 0.05 π² ≈ 0.4935``, ``j = 8``,
    ``h₂ = 0.25``, ``φ₂ = 45°``.
    """
    return PhysicalParams(inertia=2e-4, radius=0.04, drag_torque=0.02, backlash=160e-6, rpm=1500.0,
                          amplitudes=(5e-4, 1.25e-4), phases_deg=(0.0, 45.0), order=2.0)


__all__ = [
    "PhysicalParams", "lam_from_rpm", "j_from_rpm", "impulse_scale_from_rpm", "rpm_from_lam", "rpm_sweep", "omega_from_rpm",
    "rpm_from_omega", "rpm_from_sweep", "backlash_from_um", "backlash_from_angle", "example",
    "INERTIA_RANGE", "RADIUS_RANGE", "DRAG_TORQUE_RANGE", "BACKLASH_RANGE", "RPM_RANGE",
    "ORDER_RANGE", "THETA_RANGE", "ALPHA_RANGE", "SOLVE_FOR",
]
