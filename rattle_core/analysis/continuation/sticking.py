"""Orbits that stick: computed exactly from a release, and what must hold along their branch.

A release happens at a phase that depends on the parameters only, so the motion after it is the
same whatever came before: from a release, the simulator runs until a release repeats.  The
chatter before each stick phase counts as one element of the impact pattern.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from ...model.excitation import TWO_PI
from ...model.params import RattleParams
from ...solver.trajectory import simulate
from .admissibility import _gap_minima
from .orbits import MAX_ORBIT_PERIOD, ContinuationError, PeriodicOrbit, _arrays
from .parameter import _Param


def _simulate_strict(params: RattleParams, **kw):
    """``simulate`` of the strict model (no noise): periodic orbits are exact, so they need the
    deterministic solver, whatever the parameters' noise level.  The trajectory keeps the
    caller's parameters, so the orbits built from it carry them."""
    return dataclasses.replace(simulate(params.replace(noise=0.0), **kw), params=params)


def _releases(tr) -> list[tuple[float, int, float, float]]:
    """Stick phases of a trajectory: ``(release time, flank, stick start, w at the capture)``."""
    out = []
    lam = tr.params.lam
    from ...model.excitation import excitation
    for k in range(len(tr.seg_t) - 1):
        kind = int(tr.seg_kind[k])
        if kind == 0:
            continue
        ts = float(tr.seg_t[k])
        w = 0.0
        if k > 0 and tr.seg_kind[k - 1] == 0:
            s = ts - float(tr.seg_t[k - 1])
            w = float(tr.seg_v[k - 1]) - s / lam - float(excitation(ts, tr.params.h, tr.params.phi, 1))
        out.append((float(tr.seg_t[k + 1]), kind, ts, w))
    return out


def _same_phase(a: float, b: float, tol: float = 1e-9) -> bool:
    d = (a - b) % TWO_PI
    return min(d, TWO_PI - d) < tol


def stick_orbit(params: RattleParams, t_release: float, flank: int,
                max_period: int = MAX_ORBIT_PERIOD) -> PeriodicOrbit:
    """The periodic orbit through a release from a stick phase, computed exactly.

    From the release at ``t_release`` on ``flank`` (position on the wall, ``ẋ = ẏ``) the solver
    runs until the releases repeat (same phase, same flank): a release depends only on the
    phase, so the motion from then on is periodic, and superstable (multipliers 0).

    Raises
    ------
    ContinuationError
        When the releases do not repeat within ``max_period`` forcing periods.
    """
    from ...model.excitation import excitation
    p = params
    t_release = float(t_release)
    off = p.j if flank == -1 else 0.0
    x0 = float(excitation(t_release, p.h, p.phi)) + off
    v0 = float(excitation(t_release, p.h, p.phi, 1))
    tr = _simulate_strict(p, periods=2 * max_period + 1, t0=t_release, x0=x0, v0=v0)
    rel = [(t_release, int(flank), math.nan, 0.0)] + _releases(tr)
    for b in range(1, len(rel)):
        for a in range(b):
            if rel[a][1] == rel[b][1] and _same_phase(rel[a][0], rel[b][0]):
                n = int(round((rel[b][0] - rel[a][0]) / TWO_PI))
                if n < 1:
                    continue
                return _stick_from(tr, rel[a:b + 1], n)
    raise ContinuationError(f"no release repeats within {2 * max_period + 1} periods from "
                            f"t = {t_release:.10g} on flank {flank:+d} at {params}")


def _stick_from(tr, rel, n: int) -> PeriodicOrbit:
    """The stick orbit between two equal releases ``rel[0]`` and ``rel[-1]`` of ``tr``."""
    p = tr.params
    t0, t1 = rel[0][0], rel[-1][0]
    sel = (tr.impact_t >= t0) & (tr.impact_t < t1)
    t = tr.impact_t[sel]
    flank = tr.impact_flank[sel].astype(np.int8)
    w = tr.impact_w[sel]
    from ...model.excitation import excitation
    u = excitation(t, p.h, p.phi, 1) - p.r * w
    stick = np.array([(f, ts, tre) for tre, f, ts, wc in rel[1:]],
                     dtype=np.float64).reshape(-1, 3)
    shift = math.floor(t0 / TWO_PI) * TWO_PI
    t = t - shift
    stick[:, 1:] -= shift
    # the gap test: smallest interior minimum over the flights between events
    gmin, where = math.inf, (-1, math.nan, 0)
    lam, r, j, h, phi = _arrays(p)
    cphi, sphi = np.cos(phi), np.sin(phi)
    seg_t, seg_k, seg_x, seg_v = tr.seg_t, tr.seg_kind, tr.seg_x, tr.seg_v
    ys = excitation(seg_t, p.h, p.phi)
    yds = excitation(seg_t, p.h, p.phi, 1)
    for k in range(len(seg_t) - 1):
        if seg_k[k] != 0 or seg_t[k] < t0 - 1e-12 or seg_t[k] >= t1:
            continue
        leave = 0
        if abs(seg_v[k] - yds[k]) < 1e-9:
            # leaving a wall at rest: after a release, or a plastic contact that pulls away
            leave = 1 if abs(seg_x[k] - ys[k]) < abs(seg_x[k] - ys[k] - p.j) else -1
        g, s, wall = _gap_minima(float(seg_t[k]), float(seg_x[k]), float(seg_v[k]),
                                 float(seg_t[k + 1] - seg_t[k]), lam, j, h, cphi, sphi, leave)
        if g < gmin:
            gmin, where = g, (k, float(seg_t[k] + s - shift), int(wall))
    return PeriodicOrbit(params=p, period=n, t=t, u=u, flank=flank, w=w.copy(), stick=stick,
                         monodromy=np.zeros((2, 2)), multipliers=np.zeros(2, complex),
                         residual=0.0, reason="", gap_min=float(gmin), gap_where=where)


def _release_roots(params: RattleParams, flank: int) -> np.ndarray:
    """Phases in [0, 2π) where the reaction ``σ(1 + Λÿ)`` falls through zero: the releases."""
    from scipy.optimize import brentq

    from ...model.excitation import excitation
    p = params
    t = np.linspace(0.0, TWO_PI, 4097)
    f = flank * (1.0 + p.lam * excitation(t, p.h, p.phi, 2))
    out = []
    for i in np.nonzero((f[:-1] > 0) & (f[1:] <= 0))[0]:
        if f[i + 1] == 0.0:
            out.append(t[i + 1])
            continue
        out.append(brentq(lambda s: flank * (1.0 + p.lam * float(excitation(s, p.h, p.phi, 2))),
                          t[i], t[i + 1], xtol=1e-15, rtol=1e-15))
    return np.mod(np.array(out), TWO_PI)


def _stick_at(spec: _Param, q: float, handle: tuple[float, int]) -> PeriodicOrbit | None:
    """The stick orbit at ``q`` through the release nearest to ``handle = (phase, flank)``."""
    try:
        params = spec.params(q)
    except ValueError:
        return None
    roots = _release_roots(params, handle[1])
    if not len(roots):
        return None
    d = np.abs((roots - handle[0] + math.pi) % TWO_PI - math.pi)
    k = int(np.argmin(d))
    if d[k] > 0.2:
        return None
    try:
        return stick_orbit(params, float(roots[k]), handle[1])
    except ContinuationError:
        return None


def _handle(orb: PeriodicOrbit) -> tuple[float, int]:
    f, _, tr = orb.stick[-1]
    return float(tr % TWO_PI), int(f)


def _w_min(orb: PeriodicOrbit) -> float:
    """Slowest impact, signed: negative when an impact points out of its wall."""
    if orb.n_impacts == 0:
        return math.inf
    if orb.kind == "stick":
        keep = ~_tail_mask(orb)
        if not np.any(keep):
            return math.inf
        return float(np.min(-orb.flank[keep] * orb.w[keep]))
    return float(np.min(-orb.flank * orb.w))


def _tail_mask(orb: PeriodicOrbit) -> np.ndarray:
    """Impacts of the chatter before each stick phase: the run of ever slower impacts on the
    sticking flank that ends in it (how many the solver resolves depends on ``v_stick``)."""
    mask = np.zeros(orb.n_impacts, dtype=bool)
    T = TWO_PI * orb.period
    for f, ts, _ in orb.stick:
        before = np.nonzero(orb.t <= ts + 1e-12)[0]
        if not len(before):
            before = np.nonzero(orb.t - T <= ts)[0]
        k = before[-1] if len(before) else -1
        prev = 0.0
        while k >= 0 and orb.flank[k] == f and abs(orb.w[k]) > prev and not mask[k]:
            mask[k] = True
            prev = abs(orb.w[k])
            k -= 1
    return mask


def _signature(orb: PeriodicOrbit) -> tuple:
    """What must stay the same along a branch: period, flanks of the impacts (the chatter
    tails of stick phases counted as one), stick flanks."""
    if orb.kind == "impact":
        return ("impact", orb.period, tuple(int(f) for f in orb.flank))
    tail = _tail_mask(orb)
    return ("stick", orb.period, tuple(int(f) for f in orb.flank[~tail]),
            tuple(int(f) for f in orb.stick[:, 0]))


def _stick_margin(orb: PeriodicOrbit) -> float:
    if not len(orb.stick):
        return math.inf
    return float(np.min(orb.stick[:, 2] - orb.stick[:, 1]))
