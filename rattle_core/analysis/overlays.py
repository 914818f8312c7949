"""Analytic overlays: closed-form curves drawn over simulated results, and checked against them.

* the permanent-contact boundary ``Λ_c = 1 / max_t(−ÿ)`` (regime A below it);
* the one-sided period-n orbits (impulse ``2πn/Λ``) and their stability from the impact-map
  Jacobian (determinant ``r²``, trace ``1 + r² + (1 + r)² Λ ÿ(θ*)``);
* for harmonic excitation, the closed-form existence and period-doubling limits of regime C.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..model.excitation import TWO_PI, excitation
from ..model.params import RattleParams


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
