"""Instantaneous shaft speed from tachometer pulses.

Method
    ``N`` pulses per revolution at times ``p_i``: between two pulses the shaft turns
    ``1/N`` revolution, so its mean speed over the interval is ``60 / (N (p_{i+1} − p_i))``
    rpm, assigned to the interval's midpoint ``(p_i + p_{i+1}) / 2``.  These speeds are
    interpolated by a cubic spline onto a uniform grid of :data:`SAMPLES_PER_PULSE` samples
    per median pulse interval, which the order analysis reads like a measured speed.
Resolution
    The speed is known ``N`` times per revolution, an average over ``1/N`` revolution each:
    an order ``k`` is seen through the average, ``sinc(k/N) = sin(πk/N)/(πk/N)`` times its
    amplitude (:func:`averaging_gain`, divided out by the analysis), and only orders up to
    :func:`max_order` ``= N /`` :data:`PULSES_PER_CYCLE` are resolved; higher ones are refused.
Pulse columns
    A column of pulse times [s] (increasing; blank in rows without a pulse), or a sampled
    tachometer signal beside a time column, whose rising crossings of its mid level
    (linearly interpolated) are the pulses.
Refusals
    Fewer than 8 pulses, times that do not increase, and a missing pulse (an interval over
    :data:`GAP_FACTOR` times the one before) raise ``ValueError`` naming the line.
"""
from __future__ import annotations

import math
from typing import Callable

import numpy as np

#: Pulses needed per cycle of the highest order resolved.
PULSES_PER_CYCLE = 4
#: Samples of the interpolated speed per median pulse interval.
SAMPLES_PER_PULSE = 8
#: An interval over this many times the one before is a missing pulse.
GAP_FACTOR = 1.5
PPR_RANGE = (1, 10_000)


def check_ppr(pulses_per_rev) -> int:
    """Pulses per revolution, a whole number in :data:`PPR_RANGE`."""
    if isinstance(pulses_per_rev, bool) or not isinstance(pulses_per_rev, (int, float, np.integer,
                                                                           np.floating)) or \
            pulses_per_rev != int(pulses_per_rev) or \
            not PPR_RANGE[0] <= pulses_per_rev <= PPR_RANGE[1]:
        raise ValueError(f"pulses_per_rev = {pulses_per_rev!r} must be a whole number in "
                         f"[{PPR_RANGE[0]}, {PPR_RANGE[1]}]")
    return int(pulses_per_rev)


def max_order(pulses_per_rev: int) -> float:
    """The highest engine order ``N`` pulses per revolution resolve: ``N / PULSES_PER_CYCLE``."""
    return pulses_per_rev / PULSES_PER_CYCLE


def averaging_gain(orders, pulses_per_rev: int) -> np.ndarray:
    """``sinc(k/N)``: the share of order ``k``'s amplitude left by averaging over a pulse."""
    x = np.asarray(orders, dtype=np.float64) / pulses_per_rev
    return np.sinc(x)


def edges(t: np.ndarray, signal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rising crossings of a sampled tachometer signal's mid level: ``(times, index before)``."""
    mid = 0.5 * (float(np.nanmin(signal)) + float(np.nanmax(signal)))
    up = np.flatnonzero((signal[:-1] < mid) & (signal[1:] >= mid))
    frac = (mid - signal[up]) / (signal[up + 1] - signal[up])
    return t[up] + frac * (t[up + 1] - t[up]), up


def speed_from_pulses(p: np.ndarray, pulses_per_rev: int, where: Callable[[int], str],
                      lines: np.ndarray | None = None
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """``(t, rpm, lines)``: the instantaneous speed on a uniform grid (module docstring);
    ``where(i)`` names pulse ``i`` in messages."""
    from scipy.interpolate import CubicSpline
    n_ppr = check_ppr(pulses_per_rev)
    if p.size < 8:
        raise ValueError(f"{p.size} pulses; at least 8 are needed")
    d = np.diff(p)
    bad = np.flatnonzero(~(d > 0))
    if bad.size:
        i = int(bad[0]) + 1
        raise ValueError(f"{where(i)}: the pulse at {float(p[i])!r} s does not follow the one "
                         f"before ({float(p[i - 1])!r} s); pulse times must increase")
    bad = np.flatnonzero(d[1:] > GAP_FACTOR * d[:-1])
    if bad.size:
        i = int(bad[0]) + 2
        raise ValueError(f"{where(i)}: the pulse interval grows {d[bad[0] + 1] / d[bad[0]]:.2f} "
                         f"times at once (a missing pulse?); over {GAP_FACTOR:g} times is a gap; "
                         "analyse the part before or after it with from_s/to_s")
    mid = 0.5 * (p[1:] + p[:-1])
    rpm = 60.0 / (n_ppr * d)
    step = float(np.median(d)) / SAMPLES_PER_PULSE
    n = int(math.floor((mid[-1] - mid[0]) / step)) + 1
    grid = mid[0] + step * np.arange(n)
    speed = CubicSpline(mid, rpm)(grid)
    out_lines = None
    if lines is not None:
        out_lines = lines[np.clip(np.searchsorted(mid, grid, side="right"), 0, lines.size - 1)]
    return grid, speed, out_lines
