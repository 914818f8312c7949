"""A measured wall: the driving tooth's motion as pieces of smooth functions, with per-piece
derivative bounds (docs/model.md, "A run-up in physical time").

The wall is ``y(t) = Σ_k A_k(t) cos Φ_k(t)`` and the gear's flight deceleration is ``q(t)``,
both in the reference units of a replay.  Time is cut into pieces; on piece ``p``, which starts
at ``t0[p]`` and lasts ``length[p]``, with local time ``s ∈ [0, length[p]]``,

* ``A_k(s) = Σ_{i≤3} amp[p, k, i] sⁱ`` (an amplitude, cubic in time),
* ``Φ_k(s) = Σ_{i≤4} phase[p, k, i] sⁱ`` (a phase, the engine order's angle minus its measured
  phase, reduced so that the constant term is small),
* ``q(s) = decel[p, 0] + decel[p, 1] s``.

Inside a piece every function is a polynomial, so ``y`` is analytic there, and its derivatives
come from Taylor "jets": with ``α_m``, ``ϕ_m`` the Taylor coefficients of ``A`` and ``Φ`` at
``s`` and ``e_n`` those of ``exp(iΦ)`` (``e_0 = e^{iϕ_0}``, ``e_n = (i/n) Σ_{m=1..n} m ϕ_m e_{n−m}``),
``y⁽ⁿ⁾(s) = n! Re Σ_{m≤n} α_m e_{n−m}``.  The bounds of a piece are rigorous:
``y⁽ⁿ⁾ = Re(P_n e^{iΦ})`` with the polynomials ``P_0 = A``, ``P_{n+1} = P_n' + iΦ' P_n``, so
``|y⁽ⁿ⁾| ≤ max |P_n| ≤ Σ_i |c_i| (L/2)ⁱ``, ``c_i`` the coefficients of ``P_n`` about the piece's
midpoint.  The event search never steps across a piece's end, so a bound needs to hold inside
one piece only: derivatives may jump at the joints (a spline's third derivative does).
"""
from __future__ import annotations

import dataclasses

import numpy as np
from numba import njit

#: Derivatives of the wall whose bounds each piece carries: ``|y⁽ⁿ⁾| ≤ bounds[p, n]``, n = 0..5.
N_BOUNDS = 6


@dataclasses.dataclass(frozen=True, eq=False)
class PiecewiseWall:
    """A measured wall in reference units (module docstring).

    Attributes
    ----------
    t0, length : ndarray, shape (P,)
        Start and length of each piece; ``t0[p + 1] = t0[p] + length[p]``.
    amp : ndarray, shape (P, K, 4)
        Amplitude polynomials ``A_k`` in local time.
    phase : ndarray, shape (P, K, 5)
        Phase polynomials ``Φ_k`` in local time.
    decel : ndarray, shape (P, 2)
        Flight deceleration ``q = decel[p, 0] + decel[p, 1] s``.
    bounds : ndarray, shape (P, 6)
        ``|y⁽ⁿ⁾| ≤ bounds[p, n]`` on piece ``p``.
    qmax : ndarray, shape (P,)
        ``max |q|`` on piece ``p``.
    """

    t0: np.ndarray
    length: np.ndarray
    amp: np.ndarray
    phase: np.ndarray
    decel: np.ndarray
    bounds: np.ndarray
    qmax: np.ndarray

    @property
    def t_end(self) -> float:
        """End of the last piece."""
        return float(self.t0[-1] + self.length[-1])

    def piece_of(self, t) -> tuple[np.ndarray, np.ndarray]:
        """The piece holding each time ``t`` and the local time in it."""
        t = np.atleast_1d(np.asarray(t, dtype=np.float64))
        p = np.clip(np.searchsorted(self.t0, t, side="right") - 1, 0, self.t0.size - 1)
        return p, t - self.t0[p]

    def values(self, t, m: int = 0) -> np.ndarray:
        """The m-th derivative (m ≤ 4) of the wall at times ``t``."""
        p, s = self.piece_of(t)
        out = np.empty((p.size, 5))
        _wall_many(self.amp, self.phase, p.astype(np.int64), s, out)
        return out[:, m]


def piecewise_wall(t0, length, amp, phase, decel) -> PiecewiseWall:
    """A :class:`PiecewiseWall` with its bounds computed from the coefficients."""
    t0 = np.ascontiguousarray(t0, dtype=np.float64)
    length = np.ascontiguousarray(length, dtype=np.float64)
    amp = np.ascontiguousarray(amp, dtype=np.float64)
    phase = np.ascontiguousarray(phase, dtype=np.float64)
    decel = np.ascontiguousarray(decel, dtype=np.float64)
    n = t0.size
    if n < 1 or length.shape != (n,) or amp.shape[:1] != (n,) or amp.shape[2] != 4 or \
            phase.shape != amp.shape[:2] + (5,) or decel.shape != (n, 2):
        raise ValueError("a piecewise wall needs t0, length (P,), amp (P, K, 4), phase (P, K, 5) "
                         "and decel (P, 2)")
    if not np.all(length > 0) or not all(np.all(np.isfinite(a)) for a in (t0, amp, phase, decel)):
        raise ValueError("a piecewise wall needs positive piece lengths and finite coefficients")
    q_end = decel[:, 0] + decel[:, 1] * length
    qmax = np.maximum(np.abs(decel[:, 0]), np.abs(q_end))
    return PiecewiseWall(t0, length, amp, phase, decel, _bounds(amp, phase, length), qmax)


# ----- bounds (numpy, once per wall) ----------------------------------------------------------

def _shift(c: np.ndarray, h: np.ndarray) -> np.ndarray:
    """Coefficients of ``p(s + h)`` from those of ``p(s)`` (last axis), ``h`` per piece."""
    deg = c.shape[-1]
    out = np.zeros_like(c)
    hp = h.reshape((-1,) + (1,) * (c.ndim - 2))
    binom = [[1.0]]
    for i in range(1, deg):
        row = binom[-1]
        binom.append([1.0] + [row[k - 1] + row[k] for k in range(1, i)] + [1.0])
    for i in range(deg):
        for m in range(i + 1):
            out[..., m] = out[..., m] + binom[i][m] * c[..., i] * hp ** (i - m)
    return out


def _polymul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    out = np.zeros(a.shape[:-1] + (a.shape[-1] + b.shape[-1] - 1,), dtype=np.result_type(a, b))
    for i in range(a.shape[-1]):
        out[..., i:i + b.shape[-1]] += a[..., i:i + 1] * b
    return out


def _polyder(a: np.ndarray) -> np.ndarray:
    if a.shape[-1] == 1:
        return np.zeros_like(a)
    return a[..., 1:] * np.arange(1, a.shape[-1])


def _bounds(amp: np.ndarray, phase: np.ndarray, length: np.ndarray) -> np.ndarray:
    """``bounds[p, n] ≥ max |y⁽ⁿ⁾|`` on each piece (module docstring)."""
    half = 0.5 * length
    a = _shift(amp, half).astype(np.complex128)
    dphi = _polyder(_shift(phase, half)).astype(np.complex128)
    powers = half[:, None] ** np.arange(4 + 3 * N_BOUNDS)[None, :]
    out = np.zeros((length.size, N_BOUNDS))
    p = a
    for n in range(N_BOUNDS):
        deg = p.shape[-1]
        out[:, n] = np.sum(np.abs(p) * powers[:, None, :deg], axis=(1, 2))
        if n + 1 < N_BOUNDS:
            dp = _polyder(p)
            ip = 1j * _polymul(dphi, p)
            dp = np.concatenate([dp, np.zeros(dp.shape[:-1] + (ip.shape[-1] - dp.shape[-1],))],
                                axis=-1)
            p = dp + ip
    # a relative margin for the rounding of the sums above and of the jets
    return out * (1.0 + 1e-12)


# ----- evaluation (compiled) ------------------------------------------------------------------

@njit(cache=True, nogil=True)
def _wall_derivs(amp, phase, p, s):
    """``y, ẏ, ÿ, y⁽³⁾, y⁽⁴⁾`` of the wall at local time ``s`` of piece ``p`` (Taylor jets)."""
    y0 = 0.0
    y1 = 0.0
    y2 = 0.0
    y3 = 0.0
    y4 = 0.0
    for k in range(amp.shape[1]):
        c0 = amp[p, k, 0]
        c1 = amp[p, k, 1]
        c2 = amp[p, k, 2]
        c3 = amp[p, k, 3]
        if c0 == 0.0 and c1 == 0.0 and c2 == 0.0 and c3 == 0.0:
            continue
        a0 = ((c3 * s + c2) * s + c1) * s + c0
        a1 = (3.0 * c3 * s + 2.0 * c2) * s + c1
        a2 = 3.0 * c3 * s + c2
        a3 = c3
        d0 = phase[p, k, 0]
        d1 = phase[p, k, 1]
        d2 = phase[p, k, 2]
        d3 = phase[p, k, 3]
        d4 = phase[p, k, 4]
        f0 = (((d4 * s + d3) * s + d2) * s + d1) * s + d0
        f1 = ((4.0 * d4 * s + 3.0 * d3) * s + 2.0 * d2) * s + d1
        f2 = (6.0 * d4 * s + 3.0 * d3) * s + d2
        f3 = 4.0 * d4 * s + d3
        f4 = d4
        e0 = complex(np.cos(f0), np.sin(f0))
        e1 = 1j * (f1 * e0)
        e2 = 0.5j * (f1 * e1 + 2.0 * f2 * e0)
        e3 = (1j / 3.0) * (f1 * e2 + 2.0 * f2 * e1 + 3.0 * f3 * e0)
        e4 = 0.25j * (f1 * e3 + 2.0 * f2 * e2 + 3.0 * f3 * e1 + 4.0 * f4 * e0)
        y0 += (a0 * e0).real
        y1 += (a0 * e1 + a1 * e0).real
        y2 += 2.0 * (a0 * e2 + a1 * e1 + a2 * e0).real
        y3 += 6.0 * (a0 * e3 + a1 * e2 + a2 * e1 + a3 * e0).real
        y4 += 24.0 * (a0 * e4 + a1 * e3 + a2 * e2 + a3 * e1).real
    return y0, y1, y2, y3, y4


@njit(cache=True, nogil=True)
def _wall_many(amp, phase, p, s, out):
    for i in range(p.shape[0]):
        y0, y1, y2, y3, y4 = _wall_derivs(amp, phase, p[i], s[i])
        out[i, 0] = y0
        out[i, 1] = y1
        out[i, 2] = y2
        out[i, 3] = y3
        out[i, 4] = y4


__all__ = ["PiecewiseWall", "piecewise_wall"]
