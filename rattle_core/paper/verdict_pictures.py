"""matplotlib pictures of gearbox verdicts beyond one design: two designs in one figure (B
dashed), the target as a line with the failing speed ranges shaded, and the map over engine
speed × oil temperature.  Shared by the CLI and the dashboard's report."""
from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from ..analysis.vocabulary import LETTERS, REGIME_COLOURS
from ..model.target import Target
from ..store.verdict_tables import GEARBOX, failing, gear_names
from .drawing import agg_figure

_DASH = ("-", "--")


def designs_png(path: Path | str, designs: list[tuple[Any, str]], title: str,
                target: Target | None = None) -> None:
    """One or two verdicts ``[(verdict, name), ...]``: regimes per gear (a strip per gear and
    design), each gear's and the gearbox's loudness (the second design dashed), the target's
    sone limit as a red line and the gearbox's failing ranges shaded (hatched for the second)."""
    from matplotlib.colors import ListedColormap
    from matplotlib.patches import Patch
    letters = list(LETTERS)
    strips = [(res, name, g) for res, name in designs for g in gear_names(res)]
    fig = agg_figure((10.0, 8.0), dpi=110)
    has_dba = all("spl_dba" in res.table for res, _ in designs)
    panels = 3 if has_dba else 2
    axes = fig.subplots(panels, 1, sharex=True,
                        gridspec_kw={"height_ratios": [max(1, len(strips)) * 0.3] + [1] * (panels - 1)})
    ax_r, ax_l = axes[0], axes[1]
    labels = []
    for k, (res, name, gear) in enumerate(strips):
        rows = res.gear(gear)
        rpm = rows["rpm"].to_numpy(dtype=float)
        edges = (np.concatenate([[rpm[0]], 0.5 * (rpm[1:] + rpm[:-1]), [rpm[-1]]]) if rpm.size > 1
                 else np.array([rpm[0] - 1, rpm[0] + 1]))
        codes = np.array([[letters.index(g) if g in letters else len(letters) - 1
                           for g in rows["regime"]]])
        ax_r.pcolormesh(edges, [k, k + 1], codes, shading="flat", vmin=-0.5,
                        vmax=len(letters) - 0.5,
                        cmap=ListedColormap([REGIME_COLOURS[g] for g in letters]))
        labels.append(gear if len(designs) == 1 else f"{gear} ({name})")
    ax_r.set_yticks(np.arange(len(strips)) + 0.5, labels, fontsize=7)
    ax_r.legend(handles=[Patch(color=REGIME_COLOURS[g], label=g) for g in letters[:-1]],
                loc="lower center", bbox_to_anchor=(0.5, 1.0), ncol=len(letters) - 1, fontsize=7,
                frameon=False)
    colours = {}
    for d, (res, name) in enumerate(designs):
        tail = "" if len(designs) == 1 else f" ({name})"
        for i, gear in enumerate(gear_names(res) + [GEARBOX]):
            rows = res.gear(gear)
            colour = "k" if gear == GEARBOX else colours.setdefault(gear, f"C{len(colours) % 10}")
            lw = 2 if gear == GEARBOX else 1
            ax_l.plot(rows["rpm"], rows["loudness_sone"], _DASH[d % 2], color=colour, lw=lw,
                      label=gear + tail)
            if has_dba:
                axes[2].plot(rows["rpm"], rows["spl_dba"], _DASH[d % 2], color=colour, lw=lw)
        shade_failing(ax_l, res, hatch=d == 1)
    if target is not None:
        lo, hi = ax_l.get_xlim()
        grid = np.linspace(lo, hi, 200)
        for key, ax in (("sone", ax_l), ("dba", axes[2] if has_dba else None)):
            if key in target.limits and ax is not None:
                ax.plot(grid, target.limit(key, grid), color="#d62728", lw=1.5, label="target")
    ax_l.set_ylabel("loudness N5 [sone]")
    ax_l.legend(fontsize=6, frameon=False, ncol=3)
    if has_dba:
        axes[2].set_ylabel("L_Aeq [dB(A)]")
    axes[-1].set_xlabel("engine speed [rpm]")
    what = "regime per gear" + ("; B dashed" if len(designs) > 1 else "")
    fig.suptitle(f"{title}\n{what}; target red, failing speeds shaded", fontsize=9)
    fig.tight_layout()
    fig.savefig(path)


def shade_failing(ax: Any, result: Any, hatch: bool = False) -> None:
    """Shade the speed ranges in which the gearbox misses the target."""
    for a, b in failing(result).get(GEARBOX, []):
        if b <= a:
            a, b = a - 5.0, b + 5.0
        if hatch:
            ax.axvspan(a, b, fill=False, hatch="//", edgecolor="#d62728", lw=0)
        else:
            ax.axvspan(a, b, color="#d62728", alpha=0.12, lw=0)


def temperature_map_png(path: Path | str, table: Any, gears: list[str], title: str) -> None:
    """A verdict over oil temperatures (``oil_temp_C`` column): per gear its regime over
    rpm × temperature, then the gearbox's loudness and, with a target, where it fails."""
    from matplotlib.colors import ListedColormap
    letters = list(LETTERS)
    temps = np.unique(table["oil_temp_C"].to_numpy(dtype=float))
    rpm = np.unique(table["rpm"].to_numpy(dtype=float))
    has_pass = "pass" in table
    n = len(gears) + 1 + has_pass
    cols = min(3, n)
    rows_ = int(np.ceil(n / cols))
    fig = agg_figure((4.0 * cols, 3.2 * rows_), dpi=100)
    axes = np.atleast_1d(fig.subplots(rows_, cols, squeeze=False)).ravel()

    def grid(name: str, column: str, convert) -> np.ndarray:
        out = np.full((temps.size, rpm.size), np.nan)
        sel = table[table["gear"] == name]
        ti = np.searchsorted(temps, sel["oil_temp_C"].to_numpy(dtype=float))
        ri = np.searchsorted(rpm, sel["rpm"].to_numpy(dtype=float))
        out[ti, ri] = [convert(v) for v in sel[column]]
        return out
    extent = dict(shading="nearest")
    for ax, gear in zip(axes, gears):
        codes = grid(gear, "regime", lambda g: letters.index(g) if g in letters else len(letters) - 1)
        ax.pcolormesh(rpm, temps, codes, vmin=-0.5, vmax=len(letters) - 0.5,
                      cmap=ListedColormap([REGIME_COLOURS[g] for g in letters]), **extent)
        ax.set_title(f"{gear}: regime", fontsize=8)
    ax = axes[len(gears)]
    mesh = ax.pcolormesh(rpm, temps, grid(GEARBOX, "loudness_sone", float), cmap="viridis", **extent)
    fig.colorbar(mesh, ax=ax, label="loudness N5 [sone]")
    ax.set_title("gearbox: loudness", fontsize=8)
    if has_pass:
        ax = axes[len(gears) + 1]
        ax.pcolormesh(rpm, temps, grid(GEARBOX, "pass", lambda v: float(bool(v))),
                      cmap=ListedColormap(["#d62728", "#2ca02c"]), vmin=0, vmax=1, **extent)
        ax.set_title("gearbox: target met (green) or missed (red)", fontsize=8)
    for ax in axes[:n]:
        ax.set_xlabel("engine speed [rpm]", fontsize=7)
        ax.set_ylabel("oil temperature [°C]", fontsize=7)
    for ax in axes[n:]:
        ax.set_visible(False)
    fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    fig.savefig(path)


__all__ = ["designs_png", "temperature_map_png", "shade_failing"]
