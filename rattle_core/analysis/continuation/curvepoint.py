"""A point of a bifurcation curve: the orbit there, whether it is an orbit of the model, and
where it lies in the plane (for messages).

The curve's loop (:mod:`.twoparam`), its codimension-two points (:mod:`.codim2`) and the
restarts at them (:mod:`.bifcurve`) all read a point ``X = (z, q₁, q₂)`` of an extended
system this way.
"""
from __future__ import annotations

import numpy as np

from .admissibility import ADMISSIBLE, _inspect
from .defining import _Extended
from .orbits import PeriodicOrbit, _impact_orbit
from .sticking import _w_min


def _orbit(ext: _Extended, X) -> PeriodicOrbit:
    """The orbit at curve point ``X`` (a grazing curve's flight touches its wall by
    definition, so the event search does not judge it)."""
    return _impact_orbit(ext.plane.params(X[-2], X[-1]), X[:-2].copy(), ext.fl, ext.n,
                         check=ext.cond.kind != "grazing")


def _admissible(ext: _Extended, orb: PeriodicOrbit) -> bool:
    """Whether ``orb`` is an orbit of the model, but for what the curve's condition makes it:
    the touching flight of a grazing, the impact at ``v_stick`` of an onset of sticking."""
    kind = ext.cond.kind
    if kind not in ("grazing", "stick_onset"):
        return orb.admissible
    p = orb.params
    m = orb.n_impacts
    gmin, gs, contact = np.empty(m), np.empty(m), np.empty(m)
    gw = np.empty(m, dtype=np.int64)
    z = np.empty(2 * m)
    z[0::2], z[1::2] = orb.t, orb.u
    if kind == "stick_onset":
        # its impact is at v_stick by definition: judge the rest with a smaller threshold
        code = _inspect(z, ext.fl, ext.n, p.lam, p.r, p.j, p.h, p.phi, 0.5 * ext.cond.v_eff,
                        True, gmin, gs, gw, contact)
        return code == ADMISSIBLE
    # the grazing flight touches its wall by definition; every other flight must stay clear
    _inspect(z, ext.fl, ext.n, p.lam, p.r, p.j, p.h, p.phi, p.v_stick, False, gmin, gs, gw,
             contact)
    others = np.delete(gmin, ext.cond.k)
    return bool(np.all(others > -1e-12)) and _w_min(orb) > 0.0


def _where(ext: _Extended, X) -> str:
    """``param1 = …, param2 = …`` at ``X``, in the parameters' units."""
    v1, v2 = ext.plane.value_of(X[-2], X[-1])
    return f"{ext.plane.spec1.name} = {v1:.10g}, {ext.plane.spec2.name} = {v2:.10g}"
