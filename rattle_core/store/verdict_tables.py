"""A gearbox verdict as people read it: its targets and margins, every rattle range, a sentence
per gear, and two designs side by side.

The CLI, the dashboard and the report all read a verdict through these functions, so a verdict
is worded the same way everywhere.  Columns the verdict already holds are taken as they are;
a verdict without them (an older cached one) gets them here, from the same closed forms:

``target_sone``, ``margin_sone``, ``target_dba``, ``margin_dba``, ``pass``
    The target's limit at each speed, the limit minus the value (sone, dB(A)), and whether
    every margin the row has is not negative (:mod:`rattle_core.model.target`).
Ranges and sentences
    Every rattle range of a gear (:func:`~rattle_core.batch.actions.rattle_ranges`) and the
    drag or inertia that keeps it quiet (:func:`~rattle_core.batch.actions.quiet_summary`).
Two designs
    :func:`compare_frame` stacks two verdicts with a ``design`` column and adds difference rows
    (``design`` = ``B - A``): numbers as B minus A, per gear and speed; text columns (regime,
    pass, ranges) as ``a -> b`` where they differ.
"""
from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

from ..batch.actions import quiet_summary, rattle_ranges
from ..model.target import METRICS, Target, fail_ranges, format_ranges

if TYPE_CHECKING:
    import pandas as pd

#: The gearbox rows' ``gear``.
GEARBOX = "gearbox"
#: Units of the verdict's columns, as the report's and the CSV's headers name them.
UNITS = {"rpm": "rpm", "impacts_per_s": "1/s", "intensity": "N²·s", "loudness_sone": "sone",
         "sharpness_acum": "acum", "onset_rpm": "rpm", "impacts_per_s_ci95": "1/s",
         "intensity_ci95": "N²·s", "contact_ratio": "1", "lam": "1", "j": "1", "spl_dba": "dB(A)",
         "spl_dba_max": "dB(A)", "target_sone": "sone", "margin_sone": "sone",
         "target_dba": "dB(A)", "margin_dba": "dB(A)", "share": "1", "drag_Nm": "N·m",
         "drag_to_quiet_Nm": "N·m", "inertia_to_quiet_kgm2": "kg·m²", "oil_temp_C": "°C",
         "rattle_ranges": "rpm"}
#: What the text columns hold, in place of a unit.
TEXT_UNITS = {"gear": "name", "regime": "A–E, P, Q", "interval": "how", "pass": "true/false",
              "design": "name", "attractors": "count"}
#: Columns compared between two designs (those a verdict has).
COMPARED = ("onset_rpm", "loudness_sone", "spl_dba", "spl_dba_max", "margin_sone", "margin_dba",
            "impacts_per_s", "intensity")
#: Text columns compared as ``a -> b``.
COMPARED_TEXT = ("regime", "pass", "rattle_ranges")


def gear_names(result: Any) -> list[str]:
    return [g.name for g in result.gearbox.gears]


def target_of(result: Any, target: Target | None = None) -> Target | None:
    """The target a verdict is judged by: ``target`` if given, else its gearbox's (if any)."""
    return target if target is not None else getattr(result.gearbox, "target", None)


def with_target(table: "pd.DataFrame", target: Target | None) -> "pd.DataFrame":
    """``table`` with the target columns (module docstring); added only where missing."""
    if target is None:
        return table
    out = table.copy()
    rpm = out["rpm"].to_numpy(dtype=float)
    passed = np.ones(len(out), dtype=bool)
    added = False
    for key in target.limits:
        value = METRICS[key][0]
        if value not in out:
            continue
        if f"margin_{key}" not in out:
            out[f"target_{key}"] = target.limit(key, rpm)
            out[f"margin_{key}"] = out[f"target_{key}"] - out[value].to_numpy(dtype=float)
            added = True
        m = out[f"margin_{key}"].to_numpy(dtype=float)
        passed &= ~(m < 0)
    if added or "pass" not in out:
        out["pass"] = passed
    return out


def frame(result: Any, target: Target | None = None) -> "pd.DataFrame":
    """A verdict's table with its target columns and each gear's ``rattle_ranges``."""
    table = with_target(result.table, target_of(result, target))
    if "rattle_ranges" not in table:
        table = table.copy()
        table["rattle_ranges"] = table["gear"].map(
            {n: format_ranges(r) for n, r in ranges(result).items()}).fillna("")
    return table


def ranges(result: Any) -> dict[str, list[tuple[float, float]]]:
    """Every rattle range per gear, edges located on the closed-form contact boundary."""
    own = getattr(result, "ranges", None)
    if isinstance(own, dict):
        return own
    out = {}
    for i, name in enumerate(gear_names(result)):
        rows = result.gear(name)
        rpm = rows["rpm"].to_numpy(dtype=float)
        if not rpm.size:
            out[name] = []
            continue
        out[name] = rattle_ranges(rpm, rows["regime"].to_numpy() != "A",
                                  lambda x, i=i: float(result.gearbox.contact_ratio(i, [x])[0]))
    return out


def failing(result: Any, target: Target | None = None) -> dict[str, list[tuple[float, float]]]:
    """The speed ranges in which each gear and the gearbox miss the target (empty: none)."""
    t = frame(result, target)
    if "pass" not in t:
        return {}
    out = {}
    for name in gear_names(result) + [GEARBOX]:
        rows = t[t["gear"] == name].sort_values("rpm")
        out[name] = fail_ranges(rows["rpm"].to_numpy(dtype=float), rows["pass"].to_numpy(dtype=bool))
    return out


def summaries(result: Any) -> dict[str, str]:
    """One sentence per gear: what keeps it quiet over the verdict's speeds."""
    own = getattr(result, "summaries", None)
    if isinstance(own, dict) and own:
        return own
    out = {}
    for g in result.gearbox.gears:
        rows = result.gear(g.name)
        drag = (rows["drag_Nm"].to_numpy(dtype=float) if "drag_Nm" in rows
                else np.full(len(rows), getattr(g, "drag_torque_Nm", math.nan), dtype=float))
        out[g.name] = quiet_summary(g.name, drag, rows["contact_ratio"].to_numpy(dtype=float),
                                    g.inertia_kgm2, rows["rpm"].to_numpy(dtype=float))["line"]
    return out


def onset_text(value: float) -> str:
    return f"rattles from {value:g} rpm" if math.isfinite(value) else "never leaves contact"


def gear_lines(result: Any, target: Target | None = None) -> list[str]:
    """What the CLI prints and the report lists: per gear its onset, ranges, failing ranges and
    sentence, then the gearbox's loudest point and its failing ranges."""
    rng, fails, says = ranges(result), failing(result, target), summaries(result)
    lines = []
    for name, onset in result.onsets.items():
        text = f"{name}: {onset_text(onset)}"
        if rng.get(name):
            text += f" (rattles {format_ranges(rng[name])} rpm)"
        if fails.get(name):
            text += f"; misses the target at {format_ranges(fails[name])} rpm"
        lines.append(text)
        if says.get(name):
            lines.append(f"  {says[name]}")
    box = result.gear(GEARBOX)
    text = f"{GEARBOX}: up to {box['loudness_sone'].max():.3g} sone"
    if "spl_dba" in box:
        text += f", {box['spl_dba'].max():.3g} dB(A)"
    if fails.get(GEARBOX):
        text += f"; misses the target at {format_ranges(fails[GEARBOX])} rpm"
    elif fails:
        text += "; meets the target at every speed"
    lines.append(text)
    return lines


def design_names(a: str, b: str) -> tuple[str, str]:
    """The ``design`` values of two designs: their names, told apart when they are equal."""
    return (a, b) if a != b else (f"A: {a}", f"B: {b}")


def compare_frame(a: Any, b: Any, names: tuple[str, str], target: Target | None = None
                  ) -> "pd.DataFrame":
    """Two verdicts stacked with a ``design`` column, then their ``B - A`` rows (module
    docstring) for the gears both have and the gearbox, speed by speed."""
    import pandas as pd
    ta, tb = frame(a, target), frame(b, target)
    diff = ta.merge(tb, on=["gear", "rpm"], suffixes=("_a", "_b"), how="inner")
    rows = {"gear": diff["gear"], "rpm": diff["rpm"]}
    for c in COMPARED:
        if f"{c}_a" in diff and f"{c}_b" in diff:
            rows[c] = diff[f"{c}_b"].to_numpy(dtype=float) - diff[f"{c}_a"].to_numpy(dtype=float)
    for c in COMPARED_TEXT:
        if f"{c}_a" in diff and f"{c}_b" in diff:
            rows[c] = [x if str(x) == str(y) else f"{x} -> {y}"
                       for x, y in zip(diff[f"{c}_a"], diff[f"{c}_b"])]
    d = pd.DataFrame(rows)
    d.insert(0, "design", "B - A")
    out = pd.concat([ta.assign(design=names[0]), tb.assign(design=names[1]), d], ignore_index=True)
    return out[["design"] + [c for c in out.columns if c != "design"]]


def compare_lines(a: Any, b: Any, names: tuple[str, str], target: Target | None = None
                  ) -> list[str]:
    """Both designs per gear on one line each: onsets, ranges and the gearbox's loudness."""
    ra, rb = ranges(a), ranges(b)
    fa, fb = failing(a, target), failing(b, target)
    lines = [f"A = {names[0]}, B = {names[1]}"]
    for name in dict.fromkeys(list(a.onsets) + list(b.onsets)):
        def one(res, rng, name=name):
            if name not in res.onsets:
                return "no such gear"
            text = onset_text(res.onsets[name])
            return text + (f" ({format_ranges(rng[name])})" if rng.get(name) else "")
        lines.append(f"{name}: A {one(a, ra)} | B {one(b, rb)}")
    la, lb = a.gear(GEARBOX), b.gear(GEARBOX)
    text = (f"{GEARBOX}: A up to {la['loudness_sone'].max():.3g} sone | "
            f"B up to {lb['loudness_sone'].max():.3g} sone")
    if "spl_dba" in la and "spl_dba" in lb:
        text += f"; A {la['spl_dba'].max():.3g} dB(A) | B {lb['spl_dba'].max():.3g} dB(A)"
    lines.append(text)
    if fa or fb:
        lines.append(f"target: A fails at {format_ranges(fa.get(GEARBOX, [])) or 'no speed'} | "
                     f"B fails at {format_ranges(fb.get(GEARBOX, [])) or 'no speed'}")
    return lines


def with_units(table: "pd.DataFrame") -> "pd.DataFrame":
    """``table`` with each header carrying its unit (``loudness_sone [sone]``) or, for text,
    what it holds (``regime [A–E, P, Q]``); a column of no known kind is marked ``[1]``."""
    known = {**UNITS, **TEXT_UNITS}
    return table.rename(columns={c: f"{c} [{known.get(c, '1')}]" for c in table.columns})


__all__ = ["frame", "with_target", "ranges", "failing", "summaries", "gear_lines",
           "compare_frame", "compare_lines", "design_names", "with_units", "UNITS", "target_of"]
