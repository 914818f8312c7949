"""Engine speed: the fundamental frequency it sets, and sweeps over it as sweeps of Λ or j.

``ω = order × 2π × rpm / 60``.  With the driving gear's displacement amplitudes held,
``Λ = m H₁ ω² / F`` grows as ``rpm²`` and ``j`` stays; with its acceleration amplitudes held,
``H₁ = R_d α₁ / ω²``, so ``Λ`` stays and ``j = b / H₁`` grows as ``rpm²`` (the conventions are
:mod:`rattle_core.model.units`').  :func:`rpm_sweep` turns an engine-speed sweep into the
dimensionless sweep it is, and :func:`rpm_from_sweep` goes back.
"""
from __future__ import annotations

import math
from typing import Any, Protocol

import numpy as np

from ..checks import RPM_RANGE  # noqa: F401  (rev/min, open at 0)
from .params import check_range

ORDER_RANGE = (0.0, 100.0)           # excitation cycles per revolution, open at 0


class PhysicalGear(Protocol):
    """What these functions read of a gear in physical units.

    :class:`rattle_core.model.units.PhysicalParams` is one; units imports this module, so this
    module names the attributes it needs instead of importing it back.
    """

    excitation: str
    order: float
    rpm: float
    amplitudes: tuple[float, ...]
    backlash: float

    @property
    def mass(self) -> float: ...
    @property
    def force(self) -> float: ...
    @property
    def H1(self) -> float: ...
    @property
    def drive_radius(self) -> float: ...
    @property
    def lam(self) -> float: ...


def omega_from_rpm(rpm: Any, order: float = 2.0) -> np.ndarray | float:
    """Fundamental circular frequency ``ω = order × 2π × rpm / 60`` [rad/s].

    Parameters
    ----------
    rpm : float or array_like
        Engine speed [rev/min], each in (0, 1e5].
    order : float
        Engine order of the fundamental (excitation cycles per revolution), in (0, 100];
        2 for a four-cylinder four-stroke engine.
    """
    order = check_range("order", order, *ORDER_RANGE, lo_open=True)
    rpm_arr = _check_rpm_array(rpm)
    omega = order * 2.0 * math.pi * rpm_arr / 60.0
    return float(omega) if np.ndim(rpm) == 0 else omega


def rpm_from_omega(omega: Any, order: float = 2.0) -> np.ndarray | float:
    """Engine speed ``rpm = 60 ω / (2π × order)``, the inverse of :func:`omega_from_rpm`."""
    order = check_range("order", order, *ORDER_RANGE, lo_open=True)
    w = np.asarray(omega, dtype=np.float64)
    rpm = 60.0 * w / (2.0 * math.pi * order)
    return float(rpm) if np.ndim(omega) == 0 else rpm


def _check_rpm_array(rpm: Any) -> np.ndarray:
    try:
        arr = np.asarray(rpm, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"rpm must be a number or an array of numbers, got {rpm!r}") from None
    if arr.size == 0:
        raise ValueError("rpm must hold at least one engine speed, got an empty array")
    bad = ~np.isfinite(arr) | (arr <= RPM_RANGE[0]) | (arr > RPM_RANGE[1])
    if np.any(bad):
        v = arr[bad].flat[0]
        raise ValueError(f"rpm = {float(v)!r} is outside the allowed range "
                         f"({RPM_RANGE[0]:g}, {RPM_RANGE[1]:g}]")
    return arr


def lam_from_rpm(phys: PhysicalGear, rpm: Any) -> np.ndarray:
    """Λ at each engine speed, every other physical input of ``phys`` held.

    Displacement amplitudes held: ``Λ(rpm) = m R_d θ₁ ω(rpm)² / F``, which grows as ``rpm²``.
    Acceleration amplitudes held: ``Λ = m R_d α₁ / F`` at every speed (see :func:`rpm_sweep`).

    Parameters
    ----------
    phys : PhysicalParams
    rpm : array_like
        Engine speeds [rev/min], each in (0, 1e5].

    Returns
    -------
    ndarray
        Λ values, same shape as ``rpm``.
    """
    rpm_arr = _check_rpm_array(rpm)
    if phys.excitation == "acceleration":
        return np.full(rpm_arr.shape, phys.lam)
    omega = phys.order * 2.0 * math.pi * rpm_arr / 60.0
    return phys.mass * phys.H1 * omega**2 / phys.force


def j_from_rpm(phys: PhysicalGear, rpm: Any) -> np.ndarray:
    """Backlash ratio ``j = b / H₁`` at each engine speed, every other input of ``phys`` held.

    Constant with displacement amplitudes.  With acceleration amplitudes, ``H₁ = R_d α₁ / ω²``, so
    ``j = b ω² / (R_d α₁)``, which grows as ``rpm²``.
    """
    rpm_arr = _check_rpm_array(rpm)
    if phys.excitation == "displacement":
        return np.full(rpm_arr.shape, phys.backlash / phys.H1)
    omega = phys.order * 2.0 * math.pi * rpm_arr / 60.0
    return phys.backlash * omega**2 / (phys.drive_radius * phys.amplitudes[0])


def impulse_scale_from_rpm(phys: PhysicalGear, rpm: Any) -> np.ndarray:
    """Impulse scale ``m ω H₁`` [N·s] at each engine speed, other inputs of ``phys`` held.

    ``ω = order × 2π × rpm / 60``; ``H₁ = R_d θ₁`` (displacement amplitudes held) or
    ``H₁ = R_d α₁ / ω²`` (acceleration amplitudes held).
    """
    rpm_arr = _check_rpm_array(rpm)
    omega = phys.order * 2.0 * math.pi * rpm_arr / 60.0
    if phys.excitation == "displacement":
        H1 = np.full(rpm_arr.shape, phys.H1)
    else:
        H1 = phys.drive_radius * phys.amplitudes[0] / omega**2
    return phys.mass * omega * H1


def rpm_from_lam(phys: PhysicalGear, lam: Any) -> np.ndarray:
    """Engine speed giving each Λ, other inputs of ``phys`` held (displacement amplitudes only).

    Inverse of :func:`lam_from_rpm`: ``ω = sqrt(Λ F / (m H₁))``, ``rpm = 60 ω / (2π order)``.
    """
    if phys.excitation == "acceleration":
        raise ValueError("rpm_from_lam needs displacement amplitudes: with acceleration amplitudes "
                         "held, Λ does not depend on engine speed")
    lam_arr = np.asarray(lam, dtype=np.float64)
    if lam_arr.size == 0 or not np.all(np.isfinite(lam_arr)) or np.any(lam_arr <= 0):
        raise ValueError(f"lam values must be finite and > 0, got {lam!r}")
    omega = np.sqrt(lam_arr * phys.force / (phys.mass * phys.H1))
    return 60.0 * omega / (2.0 * math.pi * phys.order)


def rpm_sweep(phys: PhysicalGear, rpm: Any) -> tuple[str, np.ndarray]:
    """The dimensionless sweep equivalent to sweeping engine speed: ``(name, values)``.

    With displacement amplitudes held only Λ changes with speed, so the sweep is
    ``("lam", lam_from_rpm(phys, rpm))``; with acceleration amplitudes held only ``j`` changes,
    so it is ``("j", j_from_rpm(phys, rpm))``.  Pass the result to
    ``sweep(phys.to_dimensionless(), name, values)``.
    """
    if phys.excitation == "displacement":
        return "lam", lam_from_rpm(phys, rpm)
    return "j", j_from_rpm(phys, rpm)


def rpm_from_sweep(phys: PhysicalGear, name: str, values: Any) -> np.ndarray:
    """Inverse of :func:`rpm_sweep`: the engine speeds of a sweep of ``lam`` (displacement
    amplitudes held, :func:`rpm_from_lam`) or of ``j`` (acceleration amplitudes held,
    ``j ∝ rpm²``)."""
    vals = np.asarray(values, dtype=np.float64)
    if name == "lam":
        return rpm_from_lam(phys, vals) if vals.size else vals
    if name == "j" and phys.excitation == "acceleration":
        return phys.rpm * np.sqrt(vals / float(j_from_rpm(phys, phys.rpm)))
    raise ValueError(f"a sweep of {name!r} is not an engine-speed sweep of this gear "
                     f"({phys.excitation} amplitudes held): rpm_sweep gives "
                     f"{rpm_sweep(phys, phys.rpm)[0]!r}")
