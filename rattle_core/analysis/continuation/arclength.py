"""Following a branch: pseudo-arclength steps for impact orbits, natural steps for stick orbits.

An impact orbit's branch is followed through folds by predicting along the tangent and
correcting on the plane orthogonal to it, with a step that adapts to Newton's convergence and
to the tangent's turning.  An orbit that sticks is superstable and has no folds: its branch is
followed in the parameter itself until its impact pattern changes.
"""
from __future__ import annotations

import math

import numpy as np

from ...solver.kernel import V_FLOOR
from .branch import _Branch
from .events import LOCATE_TOL, _admissible_sign, _event, _light, _locate, _stick_event, _tests_of
from .orbits import PeriodicOrbit
from .results import _Run
from .sticking import _handle, _signature, _stick_at

#: Largest |period-doubling test| (which is in [−1, 1]) at a located multiplier −1.
_PD_ZERO = 1e-6


def _follow(run: _Run, br: _Branch, X, tau, ds, ds_min, ds_max, first_event: str = ""):
    """Pseudo-arclength continuation of an impact orbit from ``X`` along ``tau``."""
    spec = run.spec
    vs = run.v_stick
    orb = br.orbit(X)
    if not orb.admissible:
        # a sign change seen from a virtual orbit is no event of the model: nothing to locate
        run.status = "inadmissible"
        run.message = (f"the start is not an orbit of the model at {spec.name} = "
                       f"{spec.value_of(X[-1]):.10g}: {orb.reason}")
        return
    run.add(orb, X[-1], first_event)
    tests = _tests_of(orb, vs)
    X_start = X.copy()
    tol = LOCATE_TOL
    while not run.full():
        X_new, it = br.correct(X + ds * tau, tau)
        if X_new is not None and np.linalg.norm(X_new - X) > 2.0 * ds:
            X_new = None
        at_bound = False
        if X_new is not None and not run.q_lo <= X_new[-1] <= run.q_hi:
            # land on the bound instead: the point there, by Newton at the bound's value
            qb = run.q_hi if X_new[-1] > run.q_hi else run.q_lo
            frac = (qb - X[-1]) / (X_new[-1] - X[-1])
            zb, _ = br.solve_at(X[:-1] + frac * (X_new[:-1] - X[:-1]), qb)
            X_new = None if zb is None else np.append(zb, qb)
            at_bound = X_new is not None
        tau_new = None
        if X_new is not None:
            tau_new = br.tangent(X_new[:-1], X_new[-1], tau)
            if float(tau_new @ tau) < 0.95 and ds > 4.0 * ds_min:
                X_new = None
        if X_new is None:
            ds *= 0.5
            if ds < ds_min:
                run.status = "step_too_small"
                run.message = (f"the corrector failed with steps down to ds_min = {ds_min:g} near "
                               f"{spec.name} = {spec.value_of(X[-1]):.10g}")
                return
            continue
        orb_new = br.orbit(X_new)
        t_new = _tests_of(orb_new, vs)
        ok = orb_new.admissible
        # events between X and X_new, located along the arclength
        found = []
        if tau[-1] * tau_new[-1] < 0.0:
            found.append("fold")
        for key in ("pd", "gap", "w"):
            if np.isfinite(tests[key]) and np.isfinite(t_new[key]) and \
                    (tests[key] > 0) != (t_new[key] > 0):
                found.append(key)
        # an impact slowing through v_stick: the onset of sticking if its wall pushes there
        v_eff = max(vs, V_FLOOR)
        for k in np.nonzero((tests["speed"] >= v_eff) != (t_new["speed"] >= v_eff))[0]:
            found.append(("st", int(k)))
        # (at r = 1 every orbit has det M = 1: only rounding would change the sign)
        if (tests["ns"] > 0) != (t_new["ns"] > 0) and abs(tests["tr"]) < 2.0 and \
                abs(t_new["tr"]) < 2.0 and min(abs(tests["ns"]), abs(t_new["ns"])) > 1e-9:
            found.append("ns")
        located = []
        h_new = float(tau @ (X_new - X))
        for key in found:
            # grazing and sticking on the impacts' velocities and gaps, which exist there;
            # the multiplier tests only where the monodromy is needed
            fn = (lambda Y, k=key: _light(br, Y, vs, monodromy=k in ("pd", "ns"))[k])
            if key == "fold":
                def fn(Y):
                    return br.tangent(Y[:-1], Y[-1], tau)[-1]
                f0, f1 = tau[-1], tau_new[-1]
            elif isinstance(key, tuple):
                k = key[1]

                def fn(Y, k=k):
                    return _light(br, Y, vs, monodromy=False)["speed"][k] - v_eff
                f0, f1 = tests["speed"][k] - v_eff, t_new["speed"][k] - v_eff
            else:
                f0, f1 = tests[key], t_new[key]
            Xe, fe = _locate(br, X, tau, h_new, f0, f1, fn, tol)
            if Xe is None:
                continue
            if key == "pd" and not abs(fe) < _PD_ZERO:
                continue  # the test jumped through the pole of a grazing impact, not through 0
            if isinstance(key, tuple):
                if _light(br, Xe, vs, monodromy=False)["react"][key[1]] <= 0.0:
                    continue  # a pulling wall: the gear leaves at once, no sticking
                key = "st"
            located.append((float(np.linalg.norm(Xe - X)), key, Xe))
        if not ok and not any(k in ("gap", "w", "st") for _, k, _ in located):
            Xe, _ = _locate(br, X, tau, h_new, 1.0, -1.0, lambda Y: _admissible_sign(br, Y, vs),
                            tol)
            if Xe is not None:
                located.append((float(np.linalg.norm(Xe - X)), "contact", Xe))
        located.sort(key=lambda e: e[0])
        stop = False
        for _, key, Xe in located:
            if not (run.q_lo <= Xe[-1] <= run.q_hi):
                continue
            if _event(run, br, key, Xe, tau):
                stop = True
                break
        if stop:
            return
        if not ok:
            # inadmissible without a located event: stop rather than follow a virtual orbit
            run.add(orb_new, X_new[-1])
            run.status = "inadmissible"
            run.message = (f"the orbit stopped being an orbit of the model near {spec.name} = "
                           f"{spec.value_of(X_new[-1]):.10g}: {orb_new.reason}")
            return
        X, tau, tests, orb = X_new, tau_new, t_new, orb_new
        run.add(orb, X[-1])
        if at_bound:
            run.status = "bound"
            run.message = f"reached the bound {spec.name} = {spec.value_of(X[-1]):.10g}"
            return
        if len(run.rows) > 10 and np.linalg.norm(X - X_start) < 0.5 * ds:
            run.status = "closed"
            run.message = "the branch came back to its first point (a closed curve)"
            return
        ds = min(ds * (1.5 if it <= 3 else (1.0 if it <= 6 else 0.5)), ds_max)
    return


def _follow_stick(run: _Run, orb: PeriodicOrbit, q: float, dq: float, dq_min: float,
                  dq_max: float, first_event: str = ""):
    """Natural-parameter continuation of an orbit that sticks (superstable, no folds)."""
    spec = run.spec
    run.add(orb, q, first_event)
    sig = _signature(orb)
    while not run.full():
        q_new = q + dq
        at_bound = False
        if not run.q_lo <= q_new <= run.q_hi:
            q_new = run.q_hi if q_new > run.q_hi else run.q_lo
            at_bound = True
        new = _stick_at(spec, q_new, _handle(orb))
        if new is not None and _signature(new) == sig:
            q, orb = q_new, new
            run.add(orb, q)
            if at_bound:
                run.status = "bound"
                run.message = f"reached the bound {spec.name} = {spec.value_of(q):.10g}"
                return
            dq = math.copysign(min(abs(dq) * 1.5, dq_max), dq)
            continue
        if abs(dq) > 8 * dq_min and (new is None or abs(dq) > 4 * dq_min):
            # bisect the change of the impact pattern down to the locating tolerance
            lo, hi, o_lo = q, q_new, orb
            while abs(hi - lo) > LOCATE_TOL * (1.0 + abs(lo)):
                mid = 0.5 * (lo + hi)
                o = _stick_at(spec, mid, _handle(o_lo))
                if o is not None and _signature(o) == sig:
                    lo, o_lo = mid, o
                else:
                    hi = mid
            o_hi = _stick_at(spec, hi, _handle(o_lo))
            _stick_event(run, o_lo, lo, o_hi, hi)
            return
        run.status = "step_too_small"
        run.message = f"no stick orbit beyond {spec.name} = {spec.value_of(q):.10g}"
        return
