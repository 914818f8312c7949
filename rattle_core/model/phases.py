"""Phases: the paper's convention and the core's, and angles wrapped to (−180°, 180°].

The core writes the excitation literally, ``y = Σ h_k cos(k t − φ_k)``.  The paper's figures are
reproduced when its phases are read as ``y = Σ h_k sin(k t + φ_k)`` (sine reference, phase
lead; the evidence is in ``docs/phase_convention.md``).  Shifting time by a quarter period so
that the first harmonic keeps phase 0 turns that into the core's form with

    φ'_k = −φ_k − (k − 1)·90°,

so the paper's ``φ₂ = 45°`` and ``90°`` are core ``−135°`` and ``180°``.  The map is its own
inverse, so :func:`paper_to_core` and :func:`core_to_paper` compute the same thing and differ
only in what they say.
"""
from __future__ import annotations

from typing import Any, Iterable

import numpy as np


def wrap_deg(angle: Any) -> Any:
    """Angle in degrees wrapped to (−180, 180]; a float for a scalar, else an array.

    ``fmod`` is exact, so multiples of 45° (the paper's phases) stay exact.
    """
    a = np.fmod(np.asarray(angle, dtype=np.float64), 360.0)
    w = np.where(a <= -180.0, a + 360.0, np.where(a > 180.0, a - 360.0, a)) + 0.0
    return float(w) if w.ndim == 0 else w


def paper_to_core(phi_deg: Any, k: int = 2, wrap: bool = True) -> Any:
    """Core phase of harmonic ``k`` from the paper's, ``−φ − (k − 1)·90°`` (degrees).

    Scalars give floats and arrays give arrays.  ``wrap=False`` keeps the result unwrapped, so
    that a sweep of the paper's phase over 0…360° stays monotone.
    """
    out = -np.asarray(phi_deg, dtype=np.float64) - 90.0 * (k - 1)
    if wrap:
        return wrap_deg(out)
    return float(out) if out.ndim == 0 else out


def core_to_paper(phi_deg: Any, k: int = 2, wrap: bool = True) -> Any:
    """The paper's phase of harmonic ``k`` from the core's (the inverse of :func:`paper_to_core`,
    which is the same map)."""
    return paper_to_core(phi_deg, k, wrap)


def paper_to_core_phases(phases_deg: Iterable[float]) -> tuple[float, ...]:
    """All phases ``φ_1 … φ_K`` from the paper's convention to the core's, wrapped."""
    return tuple(paper_to_core(p, k) for k, p in enumerate(phases_deg, start=1))
