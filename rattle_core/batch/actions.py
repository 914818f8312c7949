"""What a verdict asks a team to do: every rattle range, each gear's share and rank, and the drag
or inertia that keeps a gear quiet.

Every rattle range
    A gear rattles where it leaves permanent contact (regime other than ``A``).  Its ranges are
    the runs of rattling grid speeds.  Each edge lies between two grid speeds; where the
    closed-form contact ratio crosses 1 between them, the edge is that crossing, located by
    Brent's method to 0.01 rpm.  Above the contact boundary permanent contact is impossible,
    below it the gear may still rattle on a coexisting attractor: an edge without a crossing
    stays at the first rattling (or last rattling) grid speed.
The drag and inertia that keep a gear quiet
    Permanent contact holds while the drag torque ``C`` exceeds the inertia torque that would
    pull the gear off its driving tooth, ``C ≥ J R_d max(−θ̈_drive) / R_b``
    (``docs/model.md``, "Physical units"; ``θ_drive`` is the speed ratio times the shaft's
    fluctuation).  So at each speed

    ``drag_to_quiet_Nm = J R_d max(−θ̈_drive) / R_b = contact_ratio · C`` and
    ``inertia_to_quiet_kgm2 = C R_b / (R_d max(−θ̈_drive)) = J / contact_ratio``,

    closed forms of the measured orders.  Over a speed range the drag to add is the largest
    ``drag_to_quiet_Nm − C`` and the inertia to remove the largest ``1 − 1/contact_ratio``.
Shares and rank
    The gears are incoherent sources (:mod:`rattle_core.batch.gearbox`), so at each speed a
    gear's share of the gearbox's sound is its share of the summed A-weighted energy
    ``10^(L_Aeq/10)``; the rank orders gears by their energy summed over all speeds.
"""
from __future__ import annotations

import math

import numpy as np
from scipy.optimize import brentq


def rattle_ranges(rpm: np.ndarray, rattles: np.ndarray, ratio) -> list[tuple[float, float]]:
    """The speed ranges in which a gear rattles (module docstring).

    Parameters
    ----------
    rpm : ndarray
        The verdict's increasing speeds.
    rattles : ndarray of bool
        Whether the gear leaves permanent contact at each speed.
    ratio : callable(rpm) -> float
        The closed-form contact ratio at any speed between the grid's.
    """
    rpm = np.asarray(rpm, dtype=float)
    rattles = np.asarray(rattles, dtype=bool)
    out, start = [], None
    for i, on in enumerate(rattles):
        if on and start is None:
            start = rpm[0] if i == 0 else _edge(ratio, rpm[i - 1], rpm[i], rpm[i])
        if not on and start is not None:
            out.append((start, _edge(ratio, rpm[i - 1], rpm[i], rpm[i - 1])))
            start = None
    if start is not None:
        out.append((start, rpm[-1]))
    return out


def _edge(ratio, lo: float, hi: float, fallback: float) -> float:
    f = lambda x: float(ratio(x)) - 1.0  # noqa: E731
    a, b = f(lo), f(hi)
    if not (math.isfinite(a) and math.isfinite(b)) or a * b > 0 or a == b:
        return float(fallback)
    return float(brentq(f, lo, hi, xtol=0.01))


def quiet_summary(name: str, drag_Nm: np.ndarray, ratio: np.ndarray, inertia_kgm2: float,
                  rpm: np.ndarray) -> dict:
    """The drag to add and the share of inertia to remove that keep a gear quiet over ``rpm``.

    Returns ``drag_add_Nm`` (≥ 0), ``inertia_remove`` (a fraction in [0, 1)) and ``line``, the
    sentence a report prints.
    """
    drag_Nm, ratio = np.asarray(drag_Nm, float), np.asarray(ratio, float)
    ok = np.isfinite(ratio)
    if not np.any(ok):
        return {"drag_add_Nm": math.nan, "inertia_remove": math.nan, "line": f"{name}: no speeds"}
    add = float(max(0.0, np.max(ratio[ok] * drag_Nm[ok] - drag_Nm[ok])))
    remove = float(max(0.0, 1.0 - 1.0 / np.max(ratio[ok])))
    top = float(np.max(np.asarray(rpm, float)[ok]))
    if add == 0.0:
        line = f"{name} stays in contact up to {top:.0f} rpm: nothing to change"
    else:
        line = (f"add {add:.3g} N·m of drag, or remove {100 * remove:.0f} % of inertia "
                f"({remove * inertia_kgm2:.3g} kg·m²), to keep {name} quiet up to {top:.0f} rpm")
    return {"drag_add_Nm": add, "inertia_remove": remove, "line": line}


def energy_shares(spl_dba: np.ndarray) -> np.ndarray:
    """Each source's share of the summed energy ``10^(L/10)`` along the last axis (NaN if silent)."""
    e = np.where(np.isfinite(spl_dba), 10.0 ** (np.asarray(spl_dba, float) / 10.0), 0.0)
    total = e.sum(axis=-1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(total > 0, e / total, np.nan)


__all__ = ["rattle_ranges", "quiet_summary", "energy_shares"]
