"""Poincaré sections of a trajectory: the stroboscopic map and the impact map.

* Stroboscopic map: ``(x, ẋ)`` at ``t = 2π n + θ``, absolute or relative to the driving tooth
  ``(x − y, ẋ − ẏ)``.  Any θ: the trajectory is re-sampled exactly when θ differs from the
  phase it was simulated with.
* Impact map: ``(t mod 2π, Ĩ)`` at each impact, the classic section of impact oscillators.
"""
from __future__ import annotations

import numpy as np

from ..model.excitation import TWO_PI, excitation
from ..model.params import check_range
from ..solver.trajectory import Trajectory


def poincare(tr: Trajectory, relative: bool = False, phase: float | None = None
             ) -> tuple[np.ndarray, np.ndarray]:
    """Stroboscopic samples of ``tr``.

    Parameters
    ----------
    tr : Trajectory
    relative : bool
        Return ``(x − y, ẋ − ẏ)`` instead of ``(x, ẋ)``.
    phase : float, optional
        Section phase θ (radians). Defaults to the phase ``tr`` was simulated with.

    Returns
    -------
    x, v : ndarray
    """
    if phase is None or np.isclose(check_range("phase", phase, -1e6, 1e6) % TWO_PI, tr.strobe_phase):
        t, x, v = tr.strobe_t, tr.strobe_x, tr.strobe_v
    else:
        theta = phase % TWO_PI
        first = np.ceil((tr.t_start - theta) / TWO_PI)
        last = np.floor((tr.t_end - theta) / TWO_PI)
        t = (np.arange(first, last + 1) * TWO_PI + theta)
        t = t[(t >= tr.t_start) & (t < tr.t_end)]
        x, v = tr.sample(t)
    if relative:
        p = tr.params
        return x - excitation(t, p.h, p.phi), v - excitation(t, p.h, p.phi, 1)
    return x, v


def impact_map(tr: Trajectory) -> tuple[np.ndarray, np.ndarray]:
    """Impact phases ``t mod 2π`` and signed impulses ``Ĩ`` of ``tr``."""
    return tr.impact_phase, tr.impact_impulse
