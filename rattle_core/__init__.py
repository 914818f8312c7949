"""Rattle Explorer's computational core: exact event-driven gear-rattle dynamics.

Layers, each importing only those listed before it (``docs/model.md`` is the specification;
``tests/test_layers.py`` enforces the order)::

    model     params, excitation, phases, units, engine, orders, gearbox
    solver    events, kernel, trajectory
    analysis  sections, classify, overlays, vocabulary, sound, loudness, continuation
    batch     chunks, executor, sweep, maps, plan, gearbox
    store     files, cache, assets, requests, exports, verdicts
    paper     cases, figures, evidence, drawing

The names below are the public entry points, importable from ``rattle_core`` itself.
"""
from . import jitcache

jitcache.refresh()

from .analysis.classify import Classification, classify
from .analysis.continuation import (Bifurcation, BifurcationCurve, ContinuationResult,
                                    PeriodicOrbit, contact_bifurcation, continue_bifurcation,
                                    continue_orbit, find_orbit)
from .analysis.overlays import contact_boundary, one_sided_impulse
from .analysis.sections import impact_map, poincare
from .batch.ensemble import NoiseSensitivity, Statistics, noise_sensitivity, statistics
from .batch.sweep import SweepResult
from .batch.sweep import sweep as sweep
from .model import units
from .model.excitation import excitation
from .model.params import RattleParams
from .solver.trajectory import SOLVER_VERSION, SolverError, Trajectory, simulate

__all__ = ["RattleParams", "Trajectory", "simulate", "excitation", "SolverError", "SOLVER_VERSION",
           "poincare", "impact_map", "classify", "Classification", "contact_boundary",
           "one_sided_impulse", "sweep", "SweepResult", "units", "continue_orbit", "find_orbit",
           "PeriodicOrbit", "Bifurcation", "ContinuationResult", "statistics", "Statistics",
           "noise_sensitivity", "NoiseSensitivity", "continue_bifurcation",
           "contact_bifurcation", "BifurcationCurve"]
