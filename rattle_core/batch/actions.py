"""What a verdict asks a team to do: its columns to act on (targets, rattle ranges, shares, the
drag or inertia that keeps each gear quiet), the closed forms behind them, and the drag that
meets a target (:mod:`rattle_core.batch.gearbox` adds the columns to its verdict).

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

Columns added to every row (gears, then the gearbox rows, ``gear`` = ``"gearbox"``):

``rattle_ranges``
    Every speed range in which the gear leaves permanent contact, ``1400-1900; 2200-3000``
    [rpm] (:func:`rattle_ranges`: edges at the closed-form contact
    boundary between grid speeds); the same on every row of a gear, empty on the gearbox's.
``share``
    The gear's share of the gearbox's A-weighted energy at that speed (0 to 1; NaN where
    nothing is heard); 1 on the gearbox rows where something is heard.
``drag_Nm``
    The gear's drag torque at that speed and the box's oil temperature [N·m].
``drag_to_quiet_Nm``, ``inertia_to_quiet_kgm2``
    The drag ``J R_d max(−θ̈_drive)/R_b = contact_ratio · C`` [N·m] and the inertia
    ``J / contact_ratio`` [kg·m²] that put the gear exactly on the contact boundary.
``target_sone``, ``margin_sone``, ``target_dba``, ``margin_dba``
    The target's limits at that speed and the margins, limit minus value.  NaN where the
    target gives no such limit; a silent point (no dB(A) level) has no ``margin_dba`` and
    passes it.
``pass``
    Whether every given margin is ≥ 0 (True when there is no target).

The drag that meets the target (:func:`drag_for_target`)
    The contact boundary's drag keeps a gear silent; a target may allow less.  The drag to add
    (the same at every speed and temperature) so that the gear alone passes its target at every
    speed of the verdict is found by bisection between 0 and the boundary's largest
    ``drag_to_quiet_Nm − drag_Nm`` (at which the gear stays in contact: silent, passing), each
    step a verdict of that gear with the verdict's own settings.  Bisection assumes that more
    drag is never louder, which holds for the contact boundary and, in the sweeps, for the
    rattle's loudness; the result is the upper end of the last bracket, which passes.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np
from scipy.optimize import brentq

from ..model.gearbox import Gearbox
from ..model.target import fail_ranges, format_ranges


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


#: The ``gear`` of the rows that describe all gears together.
GEARBOX = "gearbox"


def gear_ranges(gearbox: Gearbox, g: int, rpm: np.ndarray, regime: np.ndarray) -> list:
    """Gear ``g``'s rattle ranges [rpm] from its regimes at the speeds ``rpm``."""
    found = rattle_ranges(rpm, np.asarray(regime) != "A",
                          lambda x: float(gearbox.contact_ratio(g, [x])[0]))
    return [(float(a), float(b)) for a, b in found]


def add_columns(table, gearbox: Gearbox) -> None:
    """Add the module docstring's columns to a verdict's ``table`` in place (rows sorted by
    gear, then speed)."""
    names = [g.name for g in gearbox.gears]
    n = len(table)
    for key in ("share", "drag_Nm", "drag_to_quiet_Nm", "inertia_to_quiet_kgm2",
                "target_sone", "margin_sone", "target_dba", "margin_dba"):
        table[key] = np.full(n, math.nan)
    table["rattle_ranges"] = ""
    table["pass"] = True
    gear_col = table["gear"].to_numpy()
    rows = {name: np.flatnonzero(gear_col == name) for name in names + [GEARBOX]}
    for g, name in enumerate(names):
        idx = rows[name]
        if idx.size == 0:
            continue
        r = table["rpm"].to_numpy(float)[idx]
        drag = gearbox.drag_Nm(g, r)
        ratio = table["contact_ratio"].to_numpy(float)[idx]
        table.loc[idx, "drag_Nm"] = drag
        table.loc[idx, "drag_to_quiet_Nm"] = ratio * drag
        table.loc[idx, "inertia_to_quiet_kgm2"] = gearbox.gears[g].inertia_kgm2 / ratio
        table.loc[idx, "rattle_ranges"] = format_ranges(
            gear_ranges(gearbox, g, r, table["regime"].to_numpy()[idx]))
    if rows[GEARBOX].size and all(rows[nm].size == rows[GEARBOX].size for nm in names):
        spl = np.column_stack([table["spl_dba"].to_numpy(float)[rows[nm]] for nm in names])
        shares = energy_shares(spl)
        for g, name in enumerate(names):
            table.loc[rows[name], "share"] = shares[:, g]
        table.loc[rows[GEARBOX], "share"] = np.where(np.isnan(shares[:, 0]), math.nan, 1.0)
    target = gearbox.target
    if target is None:
        return
    r = table["rpm"].to_numpy(float)
    passed = np.ones(n, dtype=bool)
    for key, column in (("sone", "loudness_sone"), ("dba", "spl_dba")):
        if key not in target.limits:
            continue
        limit = target.limit(key, r)
        margin = limit - table[column].to_numpy(float)
        table[f"target_{key}"] = limit
        table[f"margin_{key}"] = margin
        passed &= ~(margin < 0)  # NaN (silent) passes
    table["pass"] = passed


def ranges(result) -> dict[str, list[tuple[float, float]]]:
    """Each gear's rattle ranges [rpm] in a verdict."""
    box = result.gearbox
    return {g.name: gear_ranges(box, i, (rows := result.gear(g.name))["rpm"].to_numpy(float),
                                rows["regime"].to_numpy())
            for i, g in enumerate(box.gears)}


def failing(result) -> dict[str, list[tuple[float, float]]]:
    """Each gear's and the gearbox's failing speed ranges (empty without a target)."""
    out = {}
    for name in [g.name for g in result.gearbox.gears] + [GEARBOX]:
        rows = result.gear(name)
        out[name] = [(float(a), float(b)) for a, b in
                     fail_ranges(rows["rpm"].to_numpy(float), rows["pass"].to_numpy(bool))]
    return out


def ranking(result) -> list[str]:
    """Gear names, loudest first by A-weighted energy summed over the speeds."""
    energy = {}
    for g in result.gearbox.gears:
        spl = result.gear(g.name)["spl_dba"].to_numpy(float)
        energy[g.name] = float(np.sum(10.0 ** (spl[np.isfinite(spl)] / 10.0)))
    return sorted(energy, key=lambda k: -energy[k])


def summaries(result) -> dict[str, str]:
    """One sentence per gear: the drag to add or the inertia to remove to keep it quiet."""
    out = {}
    for g in result.gearbox.gears:
        rows = result.gear(g.name)
        out[g.name] = quiet_summary(g.name, rows["drag_Nm"].to_numpy(float),
                                    rows["contact_ratio"].to_numpy(float), g.inertia_kgm2,
                                    rows["rpm"].to_numpy(float))["line"]
    return out


def added_drag(gear, delta_Nm: float):
    """``gear`` with ``delta_Nm`` [N·m] more drag at every speed and temperature."""
    d = gear.drag
    if d.kind == "constant":
        return gear.replace(drag_torque_Nm=d.value_Nm + delta_Nm)
    if d.kind == "oil":
        return gear.replace(drag=dataclasses.replace(d, bush_Nm=d.bush_Nm + delta_Nm))
    table = np.asarray(d.torque_Nm, dtype=float) + delta_Nm
    rows = tuple(map(tuple, table.tolist())) if d.temp_C else tuple(table.tolist())
    return gear.replace(drag=dataclasses.replace(d, torque_Nm=rows))


def scaled_drag(gear, factor: float):
    """``gear`` with its drag times ``factor`` (> 0) at every speed and temperature."""
    factor = float(factor)
    if not (math.isfinite(factor) and factor > 0):
        raise ValueError(f"drag factor = {factor!r} must be a positive number")
    d = gear.drag
    if d.kind == "constant":
        return gear.replace(drag_torque_Nm=d.value_Nm * factor)
    if d.kind == "oil":
        return gear.replace(drag=dataclasses.replace(d, bush_Nm=d.bush_Nm * factor,
                                                     churn_Nm=d.churn_Nm * factor))
    table = np.asarray(d.torque_Nm, dtype=float) * factor
    rows = tuple(map(tuple, table.tolist())) if d.temp_C else tuple(table.tolist())
    return gear.replace(drag=dataclasses.replace(d, torque_Nm=rows))


def drag_for_target(result, name: str, run, tol_Nm: float | None = None,
                    max_steps: int = 12) -> float:
    """The drag [N·m] to add to gear ``name`` so that it meets the verdict's target at every
    speed (module docstring); 0 when it does already.  ``run`` is the verdict function that
    made ``result`` (passed in, since the verdict's module imports this one); ``tol_Nm`` is the
    bracket's final width (default 1 % of the boundary's drag to add)."""
    box = result.gearbox
    if box.target is None:
        raise ValueError("drag_for_target needs a target: give the gearbox a [target] or "
                         "verdict(..., target=...)")
    names = [g.name for g in box.gears]
    if name not in names:
        raise ValueError(f"gear {name!r:.100} is not in this gearbox; the gears are {names}")
    rows = result.gear(name)
    if bool(rows["pass"].all()):
        return 0.0
    g = names.index(name)
    hi = float(np.nanmax(rows["drag_to_quiet_Nm"] - rows["drag_Nm"]))
    hi = max(hi, 0.0) * 1.001 + 1e-9  # just past the boundary: permanent contact
    tol = 0.01 * hi if tol_Nm is None else float(tol_Nm)
    if not (math.isfinite(tol) and tol > 0):
        raise ValueError(f"tol_Nm = {tol_Nm!r} must be a positive number of N·m")
    st = result.settings
    rpm = rows["rpm"].to_numpy(float)

    def passes(delta: float) -> bool:
        one = box.replace(gears=(added_drag(box.gears[g], delta),))
        res = run(one, rpm, transient=st["transient"], record=st["record"],
                      ensemble_runs=st["ensemble_runs"])
        return bool(res.gear(name)["pass"].all())
    lo = 0.0
    for _ in range(max_steps):
        if hi - lo <= tol:
            break
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if passes(mid) else (mid, hi)
    return hi


__all__ = ["rattle_ranges", "quiet_summary", "energy_shares", "added_drag", "scaled_drag",
           "drag_for_target", "add_columns", "gear_ranges", "ranges", "failing", "ranking",
           "summaries", "GEARBOX"]
