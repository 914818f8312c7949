"""A gearbox verdict as people read it: every rattle range, a sentence per gear, its failing
ranges, and two designs side by side.

The CLI, the dashboard and the report all read a verdict through these functions, so a verdict
is worded the same way everywhere.  The verdict holds every column, its ranges and sentences
(:mod:`rattle_core.batch.gearbox`); its target is its gearbox's (give another with
``verdict(..., target=)`` or :meth:`~rattle_core.model.gearbox.Gearbox.replace`).

Two designs
    :func:`compare_frame` stacks two verdicts with a ``design`` column and adds difference rows
    (``design`` = ``B - A``): numbers as B minus A, per gear and speed; text columns (regime,
    pass, ranges) as ``a -> b`` where they differ.
"""
from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

from ..batch.gearbox import GEARBOX
from ..model.target import Target, format_ranges

if TYPE_CHECKING:
    import pandas as pd

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
#: Columns compared between two designs.
COMPARED = ("onset_rpm", "loudness_sone", "spl_dba", "spl_dba_max", "margin_sone", "margin_dba",
            "impacts_per_s", "intensity")
#: Text columns compared as ``a -> b``.
COMPARED_TEXT = ("regime", "pass", "rattle_ranges")


def gear_names(result: Any) -> list[str]:
    return [g.name for g in result.gearbox.gears]


def target_of(result: Any) -> Target | None:
    """The target a verdict was judged by (its gearbox's), or None."""
    return result.gearbox.target


def target_text(target: Target) -> str:
    """``target`` in the CLI's text form, which :meth:`~rattle_core.model.target.Target.parse`
    reads back: ``1000:10,3000:20 sone; 1000:60,3000:70 dba``."""
    return "; ".join(",".join(f"{r:g}:{v:g}" for r, v in zip(target.rpm, vals)) + f" {key}"
                     for key, vals in target.limits.items())


def frame(result: Any) -> "pd.DataFrame":
    """A verdict's table, every column (module docstring), as a copy to extend."""
    return result.table.copy()


def ranges(result: Any) -> dict[str, list[tuple[float, float]]]:
    """Every rattle range per gear, edges located on the closed-form contact boundary."""
    return result.ranges


def failing(result: Any) -> dict[str, list[tuple[float, float]]]:
    """The speed ranges in which each gear and the gearbox miss the target (empty: none, or
    no target)."""
    return result.fail_ranges if target_of(result) is not None else {}


def summaries(result: Any) -> dict[str, str]:
    """One sentence per gear: what keeps it quiet over the verdict's speeds."""
    return result.summaries


def onset_text(value: float) -> str:
    return f"rattles from {value:g} rpm" if math.isfinite(value) else "never leaves contact"


def gear_lines(result: Any) -> list[str]:
    """What the CLI prints and the report lists: per gear its onset, ranges, failing ranges and
    sentence, then the gearbox's loudest point and its failing ranges."""
    rng, fails, says = ranges(result), failing(result), summaries(result)
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
    text += f", {box['spl_dba'].max():.3g} dB(A)"
    if fails.get(GEARBOX):
        text += f"; misses the target at {format_ranges(fails[GEARBOX])} rpm"
    elif target_of(result) is not None:
        text += "; meets the target at every speed"
    lines.append(text)
    return lines


def design_names(a: str, b: str) -> tuple[str, str]:
    """The ``design`` values of two designs: their names, told apart when they are equal."""
    return (a, b) if a != b else (f"A: {a}", f"B: {b}")


def compare_frame(a: Any, b: Any, names: tuple[str, str]) -> "pd.DataFrame":
    """Two verdicts stacked with a ``design`` column, then their ``B - A`` rows (module
    docstring) for the gears both have and the gearbox, speed by speed."""
    import pandas as pd
    ta, tb = frame(a), frame(b)
    diff = ta.merge(tb, on=["gear", "rpm"], suffixes=("_a", "_b"), how="inner")
    rows = {"gear": diff["gear"], "rpm": diff["rpm"]}
    for c in COMPARED:
        rows[c] = diff[f"{c}_b"].to_numpy(dtype=float) - diff[f"{c}_a"].to_numpy(dtype=float)
    for c in COMPARED_TEXT:
        rows[c] = [x if str(x) == str(y) else f"{x} -> {y}"
                   for x, y in zip(diff[f"{c}_a"], diff[f"{c}_b"])]
    d = pd.DataFrame(rows)
    d.insert(0, "design", "B - A")
    out = pd.concat([ta.assign(design=names[0]), tb.assign(design=names[1]), d], ignore_index=True)
    return out[["design"] + [c for c in out.columns if c != "design"]]


def compare_lines(a: Any, b: Any, names: tuple[str, str]) -> list[str]:
    """Both designs per gear on one line each: onsets, ranges and the gearbox's loudness."""
    ra, rb = ranges(a), ranges(b)
    fa, fb = failing(a), failing(b)
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


__all__ = ["frame", "ranges", "failing", "summaries", "gear_lines",
           "compare_frame", "compare_lines", "design_names", "with_units", "UNITS", "target_of",
           "target_text",
           "GEARBOX"]
