"""Continuation of periodic impacting orbits, stable and unstable, and their bifurcations.

A brute-force bifurcation diagram shows only the attractors reached from one initial state.
This package follows one periodic orbit as a parameter changes, whether the orbit is stable or
not, and finds where it is born, where it loses stability and why.

**Orbits as fixed points of the impact map.**  Between impacts the gear flies on a parabola,
``x = x_i + u_i s − s²/(2Λ)``, so a periodic orbit with ``m`` impacts in ``n`` forcing periods
is fixed by its impact times ``t_i`` and post-impact velocities ``u_i``.  The position at an
impact is the wall's, ``X_i = y(t_i)`` (active flank) or ``y(t_i) + j`` (reverse flank).  Each
flight gives two equations (multiple shooting over the impacts, with ``t_m = t_0 + 2πn`` and
``u_m = u_0``)::

    G_i = X_i(t_i) + u_i s_i − s_i²/(2Λ) − X_{i+1}(t_{i+1}) = 0        (arrival on the wall)
    H_i = u_{i+1} − ẏ(t_{i+1}) + r w_{i+1} = 0                          (impact law)

with ``s_i = t_{i+1} − t_i`` and the incoming relative velocity ``w_{i+1} = u_i − s_i/Λ −
ẏ(t_{i+1})``.  Everything is closed form, so the ``2m × 2m`` Jacobian is exact; Newton's
method solves the system to machine precision in a few steps.  The equations alone do not
know that the flight must stay between the walls: every solution is checked with the solver's
own rigorous event search (``solver._flight``), which must find the next contact exactly where
the orbit claims it, on the claimed flank.  An orbit that passes this check is an orbit of the
simulator, impact for impact.

**Floquet multipliers.**  Eliminating ``(t_{i+1}, u_{i+1})`` from one flight's equations by the
implicit-function theorem gives the local map ``D_i``; the impact map's Jacobian is
``M = D_{m−1} ⋯ D_0``.  Its eigenvalues are the Floquet multipliers (the stroboscopic map is
conjugate to the impact map).  The same numbers come out of the tangent dynamics: flights
shear ``(δx, δv)`` by ``[[1, s], [0, 1]]`` and each impact applies the saltation matrix
``[[−r, 0], [−(1+r)(1/Λ + ÿ)/w, −r]]`` (as in ``solver``); their product is the monodromy of
the stroboscopic map at the time just after the first impact, which this package reports.
Flights preserve area and each impact multiplies it by ``r²``, so ``det M = r^{2m}``: for
``r < 1`` a complex pair can never reach the unit circle, and a Neimark–Sacker bifurcation
(tested as ``det M = 1`` with ``|tr M| < 2``) cannot happen in this model.  The detector is
there for completeness and reports nothing.

**Stick phases.**  A gear that sticks to a tooth leaves it where the reaction ``R̃ = 1 + Λ ÿ``
changes sign, a phase that depends on the parameters only.  The orbit after a release is
therefore the same whatever happened before: the return map is locally constant, its Jacobian
is zero and both multipliers are exactly 0 (superstable).  Newton's method is not needed
there, nor a fit (the chatter before sticking is an infinite impact sequence): a stick
orbit is computed exactly instead: from a release, ``simulate`` runs until the gear sticks
and releases again, until a release repeats.  Such orbits have no folds and no flip or
torus bifurcations; they are followed in natural-parameter steps, and they end where their
impact pattern changes (a grazing flight) or where the stick phase shrinks to nothing.  As in
the solver, the stick phase starts at the first contact slower than ``v_stick``, which ends
the chatter (the rest of the exact model's chatter would take a time of order ``v_stick``).
How many chatter impacts the solver resolves above ``v_stick`` changes along such a branch;
the chatter before a stick phase counts as one element of the impact pattern.

**Pseudo-arclength continuation.**  With the parameter ``p`` added to the unknowns, the
solutions form curves.  From a point and its unit tangent ``τ`` (the null vector of
``[∂F/∂z | ∂F/∂p]``), a step ``ds`` predicts ``X + ds τ``, and Newton corrects on the plane
orthogonal to ``τ``.  The curve may turn back in ``p`` (a fold) and the method follows it
through.  The step grows when Newton converges quickly and shrinks when it does not, or when
the tangent turns too fast.

**Bifurcations** are zeros of test functions evaluated at every point: a fold where the
tangent's parameter component changes sign (a multiplier crosses +1, ``det(I − M) = 0``),
a period doubling where ``det(I + M)`` changes sign (−1), Neimark–Sacker where ``det M − 1``
does with ``|tr M| < 2``.  The nonsmooth events: **grazing**, where the smallest interior
minimum of a flight's gap to a wall crosses zero (the orbit gains an impact) or where an
impact's relative velocity reaches zero (it loses one); the **onset of sticking**, where an
impact on a pushing wall becomes slower than ``v_stick`` (the model then sticks); the **end
of sticking**, where a stick phase shrinks to zero length.  A sign change between two points
is located by the Illinois variant of regula falsi along the arclength, to about 1e-10 in the
parameter.  At a period doubling the branch of the doubled orbit is tangent to the critical
eigenvector: the doubled system is started there along that direction.  At a grazing the
branch stops, and :func:`continue_orbit` can restart from the reported point with the new
impact sequence (an impact inserted at the touching point, or removed): of the two directions
the new branch can leave in, the one whose orbit the event search accepts.  After the onset or
end of sticking the restart is a simulation from the old orbit, just beyond the event.

**Where each piece lives.**

* ``parameter``: the continued parameter, in the user's units and as the equations' ``q``.
* ``shooting``: the shooting equations, their exact Jacobian and Newton's method (compiled).
* ``stability``: the local maps, the impact map's Jacobian and the monodromy (compiled).
* ``admissibility``: the check against the solver's event search; gap minima (compiled).
* ``orbits``: :class:`PeriodicOrbit`, :func:`solve_orbit`, :func:`c_orbit`.
* ``sticking``: :func:`stick_orbit` and what stays the same along a branch that sticks.
* ``simulated``: :func:`find_orbit`, :func:`orbit_from_trajectory`.
* ``results``: :class:`Bifurcation`, :class:`ContinuationResult` and the run that fills it.
* ``branch``: one impact sequence under one parameter: tangent and corrector.
* ``events``: test functions, location of their zeros, the records of bifurcations.
* ``arclength``: the pseudo-arclength loop, and natural steps for orbits that stick.
* ``switching``: starting a branch, and restarting past a bifurcation.
* ``driver``: :func:`continue_orbit`, which checks the request and assembles the result.

**Two parameters.**  A located bifurcation is the orbit's equations plus one defining
condition; in the plane of two parameters these solutions form a curve, followed by the same
pseudo-arclength method with the extended system (``continue_bifurcation``).

* ``plane``: the two parameters and the model numbers they set.
* ``defining``: the defining conditions (multiplier ±1, grazing, onset of sticking) and the
  extended system's residual, exact Jacobian, tangent and Newton corrector.
* ``contact``: the contact boundary ``Λ_c = 1/max(−ÿ)`` as a curve, with its corners.
* ``stickend``: the end of sticking (an orbit that sticks has no shooting equations): natural
  steps in the second parameter, the end located in the first.
* ``codim2``: codimension-two points: test functions, location, restart onto the other curve.
* ``twoparam``: :class:`BifurcationCurve` and the loop that follows a curve both ways.
* ``bifcurve``: :func:`continue_bifurcation`, which checks the request and starts the curve.
* ``atlas``: :func:`atlas`, every curve over a window of two parameters that continuation finds
  from a few seeds.
"""
from __future__ import annotations

from .admissibility import ADMISSIBLE, CONTACT_MATCH
from .atlas import ATLAS_AXES, atlas, axes_supported
from .bifcurve import CURVE_STARTS, contact_bifurcation, continue_bifurcation
from .codim2 import CODIM2_KINDS, Codim2Point
from .driver import CONTINUATION_VERSION, MAX_POINTS, continue_orbit
from .events import LOCATE_TOL
from .orbits import (MAX_ORBIT_IMPACTS, MAX_ORBIT_PERIOD, ContinuationError, PeriodicOrbit,
                     c_orbit, solve_orbit)
from .parameter import PARAMETERS
from .results import (BIFURCATION_KINDS, IMPACT_COLUMNS, POINT_COLUMNS, TERMINAL, Bifurcation,
                      ContinuationResult)
from .shooting import NEWTON_TOL
from .simulated import find_orbit, orbit_from_trajectory
from .sticking import stick_orbit

# internals that the CLI (an early check of the parameter) and the tests reach by this name
from .branch import _Branch  # noqa: F401
from .parameter import _Param  # noqa: F401
from .stability import _local_maps  # noqa: F401
from .sticking import _release_roots  # noqa: F401
from .twoparam import CURVE_KINDS, MAX_CURVE_POINTS, BifurcationCurve

__all__ = [
    "ADMISSIBLE", "ATLAS_AXES", "BIFURCATION_KINDS", "atlas", "axes_supported", "BifurcationCurve", "CODIM2_KINDS", "CONTACT_MATCH",
    "CURVE_KINDS", "CURVE_STARTS", "Codim2Point", "MAX_CURVE_POINTS", "contact_bifurcation",
    "continue_bifurcation", "CONTINUATION_VERSION", "IMPACT_COLUMNS",
    "LOCATE_TOL", "MAX_ORBIT_IMPACTS", "MAX_ORBIT_PERIOD", "MAX_POINTS", "NEWTON_TOL",
    "PARAMETERS", "POINT_COLUMNS", "TERMINAL", "Bifurcation", "ContinuationError",
    "ContinuationResult", "PeriodicOrbit", "c_orbit", "continue_orbit", "find_orbit",
    "orbit_from_trajectory", "solve_orbit", "stick_orbit",
]
