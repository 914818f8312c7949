"""The rattle sound of a trajectory: impacts ringing the gearbox housing's modes.

Model
-----
Each impact ``n`` at time ``t_n`` is a force impulse of strength ``a_n`` on the housing, with
``a_n = Ĩ_n`` (signed: the force on the housing reverses with the flank, so active- and
reverse-flank impacts ring the housing with opposite polarity) or ``a_n = |Ĩ_n|``.  The housing
responds as a sum of damped modes ``i`` (frequency ``f_i``, damping ratio ``ζ_i``, gain ``g_i``)::

    s(t) = Σ_n a_n Σ_i g_i exp(−ζ_i ω_i (t − t_n)) sin(ω_{d,i} (t − t_n)),   t ≥ t_n,

with ``ω_i = 2π f_i`` and ``ω_{d,i} = ω_i sqrt(1 − ζ_i²)``: the impulse response of each mode,
convolved with the impulse train.  The sum is evaluated exactly at the sample times (impact
times keep their sub-sample position): per mode, the complex state
``z(t) = Σ_{t_n ≤ t} a_n exp(p_i (t − t_n))``, ``p_i = −ζ_i ω_i + i ω_{d,i}``, obeys
``z_k = exp(p_i Δt) z_{k−1} + (impacts in (t_{k−1}, t_k])``, a one-pole recursion, and
``s = Σ_i g_i Im z_i``.  Cost: O(samples + impacts) per mode.

Loudness is linear in the impulses (twice the impulses, twice the amplitude) before the
optional normalisation to a peak of 0.99 (``pn.pane.Audio`` converts floats to int16 without
clipping).  No impacts give exact silence: a periodic regime is a steady buzz at the impact
rate, a chaotic one an irregular rattle, and a sticking one falls silent once the chatter ends.

Time scale
----------
The solver's time is ``t = ω t_phys``.  In dimensionless mode the fundamental excitation
frequency ``f = ω / 2π`` defaults to :data:`DEFAULT_EXCITATION_HZ` = 50 Hz (a four-cylinder
four-stroke engine, order 2, at 1500 rpm).  In physical-units mode it follows the engine speed:
``f = order × rpm / 60`` (:class:`~rattle_core.model.units.PhysicalParams`), and the impulses are
scaled to newton-seconds, ``I = Ĩ m ω H₁``.

Default housing modes (:data:`DEFAULT_MODES`)
---------------------------------------------
Five modes between 1.2 and 5.8 kHz, the band where gear rattle is heard, with damping ratios of
1 to 3 % (lightly damped cast housings) and gains falling with frequency.  They are illustrative,
not measured on a particular gearbox; pass your own measured modes with ``modes=``.

==========  ============  =====
f [Hz]      ζ             gain
==========  ============  =====
1250        0.020         1.00
2150        0.015         0.80
3100        0.012         0.60
4300        0.020         0.45
5800        0.030         0.30
==========  ============  =====
"""
from __future__ import annotations

import dataclasses
import math
import os
from typing import BinaryIO, Iterable, Literal, Sequence

import numpy as np
from numba import njit

from ..model.params import check_bool, check_range
from ..solver.trajectory import Trajectory
from ..model.units import PhysicalParams

#: Fundamental excitation frequency used in dimensionless mode [Hz] (order 2 at 1500 rpm).
DEFAULT_EXCITATION_HZ = 50.0
DEFAULT_SAMPLE_RATE = 44_100
#: Ring-out appended after the last simulated instant [s].
DEFAULT_TAIL = 0.15
#: Peak of a normalised signal; ``pn.pane.Audio`` scales floats to int16 without clipping.
PEAK = 0.99
SAMPLE_RATE_RANGE = (4_000, 384_000)
MAX_DURATION = 600.0  # s
#: Most samples one signal may have (600 s at 48 kHz fits; 87 s at 384 kHz): the signal is
#: held in memory, 8 bytes a sample.
MAX_SAMPLES = 2**25
#: Samples rendered at once: the complex work array of the impulses stays this long.
_BLOCK = 2**20
EXCITATION_HZ_RANGE = (0.0, 10_000.0)  # open at 0


@dataclasses.dataclass(frozen=True)
class HousingMode:
    """One damped mode of the gearbox housing.

    Parameters
    ----------
    freq_hz : float
        Natural frequency ``f`` [Hz], > 0 (and below the Nyquist frequency when rendered).
    damping : float
        Damping ratio ``ζ``, in (0, 1).
    gain : float
        Relative amplitude ``g`` of the mode's response to a unit impulse, in [0, 1e6].
    """

    freq_hz: float
    damping: float = 0.02
    gain: float = 1.0

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        set_(self, "freq_hz", check_range("mode freq_hz", self.freq_hz, 0.0, 1e6, lo_open=True))
        set_(self, "damping", check_range("mode damping", self.damping, 0.0, 1.0,
                                          lo_open=True, hi_open=True))
        set_(self, "gain", check_range("mode gain", self.gain, 0.0, 1e6))

    @property
    def decay_time(self) -> float:
        """Time constant of the envelope ``1 / (ζ ω)`` [s]."""
        return 1.0 / (self.damping * 2.0 * math.pi * self.freq_hz)


DEFAULT_MODES: tuple[HousingMode, ...] = (
    HousingMode(1250.0, 0.020, 1.00),
    HousingMode(2150.0, 0.015, 0.80),
    HousingMode(3100.0, 0.012, 0.60),
    HousingMode(4300.0, 0.020, 0.45),
    HousingMode(5800.0, 0.030, 0.30),
)


def parse_modes(text: str) -> tuple[HousingMode, ...]:
    """Modes from text ``"f:zeta:gain,f:zeta:gain,..."`` (``zeta`` and ``gain`` optional).

    Example: ``"1250:0.02:1,2150:0.015:0.8"``.  Raises ``ValueError`` on malformed text.
    """
    modes = []
    for item in str(text).split(","):
        item = item.strip()
        if not item:
            continue
        parts = item.split(":")
        if len(parts) > 3:
            raise ValueError(f"mode {item!r} must read f[:damping[:gain]], e.g. 1250:0.02:1")
        try:
            nums = [float(p) for p in parts]
        except ValueError:
            raise ValueError(f"mode {item!r} must read f[:damping[:gain]] with numbers, "
                             "e.g. 1250:0.02:1") from None
        modes.append(HousingMode(*nums))
    if not modes:
        raise ValueError(f"modes {text!r} holds no mode; give at least one, e.g. 1250:0.02:1")
    return tuple(modes)


def _check_modes(modes: Iterable[HousingMode] | None, sample_rate: int) -> tuple[HousingMode, ...]:
    modes = DEFAULT_MODES if modes is None else tuple(modes)
    if not modes:
        raise ValueError("modes is empty; give at least one housing mode")
    for m in modes:
        if not isinstance(m, HousingMode):
            raise ValueError(f"modes must be HousingMode objects, got {m!r}")
        if m.freq_hz >= sample_rate / 2:
            raise ValueError(f"mode freq_hz = {m.freq_hz!r} is outside the allowed range "
                             f"(0, {sample_rate / 2:g}) (the Nyquist frequency at sample_rate "
                             f"= {sample_rate})")
    return modes


def check_length(duration: float, sample_rate: int) -> int:
    """The number of samples of a signal ``duration`` seconds long, or ``ValueError`` when the
    duration is outside (0, :data:`MAX_DURATION`] or the count over :data:`MAX_SAMPLES`."""
    sample_rate = check_sample_rate(sample_rate)
    duration = check_range("duration", duration, 0.0, MAX_DURATION, lo_open=True)
    n = max(1, int(round(duration * sample_rate)))
    if n > MAX_SAMPLES:
        raise ValueError(f"duration × sample_rate = {duration:.6g} s × {sample_rate} Hz = {n} samples "
                         f"is outside the allowed range [1, {MAX_SAMPLES}]; lower the sample rate "
                         "or the duration (fewer periods, a higher excitation frequency)")
    return n


def check_sample_rate(sample_rate: int) -> int:
    v = check_range("sample_rate", sample_rate, *SAMPLE_RATE_RANGE)
    if v != int(v):
        raise ValueError(f"sample_rate = {sample_rate!r} must be a whole number of Hz in "
                         f"[{SAMPLE_RATE_RANGE[0]}, {SAMPLE_RATE_RANGE[1]}]")
    return int(v)


def render(impact_times: Sequence[float], amplitudes: Sequence[float], duration: float,
           sample_rate: int = DEFAULT_SAMPLE_RATE,
           modes: Iterable[HousingMode] | None = None) -> np.ndarray:
    """Housing response to an impulse train, unnormalised.

    Implements ``s(t_k) = Σ_n a_n Σ_i g_i exp(−ζ_i ω_i (t_k − t_n)) sin(ω_{d,i} (t_k − t_n))``
    over impacts with ``t_n ≤ t_k``, at ``t_k = k / sample_rate``, exactly (see the module
    docstring).

    Parameters
    ----------
    impact_times : sequence of float
        Impact times ``t_n`` [s] from the start of the signal; those outside
        ``[0, duration)`` are ignored.
    amplitudes : sequence of float
        Impulse strengths ``a_n``, same length.
    duration : float
        Signal length [s], in (0, 600].
    sample_rate : int
        Samples per second, in [4000, 384000].
    modes : iterable of HousingMode, optional
        Housing modes (default :data:`DEFAULT_MODES`), each below ``sample_rate / 2``.

    Returns
    -------
    ndarray of float64
        ``round(duration × sample_rate)`` samples, linear in ``amplitudes``.
    """
    n = check_length(duration, sample_rate)
    sample_rate = check_sample_rate(sample_rate)
    modes = _check_modes(modes, sample_rate)
    t = np.asarray(impact_times, dtype=np.float64).ravel()
    a = np.asarray(amplitudes, dtype=np.float64).ravel()
    if t.shape != a.shape:
        raise ValueError(f"impact_times has {t.size} entries but amplitudes has {a.size}; "
                         "they must have the same length")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(a))):
        raise ValueError("impact_times and amplitudes must be finite")
    dt = 1.0 / sample_rate
    keep = (t >= 0.0) & (t < n * dt) & (a != 0.0)
    t, a = t[keep], a[keep]
    if t.size == 0:
        return np.zeros(n)
    # First sample at or after each impact; the impact's sub-sample offset goes into the phase.
    k = np.minimum(np.ceil(t * sample_rate - 1e-9).astype(np.int64), n - 1)
    lag = np.maximum(k * dt - t, 0.0)
    order = np.argsort(k, kind="stable")  # the kernel walks the impacts in sample order
    k, lag, a = k[order], lag[order], a[order]
    kicks = np.empty((len(modes), k.size), dtype=np.complex128)
    poles = np.empty(len(modes), dtype=np.complex128)
    gains = np.empty(len(modes))
    for i, mode in enumerate(modes):
        w = 2.0 * math.pi * mode.freq_hz
        p = complex(-mode.damping * w, w * math.sqrt(1.0 - mode.damping**2))
        kicks[i] = a * np.exp(p * lag)
        poles[i] = np.exp(p * dt)
        gains[i] = mode.gain
    return _ring(k, kicks, poles, gains, n, _BLOCK)


@njit(cache=True, nogil=True)
def _ring(k, kicks, poles, gains, n, block):
    """``Σ_i g_i Im z_i`` with ``z_{i,s} = e_i z_{i,s−1} + (kicks of sample s)``, over ``n``
    samples; ``k`` (sorted) is each kick's sample.  Each block's kicks are summed into one
    work array of ``block`` samples first, so memory stays near the output's own."""
    out = np.zeros(n)
    u = np.empty(min(n, block), dtype=np.complex128)
    for i in range(poles.size):
        e = poles[i]
        g = gains[i]
        z = 0j
        j = 0
        for s0 in range(0, n, block):
            s1 = min(n, s0 + block)
            u[:s1 - s0] = 0j
            while j < k.size and k[j] < s1:
                u[k[j] - s0] += kicks[i, j]
                j += 1
            for s in range(s0, s1):
                y = z + u[s - s0]
                z = e * y
                out[s] += g * y.imag
    return out


def normalize(signal: np.ndarray, peak: float = PEAK) -> np.ndarray:
    """``signal`` scaled so that ``max |s| = peak``; an all-zero signal stays zero."""
    peak = check_range("peak", peak, 0.0, 1.0, lo_open=True)
    s = np.asarray(signal, dtype=np.float64)
    m = float(np.max(np.abs(s))) if s.size else 0.0
    return s * (peak / m) if m > 0.0 else s.copy()


def synthesize(trajectory: Trajectory, *, sample_rate: int = DEFAULT_SAMPLE_RATE,
               excitation_hz: float | None = None, physical: PhysicalParams | None = None,
               modes: Iterable[HousingMode] | None = None, tail: float = DEFAULT_TAIL,
               polarity: Literal["signed", "absolute"] = "signed",
               normalized: bool = True) -> tuple[np.ndarray, int]:
    """The rattle sound of a simulated trajectory.

    The signal starts at the trajectory's first recorded instant ``t_start`` and lasts
    ``(t_end − t_start) / ω + tail`` seconds; impact ``n`` sounds at ``(t_n − t_start) / ω``.

    Parameters
    ----------
    trajectory : Trajectory
        From :func:`~rattle_core.simulate`.
    sample_rate : int
        Samples per second, in [4000, 384000].
    excitation_hz : float, optional
        Fundamental excitation frequency ``ω / 2π`` [Hz] in dimensionless mode, in (0, 1e4];
        default :data:`DEFAULT_EXCITATION_HZ`.  Not allowed together with ``physical``.
    physical : PhysicalParams, optional
        Physical-units mode: the time scale follows its engine speed and the impulses are in
        N·s (``I = Ĩ m ω H₁``).  Its Λ and j must match the trajectory's.
    modes : iterable of HousingMode, optional
        Housing modes; default :data:`DEFAULT_MODES`.
    tail : float
        Ring-out after the last simulated instant [s], in [0, 10].
    polarity : {"signed", "absolute"}
        Strength of each impulse: ``Ĩ`` (polarity flips with the flank) or ``|Ĩ|``.
    normalized : bool
        Scale to a peak of 0.99 (silence stays silent); otherwise the raw, linear signal.

    Returns
    -------
    signal : ndarray of float64
    sample_rate : int

    Raises
    ------
    ValueError
        Bad sample rate, frequency, modes (e.g. above the Nyquist frequency), a duration over
        600 s, or a ``physical`` that does not match the trajectory.
    """
    if not isinstance(trajectory, Trajectory):
        raise ValueError(f"trajectory must be a Trajectory, got {type(trajectory).__name__}")
    if polarity not in ("signed", "absolute"):
        raise ValueError(f"polarity = {polarity!r} is not allowed; use 'signed' or 'absolute'")
    tail = check_range("tail", tail, 0.0, 10.0)
    normalized = check_bool("normalized", normalized)
    scale = 1.0
    if physical is not None:
        if excitation_hz is not None:
            raise ValueError("give excitation_hz or physical, not both: in physical-units mode "
                             "the engine speed sets the time scale")
        p = physical.to_dimensionless()
        tp = trajectory.params
        if not (math.isclose(p.lam, tp.lam, rel_tol=1e-9) and math.isclose(p.j, tp.j, rel_tol=1e-9)):
            raise ValueError(f"physical gives lam = {p.lam:.6g}, j = {p.j:.6g} but the trajectory "
                             f"was run with lam = {tp.lam:.6g}, j = {tp.j:.6g}")
        freq = physical.frequency_hz
        scale = physical.impulse_scale
    else:
        freq = DEFAULT_EXCITATION_HZ if excitation_hz is None else excitation_hz
        freq = check_range("excitation_hz", freq, *EXCITATION_HZ_RANGE, lo_open=True)
    omega = 2.0 * math.pi * freq
    length = (trajectory.t_end - trajectory.t_start) / omega + tail
    if length > MAX_DURATION:
        raise ValueError(f"duration = {length:.6g} s is outside the allowed range (0, {MAX_DURATION:g}] s; "
                         "simulate fewer periods or raise excitation_hz")
    check_length(length, sample_rate)
    times = (trajectory.impact_t - trajectory.t_start) / omega
    strength = trajectory.impact_impulse if polarity == "signed" else np.abs(trajectory.impact_impulse)
    signal = render(times, scale * strength, length, sample_rate, modes)
    if normalized:
        signal = normalize(signal)
    return signal, int(sample_rate)


def to_int16(signal: np.ndarray) -> np.ndarray:
    """PCM int16 samples of a float signal in [−1, 1] (values outside are clipped)."""
    s = np.clip(np.asarray(signal, dtype=np.float64), -1.0, 1.0)
    return np.round(s * 32767.0).astype(np.int16)


def write_wav(path: str | os.PathLike | BinaryIO, signal: np.ndarray, sample_rate: int) -> None:
    """Write a mono 16-bit PCM WAV file with :func:`scipy.io.wavfile.write`.

    Parameters
    ----------
    path : path-like or binary file object
        Destination file (a download served from memory passes a ``BytesIO``).
    signal : ndarray
        Float samples in [−1, 1] (as returned by :func:`synthesize`); clipped beyond.
    sample_rate : int
        Samples per second, in [4000, 384000].
    """
    sample_rate = check_sample_rate(sample_rate)
    s = np.asarray(signal, dtype=np.float64)
    if s.ndim != 1:
        raise ValueError(f"signal must be one-dimensional (mono), got shape {s.shape}")
    if not np.all(np.isfinite(s)):
        raise ValueError("signal must be finite")
    from scipy.io import wavfile
    wavfile.write(path if hasattr(path, "write") else os.fspath(path), sample_rate, to_int16(s))


__all__ = ["HousingMode", "DEFAULT_MODES", "DEFAULT_EXCITATION_HZ", "DEFAULT_SAMPLE_RATE",
           "parse_modes", "render", "normalize", "synthesize", "to_int16", "write_wav"]
