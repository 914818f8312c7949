"""The periodic orbit a simulation settles on, as a starting point for continuation."""
from __future__ import annotations

import numpy as np

from ...model.excitation import TWO_PI
from ...model.params import RattleParams, check_int, check_range
from .orbits import MAX_ORBIT_PERIOD, ContinuationError, PeriodicOrbit, solve_orbit
from .sticking import _releases, _simulate_strict, stick_orbit


def find_orbit(params: RattleParams, *, x0: float | None = None, v0: float = 0.0,
               t0: float = 0.0, transient: int = 2000, max_period: int = MAX_ORBIT_PERIOD
               ) -> PeriodicOrbit:
    """The periodic orbit a simulation settles on, polished to machine precision.

    Simulates ``transient`` periods from ``(x0, v0)`` at ``t0``, finds the period of the
    stroboscopic samples, and turns the last period's impacts into a Newton guess (or, when
    the gear sticks, computes the stick orbit through the last release exactly).

    Raises
    ------
    ContinuationError
        When the response is not periodic (period above ``max_period``, chaos, a long
        transient), or Newton's method does not reproduce the simulated orbit.
    """
    from ..classify import detect_period
    if not isinstance(params, RattleParams):
        raise ValueError(f"params must be a RattleParams, got {type(params).__name__}")
    max_period = check_int("max_period", max_period, 1, MAX_ORBIT_PERIOD)
    transient = check_int("transient", transient, 0, 1_000_000)
    rec = 4 * max_period
    tr = _simulate_strict(params, periods=rec, transient=transient, x0=x0, v0=v0, t0=t0)
    n = detect_period(tr.strobe_x, tr.strobe_v, params.j, max_period, 1e-9)
    if n == 0:
        n = detect_period(tr.strobe_x, tr.strobe_v, params.j, max_period, 1e-6)
    if n == 0:
        raise ContinuationError(f"the response at {params} is not periodic with a period up to "
                                f"{max_period} after {transient} periods; try a longer "
                                "transient or another start")
    return orbit_from_trajectory(tr, n)


def orbit_from_trajectory(tr, period: int) -> PeriodicOrbit:
    """The periodic orbit of period ``period`` at the end of a :class:`Trajectory`."""
    p = tr.params
    period = check_int("period", period, 1, MAX_ORBIT_PERIOD)
    rel = _releases(tr)
    t_end = tr.t_end
    if rel and rel[-1][0] > t_end - 2 * TWO_PI * period:
        return stick_orbit(p, rel[-1][0], rel[-1][1])
    if len(tr.stick_intervals) and tr.stick_intervals[-1, 1] >= t_end - 1e-9 and \
            tr.stick_intervals[-1, 0] <= t_end - 2 * TWO_PI * period:
        raise ContinuationError(f"the gear stays in contact at {p} (regime A): no orbit with "
                                "impacts to follow")
    sel = tr.impact_t >= t_end - TWO_PI * period
    if not np.any(sel):
        raise ContinuationError(f"no impacts in the last {period} periods at {p}")
    t = tr.impact_t[sel]
    from ...model.excitation import excitation
    u = excitation(t, p.h, p.phi, 1) - p.r * tr.impact_w[sel]
    orb = solve_orbit(p, t, u, tr.impact_flank[sel], period)
    ref = np.sort(np.mod(tr.impact_t[sel], TWO_PI))
    if len(ref) != orb.n_impacts or np.max(np.abs(np.sort(orb.phase) - ref)) > 1e-6:
        raise ContinuationError(f"Newton's method moved away from the simulated orbit at {p} "
                                "(the response may not be settled yet)")
    return orb
