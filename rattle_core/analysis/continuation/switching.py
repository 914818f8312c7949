"""Starting a branch, and restarting past a bifurcation: period doubling, grazing, sticking."""
from __future__ import annotations

import numpy as np

from ...model.excitation import TWO_PI
from .arclength import _follow, _follow_stick
from .branch import _Branch
from .events import _admissible_sign
from .orbits import ContinuationError, PeriodicOrbit, _normalise, _pack
from .parameter import _Param
from .results import _Run
from .simulated import find_orbit
from .stability import _flip_vectors


def _pd_switch(run: _Run, br: _Branch, Xe, ds, ds_min, ds_max):
    """Start the doubled orbit's branch at a period doubling, along the critical eigenvector."""
    m = len(br.fl)
    z = Xe[:-1]
    lam, r, j, h, phi = br._at(Xe[-1])
    delta = _flip_vectors(z, br.fl, br.n, lam, r, h, phi)
    br2 = _Branch(br.spec, np.concatenate([br.fl, br.fl]), 2 * br.n)
    shift = np.zeros(2 * m)
    shift[0::2] = TWO_PI * br.n
    X2 = np.concatenate([z, z + shift, [Xe[-1]]])
    tau = np.concatenate([delta.ravel(), -delta.ravel(), [0.0]])
    tau /= np.linalg.norm(tau)
    h_step = ds
    while h_step >= ds_min:
        X1, _ = br2.correct(X2 + h_step * tau, tau)
        if X1 is not None:
            gap = np.max(np.abs(X1[2 * m:-1] - X1[:2 * m] - shift))
            if gap > 1e-8 and _admissible_sign(br2, X1, run.v_stick) > 0:
                t1 = br2.tangent(X1[:-1], X1[-1], (X1 - X2) / np.linalg.norm(X1 - X2))
                run.add(br2.orbit(X2), X2[-1], "period_doubling")
                _follow(run, br2, X1, t1, ds, ds_min, ds_max)
                return
        h_step *= 0.5
    raise ContinuationError(f"could not switch onto the period-{2 * br.n} branch at "
                            f"{br.spec.name} = {br.spec.value_of(Xe[-1]):.10g}")


def _surgery_start(run: _Run, br: _Branch, Xe, mode: str, ds, ds_min, ds_max):
    """Restart past a grazing with one impact more (``insert``) or fewer (``remove``)."""
    spec = br.spec
    q = float(Xe[-1])
    orb = br.orbit(Xe)
    z = Xe[:-1]
    fl = br.fl
    if mode == "insert":
        k, tg, wall = orb.gap_where
        from ...model.excitation import excitation
        p = orb.params
        ug = float(excitation(tg, p.h, p.phi, 1))
        z_new = np.concatenate([z[:2 * k + 2], [tg, ug], z[2 * k + 2:]])
        fl_new = np.concatenate([fl[:k + 1], [wall], fl[k + 1:]]).astype(np.int8)
    else:
        k = int(np.argmin(-orb.flank * orb.w))
        z_new = np.concatenate([z[:2 * k], z[2 * k + 2:]])
        fl_new = np.concatenate([fl[:k], fl[k + 1:]]).astype(np.int8)
        if len(fl_new) == 0:
            raise ContinuationError("the orbit loses its only impact: nothing left to follow")
        if k == 0:
            # the period must start at its first impact: rotate the removed one's period away
            t_new, u_new, fl_new = _normalise(z_new[0::2], z_new[1::2], fl_new, br.n)
            z_new = _pack(t_new, u_new)
    br2 = _Branch(spec, fl_new, br.n)
    X0 = np.append(z_new, q)
    if mode == "remove":
        z_fix, _ = br2.solve_at(z_new, q)
        if z_fix is not None:
            X0 = np.append(z_fix, q)
    tau = br2.tangent(X0[:-1], q, None)
    h_step = ds
    while h_step >= ds_min:
        for sgn in (1.0, -1.0):
            X1, _ = br2.correct(X0 + sgn * h_step * tau, sgn * tau)
            if X1 is not None and _admissible_sign(br2, X1, run.v_stick) > 0:
                t1 = br2.tangent(X1[:-1], X1[-1], sgn * tau)
                _follow(run, br2, X1, t1, ds, ds_min, ds_max)
                return
        h_step *= 0.5
    raise ContinuationError(f"no orbit with the new impact sequence (flanks {fl_new.tolist()}) "
                            f"near {spec.name} = {spec.value_of(q):.10g}")


def _simulate_start(run: _Run, spec: _Param, orb: PeriodicOrbit, q: float, sgn: float,
                    ds, ds_min, ds_max):
    """Restart past an event by simulation from the old orbit, just beyond it."""
    last = None
    for step in (1e-7, 1e-6, 1e-5, 1e-4):
        q1 = q + sgn * step * (1.0 + abs(q))
        try:
            params = spec.params(q1)
        except ValueError:
            break
        t0 = float(orb.t[0]) if orb.n_impacts else 0.0
        x0, v0 = orb.state_at(t0 - 1e-3)
        try:
            new = find_orbit(params, x0=float(x0), v0=float(v0), t0=t0 - 1e-3, transient=400)
        except (ContinuationError, ValueError) as exc:
            last = exc
            continue
        _start(run, spec, new, q1, sgn, ds, ds_min, ds_max)
        return
    raise ContinuationError(f"no periodic attractor found just beyond {spec.name} = "
                            f"{spec.value_of(q):.10g} by simulation from the old orbit"
                            + (f" ({last})" if last else ""))


def _start(run: _Run, spec: _Param, orb: PeriodicOrbit, q: float, sgn: float, ds, ds_min,
           ds_max, event: str = ""):
    """Continue from a solved orbit at ``q`` towards increasing ``q`` (sgn > 0) or decreasing."""
    if orb.kind == "stick":
        _follow_stick(run, orb, q, sgn * ds, ds_min, ds_max, event)
        return
    br = _Branch(spec, orb.flank, orb.period)
    X = np.append(_pack(orb.t, orb.u), q)
    prev = np.zeros(len(X))
    prev[-1] = sgn
    tau = br.tangent(X[:-1], q, prev)
    if tau[-1] * sgn < 0:
        tau = -tau
    _follow(run, br, X, tau, ds, ds_min, ds_max, event)
