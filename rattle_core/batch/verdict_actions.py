"""The columns of a gearbox verdict that a team acts on: targets, rattle ranges, shares and
the drag or inertia that keeps each gear quiet (:mod:`rattle_core.batch.actions` gives the
closed forms; :mod:`rattle_core.batch.gearbox` the verdict they are added to).

Columns added to every row (gears, then the gearbox rows, ``gear`` = ``"gearbox"``):

``rattle_ranges``
    Every speed range in which the gear leaves permanent contact, ``1400-1900; 2200-3000``
    [rpm] (:func:`~rattle_core.batch.actions.rattle_ranges`: edges at the closed-form contact
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

from ..model.gearbox import Gearbox
from ..model.target import fail_ranges, format_ranges
from .actions import energy_shares, quiet_summary, rattle_ranges

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


__all__ = ["added_drag", "drag_for_target", "add_columns", "gear_ranges", "ranges", "failing", "ranking", "summaries", "GEARBOX"]
