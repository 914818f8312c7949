"""``rattle continue``: follow a periodic orbit in one parameter; branch and bifurcations to CSV.

The command finds the first orbit (by simulation, or the closed-form C orbit), continues it
with :func:`rattle_core.analysis.continuation.continue_orbit`, and with ``--branches N`` also follows
the branches that start at its period doublings and grazings.  It writes three tables next to
each other: ``OUT`` (one row per branch point), ``OUT_impacts`` (one row per impact per
point: the branch on a bifurcation diagram) and ``OUT_bifurcations``; ``--png`` draws the
branches, stable solid and unstable dashed, with the bifurcations marked.

"""
from __future__ import annotations

import argparse
import sys

from ..common import (CLIError, Progress, add_command, axis_label, check_output,
                      distinct_outputs, info, label, meta)
from ..options import add_model_options, build_params

PARAM_CHOICES = "lam, r, j, hK (H_K/H1), phiK (degrees), rpm or drag_torque (physical units)"


HELP = "follow a periodic orbit in one parameter: branch and bifurcations to CSV"


def add_parser(sub) -> None:
    p = add_command(sub, run, HELP, name="continue")
    add_model_options(p)
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


def run(args: argparse.Namespace) -> int:
    """Continue a periodic orbit, stable or unstable, in one parameter (pseudo-arclength on the
    impact map, through folds) and locate its folds, period doublings, grazings and the onset
    and end of sticking.  Writes OUT (one row per branch point: value, stability, Floquet
    multipliers, ...), OUT_impacts (one row per impact per point) and OUT_bifurcations, as .csv
    or .parquet; --png draws the branches."""
    from rattle_core.analysis import continuation as cont
    from rattle_core.paper.drawing import continuation_png
    from rattle_core.store.exports import TABLE_SUFFIXES, write_table
    import pandas as pd

    out = check_output(args.out, TABLE_SUFFIXES, "--out")
    imp_path, bif_path = (check_output(str(out.with_name(out.stem + tail + out.suffix)),
                                       TABLE_SUFFIXES, f"the {tail[1:]} table beside --out")
                          for tail in ("_impacts", "_bifurcations"))
    png = check_output(args.png, (".png",), "--png") if args.png else None
    distinct_outputs(out, imp_path, bif_path, png)
    if not 1 <= args.branches <= 100:
        raise CLIError(f"--branches {args.branches} is outside the allowed range [1, 100]")
    if not 0 < args.ds <= 1:
        raise CLIError(f"--ds {args.ds!r} is outside the allowed range (0, 1]")
    if not args.ds <= args.ds_max <= 10:
        raise CLIError(f"--ds-max {args.ds_max!r} is outside the allowed range [--ds = {args.ds:g}, 10]")
    if not 1 <= args.max_points <= cont.MAX_POINTS:
        raise CLIError(f"--max-points {args.max_points} is outside the allowed range "
                       f"[1, {cont.MAX_POINTS}]")
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
              ds_max=args.ds_max, max_points=args.max_points,
              physical=phys if args.param in ("rpm", "drag_torque") else None)
    try:
        if args.start_from == "simulate":
            start = cont.find_orbit(params, x0=args.x0, v0=args.v0, transient=args.transient)
        else:
            start = cont.c_orbit(params, which="stable" if args.start_from == "c" else "unstable")
        info(args, f"{label(params, phys, (args.param,))}: first orbit {start.summary()}")
        bar = Progress("continuing", enabled=not getattr(args, "quiet", False), unit="point")
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
                    info(args, f"could not follow the branch from the {item.kind} at "
                                f"{item.value:.10g}: {exc}")
                    continue
                results.append(res)
                info(args, f"branch {len(results) - 1}: {len(res.points)} points, "
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
    file_meta = meta(params, phys)
    file_meta.update(param=args.param, provenance=[r.provenance for r in results])
    write_table(points, out, file_meta)
    write_table(impacts, imp_path, file_meta)
    write_table(bifs, bif_path, file_meta)
    for b in (b for r in results for b in r.bifurcations):
        info(args, f"  {b.message}")
    if png is not None:
        continuation_png(png, results, axis_label(args.param), label(params, phys, (args.param,)))
    info(args, f"wrote {out}, {imp_path} and {bif_path}" + (f"; {png}" if png else ""))
    return 0
