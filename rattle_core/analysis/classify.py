"""Regimes, period, Lyapunov exponent and rattle metrics; analytic overlays.

Definitions (all over the recorded window of ``P`` forcing periods, after the transient):

* **period n**: the smallest n ≤ ``MAX_PERIOD`` with ``|s_{k+n} − s_k| ≤ PERIOD_TOL·(1 + j)``
  for every stroboscopic sample ``s_k = (x, ẋ)`` of the last half of the window; 0 if none.
* **impacts per period**: recorded impacts on each flank divided by ``P``.
* **stick fraction**: time in permanent contact divided by the window length.
* **Lyapunov exponent λ**: largest exponent per unit dimensionless time, from the tangent
  dynamics with saltation matrices (see ``solver``), measured over the periods free of
  sticking, on excursions of at least 20 periods between stick phases (a stick phase collapses
  every perturbation); ``−inf`` if no such excursion exists.
* **chaotic**: ``period == 0`` (non-repeating section) and ``λ > LYAP_CHAOS``.  A chaotic
  response may stick now and then (the paper's "chaotic responses beside stick-and-impact").
* **sticking**: ``""`` when the window has no stick phase; ``"stick-locked"`` when every
  capture into a stick phase ended an excursion that amplified perturbations by less than
  1e10 (the motion through sticking is exact and resolvable; ``loop_amplification`` gives the
  largest, as log10); ``"chaos-through-sticking"`` when some capture was decided by rounding
  (docs/model.md, "Sticking erases the past").  With noise (``params.noise > 0``, the default)
  the window's statistics are then those at that noise level (``noisy``), which they may
  depend on (docs/model.md, "What the statistics mean"); without noise they are those of a
  loop chosen by rounding, and the label says so.
* **rattle intensity**: ``Σ Ĩ² / P``, the impulse energy per forcing period; mean and RMS
  ``|Ĩ|`` per flank.
* **regime** (paper §4), first match wins: ``A`` permanent contact (no impact, stuck the
  whole window); ``D`` chaotic; ``B`` impacts followed by permanent contact (some sticking,
  some impacts); ``C`` period 1,
  one active-flank impact per period, none on the reverse; ``D`` chaotic; ``E`` period 1, one
  impact on each flank per period.  Other responses are ``P`` (another periodic response,
  described by :attr:`Classification.label`) or ``Q`` (non-repeating without a positive
  exponent: quasi-periodic or a long transient).

:func:`classify_batch` classifies many windows at once in one compiled pass (sweeps and maps);
:func:`classify_arrays` and :func:`classify` are that pass on one window, so the rules live in
one place. Sums follow numpy's pairwise summation, so results equal the numpy expressions of
the definitions above.

The analytic curves drawn over the results are in :mod:`rattle_core.analysis.overlays`.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np
from numba import njit

from ..model.excitation import TWO_PI
from .vocabulary import CLASS_LETTERS, REGIME_MEANING, STICKING_KINDS

MAX_PERIOD = 32
PERIOD_TOL = 1e-6
LYAP_CHAOS = 1e-3
#: Regime letters in the order of the codes :func:`classify_batch` returns.
REGIME_LETTERS = CLASS_LETTERS
REGIMES = {g: REGIME_MEANING[g] for g in REGIME_LETTERS}


@dataclasses.dataclass(frozen=True)
class Classification:
    """What a recorded window of motion is. See the module docstring for each definition."""

    regime: str
    period: int
    active_per_period: float
    reverse_per_period: float
    stick_fraction: float
    lyapunov: float
    chaotic: bool
    intensity: float
    mean_impulse_active: float
    rms_impulse_active: float
    mean_impulse_reverse: float
    rms_impulse_reverse: float
    sticking: str = ""
    loop_amplification: float = -math.inf
    noisy: bool = False

    @property
    def impacts_per_period(self) -> float:
        return self.active_per_period + self.reverse_per_period

    @property
    def label(self) -> str:
        """One line for people, e.g. ``"E: period 1, 1 active + 1 reverse impact/period"``."""
        parts = [f"{self.regime}: {REGIMES[self.regime]}"]
        if self.period:
            parts.append(f"period {self.period}")
        parts.append(f"{self.active_per_period:.3g} active + {self.reverse_per_period:.3g} reverse "
                     "impacts/period")
        if self.stick_fraction > 0:
            parts.append(f"sticking {100 * self.stick_fraction:.3g}% of the time")
        if self.sticking == "stick-locked" and math.isfinite(self.loop_amplification):
            parts.append(f"stick-locked, loop amplification 10^{self.loop_amplification:.1f}")
        elif self.sticking == "chaos-through-sticking":
            parts.append("chaos through sticking, statistics at this noise level" if self.noisy else
                         "loop chosen by rounding (noise off): not resolvable in double precision")
        if not math.isnan(self.lyapunov):
            parts.append(f"λ = {self.lyapunov:.3g}")
        return ", ".join(parts)

    def as_dict(self) -> dict:
        d = dataclasses.asdict(self)
        d["impacts_per_period"] = self.impacts_per_period
        return d


def detect_period(sx: np.ndarray, sv: np.ndarray, scale: float = 1.0,
                  max_period: int = MAX_PERIOD, tol: float = PERIOD_TOL) -> int:
    """Smallest n ≤ max_period such that the last half of the section repeats every n samples
    (to ``tol × (1 + scale)`` in x and ẋ); 0 when none does or a sample is NaN."""
    return int(_detect_period_nb(np.ascontiguousarray(sx, dtype=np.float64),
                                 np.ascontiguousarray(sv, dtype=np.float64), float(scale),
                                 int(max_period), float(tol)))


def classify_arrays(impulse: np.ndarray, flank: np.ndarray, strobe_x: np.ndarray,
                    strobe_v: np.ndarray, periods: float, stick_time: float,
                    lyapunov: float, j: float, rounding: bool = False,
                    loop_amplification: float = -math.inf, kicks: int = 0) -> Classification:
    """Classify a window from its impacts, section samples, stick time and exponent
    (:func:`classify_batch` with one window: the rules live in one place)."""
    impulse = np.asarray(impulse, dtype=np.float64).ravel()
    c = classify_batch(np.array([len(impulse)]), impulse, np.asarray(flank).ravel(),
                       np.asarray(strobe_x, dtype=np.float64).reshape(1, -1),
                       np.asarray(strobe_v, dtype=np.float64).reshape(1, -1), periods,
                       np.array([stick_time]), np.array([lyapunov]), np.array([j]),
                       np.array([rounding]), np.array([loop_amplification]), np.array([kicks]))
    return Classification(
        regime=REGIME_LETTERS[c["regime"][0]], period=int(c["period"][0]),
        chaotic=bool(c["chaotic"][0]), sticking=STICKING_KINDS[c["sticking"][0]],
        loop_amplification=float(c["loop_amplification"][0]), noisy=bool(c["noisy"][0]),
        **{k: float(c[k][0]) for k in ("active_per_period", "reverse_per_period", "stick_fraction",
                                       "lyapunov", "intensity", "mean_impulse_active",
                                       "rms_impulse_active", "mean_impulse_reverse",
                                       "rms_impulse_reverse")})


@njit(cache=True, nogil=True)
def _block_sum(a, lo, n):
    if n < 8:
        res = 0.0
        for i in range(lo, lo + n):
            res += a[i]
        return res
    r0 = a[lo]
    r1 = a[lo + 1]
    r2 = a[lo + 2]
    r3 = a[lo + 3]
    r4 = a[lo + 4]
    r5 = a[lo + 5]
    r6 = a[lo + 6]
    r7 = a[lo + 7]
    m = n - n % 8
    for i in range(lo + 8, lo + m, 8):
        r0 += a[i]
        r1 += a[i + 1]
        r2 += a[i + 2]
        r3 += a[i + 3]
        r4 += a[i + 4]
        r5 += a[i + 5]
        r6 += a[i + 6]
        r7 += a[i + 7]
    res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    for i in range(lo + m, lo + n):
        res += a[i]
    return res


@njit(cache=True, nogil=True)
def _pairwise_sum(a, lo, n):
    """``np.sum(a[lo:lo + n])`` with numpy's own pairwise summation, bit for bit.

    numpy adds runs of up to 128 values in eight interleaved partial sums and splits longer
    runs in two (the first part a multiple of 8, about half), adding the halves' sums;
    following that order gives the numbers of the numpy expressions of the definitions.
    The split is walked with explicit stacks: numba cannot cache recursive functions.
    """
    if n <= 128:
        return 0.0 + _block_sum(a, lo, n)
    # a task is (start, length) to sum, or length −1: add the last two sums
    t_lo = np.empty(192, np.int64)
    t_n = np.empty(192, np.int64)
    sums = np.empty(96)
    nt = 1
    ns = 0
    t_lo[0] = lo
    t_n[0] = n
    while nt > 0:
        nt -= 1
        s0 = t_lo[nt]
        m = t_n[nt]
        if m < 0:
            ns -= 1
            sums[ns - 1] = sums[ns - 1] + sums[ns]
        elif m <= 128:
            sums[ns] = _block_sum(a, s0, m)
            ns += 1
        else:
            m2 = m // 2
            m2 -= m2 % 8
            t_n[nt] = -1
            t_lo[nt + 1] = s0 + m2
            t_n[nt + 1] = m - m2
            t_lo[nt + 2] = s0
            t_n[nt + 2] = m2
            nt += 3
    return 0.0 + sums[0]


@njit(cache=True, nogil=True)
def _detect_period_nb(sx, sv, scale, max_period, tol):
    m = sx.shape[0]
    if m < 4:
        return 0
    start = m // 2
    thr = tol * (1.0 + scale)
    top = min(max_period, m - start - 1)
    for n in range(1, top + 1):
        ok = True
        for k in range(start, m - n):
            # written as "not <=" so that a NaN fails, as it does in np.max(...) <= thr
            if not abs(sx[k + n] - sx[k]) <= thr or not abs(sv[k + n] - sv[k]) <= thr:
                ok = False
                break
        if ok:
            return n
    return 0


@njit(cache=True, nogil=True)
def _flank_stats(impulse, flank, lo, c, side, buf):
    """Count, mean |Ĩ| and RMS |Ĩ| of one flank's impacts, summed as numpy sums them."""
    k = 0
    for i in range(lo, lo + c):
        if flank[i] == side:
            buf[k] = abs(impulse[i])
            k += 1
    if k == 0:
        return 0, 0.0, 0.0
    mean = _pairwise_sum(buf, 0, k) / k
    for i in range(k):
        buf[i] = buf[i] * buf[i]
    rms = np.sqrt(_pairwise_sum(buf, 0, k) / k)
    return k, mean, rms


@njit(cache=True, nogil=True)
def _classify_kernel(counts, impulse, flank, str_x, str_v, periods, stick, lyap, j,
                     max_period, tol, chaos, regime, period, n_act, n_rev, a_pp, r_pp, stick_f,
                     chaotic, intensity, mean_a, rms_a, mean_r, rms_r):
    periods = max(periods, 1e-300)
    cmax = 0
    for i in range(counts.shape[0]):
        cmax = max(cmax, counts[i])
    buf = np.empty(cmax)
    off = 0
    for i in range(counts.shape[0]):
        c = counts[i]
        na, mean_a[i], rms_a[i] = _flank_stats(impulse, flank, off, c, 1, buf)
        nr, mean_r[i], rms_r[i] = _flank_stats(impulse, flank, off, c, -1, buf)
        for k in range(c):
            buf[k] = impulse[off + k] * impulse[off + k]
        intensity[i] = _pairwise_sum(buf, 0, c) / periods
        off += c
        sf = stick[i] / (periods * TWO_PI)
        sf = sf if sf < 1.0 else 1.0
        per = _detect_period_nb(str_x[i], str_v[i], j[i], max_period, tol)
        ch = per == 0 and lyap[i] > chaos
        ap = na / periods
        rp = nr / periods
        if na + nr == 0 and sf > 0.99:
            code = 0
        elif ch:
            code = 3
        elif sf > 0:
            code = 1
        elif per == 1 and nr == 0 and abs(ap - 1) < 0.02:
            code = 2
        elif per == 1 and abs(ap - 1) < 0.02 and abs(rp - 1) < 0.02:
            code = 4
        elif per > 0:
            code = 5
        else:
            code = 6
        regime[i] = code
        period[i] = per
        n_act[i] = na
        n_rev[i] = nr
        a_pp[i] = ap
        r_pp[i] = rp
        stick_f[i] = sf
        chaotic[i] = ch


def classify_batch(counts: np.ndarray, impulse: np.ndarray, flank: np.ndarray,
                   strobe_x: np.ndarray, strobe_v: np.ndarray, periods: float,
                   stick_time: np.ndarray, lyapunov: np.ndarray, j: np.ndarray,
                   rounding: np.ndarray | None = None, loop_amplification: np.ndarray | None = None,
                   kicks: np.ndarray | None = None, period_tol: float = PERIOD_TOL) -> dict:
    """Classify many windows at once; the same numbers as :func:`classify_arrays` for each.

    ``impulse`` and ``flank`` hold the impacts of all windows one after the other
    (``counts[i]`` of them for window i); ``strobe_x``/``strobe_v`` have one row per window;
    ``stick_time``, ``lyapunov``, ``j`` and the optional ``rounding`` (a capture decided by
    rounding), ``loop_amplification`` (log10) and ``kicks`` (release kicks applied) one value
    per window; ``periods`` is common.  ``period_tol`` replaces ``PERIOD_TOL`` (ensembles
    recognise an orbit blurred by a larger noise level with it).

    Returns a dict of arrays: ``regime`` (codes into :data:`REGIME_LETTERS`), ``period``,
    ``n_active``, ``n_reverse``, ``sticking`` (codes into :data:`STICKING_KINDS`) and every
    other field of :class:`Classification`.
    """
    counts = np.ascontiguousarray(counts, dtype=np.int64)
    nv = counts.shape[0]
    if counts.sum() != len(impulse) or len(flank) != len(impulse):
        raise ValueError(f"counts sum to {counts.sum()}, but there are {len(impulse)} impulses "
                         f"and {len(flank)} flanks")
    out = {"regime": np.empty(nv, np.int8), "period": np.empty(nv, np.int64),
           "n_active": np.empty(nv, np.int64), "n_reverse": np.empty(nv, np.int64),
           "active_per_period": np.empty(nv), "reverse_per_period": np.empty(nv),
           "stick_fraction": np.empty(nv), "chaotic": np.empty(nv, np.bool_),
           "intensity": np.empty(nv), "mean_impulse_active": np.empty(nv),
           "rms_impulse_active": np.empty(nv), "mean_impulse_reverse": np.empty(nv),
           "rms_impulse_reverse": np.empty(nv)}
    lyap = np.ascontiguousarray(lyapunov, dtype=np.float64).reshape(nv)
    _classify_kernel(counts, np.ascontiguousarray(impulse, dtype=np.float64),
                     np.ascontiguousarray(flank, dtype=np.int8),
                     np.ascontiguousarray(strobe_x, dtype=np.float64).reshape(nv, -1),
                     np.ascontiguousarray(strobe_v, dtype=np.float64).reshape(nv, -1),
                     float(periods), np.ascontiguousarray(stick_time, dtype=np.float64).reshape(nv),
                     lyap, np.ascontiguousarray(j, dtype=np.float64).reshape(nv),
                     MAX_PERIOD, float(period_tol), LYAP_CHAOS, out["regime"], out["period"],
                     out["n_active"], out["n_reverse"], out["active_per_period"],
                     out["reverse_per_period"], out["stick_fraction"], out["chaotic"],
                     out["intensity"], out["mean_impulse_active"], out["rms_impulse_active"],
                     out["mean_impulse_reverse"], out["rms_impulse_reverse"])
    out["lyapunov"] = lyap.copy()
    rnd = np.zeros(nv, np.bool_) if rounding is None else np.asarray(rounding, np.bool_).reshape(nv)
    out["sticking"] = np.where(out["stick_fraction"] > 0, np.where(rnd, 2, 1), 0).astype(np.int8)
    out["loop_amplification"] = (np.full(nv, -np.inf) if loop_amplification is None else
                                 np.asarray(loop_amplification, np.float64).reshape(nv).copy())
    out["noisy"] = (np.zeros(nv, np.bool_) if kicks is None else
                    np.asarray(kicks).reshape(nv) > 0)
    return out


def classify(tr) -> Classification:
    """Classify a :class:`~rattle_core.solver.trajectory.Trajectory` (simulate it with
    ``lyapunov=True`` for the exponent; otherwise it is NaN and chaos cannot be flagged)."""
    return classify_arrays(tr.impact_impulse, tr.impact_flank, tr.strobe_x, tr.strobe_v,
                           tr.periods, tr.stick_time, tr.lyapunov, tr.params.j,
                           tr.rounding_decided, tr.loop_amplification, tr.noise_kicks)
