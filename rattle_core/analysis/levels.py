"""Sound pressure levels in dB(A): the A-weighted equivalent level and its fast-weighted maximum.

A-weighting (IEC 61672-1:2013, Annex E)
    The weighting is the standard's closed form,

    ``R_A(f) = f₄² f⁴ / ((f² + f₁²) √((f² + f₂²)(f² + f₃²)) (f² + f₄²))``,
    ``A(f) = 20 log₁₀ R_A(f) + A₁₀₀₀``,

    with the pole frequencies ``f₁ = 20.598997``, ``f₂ = 107.65265``, ``f₃ = 737.86223`` and
    ``f₄ = 12194.217`` Hz, and ``A₁₀₀₀ = −20 log₁₀ R_A(1000)`` (about 2.00 dB), so 1 kHz passes
    at 0 dB.  It is applied to the signal's discrete Fourier transform: the gain is exactly the
    standard's at every frequency up to Nyquist, where a bilinear-transformed filter would
    bend the top octave at 48 kHz.  The phase is left alone (zero phase), which changes no
    energy and, for the exponential averaging below, only the moment the peak is reached.
    The tests check the weighting against the standard's table (Table 3, nominal frequencies,
    to its 0.1 dB) and a 1 kHz tone at 94 dB.
``spl_dba``
    ``L_Aeq = 10 log₁₀( mean(p_A²) / p₀² )`` over the analysed sound, ``p₀ = 20 µPa``.
``spl_dba_max``
    ``L_AFmax``: the maximum of the fast time-weighted level, the exponential average of
    ``p_A²`` with ``τ = 0.125 s`` (IEC 61672-1, 3.7), a compiled ``nogil`` loop.  Its first
    :data:`~rattle_core.analysis.loudness.SKIP_S` seconds are left out, as for the loudness: the
    average starts from silence.
``fast_level_series``
    ``L_AF(t)``, the same fast time-weighted level as a time series, sampled every ``step_s``;
    of several incoherent sources (rows of a 2-D array) their A-weighted energies add before
    the average, so phases never cancel.
A silent signal is ``-inf`` dB; tables show it as empty.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np
from numba import njit

#: Reference sound pressure [Pa].
P_REF = 20e-6
#: Fast time weighting's time constant [s] (IEC 61672-1).
TAU_FAST = 0.125
_F1, _F2, _F3, _F4 = 20.598997, 107.65265, 737.86223, 12194.217


def _ra(f: np.ndarray) -> np.ndarray:
    f2 = np.asarray(f, dtype=float) ** 2
    return (_F4 ** 2 * f2 ** 2) / ((f2 + _F1 ** 2) * np.sqrt((f2 + _F2 ** 2) * (f2 + _F3 ** 2))
                                   * (f2 + _F4 ** 2))


_A1000 = -20.0 * math.log10(float(_ra(np.array([1000.0]))[0]))


def a_weighting_db(f) -> np.ndarray:
    """The A-weighting ``A(f)`` [dB] of IEC 61672-1 at frequencies ``f`` [Hz] (module docstring).

    ``−inf`` at 0 Hz.
    """
    f = np.asarray(f, dtype=float)
    with np.errstate(divide="ignore"):
        return 20.0 * np.log10(_ra(f)) + _A1000


def a_weighted(pressure_pa: np.ndarray, fs: float) -> np.ndarray:
    """The A-weighted pressure ``p_A(t)`` [Pa]: the signal's spectrum times ``10^(A(f)/20)``."""
    p = np.asarray(pressure_pa, dtype=float)
    spectrum = np.fft.rfft(p)
    gain = np.zeros(spectrum.size)
    f = np.fft.rfftfreq(p.size, 1.0 / fs)
    gain[1:] = 10.0 ** (a_weighting_db(f[1:]) / 20.0)
    return np.fft.irfft(spectrum * gain, n=p.size)


@njit(cache=True, nogil=True)
def _fast_max(p2, alpha, skip):
    # exponential average of p² (a one-pole low-pass of time constant τ): alpha = 1 − e^(−1/(fs τ))
    avg = 0.0
    peak = 0.0
    for n in range(p2.size):
        avg += alpha * (p2[n] - avg)
        if n >= skip and avg > peak:
            peak = avg
    return peak


@njit(cache=True, nogil=True)
def _fast_series(p2, alpha, every):
    # the same one-pole average as _fast_max, kept at every ``every``-th sample
    out = np.empty((p2.size + every - 1) // every)
    avg = 0.0
    for n in range(p2.size):
        avg += alpha * (p2[n] - avg)
        if n % every == 0:
            out[n // every] = avg
    return out


def _db(mean_square: float) -> float:
    return 10.0 * math.log10(mean_square / P_REF ** 2) if mean_square > 0 else -math.inf


@dataclasses.dataclass(frozen=True)
class Level:
    """A sound's A-weighted levels (module docstring: definitions).

    Attributes
    ----------
    spl_dba : float
        ``L_Aeq`` [dB(A)] over the whole signal.
    spl_dba_max : float
        ``L_AFmax`` [dB(A)], fast time weighting.
    """

    spl_dba: float
    spl_dba_max: float


def level(pressure_pa: np.ndarray, fs: float, *, skip_s: float = 0.05) -> Level:
    """A-weighted equivalent and maximum fast-weighted level of a sound pressure [Pa] at ``fs``.

    Raises ``ValueError`` for an empty or non-finite signal, or ``fs`` ≤ 0.
    """
    p = np.asarray(pressure_pa, dtype=float)
    if p.ndim != 1 or p.size == 0:
        raise ValueError(f"pressure_pa must be a non-empty 1-D signal, got shape {p.shape}")
    if not np.all(np.isfinite(p)):
        raise ValueError("pressure_pa must be finite (it holds NaN or inf)")
    if not (isinstance(fs, (int, float)) and math.isfinite(fs) and fs > 0):
        raise ValueError(f"fs must be a positive sample rate [Hz], got {fs!r}")
    pa = a_weighted(p, fs)
    return level_of_power(pa * pa, fs, skip_s=skip_s)


def level_of_power(pa2: np.ndarray, fs: float, *, skip_s: float = 0.05) -> Level:
    """:func:`level` from the A-weighted power ``p_A²`` [Pa²] itself: the sum of incoherent
    sources' powers gives their levels together (energy for ``L_Aeq``, and the fast average of
    the summed power for ``L_AFmax``)."""
    alpha = -math.expm1(-1.0 / (fs * TAU_FAST))
    skip = min(int(round(skip_s * fs)), pa2.size - 1)
    return Level(_db(float(np.mean(pa2))), _db(_fast_max(pa2, alpha, skip)))


def fast_level_series(pressure_pa: np.ndarray, fs: float, *, step_s: float = 0.002
                      ) -> tuple[np.ndarray, np.ndarray]:
    """The fast time-weighted A level ``L_AF(t)`` [dB(A)] (τ = 125 ms) every ``step_s`` seconds.

    ``pressure_pa`` is one sound pressure [Pa] or several incoherent ones (rows of a 2-D array,
    equal lengths): their ``p_A²`` add before the exponential average.  Returns the times [s]
    (from 0, the first sample) and the levels; silence is ``-inf``.  Its maximum after the
    first ``skip_s`` is :func:`level`'s ``spl_dba_max``.
    """
    p = np.asarray(pressure_pa, dtype=float)
    if p.ndim == 1:
        p = p[None, :]
    if p.ndim != 2 or p.shape[1] == 0:
        raise ValueError(f"pressure_pa must be a non-empty 1-D signal or a 2-D array of signals, "
                         f"got shape {np.shape(pressure_pa)}")
    if not np.all(np.isfinite(p)):
        raise ValueError("pressure_pa must be finite (it holds NaN or inf)")
    if not (isinstance(fs, (int, float)) and math.isfinite(fs) and fs > 0):
        raise ValueError(f"fs must be a positive sample rate [Hz], got {fs!r}")
    if not (isinstance(step_s, (int, float)) and 0.0 < step_s <= 1.0):
        raise ValueError(f"step_s = {step_s!r} must be in (0, 1] s")
    p2 = np.zeros(p.shape[1])
    for row in p:
        if np.any(row):
            pa = a_weighted(row, fs)
            p2 += pa * pa
    every = max(1, int(round(step_s * fs)))
    ms = _fast_series(p2, -math.expm1(-1.0 / (fs * TAU_FAST)), every)
    with np.errstate(divide="ignore"):
        db = np.where(ms > 0, 10.0 * np.log10(np.maximum(ms, 1e-300) / P_REF ** 2), -np.inf)
    return np.arange(ms.size) * (every / fs), db


def energy_sum_db(levels_db) -> float:
    """The level of incoherent sources together: ``10 log₁₀ Σ 10^(L/10)`` (``−inf`` for none)."""
    levels = np.asarray(levels_db, dtype=float)
    levels = levels[np.isfinite(levels)]
    return 10.0 * math.log10(float(np.sum(10.0 ** (levels / 10.0)))) if levels.size else -math.inf


__all__ = ["Level", "level", "level_of_power", "a_weighting_db", "a_weighted", "energy_sum_db", "fast_level_series", "P_REF", "TAU_FAST"]
