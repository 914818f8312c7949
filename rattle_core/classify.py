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
* **rattle intensity**: ``Σ Ĩ² / P``, the impulse energy per forcing period; mean and RMS
  ``|Ĩ|`` per flank.
* **regime** (paper §4), first match wins: ``A`` permanent contact (no impact, stuck the
  whole window); ``D`` chaotic; ``B`` impacts followed by permanent contact (some sticking,
  some impacts); ``C`` period 1,
  one active-flank impact per period, none on the reverse; ``D`` chaotic; ``E`` period 1, one
  impact on each flank per period.  Other responses are ``P`` (another periodic response,
  described by :attr:`Classification.label`) or ``Q`` (non-repeating without a positive
  exponent: quasi-periodic or a long transient).

Analytic overlays: the permanent-contact boundary ``Λ_c = 1 / max_t(−ÿ)``, the one-sided
period-n orbits (impulse ``2πn/Λ``) and their stability from the impact-map Jacobian
(determinant ``r²``, trace ``1 + r² + (1 + r)² Λ ÿ(θ*)``).
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from .excitation import TWO_PI, excitation
from .params import RattleParams

MAX_PERIOD = 32
PERIOD_TOL = 1e-6
LYAP_CHAOS = 1e-3
REGIMES = {
    "A": "permanent contact",
    "B": "impacts followed by permanent contact",
    "C": "one active-flank impact per period",
    "D": "chaotic",
    "E": "two impacts per period, one on each flank",
    "P": "periodic",
    "Q": "non-repeating, no positive exponent",
}


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
            parts.append(f"sticking {100 * self.stick_fraction:.2g}% of the time")
        if not math.isnan(self.lyapunov):
            parts.append(f"λ = {self.lyapunov:.3g}")
        return ", ".join(parts)

    def as_dict(self) -> dict:
        d = dataclasses.asdict(self)
        d["impacts_per_period"] = self.impacts_per_period
        return d


def detect_period(sx: np.ndarray, sv: np.ndarray, scale: float = 1.0,
                  max_period: int = MAX_PERIOD, tol: float = PERIOD_TOL) -> int:
    """Smallest n ≤ max_period such that the last half of the section repeats every n samples."""
    m = len(sx)
    if m < 4:
        return 0
    start = m // 2
    thr = tol * (1.0 + scale)
    for n in range(1, min(max_period, m - start - 1) + 1):
        a = slice(start, m - n)
        b = slice(start + n, m)
        if (np.max(np.abs(sx[b] - sx[a])) <= thr) and (np.max(np.abs(sv[b] - sv[a])) <= thr):
            return n
    return 0


def classify_arrays(impulse: np.ndarray, flank: np.ndarray, strobe_x: np.ndarray,
                    strobe_v: np.ndarray, periods: float, stick_time: float,
                    lyapunov: float, j: float) -> Classification:
    """Classify a window from its impacts, section samples, stick time and exponent."""
    periods = max(float(periods), 1e-300)
    act = flank == 1
    rev = flank == -1
    n_act = int(act.sum())
    n_rev = int(rev.sum())
    stick_fraction = min(1.0, stick_time / (periods * TWO_PI))
    period = detect_period(strobe_x, strobe_v, j)
    chaotic = period == 0 and lyapunov > LYAP_CHAOS
    a_pp = n_act / periods
    r_pp = n_rev / periods

    def stats(sel):
        if not sel.any():
            return 0.0, 0.0
        a = np.abs(impulse[sel])
        return float(a.mean()), float(np.sqrt(np.mean(a * a)))

    ma, ra = stats(act)
    mr, rr = stats(rev)
    if n_act + n_rev == 0 and stick_fraction > 0.99:
        regime = "A"
    elif chaotic:
        regime = "D"
    elif stick_fraction > 0:
        regime = "B"
    elif period == 1 and n_rev == 0 and round(a_pp) == 1 and abs(a_pp - 1) < 0.02:
        regime = "C"
    elif period == 1 and abs(a_pp - 1) < 0.02 and abs(r_pp - 1) < 0.02:
        regime = "E"
    elif period > 0:
        regime = "P"
    else:
        regime = "Q"
    return Classification(regime=regime, period=period, active_per_period=a_pp,
                          reverse_per_period=r_pp, stick_fraction=stick_fraction,
                          lyapunov=float(lyapunov), chaotic=bool(chaotic),
                          intensity=float(np.sum(impulse * impulse) / periods),
                          mean_impulse_active=ma, rms_impulse_active=ra,
                          mean_impulse_reverse=mr, rms_impulse_reverse=rr)


def classify(tr) -> Classification:
    """Classify a :class:`~rattle_core.trajectory.Trajectory` (simulate it with ``lyapunov=True``
    for the exponent; otherwise it is NaN and chaos cannot be flagged)."""
    return classify_arrays(tr.impact_impulse, tr.impact_flank, tr.strobe_x, tr.strobe_v,
                           tr.periods, tr.stick_time, tr.lyapunov, tr.params.j)


# ----- analytic overlays --------------------------------------------------------------------

def _max_neg_ydd(params: RattleParams, grid: int = 4096) -> float:
    from scipy.optimize import brentq  # lazily: scipy.optimize costs ~0.5 s at start-up
    t = np.linspace(0.0, TWO_PI, grid, endpoint=False)
    f = -excitation(t, params.h, params.phi, 2)
    best = -np.inf
    for i in np.argsort(f)[-8:]:
        lo, hi = t[i] - TWO_PI / grid, t[i] + TWO_PI / grid

        def d3(s):
            return -excitation(s, params.h, params.phi, 3)
        a, b = d3(lo), d3(hi)
        s = brentq(d3, lo, hi, xtol=1e-15) if a * b < 0 else t[i]
        best = max(best, float(-excitation(s, params.h, params.phi, 2)))
    return best


def contact_boundary(params: RattleParams) -> float:
    """Permanent-contact boundary ``Λ_c = 1 / max_t(−ÿ(t))``.

    For ``Λ < Λ_c`` the reaction ``R̃ = 1 + Λ ÿ`` stays positive, so a gear resting on the
    active flank never leaves it (regime A).
    """
    return 1.0 / _max_neg_ydd(params)


def one_sided_impulse(lam, n: int = 1):
    """Impulse of the period-n one-sided orbit (flight 2πn, symmetric parabola): ``2πn/Λ``."""
    return TWO_PI * n / np.asarray(lam, dtype=float)


@dataclasses.dataclass(frozen=True)
class OneSidedOrbit:
    """A period-n orbit with one active-flank impact per n periods."""

    theta: float
    impulse: float
    trace: float
    det: float
    stable: bool
    fits: bool


def one_sided_orbits(params: RattleParams, n: int = 1) -> list[OneSidedOrbit]:
    """All period-n one-sided orbits: impact phases θ with ``ẏ(θ) = (1 − r) π n / ((1 + r) Λ)``.

    Stability from the impact-map Jacobian: ``det = r²``, ``trace = 1 + r² + (1+r)² Λ ÿ(θ)``;
    stable when ``|trace| < 1 + det``.  ``fits`` says whether the flight stays inside the backlash
    without touching either wall in between (checked on a fine grid).
    """
    from scipy.optimize import brentq
    p = params
    lam, r = p.lam, p.r
    target = (1 - r) * math.pi * n / ((1 + r) * lam)
    t = np.linspace(0.0, TWO_PI, 2049)
    f = excitation(t, p.h, p.phi, 1) - target
    out = []
    for i in np.nonzero(np.sign(f[:-1]) * np.sign(f[1:]) <= 0)[0]:
        if f[i] == 0 and i > 0 and f[i - 1] == 0:
            continue
        th = brentq(lambda s: float(excitation(s, p.h, p.phi, 1)) - target, t[i], t[i + 1], xtol=1e-15) \
            if f[i] * f[i + 1] < 0 else t[i]
        ydd = float(excitation(th, p.h, p.phi, 2))
        tr_ = 1 + r * r + (1 + r) ** 2 * lam * ydd
        det = r * r
        s = np.linspace(0, TWO_PI * n, 4000)[1:-1]
        y0 = float(excitation(th, p.h, p.phi))
        x = y0 + (math.pi * n / lam) * s - s * s / (2 * lam)
        y = excitation(th + s, p.h, p.phi)
        fits = bool(np.all(x > y) and np.all(x < y + p.j))
        out.append(OneSidedOrbit(theta=float(th % TWO_PI), impulse=TWO_PI * n / lam, trace=tr_,
                                 det=det, stable=abs(tr_) < 1 + det, fits=fits))
    return out


def period1_limits_harmonic(r: float) -> tuple[float, float]:
    """Closed-form existence and period-doubling limits of the stable period-1 orbit, K = 1.

    Exists when ``(1−r)π/((1+r)Λ) ≤ 1``; on the stable branch ``cos θ > 0`` the trace condition
    ``trace > −(1 + r²)`` gives ``Λ cos θ < 2(1 + r²)/(1 + r)²``.
    """
    a = (1 - r) * math.pi / (1 + r)
    b = 2 * (1 + r * r) / (1 + r) ** 2
    return a, math.sqrt(a * a + b * b)
