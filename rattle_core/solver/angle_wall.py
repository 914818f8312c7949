"""The measured shaft angle itself as a wall: low-pass filtered, as a cubic spline in pieces
(docs/model.md, "A run-up in physical time", "The measured angle as the wall").

The order reconstruction (:mod:`rattle_core.solver.runup`) keeps only the orders the analysis
estimated.  This module keeps everything the measurement holds below a stated cutoff:

1. **Angle.**  The shaft angle ``θ(t)`` [rad] at the samples: given, or the exact integral of
   the cubic spline through the measured speed (its antiderivative; the error of the
   interpolant is ``O((ω Δt)⁴)`` of a component of angular frequency ``ω``, not the trapezoid
   rule's ``O((ω Δt)²)``).
2. **Mean rotation.**  ``ψ̄(t) = p(t) + LP_mean[θ − p](t)``, ``p`` the least-squares quadratic
   through ``θ`` (it carries the rotation, so that the filter sees small numbers and its edge
   padding continues a smooth trend) and ``LP_mean`` the zero-phase low-pass below
   ``mean_hz``, a quarter of the lowest fundamental frequency of the stretch by default.
   The mean speed ``ψ̄'`` and acceleration ``ψ̄''`` come from the cubic spline through ``ψ̄``.
3. **Fluctuation.**  ``Δθ = LP_cut[θ − ψ̄]``, the zero-phase low-pass at ``cutoff_hz``.

Both low-passes are 8th-order Butterworth filters applied forwards and backwards
(``scipy.signal.sosfiltfilt`` on second-order sections): forwards-backwards cancels the phase
exactly, so an impact is not shifted in time, and the power gain ``1/(1 + (f/f_c)^16)`` is flat
to ``2·10⁻¹⁰`` at a quarter of the cutoff and falls by 96 dB per octave above it.  An FFT brick
wall would be flatter still, but it treats the record as periodic: a run-up, whose speed at the
end is not its speed at the start, would wrap its end onto its start and ring (Gibbs) over
the whole record; a Butterworth filter's edge transient dies out within a few periods of its
cutoff.  The first and last ``EDGE_PERIODS`` periods of the lower cutoff (``mean_hz``) of a
record are therefore not offered to a run (:attr:`FilteredAngle.usable_s`;
:func:`rattle_core.solver.runup.angle_runup_wall` refuses a run that reaches into them).

The wall is then the cubic spline through ``Δθ`` at the samples (not-a-knot), written as a
:class:`~rattle_core.solver.wall.PiecewiseWall` with one order, ``A(s)`` the spline's cubic on a
sample interval and ``Φ ≡ 0``, so the replay kernel reads it exactly as it reads an order
reconstruction.  Its bounds are rigorous on each piece by the same construction (:func:`spline_wall`): with
``Φ ≡ 0`` the polynomials of :mod:`~rattle_core.solver.wall` are ``P_n = A⁽ⁿ⁾``, and
``|A⁽ⁿ⁾(s)| ≤ Σ_i |c_i| (L/2)ⁱ`` holds for the Taylor coefficients ``c_i`` of ``A⁽ⁿ⁾`` about
the piece's midpoint for every ``s`` in the piece (the triangle inequality on
``|s − L/2| ≤ L/2``); the bounds carry the wall's relative margin of ``10⁻¹²`` for the rounding
of those sums.  A cubic's fourth and fifth derivatives vanish, so their bounds would be 0; the
event search reads a zero bound as "no bound" and would then creep along a release, so they
are raised to ``FLOOR`` times the piece's third-derivative bound over ``L`` and ``L²`` (any
positive number bounds a zero).  A spline's third derivative jumps at the knots, which is why the bounds are
per piece and the event search never steps across a piece's end.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.signal import butter, sosfiltfilt

from ..measure.sampling import JITTER_TOLERANCE
from ..model.params import check_range
from .wall import piecewise_wall

#: Order of the two Butterworth low-passes (each applied forwards and backwards).
FILTER_ORDER = 8
#: Cutoff periods at either end of a record left to the filters' edge transients.
EDGE_PERIODS = 20.0
#: The mean rotation's low-pass, as a fraction of the lowest fundamental frequency.
MEAN_FRACTION = 0.25
#: The bounds of a cubic's vanishing fourth and fifth derivatives, relative (module docstring).
FLOOR = 1e-12


@dataclasses.dataclass(frozen=True, eq=False)
class FilteredAngle:
    """A measured shaft angle split into its mean rotation and its filtered fluctuation.

    Attributes
    ----------
    time_s : ndarray
        The samples' times [s].
    fluctuation_rad : ndarray
        ``Δθ``, the angle about its mean rotation, low-pass filtered at ``cutoff_hz``.
    mean_speed : CubicSpline
        ``ψ̄'(t)`` [rad/s]; ``mean_speed(t, 1)`` is the mean acceleration [rad/s²].
    cutoff_hz, mean_hz, sample_rate_hz : float
    """

    time_s: np.ndarray
    fluctuation_rad: np.ndarray
    mean_speed: CubicSpline
    cutoff_hz: float
    mean_hz: float
    sample_rate_hz: float

    @property
    def usable_s(self) -> tuple[float, float]:
        """The stretch clear of the filters' edge transients [s]."""
        edge = EDGE_PERIODS / min(self.cutoff_hz, self.mean_hz)
        return float(self.time_s[0] + edge), float(self.time_s[-1] - edge)

    def mean_rpm(self, t_s) -> np.ndarray:
        """Mean shaft speed [rpm] at times ``t_s``."""
        return self.mean_speed(np.asarray(t_s, dtype=np.float64)) * (60.0 / (2.0 * math.pi))


def _rate(time_s: np.ndarray) -> float:
    dt = np.diff(time_s)
    if time_s.size < 8 or not np.all(dt > 0) or not np.all(np.isfinite(time_s)):
        raise ValueError("time_s must hold at least 8 finite, strictly increasing times")
    step = float(np.median(dt))
    if np.max(np.abs(dt - step)) > JITTER_TOLERANCE * step:
        raise ValueError("time_s must be uniformly sampled (resample the measurement first)")
    return 1.0 / step


def check_cutoff(cutoff_hz, sample_rate_hz: float) -> float:
    """``cutoff_hz`` as a float in ``(0, Nyquist)``, or a ``ValueError`` naming the range."""
    return check_range("cutoff_hz", cutoff_hz, 0.0, 0.5 * sample_rate_hz, lo_open=True,
                       hi_open=True)


def filter_angle(time_s, *, cutoff_hz: float, angle_rad=None, speed_rpm=None,
                 engine_order: float = 1.0, mean_hz: float | None = None) -> FilteredAngle:
    """Split a measured shaft angle into its mean rotation and its fluctuation, filtered at
    ``cutoff_hz`` (module docstring).

    Parameters
    ----------
    time_s : array_like
        Uniform sample times [s].
    cutoff_hz : float
        Cutoff of the fluctuation's low-pass [Hz], in ``(0, f_s/2)``.
    angle_rad, speed_rpm : array_like
        The shaft angle [rad] or its speed [rpm] at the samples; give one.
    engine_order : float
        Cycles of the fundamental per revolution (sets the default ``mean_hz``).
    mean_hz : float, optional
        Cutoff of the mean rotation's low-pass [Hz], below the cutoff (default: a quarter of
        the lowest fundamental frequency of the record).
    """
    t = np.ascontiguousarray(time_s, dtype=np.float64)
    fs = _rate(t)
    cutoff_hz = check_cutoff(cutoff_hz, fs)
    if (angle_rad is None) == (speed_rpm is None):
        raise ValueError("give the shaft angle (angle_rad) or its speed (speed_rpm), one of them")
    if angle_rad is None:
        w = np.asarray(speed_rpm, dtype=np.float64) * (2.0 * math.pi / 60.0)
        if w.shape != t.shape or not np.all(np.isfinite(w)) or not np.all(w > 0):
            raise ValueError("speed_rpm must hold one finite speed > 0 per time")
        theta = CubicSpline(t, w).antiderivative()(t)
    else:
        theta = np.asarray(angle_rad, dtype=np.float64)
        if theta.shape != t.shape or not np.all(np.isfinite(theta)):
            raise ValueError("angle_rad must hold one finite angle per time")
    tc = t - 0.5 * (t[0] + t[-1])
    scale = max(float(np.max(np.abs(tc))), 1e-300)
    poly = np.polynomial.Polynomial.fit(tc, theta, 2, domain=[-scale, scale])
    rest = theta - poly(tc)
    if mean_hz is None:
        speed = poly.deriv()(tc)
        lowest = float(np.min(speed)) / (2.0 * math.pi) * float(engine_order)
        if not lowest > 0.0:
            raise ValueError("the measured shaft does not turn forwards over the record")
        mean_hz = MEAN_FRACTION * lowest
    mean_hz = check_range("mean_hz", mean_hz, 0.0, cutoff_hz, lo_open=True, hi_open=True)
    mean_sos = butter(FILTER_ORDER, mean_hz, fs=fs, output="sos")
    slow = sosfiltfilt(mean_sos, rest)
    cut_sos = butter(FILTER_ORDER, cutoff_hz, fs=fs, output="sos")
    fluct = sosfiltfilt(cut_sos, rest - slow)
    mean = CubicSpline(t, poly(tc) + slow).derivative()
    return FilteredAngle(t, fluct, mean, cutoff_hz, mean_hz, fs)


def spline_wall(time_ref: np.ndarray, values: np.ndarray, first: int, stop: int,
                decel: np.ndarray):
    """The :class:`~rattle_core.solver.wall.PiecewiseWall` of the not-a-knot cubic spline
    through ``values`` at ``time_ref`` (reference units), on its pieces ``first .. stop − 1``,
    with flight deceleration ``decel`` (shape ``(stop − first, 2)``); bounds as in the module
    docstring."""
    t0, length, amp, phase = spline_pieces(time_ref, values)
    sl = slice(first, stop)
    wall = piecewise_wall(t0[sl], length[sl], amp[sl], phase[sl], decel)
    bounds = wall.bounds.copy()
    b3 = bounds[:, 3] + np.finfo(np.float64).tiny
    bounds[:, 4] = np.maximum(bounds[:, 4], FLOOR * b3 / wall.length)
    bounds[:, 5] = np.maximum(bounds[:, 5], FLOOR * b3 / wall.length ** 2)
    return dataclasses.replace(wall, bounds=bounds)


def spline_pieces(time_ref: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, np.ndarray,
                                                                      np.ndarray, np.ndarray]:
    """``(t0, length, amp, phase)`` of a :class:`~rattle_core.solver.wall.PiecewiseWall` that is
    the not-a-knot cubic spline through ``values`` at ``time_ref`` (one order, ``Φ ≡ 0``)."""
    sp = CubicSpline(time_ref, values)
    c = sp.c                                    # (4, P): highest power first, local time
    n = c.shape[1]
    amp = np.zeros((n, 1, 4))
    for i in range(4):
        amp[:, 0, i] = c[3 - i]
    return (np.ascontiguousarray(time_ref[:-1]), np.diff(time_ref), amp, np.zeros((n, 1, 5)))


__all__ = ["FilteredAngle", "filter_angle", "check_cutoff", "spline_pieces", "spline_wall", "FILTER_ORDER",
           "EDGE_PERIODS"]
