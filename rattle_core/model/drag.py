"""A loose gear's drag torque as a function of engine speed and oil temperature.

The drag torque ``C`` that holds a loose gear against its driving tooth sets the model's
``Λ`` and the contact boundary (``docs/model.md``, "Physical units").  In a gearbox it is not
one number: bush friction is nearly constant, churning and squeeze losses grow with speed and
with the oil's viscosity, and the viscosity falls by two orders of magnitude between a cold and
a hot box.  That is why cold idle and hot idle are the classic rattle cases.  A gear's drag is
one of three kinds; each gives ``C(rpm, T)`` [N·m] at the measured shaft's speed ``rpm`` and the
oil temperature ``T`` [°C]:

constant
    ``C`` (``drag_torque_Nm = 0.05``), whatever the speed and temperature.
table
    Measured values, interpolated linearly: over rpm (``rpm = [...]``, ``torque_Nm = [...]``),
    or over rpm and temperature (``temp_C = [...]`` and ``torque_Nm`` one row of speeds per
    temperature).  Speeds and temperatures strictly increase; outside the table is refused.
oil
    ``C = bush_Nm + churn_Nm · (ν(T) / ν(T_ref)) · (rpm / rpm_ref)``: a constant part for the
    bush, and a viscous part proportional to the kinematic viscosity and the speed (Petroff's
    law for a lubricated journal), given by its value ``churn_Nm`` at ``rpm_ref`` and
    ``T_ref`` (``at_rpm``, ``at_temp_C``).  The oil is the gearbox's (:class:`Oil`).

The oil's viscosity (:class:`Oil`)
    An ISO 3448 viscosity grade ``VG`` is the kinematic viscosity at 40 °C in mm²/s (cSt);
    ``nu100_cSt``, from the oil's data sheet, is the one at 100 °C.  Between and beyond them the
    Walther relation of ASTM D341 holds,

    ``log₁₀ log₁₀(ν + 0.7) = A − B log₁₀ T_K``,

    with ``A`` and ``B`` fixed by the two points (``T_K`` in kelvin).  It is exact at 40 and
    100 °C and is ASTM's standard extrapolation for mineral and synthetic gear oils down to
    about 2 cSt.

Ranges: temperatures −40 to 150 °C; grades those of ISO 3448; torques finite and positive.
A bad value raises ``ValueError`` naming the key, the value and the allowed range.
"""
from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from .params import check_range

#: Oil temperatures a drag model accepts [°C].
TEMP_RANGE = (-40.0, 150.0)
#: ISO 3448 viscosity grades: kinematic viscosity at 40 °C [mm²/s].
ISO_VG = (2, 3, 5, 7, 10, 15, 22, 32, 46, 68, 100, 150, 220, 320, 460, 680, 1000, 1500, 2200,
          3200)
#: Drag torques a table or model may give [N·m] (open at 0).
TORQUE_RANGE = (0.0, 1.0e4)
MAX_TABLE = 200
_OIL_KEYS = {"iso_vg", "nu100_cSt", "temp_C"}
_MODEL_KEYS = {"bush_Nm", "churn_Nm", "at_rpm", "at_temp_C"}
_TABLE_KEYS = {"rpm", "temp_C", "torque_Nm"}


def _temp(key: str, value: Any) -> float:
    return check_range(key, value, *TEMP_RANGE)


@dataclasses.dataclass(frozen=True)
class Oil:
    """The gearbox's oil: its ISO VG grade, ν at 100 °C, and the temperature a verdict runs at."""

    iso_vg: float
    nu100_cSt: float
    temp_C: float = 40.0

    def __post_init__(self) -> None:
        if isinstance(self.iso_vg, bool) or self.iso_vg not in ISO_VG:
            raise ValueError(f"iso_vg = {self.iso_vg!r} is not an ISO 3448 viscosity grade; "
                             f"the grades are {', '.join(map(str, ISO_VG))}")
        nu100 = check_range("nu100_cSt", self.nu100_cSt, 2.0, float(self.iso_vg), hi_open=True)
        object.__setattr__(self, "nu100_cSt", nu100)
        object.__setattr__(self, "temp_C", _temp("temp_C", self.temp_C))

    def _walther(self) -> tuple[float, float]:
        z40 = math.log10(math.log10(self.iso_vg + 0.7))
        z100 = math.log10(math.log10(self.nu100_cSt + 0.7))
        l40, l100 = math.log10(313.15), math.log10(373.15)
        b = (z40 - z100) / (l100 - l40)
        return z40 + b * l40, b

    def viscosity_cSt(self, temp_C: Any) -> np.ndarray:
        """Kinematic viscosity ν(T) [mm²/s] by ASTM D341 (module docstring)."""
        a, b = self._walther()
        t = np.asarray(temp_C, dtype=float)
        return 10.0 ** (10.0 ** (a - b * np.log10(t + 273.15))) - 0.7

    def canonical(self) -> dict:
        return dataclasses.asdict(self)

    @classmethod
    def from_table(cls, t: dict, where: str = "[oil]") -> "Oil":
        """An oil from a TOML table (keys ``iso_vg``, ``nu100_cSt``, ``temp_C``)."""
        if not isinstance(t, dict):
            raise ValueError(f"{where} must be a table with keys {sorted(_OIL_KEYS)}")
        unknown = set(t) - _OIL_KEYS
        if unknown:
            raise ValueError(f"{where}: unknown key {sorted(unknown)[0]!r}; "
                             f"the keys are {sorted(_OIL_KEYS)}")
        missing = {"iso_vg", "nu100_cSt"} - set(t)
        if missing:
            raise ValueError(f"{where}: {sorted(missing)[0]} is required (the oil's data sheet "
                             "gives its ISO VG grade and its viscosity at 100 °C)")
        try:
            return cls(**t)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"{where}: {exc}") from None


@dataclasses.dataclass(frozen=True)
class Drag:
    """A gear's drag torque ``C(rpm, T)`` [N·m]: constant, a table, or the oil model
    (module docstring).  Build it with :meth:`constant` or :meth:`from_value`."""

    kind: str
    value_Nm: float = math.nan
    rpm: tuple[float, ...] = ()
    temp_C: tuple[float, ...] = ()
    torque_Nm: tuple = ()
    bush_Nm: float = 0.0
    churn_Nm: float = 0.0
    at_rpm: float = math.nan
    at_temp_C: float = math.nan

    @classmethod
    def constant(cls, value_Nm: float) -> "Drag":
        return cls("constant", value_Nm=check_range("drag_torque_Nm", value_Nm, *TORQUE_RANGE,
                                                    lo_open=True))

    @property
    def needs_oil(self) -> bool:
        """Whether the torque depends on the oil's temperature."""
        return self.kind == "oil" or (self.kind == "table" and bool(self.temp_C))

    def torque(self, rpm: Any, temp_C: float | None = None, oil: Oil | None = None) -> np.ndarray:
        """``C`` [N·m] at each speed ``rpm`` and the oil temperature ``temp_C`` [°C]."""
        r = np.atleast_1d(np.asarray(rpm, dtype=float))
        if self.kind == "constant":
            return np.full(r.shape, self.value_Nm)
        if self.needs_oil and temp_C is None:
            raise ValueError("this drag depends on the oil temperature: give temp_C "
                             f"in [{TEMP_RANGE[0]:g}, {TEMP_RANGE[1]:g}] °C")
        if temp_C is not None:
            temp_C = _temp("oil temperature", temp_C)
        if self.kind == "oil":
            if oil is None:
                raise ValueError("a drag with bush_Nm and churn_Nm needs the gearbox's [oil]")
            ratio = oil.viscosity_cSt(temp_C) / oil.viscosity_cSt(self.at_temp_C)
            return self.bush_Nm + self.churn_Nm * ratio * r / self.at_rpm
        lo, hi = self.rpm[0], self.rpm[-1]
        if np.any(r < lo - 1e-9) or np.any(r > hi + 1e-9):
            raise ValueError(f"the drag table covers {lo:g} to {hi:g} rpm; "
                             f"{r[(r < lo) | (r > hi)][0]:g} rpm is outside it")
        table = np.asarray(self.torque_Nm, dtype=float)
        if not self.temp_C:
            return np.interp(r, self.rpm, table)
        temps = np.asarray(self.temp_C)
        if not temps[0] - 1e-9 <= temp_C <= temps[-1] + 1e-9:
            raise ValueError(f"the drag table covers {temps[0]:g} to {temps[-1]:g} °C; "
                             f"{temp_C:g} °C is outside it")
        rows = np.array([np.interp(r, self.rpm, row) for row in table])
        k = int(np.clip(np.searchsorted(temps, temp_C) - 1, 0, temps.size - 2))
        w = (temp_C - temps[k]) / (temps[k + 1] - temps[k])
        return (1 - w) * rows[k] + w * rows[k + 1]

    def canonical(self) -> dict:
        return {k: v for k, v in dataclasses.asdict(self).items()
                if not (isinstance(v, float) and math.isnan(v))}

    @classmethod
    def from_value(cls, value: Any, where: str) -> "Drag":
        """A drag from a gear's TOML ``drag`` value: a number, a table of values, or the oil
        model's keys (module docstring).  ``where`` names the gear in messages."""
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            try:
                return cls.constant(value)
            except ValueError as exc:
                raise ValueError(f"{where}: {exc}") from None
        if not isinstance(value, dict):
            raise ValueError(f"{where}: drag must be a number [N·m] or a table; got {value!r}")
        keys = set(value)
        try:
            if keys <= _MODEL_KEYS:
                return cls._model(value)
            if keys <= _TABLE_KEYS:
                return cls._table(value)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"{where}: drag: {exc}") from None
        raise ValueError(f"{where}: drag has keys {sorted(keys)}; give either "
                         f"{sorted(_TABLE_KEYS)} (a table) or {sorted(_MODEL_KEYS)} (the oil model)")

    @classmethod
    def _model(cls, t: dict) -> "Drag":
        missing = _MODEL_KEYS - set(t)
        if missing:
            raise ValueError(f"{sorted(missing)[0]} is required with the oil model")
        bush = check_range("bush_Nm", t["bush_Nm"], *TORQUE_RANGE)
        churn = check_range("churn_Nm", t["churn_Nm"], *TORQUE_RANGE)
        if bush + churn <= 0:
            raise ValueError("bush_Nm + churn_Nm must be positive: a gear without drag has no Λ")
        return cls("oil", bush_Nm=bush, churn_Nm=churn,
                   at_rpm=check_range("at_rpm", t["at_rpm"], 0.0, 1e5, lo_open=True),
                   at_temp_C=_temp("at_temp_C", t["at_temp_C"]))

    @classmethod
    def _table(cls, t: dict) -> "Drag":
        if "rpm" not in t or "torque_Nm" not in t:
            raise ValueError("a drag table needs rpm and torque_Nm")
        rpm = _axis("rpm", t["rpm"], 0.0, 1e5)
        temps = _axis("temp_C", t["temp_C"], *TEMP_RANGE) if "temp_C" in t else ()
        try:
            torque = np.asarray(t["torque_Nm"], dtype=float)
        except (TypeError, ValueError):
            raise ValueError("torque_Nm must hold numbers only") from None
        shape = (len(temps), len(rpm)) if temps else (len(rpm),)
        if torque.shape != shape:
            raise ValueError(f"torque_Nm has shape {torque.shape}; expected {shape} "
                             "(one value per rpm" + (", one row per temp_C)" if temps else ")"))
        if not np.all(np.isfinite(torque)) or np.any(torque <= 0) or np.any(torque > TORQUE_RANGE[1]):
            raise ValueError(f"torque_Nm values must lie in (0, {TORQUE_RANGE[1]:g}] N·m")
        return cls("table", rpm=rpm, temp_C=temps, torque_Nm=tuple(map(tuple, torque))
                   if temps else tuple(torque.tolist()))


def _axis(key: str, values: Any, lo: float, hi: float) -> tuple[float, ...]:
    if not isinstance(values, (list, tuple)) or not 2 <= len(values) <= MAX_TABLE:
        raise ValueError(f"{key} must be a list of 2 to {MAX_TABLE} numbers")
    out = tuple(check_range(f"{key}[{i}]", v, lo, hi) for i, v in enumerate(values))
    if any(b <= a for a, b in zip(out, out[1:])):
        raise ValueError(f"{key} must increase strictly; got {list(out)}")
    return out


__all__ = ["Drag", "Oil", "ISO_VG", "TEMP_RANGE"]
