"""A measured speed ready for the order analysis: the file read (:mod:`.read`), the speed
taken from pulses if asked (:mod:`.pulses`), a time window cut (:mod:`.sampling`), and its
plausibility checked (:func:`rattle_core.measure.sniff.plausibility`).

:func:`measurement_options` checks the reading options where they come from a settings
file (a GEARBOX.toml's ``[excitation]``), so that every front end accepts the same keys.
"""
from __future__ import annotations

import dataclasses
import os
from typing import Any

import numpy as np

from .pulses import check_ppr, edges, max_order, speed_from_pulses
from .read import Detected, read_table
from .sampling import rate_text, time_window
from .sniff import SPEED_UNITS, plausibility

#: The reading options, as keyword arguments of :func:`read_measurement` and keys of a file.
OPTIONS = ("time_column", "speed_column", "speed_unit", "pulse_column", "pulses_per_rev",
           "from_s", "to_s")


@dataclasses.dataclass(frozen=True)
class Measurement:
    """Samples of the shaft speed, each with its file line, and how they were read."""

    time_s: np.ndarray
    speed_rpm: np.ndarray
    lines: np.ndarray
    detected: Detected
    #: the highest order the pulses resolve (None for a measured speed)
    max_order: float | None = None
    pulses_per_rev: int = 0


def measurement_options(table: dict, where: str = "") -> dict[str, Any]:
    """The reading options among a settings table's keys (:data:`OPTIONS`), checked; the rest
    is left to the caller.  ``where`` prefixes messages (``"[excitation]"``)."""
    out: dict[str, Any] = {}
    pre = f"{where} " if where else ""
    for key in OPTIONS:
        if key not in table:
            continue
        v = table[key]
        if key in ("time_column", "speed_column", "pulse_column"):
            if not isinstance(v, str) or not v.strip() or len(v) > 200:
                raise ValueError(f"{pre}{key} = {v!r:.80} must be a column name (text)")
        elif key == "speed_unit":
            if v not in SPEED_UNITS:
                raise ValueError(f"{pre}speed_unit = {v!r:.80} is not a known unit; the allowed "
                                 f"units are {', '.join(SPEED_UNITS)}")
        elif key == "pulses_per_rev":
            try:
                v = check_ppr(v)
            except ValueError as exc:
                raise ValueError(f"{pre}{exc}") from None
        else:
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v):
                raise ValueError(f"{pre}{key} = {v!r:.80} must be a time in seconds (a number)")
            v = float(v)
        out[key] = v
    if ("pulse_column" in out) != ("pulses_per_rev" in out):
        raise ValueError(f"{pre}pulse_column and pulses_per_rev go together")
    return out


def read_measurement(path: str | os.PathLike, label: str | None = None,
                     max_rows: int | None = None, *, time_column: str | None = None,
                     speed_column: str | None = None, speed_unit: str | None = None,
                     pulse_column: str | None = None, pulses_per_rev: int | None = None,
                     from_s: float | None = None, to_s: float | None = None) -> Measurement:
    """The shaft speed of a measurement file (module docstring); options as in
    :meth:`rattle_core.measure.orders.OrderMap.from_csv`."""
    if pulses_per_rev is not None:
        pulses_per_rev = check_ppr(pulses_per_rev)
    table = read_table(path, label, max_rows, time_column=time_column,
                       speed_column=speed_column, speed_unit=speed_unit,
                       pulse_column=pulse_column, pulses_per_rev=pulses_per_rev)
    det = table.detected
    name = det.source
    lines = table.lines
    notes = list(det.notes)
    top = None
    if pulse_column is not None:
        pulse = table.columns["pulse"]
        t = table.columns.get("time_s")
        keep = np.flatnonzero(np.isfinite(pulse))
        if np.all(np.diff(pulse[keep]) > 0) or t is None:
            times, plines = pulse[keep], lines[keep]
        else:  # a sampled tachometer signal beside a time column
            times, up = edges(t, pulse)
            plines = lines[up]
        keep, note = time_window(times, from_s, to_s, name)
        if note:
            notes.append(note)
        times, plines = times[keep], plines[keep]
        tt, w, lines = speed_from_pulses(times, pulses_per_rev,
                                         lambda i: f"{name}, line {int(plines[i])}", plines)
        top = max_order(pulses_per_rev)
        notes.append(f"{times.size} pulses → speed at the midpoints between pulses, a cubic "
                     f"spline through them at {rate_text(1 / float(np.median(np.diff(tt))))}; "
                     f"orders up to {top:g} resolved")
        rows = times.size
    else:
        tt, w = table.columns["time_s"], table.columns["speed_rpm"]
        keep, note = time_window(tt, from_s, to_s, name) if tt.size else (np.arange(0), "")
        if note:
            notes.append(note)
            tt, w, lines = tt[keep], w[keep], lines[keep]
        rows = tt.size
    warnings = []
    if pulse_column is None and w.size:
        warnings = plausibility(w / (1.0 if det.speed_unit == "rpm" else
                                     {"rad/s": 60 / (2 * np.pi), "Hz": 60.0}[det.speed_unit]),
                                det.speed_unit, det.speed_column)
    dt = np.diff(tt)
    step = float(np.median(dt)) if dt.size else 0.0
    det = dataclasses.replace(det, rows=int(rows), notes=tuple(notes), warnings=tuple(warnings),
                              duration_s=float(tt[-1] - tt[0]) if tt.size else 0.0,
                              sample_rate_hz=1.0 / step if step > 0 else 0.0)
    return Measurement(tt, w, lines, det, top, int(pulses_per_rev or 0))
