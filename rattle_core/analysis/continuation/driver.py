"""continue_orbit(): the request checked, the branch started, the result assembled."""
from __future__ import annotations

import dataclasses
import math
import threading
import time
from typing import Any, Callable, Sequence

import numpy as np

from ...model.params import (ArgumentTypeError, RattleParams, check_cancel, check_int,
                             check_progress, check_range)
from ...solver.trajectory import SOLVER_VERSION
from .arclength import _follow
from .orbits import PeriodicOrbit
from .parameter import _KIND_J, _KIND_LAM, _Param
from .results import IMPACT_COLUMNS, POINT_COLUMNS, Bifurcation, ContinuationResult, _Run
from .simulated import find_orbit
from .switching import _pd_switch, _simulate_start, _start, _surgery_start

CONTINUATION_VERSION = "1.0.0"
#: Most branch points one call may compute.
MAX_POINTS = 100_000


def continue_orbit(start, param: str | None = None, *, bounds: Sequence[float] | None = None,
                   direction: int = 1, ds: float = 0.01, ds_min: float = 1e-9,
                   ds_max: float = 0.1, max_points: int = 1000, physical=None,
                   progress: Callable[[int, int], Any] | None = None,
                   cancel: threading.Event | Callable[[], bool] | None = None
                   ) -> ContinuationResult:
    """Follow a periodic orbit as one parameter changes; locate its bifurcations.

    Pseudo-arclength continuation of the shooting equations for orbits with impacts only
    (through folds, stable and unstable alike); natural-parameter steps for orbits that stick
    (superstable).  The method is explained in :mod:`rattle_core.analysis.continuation`.

    Parameters
    ----------
    start : PeriodicOrbit, RattleParams or Bifurcation
        The first orbit (from :func:`find_orbit`, :func:`c_orbit`, :func:`solve_orbit`,
        :func:`stick_orbit`); parameters, to start from the orbit a simulation settles on; or a
        bifurcation of an earlier result: a period doubling starts the doubled orbit's branch,
        a grazing restarts with the impact gained or lost, an onset or end of sticking restarts
        from a simulation just beyond, a fold goes on through it.
    param : str
        ``lam``, ``r``, ``j``, ``hK`` (H_K/H1), ``phiK`` (degrees), or with ``physical``
        ``rpm`` (engine speed) or ``drag_torque`` [N·m].  May be left out only when ``start``
        is a bifurcation: its own parameter is then continued.
    bounds : (float, float), optional
        Stop when the parameter leaves this interval (its units).  Default: the model's range.
    direction : {1, -1}
        Start towards increasing (1) or decreasing (−1) values; an int.
    ds, ds_min, ds_max : float
        First, smallest and largest arclength step, in the dimensionless unknowns (impact
        times, velocities and Λ, r, j, h_K, or φ_K in radians).
    max_points : int
        Most branch points, in [1, 100000]; the run stops there with a message.
    physical : PhysicalParams, optional
        The gear in physical units, for ``rpm`` and ``drag_torque``; ``start`` must then be
        an orbit at ``physical.to_dimensionless()``.
    progress : callable(done, max_points), optional
        Called after every point.
    cancel : threading.Event or callable() -> bool, optional
        Polled after every point; when set the run stops (``status == "cancelled"``) and
        returns the points so far.

    Returns
    -------
    ContinuationResult
        Branch points, impacts per point, bifurcations, why it stopped, provenance.
    """
    import pandas as pd

    t_start = time.perf_counter()
    progress = check_progress(progress)
    cancel = check_cancel(cancel)
    if param is None:
        if not isinstance(start, Bifurcation):
            raise ValueError("param = None: name the continued parameter (lam, r, j, hK, phiK, "
                             "rpm or drag_torque); only a bifurcation's restart may leave it out")
        param = start.param
    elif not isinstance(param, str):
        raise ArgumentTypeError(f"param = {param!r:.60} must be a parameter name (lam, r, j, hK, "
                                "phiK, rpm or drag_torque)")
    if (isinstance(direction, (bool, np.bool_)) or not isinstance(direction, (int, np.integer))
            or direction not in (1, -1)):
        raise ValueError(f"direction = {direction!r}; allowed: the int 1 (increasing) or -1 "
                         "(decreasing)")
    if isinstance(start, Bifurcation):
        if param != start.param:
            raise ValueError(f"param = {param!r}, but the bifurcation was found in "
                             f"{start.param!r}; restart in the same parameter")
        if start._restart is None:
            raise ValueError(f"a {start.kind} bifurcation offers no restart")
        params0 = start.orbit.params
    elif isinstance(start, PeriodicOrbit):
        params0 = start.params
        if not start.admissible:
            raise ValueError(f"start is not an orbit of the model, so it cannot be continued: "
                             f"{start.reason} (a closed-form or Newton solution that violates "
                             "the backlash or a contact condition; check .admissible first)")
    elif isinstance(start, RattleParams):
        params0 = start
    else:
        raise ValueError(f"start must be a PeriodicOrbit, a RattleParams or a Bifurcation, got "
                         f"{type(start).__name__}")
    ds = check_range("ds", ds, 0.0, 1.0, lo_open=True)
    ds_max = check_range("ds_max", ds_max, ds, 10.0)
    ds_min = check_range("ds_min", ds_min, 0.0, ds, lo_open=True)
    max_points = check_int("max_points", max_points, 1, MAX_POINTS)
    if isinstance(start, Bifurcation):
        spec = start._spec
        physical = spec.physical
    else:
        spec = _Param.make(param, params0, physical)
        if physical is not None and param in ("rpm", "drag_torque"):
            a, b = spec.base.canonical(), params0.canonical()
            if a != b and not _close_params(spec.base, params0):
                raise ValueError("start is not at the parameters of physical "
                                 f"(physical.to_dimensionless() = {spec.base}, start at {params0})")
    # the internal range, and the user's bounds in it
    lo_q, hi_q = spec.q_range()
    if bounds is not None:
        try:
            b0, b1 = (float(v) for v in bounds)
        except (TypeError, ValueError):
            raise ValueError(f"bounds must be two numbers (low, high), got {bounds!r}") from None
        if not (math.isfinite(b0) and math.isfinite(b1)) or b0 >= b1:
            raise ValueError(f"bounds = {bounds!r} must be two finite numbers, low < high")
        qa, qb = sorted((spec.q_of(b0), spec.q_of(b1)))
        for v, qv in ((b0, qa), (b1, qb)):
            try:
                spec.params(qv)
            except ValueError as exc:
                raise ValueError(f"bounds: {param} = {v!r} is outside the model's range ({exc})") \
                    from None
        lo_q, hi_q = max(lo_q, qa), min(hi_q, qb)
    eps = 1e-12 * (1.0 + abs(hi_q - lo_q))
    if spec.kind in (_KIND_LAM, _KIND_J):
        lo_q = max(lo_q, 1e-9)
    q_start = spec.q0 if not isinstance(start, Bifurcation) else start.q
    if not lo_q - eps <= q_start <= hi_q + eps:
        raise ValueError(f"the start, {param} = {spec.value_of(q_start):.10g}, lies outside "
                         f"bounds [{spec.value_of(lo_q):.10g}, {spec.value_of(hi_q):.10g}]")
    sgn = float(direction)
    if param == "drag_torque":
        sgn = -sgn  # Λ falls as the drag torque grows
    run = _Run(spec, lo_q, hi_q, max_points, progress, cancel, float(params0.v_stick))

    if isinstance(start, RattleParams):
        start = find_orbit(start)
    if isinstance(start, PeriodicOrbit):
        _start(run, spec, start, spec.q0, sgn, ds, ds_min, ds_max)
    else:
        how = start._restart
        if how[0] == "pd":
            _pd_switch(run, how[1], how[2], ds, ds_min, ds_max)
        elif how[0] in ("insert", "remove"):
            _surgery_start(run, how[1], how[2], how[0], ds, ds_min, ds_max)
        elif how[0] == "fold":
            _follow(run, how[1], how[2], how[3], ds, ds_min, ds_max, "fold")
        else:
            beyond = float(np.sign(how[3][-1])) if how[1] is not None else \
                float(np.sign(how[3] - how[2]))
            _simulate_start(run, spec, start.orbit, start.q, beyond or sgn, ds, ds_min, ds_max)
    if not run.status:
        run.status = "done"
    points = pd.DataFrame(run.rows, columns=POINT_COLUMNS)
    impacts = pd.DataFrame(run.impact_rows, columns=IMPACT_COLUMNS)
    impacts["flank"] = impacts["flank"].astype(np.int8)
    provenance = {
        "param": param, "params": params0.to_dict(),
        "physical": dataclasses.asdict(physical) if physical is not None else None,
        "start": _start_provenance(start),
        "settings": {"bounds": [spec.value_of(lo_q), spec.value_of(hi_q)],
                     "direction": direction, "ds": ds, "ds_min": ds_min, "ds_max": ds_max,
                     "max_points": max_points},
        "solver_version": SOLVER_VERSION, "continuation_version": CONTINUATION_VERSION,
    }
    return ContinuationResult(param=param, points=points, impacts=impacts,
                              bifurcations=run.bifs, status=run.status, message=run.message,
                              provenance=provenance, orbits=run.orbits, _spec=spec,
                              seconds=time.perf_counter() - t_start)


def _close_params(a: RattleParams, b: RattleParams) -> bool:
    da, db = a.to_dict(), b.to_dict()
    return all(np.allclose(np.atleast_1d(da[k]), np.atleast_1d(db[k]), rtol=1e-12, atol=1e-12)
               if len(np.atleast_1d(da[k])) == len(np.atleast_1d(db[k])) else False for k in da)


def _start_provenance(start) -> dict:
    if isinstance(start, Bifurcation):
        return {"bifurcation": start.kind, "value": start.value, "param": start.param,
                "orbit": _start_provenance(start.orbit)}
    if isinstance(start, PeriodicOrbit):
        return {"period": start.period, "t": start.t.tolist(), "u": start.u.tolist(),
                "flank": start.flank.tolist(), "stick": start.stick.tolist(),
                "params": start.params.to_dict()}
    return {}
