"""Periodic orbits: the :class:`PeriodicOrbit` record and the orbits found by Newton's method.

:func:`solve_orbit` polishes a guess of the impacts to machine precision and checks the result
against the simulator; :func:`c_orbit` starts from the one-sided orbit in closed form.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from ...model.excitation import TWO_PI
from ...model.params import RattleParams, check_int, check_range
from .admissibility import _REASONS, _inspect
from .parameter import _KIND_LAM
from .shooting import NEWTON_TOL, _newton, _scaled_norm, _system
from .stability import _maps

#: Most impacts one orbit may have (over its whole period).
MAX_ORBIT_IMPACTS = 512
#: Longest period (in forcing periods) of an orbit that :func:`find_orbit` looks for.
MAX_ORBIT_PERIOD = 32


class ContinuationError(RuntimeError):
    """No orbit could be found or continued (Newton failed, the orbit is not periodic, ...)."""


@dataclasses.dataclass(frozen=True, eq=False)
class PeriodicOrbit:
    """A periodic orbit of the rattle model, exact to rounding.

    Attributes
    ----------
    params : RattleParams
    period : int
        Period in forcing periods (each 2π long).
    t : ndarray
        Impact times over one period, increasing (``t[0]`` in ``[0, 2π)`` for a new orbit; along
        a branch each impact keeps its place in the list, so ``t[0]`` may drift out of it).
    u : ndarray
        Absolute velocity just after each impact, ``ẋ⁺ = ẏ − r w``.
    flank : ndarray of int8
        +1 active flank, −1 reverse flank.
    w : ndarray
        Incoming relative velocity ``w = ẋ⁻ − ẏ`` of each impact.
    stick : ndarray, shape (k, 3)
        Stick phases: flank, start time, release time (empty for an impact orbit).  The start
        is where the solver ends the chatter (the first contact slower than ``v_stick``).
    monodromy : ndarray, shape (2, 2)
        Jacobian of the stroboscopic map over one period, in ``(x, ẋ)``, at the time just after
        the first impact (zero for an orbit that sticks).
    multipliers : ndarray of complex
        Its eigenvalues, the Floquet multipliers, largest modulus first.
    residual : float
        Largest scaled residual of the shooting equations (0 for an orbit that sticks, which
        is computed by direct simulation).
    reason : str
        Empty when the orbit is an orbit of the simulator; otherwise why not (e.g. a flight
        that meets a wall before its next impact: the orbit exists only as a solution of the
        equations).
    gap_min : float
        Smallest interior minimum of a flight's gap to a wall (``inf`` if none): the grazing
        test function.
    """

    params: RattleParams
    period: int
    t: np.ndarray
    u: np.ndarray
    flank: np.ndarray
    w: np.ndarray
    stick: np.ndarray
    monodromy: np.ndarray
    multipliers: np.ndarray
    residual: float
    reason: str
    gap_min: float
    gap_where: tuple = (-1, math.nan, 0)

    @property
    def kind(self) -> str:
        """``"impact"`` (impacts only, found by Newton) or ``"stick"`` (has a stick phase)."""
        return "stick" if len(self.stick) else "impact"

    @property
    def admissible(self) -> bool:
        return self.reason == ""

    @property
    def impulse(self) -> np.ndarray:
        """Signed impulse of each impact, ``Ĩ = −(1 + r) w``."""
        return -(1.0 + self.params.r) * self.w

    @property
    def phase(self) -> np.ndarray:
        """Impact phases ``t mod 2π``."""
        return np.mod(self.t, TWO_PI)

    @property
    def n_impacts(self) -> int:
        return len(self.t)

    @property
    def stable(self) -> bool:
        """All multipliers inside the unit circle (orbits that stick are superstable)."""
        return bool(np.max(np.abs(self.multipliers)) < 1.0)

    @property
    def stick_time(self) -> float:
        """Total time stuck per period."""
        return float(np.sum(self.stick[:, 2] - self.stick[:, 1])) if len(self.stick) else 0.0

    def state_at(self, t) -> tuple[np.ndarray, np.ndarray]:
        """Exact position and velocity on the orbit at times ``t`` (any, the orbit is periodic)."""
        p = self.params
        t = np.asarray(t, dtype=np.float64)
        shape = t.shape
        t = np.atleast_1d(t)
        T = TWO_PI * self.period
        ev_t, ev_k, ev_x, ev_v = self._events()
        tt = ev_t[0] + np.mod(t - ev_t[0], T)
        idx = np.clip(np.searchsorted(ev_t, tt, side="right") - 1, 0, len(ev_t) - 1)
        s = tt - ev_t[idx]
        x = ev_x[idx] + ev_v[idx] * s - 0.5 * s * s / p.lam
        v = ev_v[idx] - s / p.lam
        kind = ev_k[idx]
        stuck = kind != 0
        if np.any(stuck):
            from ...model.excitation import excitation
            x[stuck] = excitation(tt[stuck], p.h, p.phi) + np.where(kind[stuck] == -1, p.j, 0.0)
            v[stuck] = excitation(tt[stuck], p.h, p.phi, 1)
        return x.reshape(shape), v.reshape(shape)

    def _events(self):
        """Segments over one period: start time, kind (0 flight, ±1 stuck), state at start."""
        from ...model.excitation import excitation
        p = self.params
        y = excitation(self.t, p.h, p.phi)
        ev = [(float(ti), 0, float(yi + (p.j if f == -1 else 0.0)), float(ui))
              for ti, yi, f, ui in zip(self.t, y, self.flank, self.u)]
        for f, ts, tr in self.stick:
            ys = float(excitation(ts, p.h, p.phi))
            yr = float(excitation(tr, p.h, p.phi))
            vs = float(excitation(ts, p.h, p.phi, 1))
            vr = float(excitation(tr, p.h, p.phi, 1))
            off = p.j if f == -1 else 0.0
            ev.append((float(ts), int(f), ys + off, vs))
            ev.append((float(tr), 0, yr + off, vr))
        ev.sort(key=lambda e: e[0])
        t0 = ev[0][0]
        ev.append((t0 + TWO_PI * self.period,) + ev[0][1:])
        a = np.array([e[0] for e in ev]), np.array([e[1] for e in ev], dtype=np.int8), \
            np.array([e[2] for e in ev]), np.array([e[3] for e in ev])
        return a

    def summary(self) -> str:
        """One line: period, impacts per flank, stability."""
        na = int(np.sum(self.flank == 1))
        nr = int(np.sum(self.flank == -1))
        mu = ", ".join(f"{m:.4g}" for m in self.multipliers)
        extra = f", stuck {self.stick_time:.4g} per period" if len(self.stick) else ""
        return (f"period {self.period}, {na} active + {nr} reverse impacts{extra}, "
                f"{'stable' if self.stable else 'unstable'} (multipliers {mu})")


def _arrays(params: RattleParams):
    return (float(params.lam), float(params.r), float(params.j),
            np.ascontiguousarray(params.h), np.ascontiguousarray(params.phi))


def _normalise(t: np.ndarray, u: np.ndarray, fl: np.ndarray, n: int):
    """Rotate the impact list so that it starts with the first impact of [0, 2π)."""
    T = TWO_PI * n
    t = np.asarray(t, dtype=np.float64)
    k = np.floor(t[0] / TWO_PI)
    t = t - k * TWO_PI
    # one period [t0, t0 + T): bring each time into it, then start at the smallest phase
    t = t[0] + np.mod(t - t[0], T)
    order = np.argsort(t, kind="stable")
    t, u, fl = t[order], np.asarray(u, float)[order], np.asarray(fl, np.int8)[order]
    ph = np.mod(t, TWO_PI)
    i0 = int(np.argmin(np.where(t - t[0] < TWO_PI, ph, np.inf)))
    t = np.concatenate([t[i0:], t[:i0] + T])
    u = np.concatenate([u[i0:], u[:i0]])
    fl = np.concatenate([fl[i0:], fl[:i0]])
    t = t - np.floor(t[0] / TWO_PI) * TWO_PI
    return t, u, fl


def _pack(t, u):
    z = np.empty(2 * len(t))
    z[0::2] = t
    z[1::2] = u
    return z


def _impact_orbit(params: RattleParams, z: np.ndarray, fl: np.ndarray, n: int,
                  check: bool = True) -> PeriodicOrbit:
    """A :class:`PeriodicOrbit` from a solution of the shooting equations."""
    lam, r, j, h, phi = _arrays(params)
    m = len(fl)
    w = np.empty(m)
    M = np.empty((2, 2))
    S = np.empty((2, 2))
    _maps(z, fl, n, lam, r, j, h, phi, w, M, S)
    F = np.empty(2 * m)
    J = np.empty((2 * m, 2 * m))
    Fp = np.empty(2 * m)
    _system(z, fl, n, lam, r, j, h, phi, _KIND_LAM, 0, F, J, Fp)
    gmin = np.empty(m)
    gs = np.empty(m)
    gw = np.empty(m, dtype=np.int64)
    contact = np.empty(m)
    code = _inspect(z, fl, n, lam, r, j, h, phi, float(params.v_stick), check, gmin, gs, gw,
                    contact)
    mu = np.linalg.eigvals(S) if np.all(np.isfinite(S)) else np.array([np.nan, np.nan])
    mu = mu[np.argsort(-np.abs(mu), kind="stable")].astype(complex)
    k = int(np.argmin(gmin)) if m else -1
    return PeriodicOrbit(
        params=params, period=int(n), t=z[0::2].copy(), u=z[1::2].copy(), flank=fl.copy(),
        w=w, stick=np.zeros((0, 3)), monodromy=S, multipliers=mu,
        residual=float(_scaled_norm(F, z)), reason=_REASONS.get(int(code), ""),
        gap_min=float(gmin[k]) if m else math.inf,
        gap_where=(k, float(z[2 * k] + gs[k]) if m else math.nan, int(gw[k]) if m else 0))


def solve_orbit(params: RattleParams, t, u, flank, period: int, *, maxit: int = 30
                ) -> PeriodicOrbit:
    """Newton's method on the shooting equations from a guess of the impacts.

    Parameters
    ----------
    params : RattleParams
    t, u : array_like
        Guessed impact times over one period and post-impact velocities.
    flank : array_like of int
        Flank of each impact, +1 or −1.
    period : int
        Period in forcing periods, in [1, 32·16].

    Returns
    -------
    PeriodicOrbit
        Check :attr:`PeriodicOrbit.admissible`: a solution of the equations whose flight
        meets a wall early is not an orbit of the model.

    Raises
    ------
    ContinuationError
        When Newton's method does not converge.
    """
    if not isinstance(params, RattleParams):
        raise ValueError(f"params must be a RattleParams, got {type(params).__name__}")
    period = check_int("period", period, 1, 16 * MAX_ORBIT_PERIOD)
    t = np.atleast_1d(np.asarray(t, dtype=np.float64))
    u = np.atleast_1d(np.asarray(u, dtype=np.float64))
    fl = np.atleast_1d(np.asarray(flank)).astype(np.int8)
    if not (len(t) == len(u) == len(fl)) or len(t) == 0:
        raise ValueError(f"t, u and flank must have the same length, at least 1; got "
                         f"{len(t)}, {len(u)}, {len(fl)}")
    if len(t) > MAX_ORBIT_IMPACTS:
        raise ValueError(f"the orbit has {len(t)} impacts; the allowed range is 1 to "
                         f"{MAX_ORBIT_IMPACTS}")
    if not np.all(np.isin(fl, (-1, 1))):
        raise ValueError(f"flank values must be +1 (active) or -1 (reverse), got {flank!r}")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(u))):
        raise ValueError("t and u must be finite")
    t, u, fl = _normalise(t, u, fl, period)
    z = _pack(t, u)
    lam, r, j, h, phi = _arrays(params)
    st, _, it, res = _newton(z, lam, fl, period, lam, r, j, h, phi, _KIND_LAM, 0,
                             np.zeros(1), np.zeros(1), False, NEWTON_TOL, maxit)
    if st != 0:
        raise ContinuationError(f"Newton's method did not converge (residual {res:.3g} after "
                                f"{it} iterations) for the period-{period} orbit with flanks "
                                f"{fl.tolist()} at {params}")
    t, u, fl = _normalise(z[0::2], z[1::2], fl, period)
    return _impact_orbit(params, _pack(t, u), fl, period)


def c_orbit(params: RattleParams, n: int = 1, which: str = "stable") -> PeriodicOrbit:
    """The one-sided period-n orbit in closed form: one active-flank impact every n periods.

    A flight of ``2πn`` on a symmetric parabola gives ``ẋ⁺ = πn/Λ`` and ``Ĩ = 2πn/Λ``; the
    impact phase solves ``ẏ(θ) = (1 − r)πn / ((1 + r)Λ)`` (``classify.one_sided_orbits``).
    ``which`` picks the root with the smaller trace of the impact map (``"stable"``, the
    regime C orbit where it is stable) or the larger (``"unstable"``).  The closed form is then
    polished by Newton's method (it is a solution already, to rounding).

    Raises
    ------
    ContinuationError
        When ``ẏ`` never reaches the required value (no such orbit at these parameters).
    """
    from ..overlays import one_sided_orbits
    if which not in ("stable", "unstable"):
        raise ValueError(f"which = {which!r}; allowed: 'stable' or 'unstable'")
    n = check_int("n", n, 1, MAX_ORBIT_PERIOD)
    orbits = one_sided_orbits(params, n)
    if not orbits:
        raise ContinuationError(f"no one-sided period-{n} orbit at {params}: ẏ never reaches "
                                f"(1 − r)πn/((1 + r)Λ) = "
                                f"{(1 - params.r) * math.pi * n / ((1 + params.r) * params.lam):.6g}")
    pick = min(orbits, key=lambda o: o.trace) if which == "stable" else max(orbits, key=lambda o: o.trace)
    return solve_orbit(params, [pick.theta], [math.pi * n / params.lam], [1], n)
