"""Rattle Explorer's computational core: exact event-driven gear-rattle dynamics.

Layers, each importing only those before it:
``params`` → ``excitation`` → ``events`` → ``solver`` → ``trajectory`` → ``sections``,
``classify``, ``continuation`` → ``sweep`` → ``cache``.
"""
from . import jitcache

jitcache.refresh()

from .classify import Classification, classify, contact_boundary, one_sided_impulse
from .continuation import (Bifurcation, ContinuationResult, PeriodicOrbit, continue_orbit,
                           find_orbit)
from .excitation import excitation
from .params import RattleParams
from .sections import impact_map, poincare
from .sweep import SweepResult
from .sweep import sweep as sweep
from .trajectory import SOLVER_VERSION, SolverError, Trajectory, simulate

__all__ = ["RattleParams", "Trajectory", "simulate", "excitation", "SolverError", "SOLVER_VERSION",
           "poincare", "impact_map", "classify", "Classification", "contact_boundary",
           "one_sided_impulse", "sweep", "SweepResult", "continue_orbit", "find_orbit",
           "PeriodicOrbit", "Bifurcation", "ContinuationResult"]
