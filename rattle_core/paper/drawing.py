"""Matplotlib pictures of sweeps and maps, shared by the paper's figures and the CLI's PNGs.

Colours and labels come from :mod:`rattle_core.analysis.vocabulary`, so a regime or a flank
looks the same in every picture and in the dashboard.  Figures use the Agg canvas directly, not
pyplot: no global backend or state is touched inside a web server or a CLI.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any, Sequence

import numpy as np

from ..analysis.vocabulary import (ACTIVE, CODIM2_MARKERS, CURVE_STYLES, FLANK_COLOURS,
                                   FLANK_LABELS, LETTERS, MPL_DASH, REGIME_COLOURS, REVERSE)


def agg_figure(figsize: tuple[float, float], dpi: int = 110):
    """A matplotlib ``Figure`` on its own Agg canvas."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    fig = Figure(figsize=figsize, dpi=dpi)
    FigureCanvasAgg(fig)
    return fig


def scatter_flanks(ax, x, impulse, flank, size: float, signs: bool = False) -> None:
    """Impulses against ``x``, one colour per flank; ``signs`` adds "(Ĩ > 0)" to the labels."""
    x, impulse, flank = (np.asarray(a) for a in (x, impulse, flank))
    for side, sign in ((ACTIVE, " (Ĩ > 0)"), (REVERSE, " (Ĩ < 0)")):
        sel = flank == side
        ax.scatter(x[sel], impulse[sel], s=size, c=FLANK_COLOURS[side], marker=".",
                   linewidths=0, rasterized=True,
                   label=FLANK_LABELS[side] + (sign if signs else ""))
    ax.axhline(0.0, color="0.6", lw=0.5)


def regime_strip(ax, x: np.ndarray, regimes: Sequence[str]) -> None:
    """A strip of coloured cells, one per swept value, with a legend of the regimes present."""
    from matplotlib.colors import ListedColormap
    from matplotlib.patches import Patch
    letters = list(LETTERS)
    codes = np.array([letters.index(g) if g in letters else len(letters) - 1 for g in regimes])
    order = np.argsort(x)
    x, codes = np.asarray(x)[order], codes[order]
    edges = np.concatenate([[x[0]], 0.5 * (x[1:] + x[:-1]), [x[-1]]]) if len(x) > 1 \
        else np.array([x[0] - 0.5, x[0] + 0.5])
    ax.pcolormesh(edges, [0, 1], codes[None, :], cmap=ListedColormap([REGIME_COLOURS[g] for g in letters]),
                  vmin=-0.5, vmax=len(letters) - 0.5, shading="flat", rasterized=True)
    ax.set_yticks([])
    ax.set_xlim(edges[0], edges[-1])
    ax.tick_params(labelbottom=False)
    present = [g for g in letters if g in set(regimes)]
    ax.legend(handles=[Patch(color=REGIME_COLOURS[g], label=g) for g in present],
              loc="lower center", bbox_to_anchor=(0.5, 1.0), ncol=len(present), fontsize=7,
              frameon=False, handlelength=1.0, columnspacing=0.8)


def sweep_png(path: Path | str, x, impulse, flank, xlabel: str, title: str) -> None:
    """A bifurcation diagram: impulse against the swept value, coloured by flank."""
    fig = agg_figure((9.0, 5.5), dpi=120)
    ax = fig.add_subplot()
    size = float(min(6.0, max(0.5, 2e4 / max(len(impulse), 1))))  # dots shrink as points crowd
    scatter_flanks(ax, x, impulse, flank, size)
    ax.set_xlabel(xlabel)
    ax.set_ylabel("dimensionless impulse Ĩ")
    ax.set_title(title, fontsize=9)
    ax.legend(loc="upper left", markerscale=12, fontsize=8, frameon=False)
    fig.tight_layout()
    fig.savefig(path)


def map_png(path: Path | str, result: Any, xlabel: str, ylabel: str, title: str) -> None:
    """A map: regimes (or, for basins, the attractor reached) on the left, rattle intensity on
    the right (log scale over four decades; blank where there are no impacts)."""
    from matplotlib import colormaps
    from matplotlib.colors import ListedColormap, LogNorm
    from matplotlib.patches import Patch
    x, y = result.x_values, result.y_values
    extent = [x[0], x[-1], y[0], y[-1]] if x.size > 1 and y.size > 1 else None
    fig = agg_figure((12.0, 5.0))
    ax1, ax2 = fig.subplots(1, 2)
    if result.kind == "basin":
        att = result.fields["attractor"].astype(float)
        att[att < 0] = np.nan
        n = max(2, len(result.attractors))
        cmap = colormaps["tab20"].resampled(n)
        ax1.imshow(att, origin="lower", aspect="auto", extent=extent, cmap=cmap,
                   vmin=-0.5, vmax=n - 0.5, interpolation="nearest")
        handles = [Patch(color=cmap(i), label=f"{a['regime']} period {a['period']}")
                   for i, a in enumerate(result.attractors[:10])]
        ax1.set_title("attractor reached", fontsize=10)
    else:
        colours = [REGIME_COLOURS[g] for g in LETTERS]
        reg = result.fields["regime"].astype(float)
        reg[reg < 0] = np.nan
        ax1.imshow(reg, origin="lower", aspect="auto", extent=extent, cmap=ListedColormap(colours),
                   vmin=-0.5, vmax=len(LETTERS) - 0.5, interpolation="nearest")
        present = {int(c) for c in np.unique(result.fields["regime"]) if c >= 0}
        handles = [Patch(color=colours[c], label=LETTERS[c]) for c in sorted(present)]
        ax1.set_title("regime", fontsize=10)
    ax1.legend(handles=handles, fontsize=7, loc="upper left", bbox_to_anchor=(1.0, 1.0),
               frameon=False)
    inten = np.asarray(result.fields["intensity"], dtype=float)
    positive = inten[np.isfinite(inten) & (inten > 0)]
    shown = np.where(inten > 0, inten, np.nan)
    # four decades are enough; the faint chatter tail would otherwise wash out the scale
    norm = (LogNorm(vmin=max(positive.min(), 1e-4 * positive.max()), vmax=positive.max(), clip=True)
            if positive.size else None)
    im = ax2.imshow(shown, origin="lower", aspect="auto", extent=extent, cmap="magma",
                    norm=norm, interpolation="nearest")
    fig.colorbar(im, ax=ax2, label="rattle intensity Σ Ĩ² per period")
    ax2.set_title("rattle intensity (blank: no impacts)", fontsize=10)
    for ax in (ax1, ax2):
        ax.set_xlabel(xlabel)
        ax.set_ylabel(ylabel)
    fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    fig.savefig(path)


_BIFURCATION_MARKERS = {"fold": ("o", "fold"), "period_doubling": ("s", "PD"),
            "neimark_sacker": ("D", "NS"), "grazing": ("^", "graze"),
            "stick_onset": ("v", "stick on"), "stick_end": ("v", "stick end"),
            "sequence_change": ("x", "change"), "permanent_contact": ("x", "contact")}


def continuation_png(path: Path | str, results: Sequence[Any], xlabel: str, title: str) -> None:
    """Branches of :func:`~rattle_core.analysis.continuation.continue_orbit`: impulse against
    the parameter, stable solid, unstable dashed, bifurcations marked and labelled."""
    fig = agg_figure((9.0, 5.5), dpi=120)
    ax = fig.subplots()
    colours = FLANK_COLOURS
    for res in results:
        imp = res.impacts
        pts = res.points
        # one line per impact slot; a slot is split where the impact sequence changes
        seg = (pts["n_impacts"].diff().fillna(0) != 0).cumsum().to_numpy()
        for k in range(int(pts["n_impacts"].max()) if len(pts) else 0):
            rows = imp[imp["impact"] == k]
            if rows.empty:
                continue
            p_idx = rows["point"].to_numpy()
            x = rows["value"].to_numpy()
            y = rows["impulse"].to_numpy()
            st = rows["stable"].to_numpy(bool)
            fl = int(np.sign(np.median(rows["flank"])))
            for s in np.unique(seg[p_idx]):
                sel = seg[p_idx] == s
                xs, ys, ss = x[sel], y[sel], st[sel]
                for stable, style in ((True, "-"), (False, "--")):
                    yy = np.where(ss == stable, ys, np.nan)
                    # keep the joins: a point where stability changes belongs to both
                    edge = np.r_[False, ss[1:] != ss[:-1]] | np.r_[ss[:-1] != ss[1:], False]
                    yy = np.where(edge, ys, yy)
                    ax.plot(xs, yy, style, color=colours.get(fl, "k"), lw=1.2)
        for b in res.bifurcations:
            marker, label = _BIFURCATION_MARKERS.get(b.kind, ("x", b.kind))
            for yv in b.orbit.impulse[:8]:
                ax.plot([b.value], [yv], marker, color="k", ms=5, mfc="none")
            ax.annotate(label, (b.value, float(np.max(b.orbit.impulse))), fontsize=7,
                        xytext=(3, 4), textcoords="offset points")
    ax.axhline(0.0, color="0.6", lw=0.5)
    ax.set_xlabel(xlabel)
    ax.set_ylabel("dimensionless impulse Ĩ (active > 0, reverse < 0)")
    ax.set_title(f"{title}\nstable solid, unstable dashed", fontsize=9)
    fig.tight_layout()
    fig.savefig(path)


def atlas_png(path: Path | str, curves: Sequence[Any], xlabel: str, ylabel: str,
              title: str) -> None:
    """Bifurcation curves of :func:`~rattle_core.analysis.continuation.continue_bifurcation`
    in the plane of their two parameters (the first across), one line style per kind, with
    the codimension-two points marked and labelled."""
    fig = agg_figure((8.0, 6.0), dpi=120)
    ax = fig.subplots()
    seen = set()
    for c in curves:
        st = CURVE_STYLES[c.kind]
        pts = c.points
        label = st.label if c.kind not in seen else None
        seen.add(c.kind)
        ax.plot(pts[c.param1], pts[c.param2], MPL_DASH[st.dash], color=st.colour, lw=1.5,
                label=label)
        for p in c.codim2:
            marker, text = CODIM2_MARKERS[p.kind]
            ax.plot([p.value1], [p.value2], marker, color="k", ms=6, mfc="none")
            ax.annotate(text, (p.value1, p.value2), fontsize=7, xytext=(4, 4),
                        textcoords="offset points")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=9)
    if seen:
        ax.legend(fontsize=8, loc="best")
    fig.tight_layout()
    fig.savefig(path)


def orders_png(path: Path | str, order_map: Any, title: str) -> None:
    """An order map: each order's angular-acceleration amplitude (left) and phase (right)
    against engine speed."""
    fig = agg_figure((10.0, 4.5), dpi=110)
    ax, axp = fig.subplots(1, 2)
    for j, k in enumerate(order_map.orders):
        ax.plot(order_map.rpm, order_map.accel_rad_s2[:, j], ".-", label=f"order {k:g}")
        axp.plot(order_map.rpm, order_map.phase_deg[:, j], ".-", label=f"order {k:g}")
    ax.set_xlabel("engine speed [rpm]")
    ax.set_ylabel("angular acceleration amplitude [rad/s²]")
    ax.legend(fontsize=8, frameon=False)
    axp.set_xlabel("engine speed [rpm]")
    axp.set_ylabel("phase φ_k of θ_k cos(kψ − φ_k) [deg]")
    axp.set_ylim(-180, 180)
    fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    fig.savefig(path)


def campbell_png(path: Path | str, data: Any, title: str) -> None:
    """A Campbell diagram: the order spectrum (dB re 1 rad) as colours, orders across and rpm
    up, the analysed orders marked by dashed lines, so that one sees whether they dominate."""
    fig = agg_figure((8.0, 6.0), dpi=110)
    ax = fig.subplots()
    level = data.level_db
    top = float(np.nanmax(level)) if np.isfinite(level).any() else 0.0
    mesh = ax.pcolormesh(data.orders, data.rpm, level, shading="nearest", cmap="viridis",
                         vmin=top - 60.0, vmax=top)
    fig.colorbar(mesh, ax=ax, label="angular amplitude [dB re 1 rad]")
    for k in data.analysed_orders:
        ax.axvline(k, color="white", ls="--", lw=0.9)
        ax.text(k, data.rpm[-1], f" {k:g}", color="white", va="top", fontsize=8)
    ax.set_xlabel("engine order")
    ax.set_ylabel("engine speed [rpm]")
    ax.set_title(title, fontsize=9)
    fig.tight_layout()
    fig.savefig(path)


def verdict_png(path: Path | str, result: Any, title: str) -> None:
    """A gearbox verdict: each gear's regime against engine speed (a strip per gear, its onset
    marked), the rattle intensity and the loudness of each gear and of the whole gearbox."""
    from matplotlib.colors import ListedColormap
    from matplotlib.patches import Patch
    names = [g.name for g in result.gearbox.gears]
    fig = agg_figure((10.0, 8.0), dpi=110)
    ax_r, ax_i, ax_l = fig.subplots(3, 1, sharex=True,
                                    gridspec_kw={"height_ratios": [max(1, len(names)) * 0.35, 1, 1]})
    letters = list(LETTERS)
    rpm = np.asarray(result.rpm)
    edges = np.concatenate([[rpm[0]], 0.5 * (rpm[1:] + rpm[:-1]), [rpm[-1]]]) if rpm.size > 1 \
        else np.array([rpm[0] - 1, rpm[0] + 1])
    codes = np.full((len(names), rpm.size), len(letters) - 1)
    for i, name in enumerate(names):
        rows = result.gear(name)
        idx = np.searchsorted(rpm, rows["rpm"].to_numpy())
        codes[i, idx] = [letters.index(g) if g in letters else len(letters) - 1
                         for g in rows["regime"]]
        ax_i.plot(rows["rpm"], rows["intensity"], ".-", label=name)
        ax_l.plot(rows["rpm"], rows["loudness_sone"], ".-", label=name)
        onset = rows["onset_rpm"].iloc[0] if len(rows) else np.nan
        if np.isfinite(onset):
            ax_r.plot([onset], [i + 0.5], "k|", ms=14, mew=2)
    ax_r.pcolormesh(edges, np.arange(len(names) + 1), codes,
                    cmap=ListedColormap([REGIME_COLOURS[g] for g in letters]),
                    vmin=-0.5, vmax=len(letters) - 0.5, shading="flat")
    ax_r.set_yticks(np.arange(len(names)) + 0.5, names, fontsize=8)
    present = sorted({letters[c] for c in codes.ravel()}, key=letters.index)
    ax_r.legend(handles=[Patch(color=REGIME_COLOURS[g], label=g) for g in present],
                loc="lower center", bbox_to_anchor=(0.5, 1.0), ncol=len(present), fontsize=7,
                frameon=False)
    box = result.gear("gearbox")
    ax_i.plot(box["rpm"], box["intensity"], "k-", lw=2, label="gearbox")
    ax_l.plot(box["rpm"], box["loudness_sone"], "k-", lw=2, label="gearbox")
    ax_i.set_yscale("symlog", linthresh=1e-5)
    ax_i.set_ylabel("intensity Σ I²/s [N²·s]")
    ax_l.set_ylabel("loudness N5 [sone]")
    ax_l.set_xlabel("engine speed [rpm]")
    ax_l.legend(fontsize=7, frameon=False, ncol=3)
    fig.suptitle(title + "\nregime per gear (onset marked |)", fontsize=9)
    fig.tight_layout()
    fig.savefig(path)
