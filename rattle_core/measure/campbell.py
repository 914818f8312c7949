"""Campbell data of a measured speed: the order spectrum of the shaft's angular fluctuation
against rpm, in the angle domain.

Method
    The speed is integrated to the shaft angle and resampled at :data:`SAMPLES_PER_REV`-fold
    powers of two per revolution (enough for the orders shown); blocks of
    :data:`BLOCK_REVS` revolutions, overlapping by half, lose their mean and linear trend, are
    Hann-windowed and Fourier transformed, so that the spectrum's bins are orders
    ``m / BLOCK_REVS``.  The speed's amplitude at order ``k`` is turned into the angle's,
    ``θ_k = |Ω_k| / (k Ω)``, and blocks are averaged (in power) per rpm bin.  The level is
    ``20 log10(θ_k / 1 rad)`` [dB re 1 rad].
"""
from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from .sampling import regularise

#: Revolutions per block: the order resolution is ``1 / BLOCK_REVS``.
BLOCK_REVS = 8
#: Orders shown at least, and at most.
MIN_SHOWN_ORDER, MAX_SHOWN_ORDER = 12.0, 64.0


@dataclasses.dataclass(frozen=True)
class CampbellData:
    """``level_db[i, j]``: the angle's amplitude at ``orders[j]`` in rpm bin ``rpm[i]``."""

    rpm: np.ndarray
    orders: np.ndarray
    level_db: np.ndarray
    analysed_orders: np.ndarray
    source: str = ""

    def dominant_order(self) -> float:
        """The order of the highest level, averaged in power over the rpm bins."""
        power = np.nanmean(10.0 ** (self.level_db / 10.0), axis=0)
        return float(self.orders[int(np.nanargmax(power))])


def campbell(meas: Any, analysed_orders: Any = (), rpm_step: float = 100.0,
             max_order: float | None = None) -> CampbellData:
    """The Campbell data of a :class:`~rattle_core.measure.measurement.Measurement` (module
    docstring); ``analysed_orders`` are kept to be marked."""
    from scipy.integrate import cumulative_simpson
    from scipy.interpolate import CubicSpline

    t, w, _, _ = regularise(np.asarray(meas.time_s, float), np.asarray(meas.speed_rpm, float),
                            lambda i: f"sample {i}", None)
    analysed = np.asarray(analysed_orders, dtype=np.float64)
    omega = w * (2 * math.pi / 60)
    angle = cumulative_simpson(omega, x=t, initial=0.0)
    revs = angle[-1] / (2 * math.pi)
    if revs < BLOCK_REVS:
        raise ValueError(f"the measurement covers {revs:.1f} revolutions; a Campbell diagram "
                         f"needs at least {BLOCK_REVS}")
    per_rev_time = t.size / revs  # the file's own samples per revolution
    top = max(MIN_SHOWN_ORDER, 2 * float(analysed.max()) if analysed.size else 0.0)
    top = min(top, MAX_SHOWN_ORDER, per_rev_time / 2.5) if max_order is None else max_order
    per_rev = 1 << max(3, math.ceil(math.log2(4 * top)))
    n = int(revs * per_rev)
    grid = np.arange(n) * (2 * math.pi / per_rev)
    speed = CubicSpline(angle, omega)(grid)
    size = BLOCK_REVS * per_rev
    hop = size // 2
    starts = np.arange(0, n - size + 1, hop)
    win = np.hanning(size)
    u = np.linspace(-1.0, 1.0, size)
    k = np.fft.rfftfreq(size, d=1.0 / per_rev)      # orders
    keep = (k > 0) & (k <= top)
    k = k[keep]
    rpm_blocks = np.empty(starts.size)
    amp = np.empty((starts.size, k.size))
    for b, s0 in enumerate(starts):
        x = speed[s0:s0 + size]
        mean = float(x.mean())
        slope = float(np.dot(x - mean, u) / np.dot(u, u))
        spec = np.fft.rfft((x - mean - slope * u) * win)[keep]
        rpm_blocks[b] = mean * 60 / (2 * math.pi)
        amp[b] = 2 * np.abs(spec) / win.sum() / (k * mean)
    bins = np.round(rpm_blocks / rpm_step).astype(np.int64)
    present = np.unique(bins)
    level = np.empty((present.size, k.size))
    rpm = np.empty(present.size)
    for i, b in enumerate(present):
        sel = bins == b
        rpm[i] = rpm_blocks[sel].mean()
        level[i] = 10 * np.log10(np.mean(amp[sel] ** 2, axis=0) + 1e-300)
    return CampbellData(rpm=rpm, orders=k, level_db=level, analysed_orders=analysed,
                        source=getattr(getattr(meas, "detected", None), "source", ""))
