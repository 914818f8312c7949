"""Rattle Explorer's computational core: exact event-driven gear-rattle dynamics.

Layers, each importing only those before it:
``params`` → ``excitation`` → ``events`` → ``solver`` → ``trajectory``.
"""
from .excitation import excitation
from .params import RattleParams
from .trajectory import SOLVER_VERSION, SolverError, Trajectory, simulate

__all__ = ["RattleParams", "Trajectory", "simulate", "excitation", "SolverError", "SOLVER_VERSION"]
