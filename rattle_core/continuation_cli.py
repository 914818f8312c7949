"""``rattle continue``: follow a periodic orbit in one parameter; branch and bifurcations to CSV.

The command finds the first orbit (by simulation, or the closed-form C orbit), continues it
with :func:`rattle_core.continuation.continue_orbit`, and with ``--branches N`` also follows
the branches that start at its period doublings and grazings.  It writes three tables next to
each other: ``OUT`` (one row per branch point), ``OUT_impacts`` (one row per impact per
point: the branch on a bifurcation diagram) and ``OUT_bifurcations``; ``--png`` draws the
branches, stable solid and unstable dashed, with the bifurcations marked.

:func:`add_parser` registers the subcommand on the ``rattle`` parser; :func:`run` runs it.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

PARAM_CHOICES = "lam, r, j, hK (H_K/H1), phiK (degrees), rpm or drag_torque (physical units)"


def add_parser(sub, parents: list, formatter_class=argparse.HelpFormatter) -> argparse.ArgumentParser:
    """Add ``continue`` to the ``rattle`` subparsers ``sub``."""
    from .cli import _add_model_options

    p = sub.add_parser(
        "continue", parents=parents, formatter_class=formatter_class,
        help="follow a periodic orbit in one parameter: branch and bifurcations to CSV",
        description="Continue a periodic orbit, stable or unstable, in one parameter "
                    "(pseudo-arclength on the impact map, through folds) and locate its folds, "
                    "period doublings, grazings and the onset and end of sticking.  Writes OUT "
                    "(one row per branch point: value, stability, Floquet multipliers, ...), "
                    "OUT_impacts (one row per impact per point) and OUT_bifurcations, as .csv or "
                    ".parquet; --png draws the branches.")
    _add_model_options(p)
    c = p.add_argument_group("continuation")
    c.add_argument("--param", default="lam", help=f"continued parameter: {PARAM_CHOICES} "
                                                  "(default lam)")
    c.add_argument("--start", dest="start_from", choices=("simulate", "c", "c-unstable"),
                   default="simulate",
                   help="first orbit: the one a simulation settles on (from --x0, --v0 at t = 0, "
                        "after --transient periods), or the closed-form one-sided C orbit, "
                        "stable or unstable root (default simulate)")
    c.add_argument("--x0", type=float, default=None, help="start position for --start simulate "
                                                          "(default: mid-backlash)")
    c.add_argument("--v0", type=float, default=0.0, help="start velocity (default 0)")
    c.add_argument("--transient", type=int, default=2000,
                   help="periods simulated before the orbit is taken (default 2000)")
    c.add_argument("--bounds", metavar="LO,HI", help="stop when the parameter leaves [LO, HI] "
                                                     "(its units; default: the model's range)")
    c.add_argument("--direction", choices=("up", "down"), default="up",
                   help="start towards larger (up) or smaller (down) values (default up)")
    c.add_argument("--max-points", dest="max_points", type=int, default=1000,
                   help="most points per branch, in [1, 100000] (default 1000)")
    c.add_argument("--ds", type=float, default=0.01, help="first arclength step (default 0.01)")
    c.add_argument("--ds-max", dest="ds_max", type=float, default=0.1,
                   help="largest arclength step (default 0.1)")
    c.add_argument("--branches", type=int, default=1,
                   help="branches to follow in all: beyond the first, those that start at its "
                        "period doublings, grazings and ends of sticking, breadth first "
                        "(default 1)")
    c.add_argument("--out", required=True, metavar="FILE",
                   help="branch points (.csv or .parquet); OUT_impacts and OUT_bifurcations "
                        "are written beside it")
    c.add_argument("--png", metavar="FILE", help="also draw the branches into this PNG")
    p.set_defaults(func=run)
    return p


def run(args: argparse.Namespace) -> int:
    """Run ``rattle continue``; returns the exit status."""
    import pandas as pd

    from . import continuation as cont
    from .cli import (TABLE_SUFFIXES, CLIError, _check_output, _info, _label, _meta, _Progress,
                      _write_table, build_params)

    out = _check_output(args.out, TABLE_SUFFIXES, "--out")
    png = _check_output(args.png, (".png",), "--png") if args.png else None
    if not 1 <= args.branches <= 100:
        raise CLIError(f"--branches {args.branches} is outside the allowed range [1, 100]")
    params, phys = build_params(args)
    if args.param in ("rpm", "drag_torque") and phys is None:
        raise CLIError(f"--param {args.param} needs physical units (--inertia, --radius, "
                       "--drag-torque, --backlash-um, --rpm, --theta-amp or --alpha-amp)")
    cont._Param.make(args.param, params, phys)  # an unknown parameter fails before any work
    bounds = None
    if args.bounds is not None:
        try:
            bounds = tuple(float(v) for v in args.bounds.split(","))
        except ValueError:
            raise CLIError(f"--bounds {args.bounds!r}: give two numbers LO,HI") from None
        if len(bounds) != 2:
            raise CLIError(f"--bounds {args.bounds!r}: give two numbers LO,HI")
    kw = dict(bounds=bounds, direction=1 if args.direction == "up" else -1, ds=args.ds,
              ds_max=max(args.ds_max, args.ds), max_points=args.max_points,
              physical=phys if args.param in ("rpm", "drag_torque") else None)
    try:
        if args.start_from == "simulate":
            start = cont.find_orbit(params, x0=args.x0, v0=args.v0, transient=args.transient)
        else:
            start = cont.c_orbit(params, which="stable" if args.start_from == "c" else "unstable")
        _info(args, f"{_label(params, phys, (args.param,))}: first orbit {start.summary()}")
        bar = _Progress("continuing", enabled=not getattr(args, "quiet", False), unit="point")
        results = []
        todo: list = [start]
        done = [0]

        def progress(n: int, _total: int) -> None:
            bar(done[0] + n, None)
        try:
            while todo and len(results) < args.branches:
                item = todo.pop(0)
                try:
                    res = cont.continue_orbit(item, args.param, progress=progress, **kw)
                    done[0] += len(res.points)
                except cont.ContinuationError as exc:
                    if not results:
                        raise
                    _info(args, f"could not follow the branch from the {item.kind} at "
                                f"{item.value:.10g}: {exc}")
                    continue
                results.append(res)
                _info(args, f"branch {len(results) - 1}: {len(res.points)} points, "
                            f"{res.status}: {res.message}")
                todo.extend(b for b in res.bifurcations if b.can_restart and b.kind != "fold")
        finally:
            bar.close()
    except cont.ContinuationError as exc:
        print(f"rattle: error: {' '.join(str(exc).split())}", file=sys.stderr)
        return 1
    points = pd.concat([r.points.assign(branch=i) for i, r in enumerate(results)],
                       ignore_index=True)
    impacts = pd.concat([r.impacts.assign(branch=i) for i, r in enumerate(results)],
                        ignore_index=True)
    bifs = pd.concat([r.bifurcation_table.assign(branch=i) for i, r in enumerate(results)],
                     ignore_index=True)
    for df in (points, impacts, bifs):
        df.insert(0, "branch", df.pop("branch"))
    meta = _meta(params, phys)
    meta.update(param=args.param, provenance=[r.provenance for r in results])
    imp_path = out.with_name(out.stem + "_impacts" + out.suffix)
    bif_path = out.with_name(out.stem + "_bifurcations" + out.suffix)
    _write_table(points, out, meta)
    _write_table(impacts, imp_path, meta)
    _write_table(bifs, bif_path, meta)
    for b in (b for r in results for b in r.bifurcations):
        _info(args, f"  {b.message}")
    if png is not None:
        plot_branches(png, results, args.param, _label(params, phys, (args.param,)))
    _info(args, f"wrote {out}, {imp_path} and {bif_path}" + (f"; {png}" if png else ""))
    return 0


_MARKERS = {"fold": ("o", "fold"), "period_doubling": ("s", "PD"),
            "neimark_sacker": ("D", "NS"), "grazing": ("^", "graze"),
            "stick_onset": ("v", "stick on"), "stick_end": ("v", "stick end"),
            "sequence_change": ("x", "change"), "permanent_contact": ("x", "contact")}


def plot_branches(path: Path, results, param: str, title: str) -> None:
    """Impulse against the parameter: stable solid, unstable dashed, bifurcations marked."""
    import numpy as np

    from .cli import CLIError, _axis_label
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        raise CLIError("writing the PNG needs matplotlib, which is not installed") from None
    fig, ax = plt.subplots(figsize=(9, 5.5), dpi=120)
    colours = {1: "#1f5fa8", -1: "#c0392b"}
    try:
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
                marker, label = _MARKERS.get(b.kind, ("x", b.kind))
                for yv in b.orbit.impulse[:8]:
                    ax.plot([b.value], [yv], marker, color="k", ms=5, mfc="none")
                ax.annotate(label, (b.value, float(np.max(b.orbit.impulse))), fontsize=7,
                            xytext=(3, 4), textcoords="offset points")
        ax.axhline(0.0, color="0.6", lw=0.5)
        ax.set_xlabel(_axis_label(param))
        ax.set_ylabel("dimensionless impulse Ĩ (active > 0, reverse < 0)")
        ax.set_title(f"{title}\nstable solid, unstable dashed", fontsize=9)
        fig.tight_layout()
        fig.savefig(path)
    finally:
        plt.close(fig)
