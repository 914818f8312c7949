"""The end of sticking in two parameters: natural steps in the second, the event in the first.

An orbit that sticks is computed exactly by simulation from a release (:mod:`.sticking`), not
by Newton's method, so its end of sticking has no extended system.  Its stick phase shrinks
smoothly to nothing as the first parameter approaches the end, so at each value of the second
parameter the end is located in the first by secant steps on the stick phase's length, kept
inside a bracket whose one side sticks with the branch's impact pattern and whose other side
does not (a bisection step whenever a secant step fails to halve it), to ``LOCATE_TOL``.  The
second parameter moves in natural steps, the first predicted along the curve's secant; a step
that finds no bracket is halved.
"""
from __future__ import annotations

import math

import numpy as np

from .events import LOCATE_TOL
from .plane import _Plane
from .results import _limit
from .sticking import _handle, _signature, _stick_at, _stick_margin


class _AtQ2:
    """The first parameter alone, the second held at ``q2`` (what ``_stick_at`` asks of a
    parameter: ``params(q)``)."""

    def __init__(self, plane: _Plane, q2: float):
        self.plane, self.q2 = plane, q2

    def params(self, q: float):
        return self.plane.params(q, self.q2)


def _sticks(plane, q1, q2, handle, sig):
    """The orbit at ``(q1, q2)`` if it sticks with the pattern ``sig``, with its stick margin."""
    o = _stick_at(_AtQ2(plane, q2), q1, handle)
    if o is None or _signature(o) != sig:
        return None, -math.inf
    return o, _stick_margin(o)


def _locate_end(plane, q2, a, b, handle, sig, max_eval: int = 60):
    """The end of sticking between ``a`` (sticks) and ``b`` (does not), at ``q2``."""
    o_a, m_a = _sticks(plane, a, q2, handle, sig)
    if o_a is None:
        return None
    prev = None
    for _ in range(max_eval):
        width = abs(b - a)
        if width < LOCATE_TOL * (1.0 + abs(a)):
            break
        cand = 0.5 * (a + b)
        if prev is not None and prev[1] != m_a:
            sec = a - m_a * (a - prev[0]) / (m_a - prev[1])
            if min(a, b) < sec < max(a, b):
                cand = sec
        o, m = _sticks(plane, cand, q2, handle, sig)
        if o is None or m <= 0.0:
            b = cand
        else:
            prev, a, m_a, o_a = (a, m_a), cand, m, o
        if abs(b - a) > 0.5 * width:
            # the secant did not halve the bracket: bisect once
            mid = 0.5 * (a + b)
            o, m = _sticks(plane, mid, q2, handle, sig)
            if o is None or m <= 0.0:
                b = mid
            else:
                prev, a, m_a, o_a = (a, m_a), mid, m, o
    return a, o_a


def _stick_end_side(plane, X0, orb0, inside: float, sgn: float, bounds_q, dq, dq_min, dq_max,
                    count, max_points, cancel):
    """One side of the end-of-sticking curve from ``(q1, q2) = X0`` towards ``sgn`` in q₂."""
    (a1, b1), (a2, b2) = bounds_q
    sig = _signature(orb0)
    pts = [(np.array(X0, dtype=float), orb0)]
    status = message = ""
    while True:
        status, message = _limit(count[0], max_points, cancel)
        if status:
            break
        (q1, q2), orb = pts[-1]
        q2n = q2 + sgn * dq
        at_bound = not a2 <= q2n <= b2
        q2n = min(max(q2n, a2), b2)
        slope = 0.0
        if len(pts) > 1:
            (p1, p2), _ = pts[-2]
            slope = (q1 - p1) / (q2 - p2) if q2 != p2 else 0.0
        guess = q1 + slope * (q2n - q2)
        w = max(4.0 * abs(slope * dq), 1e-4 * (1.0 + abs(q1)))
        found = None
        for _ in range(4):
            qa, qb = guess + inside * w, guess - inside * w
            if a1 <= min(qa, qb) and max(qa, qb) <= b1:
                oa, _ = _sticks(plane, qa, q2n, _handle(orb), sig)
                ob, mb = _sticks(plane, qb, q2n, _handle(orb), sig)
                if oa is not None and (ob is None or mb <= 0.0):
                    found = _locate_end(plane, q2n, qa, qb, _handle(orb), sig)
                    break
            w *= 4.0
        if found is None:
            dq *= 0.5
            if dq < dq_min:
                status = "step_too_small"
                message = (f"the end of sticking was lost near {plane.spec2.name} = "
                           f"{plane.spec2.value_of(q2):.10g} (the impact pattern changes)")
                break
            continue
        q1n, on = found
        pts.append((np.array([q1n, q2n]), on))
        count[0] += 1
        if at_bound:
            status, message = "bound", "reached the bound"
            break
        dq = min(dq * 1.5, dq_max)
    return pts, status, message
