"""The paper's Figures 2 to 8, drawn again from the exact solver (:func:`write_paper_figures`).

Bifurcation diagrams come from :func:`~rattle_core.paper.cases.paper_sweep` (the shipped
assets while they match the solver); time histories and Poincaré maps are simulated here.
``rattle paper`` and ``scripts/make_assets.py`` call :func:`write_paper_figures`.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Callable

import numpy as np

from ..analysis.classify import classify
from ..analysis.overlays import contact_boundary, period1_limits_harmonic
from ..analysis.vocabulary import (ACTIVE, FLANK_COLOURS, FLANK_LABELS, REGIME_COLOURS, REVERSE,
                                   STICK_COLOUR)
from ..batch.sweep import SweepResult
from ..model.excitation import TWO_PI
from ..model.params import RattleParams
from ..solver.trajectory import Trajectory, simulate
from .cases import CASES, PAPER_LAM_RANGE, PaperCase, paper_sweep, poincare_cloud
from .drawing import agg_figure, regime_strip, scatter_flanks
from .evidence import phase_convention_evidence

Progress = Callable[[int, int], Any]


def _draw_bifurcation(case: PaperCase, res: SweepResult, path: Path) -> None:
    fig = agg_figure((8.0, 5.0))
    gs = fig.add_gridspec(2, 1, height_ratios=[1, 14], hspace=0.04)
    strip = fig.add_subplot(gs[0])
    ax = fig.add_subplot(gs[1], sharex=strip)
    t = res.table
    scatter_flanks(ax, case.axis(t["value"].to_numpy(dtype=float)),
                   t["impulse"].to_numpy(dtype=float), t["flank"].to_numpy(), 0.15, signs=True)
    if case.name == "lam":
        lam = np.linspace(*PAPER_LAM_RANGE, 400)
        ax.plot(lam, TWO_PI / lam, color="0.3", lw=0.7, ls="--", label="2π/Λ (one-sided orbit)")
        lc = contact_boundary(case.params)
        ax.axvline(lc, color="0.3", lw=0.7, ls=":", label=f"Λc = {lc:.3f} (contact boundary)")
        if case.paper_phi2 is None:
            ax.axvline(period1_limits_harmonic(case.params.r)[1], color=REGIME_COLOURS["C"],
                       lw=0.7, ls="-.", label="period-doubling limit of C")
    s = res.summary
    regime_strip(strip, case.axis(s["value"].to_numpy(dtype=float)), list(s["regime"]))
    ax.set_xlabel(case.x_label)
    ax.set_ylabel("impulse Ĩ")
    ax.legend(loc="upper right", fontsize=7, markerscale=30, frameon=False)
    fig.suptitle(f"{case.key}: {case.caption}", fontsize=8.5, y=0.995)
    fig.savefig(path)


def short_label(c) -> str:
    """Two-line description of a :class:`~rattle_core.analysis.classify.Classification` for a
    title."""
    per = f"period {c.period}" if c.period else "no period ≤ 32"
    line2 = f"{c.active_per_period:.3g} active + {c.reverse_per_period:.3g} reverse impacts/period"
    if c.stick_fraction > 0:
        line2 += f", sticking {100 * c.stick_fraction:.2g}%"
    if c.sticking == "chaos-through-sticking":
        line2 += ", chaos through sticking" + (" (noisy model)" if c.noisy else "")
    # with sticking in every period the exponent says nothing about the flight dynamics
    if not math.isnan(c.lyapunov) and c.regime not in ("A", "B"):
        line2 += f", λ = {c.lyapunov:.3g}"
    return f"regime {c.regime} ({per})\n{line2}"


def _draw_time(ax, params: RattleParams, transient: int, periods: int, title: str) -> Trajectory:
    tr = simulate(params, periods=periods, transient=transient)
    t = np.linspace(tr.t_start, tr.t_end, 300 * periods)
    x, _ = tr.sample(t)
    y, yj = tr.walls(t)
    tp = (t - tr.t_start) / TWO_PI
    ax.plot(tp, y, color="k", lw=0.9)
    ax.plot(tp, yj, color="k", lw=0.9)
    ax.plot(tp, x, color="#1565c0", lw=1.0)
    it = tr.impact_t
    if len(it):
        xi, _ = tr.sample(it)
        ip = (it - tr.t_start) / TWO_PI
        act = tr.impact_flank == 1
        ax.plot(ip[act], xi[act], "^", ms=3.5, color=FLANK_COLOURS[ACTIVE],
                label=f"{FLANK_LABELS[ACTIVE]} impact")
        ax.plot(ip[~act], xi[~act], "v", ms=3.5, color=FLANK_COLOURS[REVERSE],
                label=f"{FLANK_LABELS[REVERSE]} impact")
    for a, b in tr.stick_intervals:
        ax.axvspan((a - tr.t_start) / TWO_PI, (b - tr.t_start) / TWO_PI, color=STICK_COLOUR,
                   alpha=0.15, lw=0)
    c = classify(simulate(params, periods=200, transient=transient, lyapunov=True))
    ax.set_title(f"{title}: {short_label(c)}", fontsize=7.5)
    ax.set_xlabel("t / 2π (periods after the transient)")
    ax.set_ylabel("x, y, y + j")
    return tr


def _draw_fig3(case: PaperCase, path: Path) -> None:
    fig = agg_figure((10.0, 7.0))
    axes = fig.subplots(2, 2).ravel()
    for ax, lam, reg in zip(axes, case.lams, "BCDE"):
        periods = case.record if reg == "D" else 4
        _draw_time(ax, case.params.replace(lam=lam), case.transient, periods,
                   f"Λ = {lam:g}")
    axes[3].legend(fontsize=7, loc="lower right", framealpha=0.9)
    fig.suptitle(f"{case.key}: {case.caption}", fontsize=9)
    fig.tight_layout()
    fig.savefig(path)


def _draw_sections(ax_s, ax_i, params: RattleParams, n_points: int, title: str) -> None:
    x, v, ph, imp = poincare_cloud(params, n_points=n_points)
    ax_s.scatter(x, v, s=1.5, c="k", marker="o", linewidths=0, rasterized=True)
    ax_s.set_xlabel("x at t = 2πn")
    ax_s.set_ylabel("ẋ at t = 2πn")
    ax_s.set_title(f"{title}: stroboscopic section, {len(x)} points", fontsize=8)
    if ax_i is not None:
        scatter_flanks(ax_i, ph, imp, np.where(imp > 0, ACTIVE, REVERSE), 1.0)
        ax_i.set_xlim(0, TWO_PI)
        ax_i.set_xlabel("impact phase t mod 2π")
        ax_i.set_ylabel("impulse Ĩ")
        ax_i.set_title(f"impact map, {len(ph)} impacts", fontsize=8)


def _draw_fig7(case: PaperCase, path: Path) -> None:
    fig = agg_figure((10.0, 4.6))
    ax_s, ax_i = fig.subplots(1, 2)
    _draw_sections(ax_s, ax_i, case.params, case.record, "Λ = 3.3, paper φ2 = 45°")
    c = classify(simulate(case.params, periods=1000, transient=500, lyapunov=True))
    fig.suptitle(f"{case.key}: {case.caption}\n500 + 1000 periods from mid-backlash: "
                 + short_label(c).replace("\n", ", "), fontsize=8.5)
    fig.tight_layout()
    fig.savefig(path)


def _draw_fig8(case: PaperCase, path: Path) -> None:
    fig = agg_figure((10.0, 4.6))
    ax_t, ax_s = fig.subplots(1, 2)
    _draw_time(ax_t, case.params, case.transient, 4, "(a) Λ = 3.3, paper φ2 = 90°")
    ax_t.legend(fontsize=7, loc="center right", framealpha=0.9)
    tr = simulate(case.params, periods=case.record, transient=case.transient)
    ax_s.plot(tr.strobe_x, tr.strobe_v, "o", ms=4, color="k")
    ax_s.set_xlabel("x at t = 2πn")
    ax_s.set_ylabel("ẋ at t = 2πn")
    ax_s.set_title(f"(b) stroboscopic section: {len(tr.strobe_x)} periods, "
                   f"{len(np.unique(np.round(tr.strobe_x, 8)))} distinct point(s)", fontsize=8)
    fig.suptitle(f"{case.key}: {case.caption}", fontsize=8.5)
    fig.tight_layout()
    fig.savefig(path)


def write_paper_figures(out_dir: Path | str, progress: Progress | None = None,
                        use_assets: bool = True, *, evidence: bool = True,
                        cache_directory: Path | str | None = None) -> list[Path]:
    """Draw the paper's Figures 2 to 8 as PNG files in ``out_dir``.

    Parameters
    ----------
    out_dir : path
        Created if missing; ``fig2.png`` … ``fig8.png`` are written there.
    progress : callable(done, total), optional
        Called with increasing counts, ending with ``done == total``.
    use_assets : bool
        Take the bifurcation diagrams from the shipped assets when they match the solver;
        otherwise (or when absent) from the disk cache, computing on a miss.
    evidence : bool
        Also write ``phase_convention.md`` (:func:`phase_convention_evidence`).
    cache_directory : path, optional
        Disk-cache directory for the sweeps (default: :func:`rattle_core.store.cache.cache_dir`).

    Returns
    -------
    list of Path
        The files written: ``fig2.png`` … ``fig8.png``, then ``phase_convention.md`` if asked.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    steps = list(CASES) + (["phase_convention"] if evidence else [])
    unit = 100
    total = unit * len(steps)
    paths: dict[str, Path] = {}

    def report(done):
        if progress is not None:
            progress(int(done), total)

    for i, key in enumerate(steps):
        base = i * unit

        def sub(done, n, base=base):
            report(base + min(unit - 1, (unit * done) // max(n, 1)))

        if key == "phase_convention":
            phase_convention_evidence(out, progress=sub, directory=cache_directory)
            paths[key] = out / "phase_convention.md"
        else:
            case = CASES[key]
            path = out / f"{key}.png"
            if case.kind == "sweep":
                res = paper_sweep(key, use_assets=use_assets, progress=sub,
                                  directory=cache_directory)
                _draw_bifurcation(case, res, path)
            elif key == "fig3":
                _draw_fig3(case, path)
            elif key == "fig7":
                _draw_fig7(case, path)
            else:
                _draw_fig8(case, path)
            paths[key] = path
        report(base + unit)
    return list(paths.values())
