"""A measured speed's time base made fit for the order analysis: a time window cut out, gaps
refused, irregular steps resampled to a uniform grid.

Steps within :data:`JITTER_TOLERANCE` of the median step are regular.  A file with others
(timestamp jitter, a sampling that varies) is resampled at its median step by a cubic spline
through its samples, and the report says so ("resampled 12 034 irregular steps to 10 kHz").
A step over :data:`GAP_FACTOR` times the median is a gap: data are missing there, and no
interpolation can make them up, so the file is refused at that line.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

#: A time step over this many times the median step is a gap.
GAP_FACTOR = 1.5
#: A step differing from the median by more than this share of it is irregular.
JITTER_TOLERANCE = 0.01


def _group(n: int) -> str:
    return f"{n:,}".replace(",", " ")


def rate_text(hz: float) -> str:
    """``10 kHz``, ``2.5 kHz``, ``500 Hz``."""
    return f"{hz / 1000:.4g} kHz" if hz >= 1000 else f"{hz:.4g} Hz"


def time_window(t: np.ndarray, from_s: float | None, to_s: float | None, name: str
                ) -> tuple[np.ndarray, str]:
    """Indices of the samples with ``from_s ≤ t ≤ to_s`` and a note; ``ValueError`` naming the
    option when the window is empty or reversed."""
    if from_s is None and to_s is None:
        return np.arange(t.size), ""
    lo = -np.inf if from_s is None else float(from_s)
    hi = np.inf if to_s is None else float(to_s)
    for opt, v in (("from_s", from_s), ("to_s", to_s)):
        if v is not None and not np.isfinite(float(v)):
            raise ValueError(f"{opt} = {v!r} must be a finite time [s]")
    if lo >= hi:
        raise ValueError(f"from_s = {lo:g} must be below to_s = {hi:g}")
    keep = np.flatnonzero((t >= lo) & (t <= hi))
    if keep.size == 0:
        t0, t1 = (float(t[0]), float(t[-1])) if t.size else (0.0, 0.0)
        raise ValueError(f"{name}: no sample lies between from_s = {lo:g} and to_s = {hi:g} s; "
                         f"the file's time runs from {t0:g} to {t1:g} s")
    return keep, f"analysed {float(t[keep[0]]):g} to {float(t[keep[-1]]):g} s of " \
                 f"{float(t[0]):g} to {float(t[-1]):g} s"


def regularise(t: np.ndarray, w: np.ndarray, where: Callable[[int], str], lines: np.ndarray | None
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, str]:
    """``(t, w, lines, note)`` on a uniform grid (module docstring); ``t`` must increase.

    ``lines`` (each sample's file line) follow the samples: a grid sample gets the line of the
    sample at or before it."""
    dt = np.diff(t)
    step = float(np.median(dt))
    bad = np.flatnonzero(dt > GAP_FACTOR * step)
    if bad.size:
        i = int(bad[0]) + 1
        raise ValueError(f"{where(i)}: a gap of {dt[bad[0]]:.6g} s after time_s = {float(t[i - 1])!r} "
                         f"(the sampling step is {step:.6g} s; steps over {GAP_FACTOR:g} times it "
                         "are gaps); analyse the part before or after it with from_s/to_s")
    irregular = int(np.count_nonzero(np.abs(dt - step) > JITTER_TOLERANCE * step))
    if irregular == 0:
        return t, w, lines, ""
    from scipy.interpolate import CubicSpline
    n = int(np.floor((t[-1] - t[0]) / step + 1e-9)) + 1
    grid = t[0] + step * np.arange(n)
    grid[-1] = min(grid[-1], t[-1])
    w2 = CubicSpline(t, w)(grid)
    lines2 = None
    if lines is not None:
        lines2 = lines[np.clip(np.searchsorted(t, grid, side="right") - 1, 0, t.size - 1)]
    note = f"resampled {_group(irregular)} irregular steps to {rate_text(1.0 / step)}"
    return grid, w2, lines2, note
