"""A measurement file's layout guessed from its first lines, and its columns recognised.

Delimiter
    Of tab, ``;``, ``,`` and spaces (in that order of preference), the first that splits the
    header into two or more fields and the first data rows into as many.
Decimal mark
    A comma where the delimiter is not a comma and the data's fields read as ``12,5``.
Units row
    A line under the header whose fields are not numbers (``s;rpm``, ``[s];[1/min]``).
Columns
    A header ``name [unit]``, ``name (unit)``, ``name/unit`` or ``name_unit`` is split into a
    name and a unit (or a units row gives the unit).  Time: a name ``t``, ``time``, ``zeit``
    or ``timestamp``, or a unit ``s``/``ms``/``us``.  Speed: a unit ``rpm``, ``1/min``,
    ``rev/min``, ``r/min``, ``min^-1`` (rpm), ``rad/s`` (× 60/2π) or ``Hz`` (× 60), or a name
    ``speed``, ``n``, ``rpm``, ``omega``, ``f``, ``drehzahl`` (``omega`` without a unit is rad/s,
    ``f`` Hz, the others rpm).  Explicit ``time_column``, ``speed_column`` and ``speed_unit``
    override the guess.
"""
from __future__ import annotations

import csv
import dataclasses
import math
import re
from typing import Any

SPEED_UNITS = ("rpm", "rad/s", "Hz")
_TO_RPM = {"rpm": 1.0, "rad/s": 60.0 / (2.0 * math.pi), "Hz": 60.0}
_UNIT_WORDS = {
    "s": ("time", 1.0), "sec": ("time", 1.0), "ms": ("time", 1e-3), "us": ("time", 1e-6),
    "µs": ("time", 1e-6),
    "rpm": ("speed", "rpm"), "1/min": ("speed", "rpm"), "rev/min": ("speed", "rpm"),
    "r/min": ("speed", "rpm"), "min^-1": ("speed", "rpm"), "min-1": ("speed", "rpm"),
    "u/min": ("speed", "rpm"), "min⁻¹": ("speed", "rpm"),
    "rad/s": ("speed", "rad/s"), "rad_s": ("speed", "rad/s"), "rad/sec": ("speed", "rad/s"),
    "hz": ("speed", "Hz"), "1/s": ("speed", "Hz"), "rev/s": ("speed", "Hz"), "rps": ("speed", "Hz"),
}
_TIME_NAMES = {"t", "time", "zeit", "timestamp", "time_s", "seconds"}
#: speed names, with the unit meant when none is written
_SPEED_NAMES = {"speed": "rpm", "n": "rpm", "rpm": "rpm", "omega": "rad/s", "w": "rad/s",
                "f": "Hz", "freq": "Hz", "frequency": "Hz", "drehzahl": "rpm",
                "engine_speed": "rpm", "shaft_speed": "rpm", "speed_rpm": "rpm",
                "engine speed": "rpm", "shaft speed": "rpm", "n_mot": "rpm", "nmot": "rpm"}
#: a plausible mean speed in each unit (a shaft at 300 to 20 000 rpm)
_PLAUSIBLE = {"rpm": (300.0, 20_000.0), "rad/s": (31.0, 2100.0), "Hz": (5.0, 340.0)}
#: first data rows looked at to sniff the layout
SNIFF_ROWS = 20
_NUMBER = re.compile(r"^[+-]?(\d+([.,]\d*)?|[.,]\d+)([eE][+-]?\d+)?$")


@dataclasses.dataclass
class Layout:
    """How a file is laid out: header fields, delimiter, decimal mark, units row."""

    header: list[str]
    delimiter: str
    decimal: str
    units_row: bool
    units: list[str]
    header_line: int        # 0-based index of the header line
    first_data: int         # 0-based index of the first line after the header (and units)


@dataclasses.dataclass
class Columns:
    """Which fields are time, speed and pulses; the speed's unit and its factor to rpm."""

    time: int | None
    speed: int | None
    pulse: int | None
    unit: str
    to_rpm: float
    time_scale: float
    notes: list[str]


def split_fields(text: str, delimiter: str) -> list[str]:
    """A line's fields: by runs of spaces or tabs for ``" "``, else as CSV with quotes."""
    if delimiter == " ":
        return text.split()
    return next(csv.reader([text], delimiter=delimiter), [])


def _is_number(text: str) -> bool:
    t = text.strip().strip('"')
    return bool(_NUMBER.match(t)) or t.lower() in ("nan", "-nan", "+nan")


def sniff_layout(lines: Any, name: str) -> Layout:
    """The layout of a file's lines (:class:`rattle_core.measure.read._Lines`)."""
    first = []
    for i in range(min(lines.starts.size, SNIFF_ROWS + 1000)):
        text = lines.text(i)
        if text.strip() and not text.lstrip().startswith("#"):
            first.append((i, text))
            if len(first) > SNIFF_ROWS + 1:
                break
    if not first:
        raise ValueError(f"{name} holds no header line; it needs a header naming a time and a "
                         "speed column, e.g. time_s,speed_rpm")
    h, head = first[0]
    rows = [t for _, t in first[1:]]
    delim = None
    for d in ("\t", ";", ",", " "):
        n = len(split_fields(head, d))
        if n >= 2 and all(len(split_fields(r, d)) == n for r in rows[:SNIFF_ROWS]):
            delim = d
            break
    if delim is None and all(len(split_fields(r, ",")) == 1 for r in [head] + rows[:SNIFF_ROWS]):
        delim = ","  # one column (pulse times)
    if delim is None:  # the rows disagree: the most fields in the header wins, for the message
        delim = max(("\t", ";", ",", " "), key=lambda d: len(split_fields(head, d)))
        if len(split_fields(head, delim)) < 2:
            raise ValueError(f"{name}, line {h + 1}: a header of two or more columns separated "
                             f"by commas, semicolons, tabs or spaces; got {head[:80]!r}")
    header = [c.strip().strip('"').lstrip("\ufeff").strip() for c in split_fields(head, delim)]
    units_row = bool(rows) and not any(_is_number(f) for f in split_fields(rows[0], delim))
    units = [u.strip() for u in split_fields(rows[0], delim)] if units_row else []
    data = rows[1:] if units_row else rows
    fields = [f.strip().strip('"') for r in data[:SNIFF_ROWS] for f in split_fields(r, delim)]
    decimal = "."
    if delim != "," and any(re.match(r"^[+-]?\d*,\d+([eE][+-]?\d+)?$", f) for f in fields) and \
            not any(re.match(r"^[+-]?\d*\.\d+", f) for f in fields):
        decimal = ","
    first_data = (first[2][0] if len(first) > 2 else lines.starts.size) if units_row else h + 1
    return Layout(header, delim, decimal, units_row, units, h, first_data)


def split_unit(field: str) -> tuple[str, str]:
    """``(name, unit)`` of a header field: ``Speed [rpm]`` → ``("speed", "rpm")``."""
    f = field.strip().lower()
    m = re.match(r"^(.*?)\s*[\[(](.*?)[\])]\s*$", f)
    if m:
        return m.group(1).strip(), m.group(2).strip()
    for sep in ("/", " in "):
        if sep in f:
            left, right = f.split(sep, 1)
            if right.strip() in _UNIT_WORDS or f"1/{right.strip()}" in _UNIT_WORDS:
                return left.strip(), right.strip()
    for unit in sorted(_UNIT_WORDS, key=len, reverse=True):
        u = unit.replace("/", "_")
        if f.endswith("_" + u) and len(f) > len(u) + 1:
            return f[:-len(u) - 1], unit
    return f, ""


def _unit_of(unit: str) -> tuple[str, Any] | None:
    u = unit.strip().strip("[]()").strip().lower().replace(" ", "")
    return _UNIT_WORDS.get(u)


def find_columns(layout: Layout, name: str, *, time_column: str | None = None,
                 speed_column: str | None = None, speed_unit: str | None = None,
                 pulse_column: str | None = None, pulses_per_rev: int | None = None) -> Columns:
    """The time, speed and pulse columns of ``layout`` (module docstring), or ``ValueError``
    naming the file, the header line and the option that would choose them."""
    header = layout.header
    line = layout.header_line + 1
    found = ", ".join(repr(c) for c in header)[:200]

    def named(option: str, value: str) -> int:
        want = value.strip().lower()
        for j, c in enumerate(header):
            if c.strip().lower() == want:
                return j
        raise ValueError(f"{name}, line {line}: {option} = {value!r} is not a column of the "
                         f"header; its columns are {found}")
    if speed_unit is not None and speed_unit not in SPEED_UNITS:
        raise ValueError(f"speed_unit = {speed_unit!r} is not a known unit; the allowed units are "
                         f"{', '.join(SPEED_UNITS)}")
    parsed = []
    for j, c in enumerate(header):
        base, unit = split_unit(c)
        if not unit and layout.units_row and j < len(layout.units):
            unit = layout.units[j]
        parsed.append((base, _unit_of(unit) if unit else None))
    notes = []
    if layout.units_row:
        notes.append(f"line {layout.header_line + 2}: read as units "
                     f"({', '.join(layout.units)[:80]})")
    # time
    if time_column is not None:
        t = named("time_column", time_column)
    else:
        t = next((j for j, (b, u) in enumerate(parsed) if b in _TIME_NAMES
                  and (u is None or u[0] == "time")), None)
        if t is None:
            t = next((j for j, (b, u) in enumerate(parsed) if u and u[0] == "time"), None)
    time_scale = 1.0
    if t is not None and parsed[t][1] and parsed[t][1][0] == "time":
        time_scale = float(parsed[t][1][1])
    pulse = None
    if pulse_column is not None:
        pulse = named("pulse_column", pulse_column)
        if pulses_per_rev is None:
            raise ValueError(f"{name}: pulse_column = {pulse_column!r} needs pulses_per_rev, "
                             "the pulses per revolution of the shaft")
        return Columns(t, None, pulse, "rpm", 1.0, time_scale, notes)
    if t is None:
        raise ValueError(f"{name}, line {line}: no time column recognised among {found}; "
                         "expected a name like time_s, Time [s] or t (s) — name it with "
                         "time_column (--time-column)")
    # speed
    if speed_column is not None:
        s = named("speed_column", speed_column)
    else:
        s = next((j for j, (b, u) in enumerate(parsed) if j != t and u and u[0] == "speed"), None)
        if s is None:
            s = next((j for j, (b, u) in enumerate(parsed) if j != t and b in _SPEED_NAMES), None)
    if s is None:
        raise ValueError(f"{name}, line {line}: no speed column recognised among {found}; "
                         "expected a name like speed_rpm, Speed [rpm], omega [rad/s] or f [Hz] "
                         "— name it with speed_column (--speed-column) and its unit with "
                         "speed_unit (--speed-unit)")
    base, u = parsed[s]
    if speed_unit is not None:
        unit = speed_unit
    elif u and u[0] == "speed":
        unit = u[1]
    elif base in _SPEED_NAMES:
        unit = _SPEED_NAMES[base]
        if unit == "rpm" and base != "rpm" and not base.endswith("rpm"):
            notes.append(f"column {header[s]!r} has no unit; read as rpm (speed_unit sets it)")
    else:
        unit = "rpm"
        notes.append(f"column {header[s]!r} has no unit; read as rpm (speed_unit sets it)")
    return Columns(t, s, None, unit, _TO_RPM[unit], time_scale, notes)


def plausibility(speed: Any, unit: str, column: str) -> list[str]:
    """Warnings where a speed column's values do not fit its unit (a column of rad/s under a
    ``speed_rpm`` header has a mean near 44 where rpm would be near 420)."""
    import numpy as np
    v = np.asarray(speed, dtype=np.float64)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return []
    mean = float(np.mean(v))
    lo, hi = _PLAUSIBLE[unit]
    if lo <= mean <= hi:
        return []
    fits = [u for u, (a, b) in _PLAUSIBLE.items() if u != unit and a <= mean <= b]
    rpm_if = {u: mean * _TO_RPM[u] for u in fits}
    guess = "; ".join(f"as {u} it would be {rpm_if[u]:.0f} rpm" for u in fits)
    return [f"column {column!r} has a mean of {mean:.4g} {unit}, unusual for a shaft "
            f"({lo:g} to {hi:g} {unit})" + (f"; {guess} — set speed_unit if so" if guess else "")]
