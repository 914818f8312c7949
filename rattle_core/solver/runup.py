"""Run-up replay: one loose gear of a gearbox driven through a run-up, in physical time.

The measured shaft's speed ramps from ``rpm_from`` to ``rpm_to`` in ``duration_s``; its
orders ``θ_k``, ``φ_k`` follow the speed, interpolated smoothly between the order map's rpm
bins (a cubic spline in rpm, so a cubic in time on each stretch between bins); the driving tooth
moves by ``R_d · speed_ratio · Σ_k θ_k(t) cos(k ψ(t) − φ_k(t))`` about the mean rotation
``ψ(t)``, the integral of the mean speed.  The gear feels its drag at each instant's speed and
the mean rotation's acceleration.  The model, and why at constant speed it is the paper's,
are in docs/model.md, "A run-up in physical time".

The wall is built in the reference units of the start speed (``ω_ref``, ``H_ref = R_d ·
speed_ratio · θ₁`` there), cut into pieces of one forcing period (split again where the speed
crosses an rpm bin), and solved exactly by :func:`rattle_core.solver.replay.run_wall`.
"""
from __future__ import annotations

import dataclasses
import math
from typing import Any, Callable

import numpy as np
from scipy.interpolate import CubicSpline

from ..model.gearbox import Gearbox
from ..model.params import check_range
from .kernel import FLIGHT
from .angle_wall import FilteredAngle, spline_wall
from .replay import WallRun, run_wall
from .wall import PiecewiseWall, piecewise_wall

#: Largest number of forcing periods one replay may run (the wall is stored piece by piece).
RUNUP_PERIOD_BUDGET = 200_000
DURATION_RANGE_S = (0.0, 3600.0)      # open at 0
#: Knot spacing [rpm] of the interpolant when the orders are given as constants, not measured.
CONSTANT_KNOT_RPM = 25.0
DEFAULT_V_STICK = 1e-6
#: Largest number of samples (pieces) a measured-angle wall may hold (about 160 bytes each).
ANGLE_PIECE_BUDGET = 4_000_000

DragFn = Callable[[np.ndarray], Any]


@dataclasses.dataclass(frozen=True, eq=False)
class RunupWall:
    """A gear's measured wall over a run-up, with the scales back to physical units.

    Attributes
    ----------
    wall : PiecewiseWall
        Reference units: time ``ω_ref t``, positions over ``H_ref``.
    omega_ref, H_ref, mass : float
        ``ω_ref`` [rad/s] (the fundamental at ``rpm_from``), ``H_ref`` [m], ``m = J/R_b²`` [kg].
    j, r : float
        Backlash ``b / H_ref`` and restitution.
    """

    wall: PiecewiseWall
    omega_ref: float
    H_ref: float
    mass: float
    j: float
    r: float
    rpm_from: float
    rpm_to: float
    duration_s: float
    engine_order: float
    gear: str
    #: mean shaft speed [rpm] of physical time from the start, for a measured (not linear) run
    mean_rpm: Callable[[np.ndarray], np.ndarray] | None = None

    def seconds(self, t) -> np.ndarray:
        """Physical time [s] from the start of the run, of dimensionless times."""
        return np.asarray(t, dtype=np.float64) / self.omega_ref

    def rpm_at(self, t_s) -> np.ndarray:
        """Mean shaft speed [rpm] at physical times ``t_s``."""
        t_s = np.asarray(t_s, dtype=np.float64)
        if self.mean_rpm is not None:
            return np.asarray(self.mean_rpm(t_s), dtype=np.float64)
        return self.rpm_from + (self.rpm_to - self.rpm_from) * t_s / self.duration_s

    @property
    def impulse_scale(self) -> float:
        """N·s per dimensionless impulse: ``m ω_ref H_ref``."""
        return self.mass * self.omega_ref * self.H_ref


class ImpactRows:
    """A gear's impacts over a run (``gear``, ``impact_t``, ``impact_rpm``, ``impact_flank``,
    ``impact_impulse``), read as its onset and as a table: a replay's and a stored replay's."""

    @property
    def onset_rpm(self) -> float:
        """Speed of the first impact [rpm] (NaN when the gear never leaves the tooth)."""
        return float(self.impact_rpm[0]) if self.impact_rpm.size else math.nan

    def to_frame(self):
        """One row per impact: ``t_s, rpm, gear, flank, impulse_Ns`` (a DataFrame)."""
        import pandas as pd
        return pd.DataFrame({"t_s": self.impact_t, "rpm": self.impact_rpm,
                             "gear": np.full(self.impact_t.size, self.gear, dtype=object),
                             "flank": np.where(self.impact_flank > 0, "active", "reverse"),
                             "impulse_Ns": self.impact_impulse})


@dataclasses.dataclass(frozen=True, eq=False)
class RunupReplay(ImpactRows):
    """One gear over a run-up: every impact, and the gear's state at the end.

    Attributes
    ----------
    impact_t : ndarray
        Impact times [s] from the start of the run.
    impact_rpm : ndarray
        Mean shaft speed at each impact [rpm].
    impact_flank : ndarray of int8
        +1 active flank, −1 reverse flank.
    impact_impulse : ndarray
        Signed impulse along the line of action [N·s] (> 0 on the active flank).
    x_m, v_mps, mode : float, float, int
        The gear's state at the end, relative to the mean rotation along the line of action
        (position [m], velocity [m/s]) and 0 in flight or ±1 stuck on that flank.
    run : WallRun
        The same run in reference units.
    runup : RunupWall
        The wall and its scales.
    """

    impact_t: np.ndarray
    impact_rpm: np.ndarray
    impact_flank: np.ndarray
    impact_impulse: np.ndarray
    x_m: float
    v_mps: float
    mode: int
    run: WallRun
    runup: RunupWall

    @property
    def gear(self) -> str:
        return self.runup.gear



def _drag_torques(g: Any, drag: Any, rpm: np.ndarray) -> np.ndarray:
    """The gear's drag torque [N·m] at the speeds ``rpm``: its constant ``drag_torque_Nm``, or
    ``drag(rpm)``, which must be finite and > 0 throughout."""
    shape = np.shape(rpm)
    if drag is None:
        return np.full(shape, g.drag_torque_Nm)
    torque = np.asarray(drag(rpm), dtype=np.float64) * np.ones(shape)
    if not np.all(np.isfinite(torque)) or np.any(torque <= 0.0):
        raise ValueError(f"drag must give a finite torque > 0 N·m at every speed of the run; "
                         f"got {float(torque[~(np.isfinite(torque) & (torque > 0))][0])!r}")
    return torque


def _gear_index(gearbox: Gearbox, gear: int | str) -> int:
    names = [g.name for g in gearbox.gears]
    if isinstance(gear, str):
        if gear not in names:
            raise ValueError(f"gear = {gear!r} is not in the gearbox; its gears are "
                             f"{', '.join(repr(n) for n in names)}")
        return names.index(gear)
    if isinstance(gear, bool) or not isinstance(gear, (int, np.integer)) or \
            not 0 <= int(gear) < len(names):
        raise ValueError(f"gear = {gear!r} must be a gear name or an index in [0, {len(names) - 1}]")
    return int(gear)


def check_run(gearbox: Gearbox, rpm_from: float, rpm_to: float, duration_s: float) -> float:
    """Refuse a run outside the measured speeds or over the period budget; its forcing periods.

    A run of a linear ramp turns the fundamental ``engine_order · (rpm_from + rpm_to)/2 ·
    duration_s / 60`` times.
    """
    lo, hi = gearbox.excitation.rpm_range
    for name, value in (("rpm_from", rpm_from), ("rpm_to", rpm_to)):
        v = check_range(name, value, 0.0, 1e5, lo_open=True)
        if not lo - 1e-9 <= v <= hi + 1e-9:
            raise ValueError(f"{name} = {value!r} is outside the measurement's speed range "
                             f"[{lo:g}, {hi:g}] rpm")
    duration_s = check_range("duration_s", duration_s, *DURATION_RANGE_S, lo_open=True)
    periods = gearbox.excitation.engine_order * 0.5 * (rpm_from + rpm_to) / 60.0 * duration_s
    if periods > RUNUP_PERIOD_BUDGET:
        raise ValueError(f"the run turns the fundamental {periods:.6g} times; the period budget "
                         f"allows up to {RUNUP_PERIOD_BUDGET} (shorten duration_s or lower the speeds)")
    return periods


def _order_splines(gearbox: Gearbox, lo: float, hi: float):
    """Knots [rpm] and cubic splines in rpm of ``θ_n`` and of the unwrapped ``φ_n`` [rad] of the
    model's harmonics ``n = 1..K`` (engine orders ``engine_order · n``)."""
    exc = gearbox.excitation
    omap = exc.order_map
    if omap is not None:
        want = exc.engine_order * np.arange(1, exc.harmonics + 1)
        cols = [int(np.nonzero(np.isclose(omap.orders, o, rtol=0, atol=1e-9))[0][0]) for o in want]
        knots = np.asarray(omap.rpm, dtype=np.float64)
        theta = np.asarray(omap.amplitude_rad, dtype=np.float64)[:, cols]
        phase = np.unwrap(np.deg2rad(np.asarray(omap.phase_deg, dtype=np.float64)[:, cols]), axis=0)
    else:
        n = max(2, int(math.ceil((hi - lo) / CONSTANT_KNOT_RPM)) + 1)
        knots = np.linspace(lo, hi, n) if hi > lo else np.array([lo])
        theta, ph_deg = exc.shaft(knots)
        phase = np.unwrap(np.deg2rad(ph_deg), axis=0)
    if knots.size == 1:
        return knots, _Const(theta[0]), _Const(phase[0])
    return knots, CubicSpline(knots, theta, axis=0), CubicSpline(knots, phase, axis=0)


class _Const:
    """A spline of one knot: the same values at every speed."""

    def __init__(self, values: np.ndarray) -> None:
        self.values = np.asarray(values, dtype=np.float64)

    def __call__(self, x, nu: int = 0) -> np.ndarray:
        x = np.atleast_1d(np.asarray(x, dtype=np.float64))
        v = self.values if nu == 0 else np.zeros_like(self.values)
        return np.broadcast_to(v, x.shape + v.shape).copy()


def runup_wall(gearbox: Gearbox, gear: int | str, rpm_from: float, rpm_to: float,
               duration_s: float, drag: DragFn | None = None) -> RunupWall:
    """The measured wall of one gear over a linear run-up (or run-down), in reference units.

    Parameters
    ----------
    gearbox : Gearbox
    gear : int or str
        The gear, by index or name.
    rpm_from, rpm_to : float
        Mean shaft speed at the start and at the end [rpm], inside the measurement's range.
    duration_s : float
        Length of the run [s], in (0, 3600].
    drag : callable, optional
        ``drag(rpm) -> torque [N·m]`` at each shaft speed (vectorised); default the gear's own
        drag (:meth:`Gearbox.drag_Nm`: a constant, or a table or the oil model at each speed).  It is evaluated at each piece's ends and linear between.
    """
    if not isinstance(gearbox, Gearbox):
        raise TypeError(f"gearbox must be a Gearbox, got {type(gearbox).__name__}")
    gi = _gear_index(gearbox, gear)
    check_run(gearbox, rpm_from, rpm_to, duration_s)
    rpm_from, rpm_to, duration_s = float(rpm_from), float(rpm_to), float(duration_s)
    g = gearbox.gears[gi]
    if drag is None and g.drag_torque_Nm is None:
        # a drag that varies (a table, the oil model): the gear's own, at the box's oil temperature
        drag = lambda rpm: gearbox.drag_Nm(gi, rpm)  # noqa: E731
    exc = gearbox.excitation
    eo = float(exc.engine_order)
    lo, hi = min(rpm_from, rpm_to), max(rpm_from, rpm_to)
    knots, th_s, ph_s = _order_splines(gearbox, lo, hi)

    omega_ref = eo * 2.0 * math.pi * rpm_from / 60.0
    scale = g.drive_radius_m * g.speed_ratio
    # grouped as units.PhysicalParams groups them, so that a steady run is that model's numbers
    H_ref = g.drive_radius_m * (float(th_s(np.array([rpm_from]))[0, 0]) * g.speed_ratio)
    if not H_ref > 0.0:
        raise ValueError(f"gear {g.name!r}: the fundamental's amplitude at {rpm_from:g} rpm is "
                         f"{H_ref / scale:g} rad; the replay needs it > 0")
    mass = g.inertia_kgm2 / g.base_radius_m ** 2
    c = (rpm_to - rpm_from) / duration_s                 # rpm/s
    beta = c / omega_ref                                 # rpm per unit of dimensionless time
    kappa = beta / rpm_from
    tau_end = omega_ref * duration_s

    # piece boundaries: the fundamental's periods, ψ̃(τ) = τ + κτ²/2 = 2πp, and the bin knots
    psi_end = tau_end + 0.5 * kappa * tau_end ** 2
    n_per = int(math.floor(psi_end / (2.0 * math.pi)))
    two_pi_p = 2.0 * math.pi * np.arange(n_per + 1, dtype=np.float64)
    tau_p = 2.0 * two_pi_p / (1.0 + np.sqrt(1.0 + 2.0 * kappa * two_pi_p))
    tau_p = tau_p[tau_p < tau_end]
    inner = knots[(knots > lo) & (knots < hi)]
    tau_k = (inner - rpm_from) / beta if beta != 0.0 else np.empty(0)
    starts = np.union1d(tau_p, tau_k[(tau_k > 0.0) & (tau_k < tau_end)])
    # a knot a rounding away from a period's start (or the end) makes no piece of its own
    eps = 1e-12 * max(1.0, tau_end)
    keep = np.diff(np.append(starts, tau_end)) > eps
    keep[0] = True
    starts = starts[keep]
    length = np.diff(np.append(starts, tau_end))
    per = np.searchsorted(tau_p, starts, side="right") - 1
    t_per = tau_p[per]
    delta = starts - t_per

    # phase of the fundamental from its period's start: small numbers, exact at late times
    psi0 = delta * (1.0 + kappa * t_per) + 0.5 * kappa * delta ** 2
    psi1 = 1.0 + kappa * starts
    rpm_a = rpm_from * (1.0 + kappa * starts)
    rpm_mid = rpm_from * (1.0 + kappa * (starts + 0.5 * length))
    K = exc.harmonics
    n = np.arange(1, K + 1, dtype=np.float64)
    amp = np.zeros((starts.size, K, 4))
    phase = np.zeros((starts.size, K, 5))
    fact = (1.0, 1.0, 2.0, 6.0)
    for m in range(4):
        at = rpm_mid if m == 3 else rpm_a
        bm = beta ** m / fact[m]
        amp[:, :, m] = g.drive_radius_m * (th_s(at, m) * g.speed_ratio) / H_ref * bm
        phase[:, :, m] = -ph_s(at, m) * bm
    phase[:, :, 0] += n[None, :] * psi0[:, None]
    phase[:, :, 1] += n[None, :] * psi1[:, None]
    phase[:, :, 2] += n[None, :] * 0.5 * kappa
    # the constant term reduced: the phase is what matters, its size only costs digits
    phase[:, :, 0] = np.remainder(phase[:, :, 0] + math.pi, 2.0 * math.pi) - math.pi

    # flight deceleration: drag over inertia plus the mean rotation's acceleration
    rpm_b = rpm_from * (1.0 + kappa * np.append(starts, tau_end))
    torque = _drag_torques(g, drag, rpm_b)
    accel = scale * 2.0 * math.pi * c / 60.0                # R_d · ratio · dΩ/dt [m/s²]
    qn = 1.0 / (mass * H_ref * omega_ref ** 2 / (torque / g.base_radius_m + mass * accel))
    decel = np.empty((starts.size, 2))
    decel[:, 0] = qn[:-1]
    decel[:, 1] = (qn[1:] - qn[:-1]) / length
    if drag is None:
        decel[:, 1] = 0.0
    wall = piecewise_wall(starts, length, amp, phase, decel)
    return RunupWall(wall=wall, omega_ref=omega_ref, H_ref=H_ref, mass=mass,
                     j=g.backlash_um * 1e-6 / H_ref, r=g.restitution, rpm_from=rpm_from,
                     rpm_to=rpm_to, duration_s=duration_s, engine_order=eo, gear=g.name)


def measured_window(angle: FilteredAngle, rpm_from: float, rpm_to: float) -> tuple[float, float]:
    """The stretch ``(start_s, end_s)`` of a measurement a run from ``rpm_from`` to ``rpm_to``
    replays: from the first sample, clear of the filters' edges, at which the mean speed has
    reached ``rpm_from`` to the first sample after it at which it has reached ``rpm_to``.

    A speed the usable stretch's mean speed never reaches is refused with that stretch's range.
    """
    lo_s, hi_s = angle.usable_s
    t = angle.time_s
    inside = (t >= lo_s) & (t <= hi_s)
    if lo_s >= hi_s or np.count_nonzero(inside) < 2:
        raise ValueError(f"the measurement lasts {t[-1] - t[0]:.6g} s; the filters' edges take "
                         f"{lo_s - t[0]:.6g} s at either end and leave nothing to replay")
    ts = t[inside]
    rpm = angle.mean_rpm(ts)
    lo, hi = float(np.min(rpm)), float(np.max(rpm))
    for name, value in (("rpm_from", rpm_from), ("rpm_to", rpm_to)):
        v = check_range(name, value, 0.0, 1e5, lo_open=True)
        if not lo <= v <= hi:
            raise ValueError(f"{name} = {value!r} is outside the measurement's speed range "
                             f"[{lo:g}, {hi:g}] rpm (its mean speed, clear of the filters' edges)")

    def first(after: int, target: float) -> int | None:
        rel = rpm[after:] - target
        sign0 = np.sign(rel[0])
        if sign0 == 0.0:
            return after
        hit = np.nonzero((rel == 0.0) | (np.sign(rel) != sign0))[0]
        return after + int(hit[0]) if hit.size else None

    a = first(0, float(rpm_from))
    b = first(a, float(rpm_to))
    if b is None:
        # a run-down asked of a run-up (or the reverse): the second speed comes before the first
        raise ValueError(f"rpm_to = {rpm_to!r} is not reached after rpm_from = {rpm_from!r} on "
                         f"the measurement, whose mean speed runs from {rpm[0]:g} to "
                         f"{rpm[-1]:g} rpm; a run follows the measurement's own direction")
    if b <= a:
        raise ValueError(f"rpm_from = {rpm_from!r} and rpm_to = {rpm_to!r} are met at the same "
                         "sample of the measurement; a run needs two different speeds it passes "
                         "through one after the other")
    return float(ts[a]), float(ts[b])


def angle_runup_wall(gearbox: Gearbox, gear: int | str, angle: FilteredAngle, start_s: float,
                     end_s: float, drag: DragFn | None = None) -> RunupWall:
    """The wall of one gear driven by the measured angle itself, over ``[start_s, end_s]`` of
    the measurement (:mod:`rattle_core.solver.angle_wall`), in reference units.

    The tooth moves by ``R_d · speed_ratio · Δθ(t)``, ``Δθ`` the filtered fluctuation; the gear
    feels its drag at the mean speed and the mean rotation's acceleration ``ψ̄''``, both taken
    at the samples and linear between.  The run starts and ends at the samples nearest
    ``start_s`` and ``end_s``, which must lie clear of the filters' edges
    (:attr:`FilteredAngle.usable_s`).  The reference units are those of :func:`runup_wall` at
    the mean speed of the start.
    """
    if not isinstance(gearbox, Gearbox):
        raise TypeError(f"gearbox must be a Gearbox, got {type(gearbox).__name__}")
    if not isinstance(angle, FilteredAngle):
        raise TypeError(f"angle must be a FilteredAngle, got {type(angle).__name__}")
    gi = _gear_index(gearbox, gear)
    lo_s, hi_s = angle.usable_s
    start_s = check_range("start_s", start_s, lo_s, hi_s)
    end_s = check_range("end_s", end_s, start_s, hi_s, lo_open=True)
    t = angle.time_s
    ia = int(np.argmin(np.abs(t - start_s)))
    ib = int(np.argmin(np.abs(t - end_s)))
    if ib <= ia:
        raise ValueError(f"end_s = {end_s!r} is less than one sample after start_s = {start_s!r}")
    if ib - ia > ANGLE_PIECE_BUDGET:
        raise ValueError(f"the run holds {ib - ia} samples; a measured-angle wall allows up to "
                         f"{ANGLE_PIECE_BUDGET} (shorten the run)")
    g = gearbox.gears[gi]
    exc = gearbox.excitation
    eo = float(exc.engine_order)
    ts = t[ia:ib + 1]
    rpm = angle.mean_rpm(ts)
    rpm_a = float(rpm[0])
    turns = eo * float(np.sum(0.5 * (rpm[1:] + rpm[:-1]) * np.diff(ts))) / 60.0
    if turns > RUNUP_PERIOD_BUDGET:
        raise ValueError(f"the run turns the fundamental {turns:.6g} times; the period budget "
                         f"allows up to {RUNUP_PERIOD_BUDGET} (shorten the run)")
    if drag is None and g.drag_torque_Nm is None:
        drag = lambda r: gearbox.drag_Nm(gi, r)  # noqa: E731
    omega_ref = eo * 2.0 * math.pi * rpm_a / 60.0
    scale = g.drive_radius_m * g.speed_ratio
    lo, hi = exc.rpm_range
    theta1 = float(exc.shaft(np.array([min(max(rpm_a, lo), hi)]))[0][0, 0]) \
        if lo <= rpm_a <= hi else math.nan
    H_ref = g.drive_radius_m * (theta1 * g.speed_ratio)
    if not H_ref > 0.0:
        # no fundamental to measure by: the fluctuation's own size over the run
        H_ref = scale * math.sqrt(2.0) * float(np.std(angle.fluctuation_rad[ia:ib + 1]))
    if not H_ref > 0.0:
        raise ValueError(f"gear {g.name!r}: the measured angle does not fluctuate over the run")
    mass = g.inertia_kgm2 / g.base_radius_m ** 2
    tau = omega_ref * (t - t[ia])
    length = np.diff(tau[ia:ib + 1])
    torque = _drag_torques(g, drag, rpm)
    accel = scale * angle.mean_speed(ts, 1)               # R_d · ratio · ψ̄'' [m/s²]
    qn = (torque / g.base_radius_m + mass * accel) / (mass * H_ref * omega_ref ** 2)
    decel = np.empty((length.size, 2))
    decel[:, 0] = qn[:-1]
    decel[:, 1] = (qn[1:] - qn[:-1]) / length
    wall = spline_wall(tau, angle.fluctuation_rad * (scale / H_ref), ia, ib, decel)
    t_a = float(t[ia])
    duration_s = float(t[ib] - t_a)
    return RunupWall(wall=wall, omega_ref=omega_ref, H_ref=H_ref, mass=mass,
                     j=g.backlash_um * 1e-6 / H_ref, r=g.restitution, rpm_from=rpm_a,
                     rpm_to=float(rpm[-1]), duration_s=duration_s, engine_order=eo, gear=g.name,
                     mean_rpm=lambda s: angle.mean_rpm(t_a + np.asarray(s, dtype=np.float64)))


def replay_angle(gearbox: Gearbox, gear: int | str, angle: FilteredAngle, start_s: float,
                 end_s: float, *, drag: DragFn | None = None, start: str = "active",
                 v_stick: float = DEFAULT_V_STICK, segments: bool = False) -> RunupReplay:
    """Replay one gear driven by the measured angle itself over ``[start_s, end_s]`` of the
    measurement (:func:`angle_runup_wall`); impact times are from the run's start, and
    ``start``, ``v_stick``, ``segments`` are those of :func:`replay`."""
    if start not in ("active", "reverse", "middle"):
        raise ValueError(f"start = {start!r} must be 'active', 'reverse' or 'middle'")
    return _replay_wall(angle_runup_wall(gearbox, gear, angle, start_s, end_s, drag), start,
                        v_stick, segments)


def replay(gearbox: Gearbox, gear: int | str, rpm_from: float, rpm_to: float,
           duration_s: float, *, drag: DragFn | None = None, start: str = "active",
           v_stick: float = DEFAULT_V_STICK, segments: bool = False) -> RunupReplay:
    """Replay one gear over a linear run-up (``rpm_to > rpm_from``) or run-down.

    Implements docs/model.md, "A run-up in physical time": the gear in flight under its drag
    and the mean rotation's acceleration, impacts with restitution, sticking while the reaction
    keeps its sign, against the measured wall built by :func:`runup_wall`, solved exactly.

    Parameters
    ----------
    gearbox, gear, rpm_from, rpm_to, duration_s, drag
        As in :func:`runup_wall`.
    start : {"active", "reverse", "middle"}
        The gear at the start: resting on the active or reverse flank (moving with the tooth),
        or in the middle of the backlash at the tooth's velocity.
    v_stick : float
        Dimensionless limit impact velocity (reference units), in [0, 10].
    segments : bool
        Keep the segments of the motion (for sampling it, :meth:`WallRun.sample`).

    Raises
    ------
    ValueError
        A speed outside the measurement's range (the message gives the range), a run over
        :data:`RUNUP_PERIOD_BUDGET` forcing periods (refused before it starts), a bad value.
    """
    if start not in ("active", "reverse", "middle"):
        raise ValueError(f"start = {start!r} must be 'active', 'reverse' or 'middle'")
    rw = runup_wall(gearbox, gear, rpm_from, rpm_to, duration_s, drag)
    return _replay_wall(rw, start, v_stick, segments)


def _replay_wall(rw: RunupWall, start: str, v_stick: float, segments: bool) -> RunupReplay:
    if start not in ("active", "reverse", "middle"):
        raise ValueError(f"start = {start!r} must be 'active', 'reverse' or 'middle'")
    w = rw.wall
    if start == "middle":
        y = w.values(w.t0[0])
        yd = w.values(w.t0[0], 1)
        run = run_wall(w, rw.r, rw.j, v_stick, x0=float(y[0]) + 0.5 * rw.j, v0=float(yd[0]),
                       mode=FLIGHT, segments=segments)
    else:
        run = run_wall(w, rw.r, rw.j, v_stick, mode=1 if start == "active" else -1,
                       segments=segments)
    t_s = rw.seconds(run.impact_t)
    return RunupReplay(impact_t=t_s, impact_rpm=rw.rpm_at(t_s), impact_flank=run.impact_flank,
                       impact_impulse=run.impact_impulse * rw.impulse_scale,
                       x_m=run.x * rw.H_ref, v_mps=run.v * rw.H_ref * rw.omega_ref,
                       mode=run.mode, run=run, runup=rw)

__all__ = ["RunupWall", "RunupReplay", "runup_wall", "replay", "check_run",
           "RUNUP_PERIOD_BUDGET", "measured_window", "angle_runup_wall", "replay_angle",
           "ANGLE_PIECE_BUDGET"]
