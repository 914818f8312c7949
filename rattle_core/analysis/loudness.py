"""How loud a rattle is: loudness (ISO 532-1, Zwicker, time-varying) and sharpness (DIN 45692).

The computation is MOSQITO's (``mosqito.sq_metrics``, version 1.2.1): third-octave levels,
core loudness, the nonlinear temporal decay of hearing, specific loudness and temporal
weighting, then DIN 45692 sharpness from the specific loudness.  One step, the nonlinear decay,
is MOSQITO's loop (``_nl_loudness``) compiled here statement for statement: in MOSQITO it is a
Python loop of 48 000 steps per second of sound and costs 95 % of the time.  The test suite
checks the result against ``mosqito.sq_metrics.loudness_zwtv`` itself.

Single numbers
    ``loudness_sone`` is ``N5``, the loudness exceeded 5 % of the time (ISO 532-1's figure for
    time-varying sounds); ``sharpness_acum`` is the mean DIN 45692 sharpness over the frames
    with loudness.  The first :data:`SKIP_S` seconds are left out of both (the filters settle).
    A silent signal is 0 sone and 0 acum.
From impulses to sound pressure
    Loudness is not linear in level, so the sound needs an absolute level.  The rattle sound of
    :mod:`rattle_core.analysis.sound` rings the housing's modes with each impact's impulse in
    N·s; the sound pressure at the listener is that signal times a transfer ``T`` [Pa per N·s]:
    the peak pressure that a 1 N·s tooth impulse makes through a mode of gain 1.  The default
    :data:`~rattle_core.model.gearbox.DEFAULT_TRANSFER_PA_PER_NS` = 5 Pa/(N·s) puts a small
    car gearbox's rattle (impulses of 1 to 20 mN·s, some hundred a second) at 70 to 85 dB near
    the housing, 10 to 40 sone.  It is illustrative, not
    measured: give your own from a measured impulse response or a calibrated impact.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np
from numba import njit

from ..model.gearbox import DEFAULT_TRANSFER_PA_PER_NS

#: Sample rate ISO 532-1 asks for [Hz].
SAMPLE_RATE = 48_000
#: Settling time left out of the single numbers [s].
SKIP_S = 0.05
#: Field type of ISO 532-1 used throughout.
FIELD = "free"


@dataclasses.dataclass(frozen=True)
class Loudness:
    """Loudness and sharpness of one sound (module docstring: definitions).

    Attributes
    ----------
    loudness_sone : float
        ``N5`` [sone].
    sharpness_acum : float
        Mean DIN 45692 sharpness [acum] over the frames with loudness.
    time_s, loudness_t : ndarray
        The time-varying loudness ``N(t)`` [sone], every 2 ms.
    """

    loudness_sone: float
    sharpness_acum: float
    time_s: np.ndarray
    loudness_t: np.ndarray


@njit(cache=True, nogil=True)
def _decay(ui, uo, u2, b0, b1, b2, b3, b4, b5):
    """MOSQITO 1.2.1's ``_nl_loudness`` column loop, compiled: ``uo`` and ``u2`` in place.

    Column ``c`` reads column ``c − 1`` (column −1 is the last, as numpy's indexing does)."""
    rows, cols = ui.shape
    for c in range(cols):
        p = c - 1 if c > 0 else cols - 1
        for i in range(rows):
            uo_p = uo[i, p]
            u2_p = u2[i, p]
            x = ui[i, c]
            uo2 = uo_p * b2 - u2_p * b3
            if uo_p > u2_p and uo2 >= x:
                uo[i, c] = uo2
            uo2 = uo_p * b4
            if uo_p <= u2_p and uo2 >= x:
                uo[i, c] = uo2
            u2[i, c] = uo[i, c]
            u22 = uo_p * b0 - u2_p * b1
            if x < uo_p and uo_p > u2_p and u22 <= uo[i, c]:
                u2[i, c] = u22
            u2_2 = (u2_p - x) * b5 + x
            if x >= uo_p and not (abs(x - uo_p) < 1e-5 and uo[i, c] <= u2_p):
                u2[i, c] = u2_2


def _nl_loudness(core_loudness: np.ndarray) -> np.ndarray:
    """The nonlinear temporal decay of hearing (ISO 532-1), as MOSQITO 1.2.1 computes it."""
    sample_rate = 2000
    nl_iter = 24
    t_short, t_long, t_var = 0.005, 0.015, 0.075
    delta_t = 1 / (sample_rate * nl_iter)
    P = (t_var + t_long) / (t_var * t_short)
    Q = 1 / (t_short * t_var)
    lambda_1 = -P / 2 + math.sqrt(P * P / 4 - Q)
    lambda_2 = -P / 2 - math.sqrt(P * P / 4 - Q)
    den = t_var * (lambda_1 - lambda_2)
    e1 = math.exp(lambda_1 * delta_t)
    e2 = math.exp(lambda_2 * delta_t)
    B = [(e1 - e2) / den,
         ((t_var * lambda_2 + 1) * e1 - (t_var * lambda_1 + 1) * e2) / den,
         ((t_var * lambda_1 + 1) * e1 - (t_var * lambda_2 + 1) * e2) / den,
         (t_var * lambda_1 + 1) * (t_var * lambda_2 + 1) * (e1 - e2) / den,
         math.exp(-delta_t / t_long),
         math.exp(-delta_t / t_var)]
    rows, n = core_loudness.shape
    delta = np.roll(core_loudness, -1, axis=1)
    delta[:, -1] = 0
    delta = (delta - core_loudness) / nl_iter
    ui = np.zeros((rows, n, nl_iter))
    ui[:, :, 0] = core_loudness
    for i in range(1, nl_iter):
        ui[:, :, i] = ui[:, :, i - 1] + delta
    ui = ui.reshape(rows, n * nl_iter)
    uo = ui.copy()
    u2 = np.zeros_like(ui)
    mask = core_loudness[:, 0] >= 1e-5
    u2[mask, 0] = core_loudness[mask, 0] * (1 - B[5])
    _decay(ui, uo, u2, *B)
    return uo.reshape(rows, n, nl_iter)[:, :, 0]


def loudness_zwtv(signal: np.ndarray, fs: int = SAMPLE_RATE):
    """``(N, N_specific, bark_axis, time_axis)`` as ``mosqito.sq_metrics.loudness_zwtv`` returns
    them (free field), with the nonlinear decay compiled.  ``fs`` must be 48 kHz."""
    from mosqito.sq_metrics.loudness.loudness_zwst._calc_slopes import _calc_slopes
    from mosqito.sq_metrics.loudness.loudness_zwst._main_loudness import _main_loudness
    from mosqito.sq_metrics.loudness.loudness_zwtv._temporal_weighting import _temporal_weighting
    from mosqito.sq_metrics.loudness.loudness_zwtv._third_octave_levels import _third_octave_levels
    if fs != SAMPLE_RATE:
        raise ValueError(f"fs = {fs!r} is not allowed; ISO 532-1 loudness here takes "
                         f"{SAMPLE_RATE} Hz")
    spec_third, time_axis, _ = _third_octave_levels(np.asarray(signal, dtype=np.float64), fs)
    core = _nl_loudness(_main_loudness(spec_third, FIELD))
    total, specific = _calc_slopes(core)
    filt = _temporal_weighting(total)
    return filt[::4], specific[:, ::4], np.linspace(0.1, 24, 240), time_axis[::4]


def loudness(pressure_pa: np.ndarray, fs: int = SAMPLE_RATE) -> Loudness:
    """Loudness ``N5`` [sone] and mean sharpness [acum] of a sound-pressure signal [Pa].

    Parameters
    ----------
    pressure_pa : ndarray
        Sound pressure at the listener [Pa], sampled at ``fs``; at least 0.1 s long.
    fs : int
        48 000 Hz (ISO 532-1).
    """
    p = np.asarray(pressure_pa, dtype=np.float64)
    if p.ndim != 1 or p.size < 0.1 * SAMPLE_RATE:
        raise ValueError(f"pressure_pa must be a signal of at least 0.1 s at {SAMPLE_RATE} Hz, "
                         f"got shape {p.shape}")
    if not np.all(np.isfinite(p)):
        raise ValueError("pressure_pa must be finite")
    if not np.any(p):
        t = np.arange(p.size // 96) * 0.002
        return Loudness(0.0, 0.0, t, np.zeros(t.size))
    from mosqito.sq_metrics import sharpness_din_from_loudness
    N, spec, _, t = loudness_zwtv(p, fs)
    keep = t >= SKIP_S
    n5 = float(np.percentile(N[keep], 95)) if np.any(keep) else float(np.percentile(N, 95))
    with np.errstate(invalid="ignore", divide="ignore"):  # silent frames divide 0 by 0
        S = np.asarray(sharpness_din_from_loudness(N, spec, "din"), dtype=np.float64)
    heard = keep & (N > 0) & np.isfinite(S)
    sharp = float(np.mean(S[heard])) if np.any(heard) else 0.0
    return Loudness(n5, sharp, np.asarray(t), np.asarray(N))


__all__ = ["Loudness", "loudness", "loudness_zwtv", "SAMPLE_RATE",
           "DEFAULT_TRANSFER_PA_PER_NS", "SKIP_S"]
