"""A rattle target: limit curves over engine speed, in sone and/or dB(A).

In a ``GEARBOX.toml``::

    [target]
    rpm = [800, 1500, 3000]     # engine speeds of the limit's corners [rpm]
    sone = [8, 12, 20]          # the loudness limit (ISO 532-1 N5) at those speeds, and/or
    dba = [60, 66, 72]          # the A-weighted level limit (L_Aeq)

Between corners the limit is interpolated linearly; beyond the first and last corner it is
held (a limit is a promise over the whole speed range, not only between the points a team
wrote down).  A verdict compares each gear and the whole gearbox with it: ``margin`` is the
limit minus the value, and a point passes where the margin is not negative.
"""
from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from .params import check_range

#: What a target may limit: the verdict's column and its allowed range.
METRICS = {"sone": ("loudness_sone", (0.0, 1000.0)), "dba": ("spl_dba", (0.0, 200.0))}
MAX_POINTS = 200
_KEYS = {"rpm"} | set(METRICS)


@dataclasses.dataclass(frozen=True)
class Target:
    """Limit curves over rpm (module docstring).  ``limits`` maps ``"sone"``/``"dba"`` to values."""

    rpm: tuple[float, ...]
    limits: dict

    def __post_init__(self) -> None:
        rpm = _rpm(self.rpm)
        limits = {}
        if not self.limits:
            raise ValueError("a target needs sone and/or dba limits")
        for key, values in self.limits.items():
            if key not in METRICS:
                raise ValueError(f"target: unknown limit {key!r}; the limits are {sorted(METRICS)}")
            lo, hi = METRICS[key][1]
            if not isinstance(values, (list, tuple)) or len(values) != len(rpm):
                raise ValueError(f"target {key} must list one value per rpm ({len(rpm)} values)")
            limits[key] = tuple(check_range(f"target {key}[{i}]", v, lo, hi)
                                for i, v in enumerate(values))
        object.__setattr__(self, "rpm", rpm)
        object.__setattr__(self, "limits", limits)

    def limit(self, key: str, rpm: Any) -> np.ndarray:
        """The limit ``key`` at the speeds ``rpm``, held beyond the first and last corner."""
        return np.interp(np.asarray(rpm, dtype=float), self.rpm, self.limits[key])

    def canonical(self) -> dict:
        return {"rpm": list(self.rpm), **{k: list(v) for k, v in sorted(self.limits.items())}}

    @classmethod
    def from_table(cls, t: Any, where: str = "[target]") -> "Target":
        """A target from its TOML table (keys ``rpm``, ``sone``, ``dba``)."""
        if not isinstance(t, dict):
            raise ValueError(f"{where} must be a table with keys {sorted(_KEYS)}")
        unknown = set(t) - _KEYS
        if unknown:
            raise ValueError(f"{where}: unknown key {sorted(unknown)[0]!r}; the keys are {sorted(_KEYS)}")
        if "rpm" not in t:
            raise ValueError(f"{where}: rpm is required")
        try:
            return cls(t["rpm"], {k: t[k] for k in METRICS if k in t})
        except (TypeError, ValueError) as exc:
            raise ValueError(f"{where}: {exc}") from None

    @classmethod
    def parse(cls, text: str) -> "Target":
        """A target from the CLI's ``RPM:VALUE,RPM:VALUE,...`` with a unit suffix per curve:
        ``"1000:10,3000:20 sone"`` or ``"1000:60,3000:70 dba"``; curves separated by ``;``."""
        limits, rpm = {}, None
        for part in str(text).split(";"):
            body, _, unit = part.strip().rpartition(" ")
            unit = unit.strip().lower()
            if unit not in METRICS or not body:
                raise ValueError(f"target {part.strip()[:40]!r}: expected 'RPM:VALUE,... sone' or "
                                 "'RPM:VALUE,... dba'")
            pts = []
            for item in body.split(","):
                a, sep, b = item.partition(":")
                try:
                    pts.append((float(a), float(b)))
                except ValueError:
                    raise ValueError(f"target point {item.strip()[:40]!r} is not RPM:VALUE") from None
                if not sep:
                    raise ValueError(f"target point {item.strip()[:40]!r} is not RPM:VALUE")
            these = tuple(p[0] for p in pts)
            if rpm is not None and these != rpm:
                raise ValueError("target curves must share their rpm points")
            rpm = these
            limits[unit] = tuple(p[1] for p in pts)
        return cls(rpm, limits)


def _rpm(values: Any) -> tuple[float, ...]:
    if not isinstance(values, (list, tuple)) or not 1 <= len(values) <= MAX_POINTS:
        raise ValueError(f"target rpm must be a list of 1 to {MAX_POINTS} speeds")
    out = tuple(check_range(f"target rpm[{i}]", v, 0.0, 1e5, lo_open=True)
                for i, v in enumerate(values))
    if any(b <= a for a, b in zip(out, out[1:])):
        raise ValueError(f"target rpm must increase strictly; got {list(out)}")
    return out


def fail_ranges(rpm: np.ndarray, passed: np.ndarray) -> list[tuple[float, float]]:
    """The speed ranges (first and last failing grid speed) where ``passed`` is false."""
    out, start = [], None
    for r, ok in zip(np.asarray(rpm, dtype=float), np.asarray(passed, dtype=bool)):
        if not ok and start is None:
            start = r
        if not ok:
            end = r
        if ok and start is not None:
            out.append((start, end))
            start = None
    if start is not None:
        out.append((start, end))
    return out


def format_ranges(ranges: list[tuple[float, float]]) -> str:
    """``1400-1900; 2200-4500`` (rounded to whole rpm); empty for none."""
    def r(v):
        return f"{v:.0f}" if math.isfinite(v) else "?"
    return "; ".join(f"{r(a)}-{r(b)}" for a, b in ranges)


__all__ = ["Target", "fail_ranges", "format_ranges", "METRICS"]
