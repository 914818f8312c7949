"""``rattle sweep``: a bifurcation diagram, or with ``--param2`` a 2-D map, to a file plus PNG."""
from __future__ import annotations

import argparse
import contextlib
import dataclasses
from pathlib import Path
from typing import Any

from ..common import (CLIError, Progress, add_command, axis_label, check_output,
                      distinct_outputs, finite, info, label, user_permissions)
from ..options import add_model_options, build_params, float_list

HELP = "bifurcation diagram (impulses against a parameter) to a file plus PNG"


def add_parser(sub) -> None:
    p = add_command(sub, run, HELP)
    add_model_options(p)
    s = p.add_argument_group("sweep")
    s.add_argument("--param", default="lam",
                   help="swept parameter: lam, r, j, v_stick, hK (H_K/H1), phiK (degrees) or rpm "
                        "(physical units; a sweep of Λ with displacement amplitudes, of j with "
                        "acceleration amplitudes) (default lam)")
    s.add_argument("--start", type=float, help="first value")
    s.add_argument("--stop", type=float, help="last value")
    s.add_argument("--num", type=int, help="number of values, evenly spaced (default 200)")
    s.add_argument("--values", type=float_list("--values"), metavar="V[,V...]",
                   help="explicit values instead of --start/--stop/--num")
    s.add_argument("--transient", type=int,
                   help="unrecorded periods per value (default 500; 300 for 2-D maps)")
    s.add_argument("--record", type=int,
                   help="recorded periods per value (default 200; 100 for 2-D maps)")
    s.add_argument("--mode", choices=("fresh", "continuation"), default="fresh",
                   help="fresh: every value from the same start; continuation: each value from the "
                        "previous one's final state, which reveals coexisting attractors (default fresh)")
    s.add_argument("--x0", type=float, default=None, help="start position (default: mid-backlash)")
    s.add_argument("--v0", type=float, default=0.0, help="start velocity (default 0)")
    m = p.add_argument_group(
        "2-D maps",
        "With --param2, map the regime and the rattle intensity over --param × --param2 instead "
        "of a bifurcation diagram.  Each axis is a dimensionless name (lam, r, j, v_stick, hK, phiK) "
        "or, in physical units, rpm, drag_torque [N·m], inertia [kg·m²] or backlash_um [µm]; e.g. "
        "--param rpm --param2 drag_torque.  --param x0 --param2 v0 maps the basins of attraction "
        "over the initial state at t = 0 instead.  Files: .npz (the cache's map format), or "
        ".csv/.parquet with one row per grid point; the PNG shows the regimes and the intensity.")
    m.add_argument("--param2", metavar="NAME", help="second swept parameter (the map's vertical axis)")
    m.add_argument("--start2", type=float, help="first value of --param2")
    m.add_argument("--stop2", type=float, help="last value of --param2")
    m.add_argument("--num2", type=int, help="number of --param2 values (default 100)")
    m.add_argument("--values2", type=float_list("--values2"), metavar="V[,V...]",
                   help="explicit --param2 values")
    s.add_argument("--orders-from", dest="orders_from", metavar="FILE.csv",
                   help="physical units: take the harmonics at each engine speed from a measurement "
                        "(time_s, speed_rpm) or an order table (rattle orders): harmonic n is engine "
                        "order n × --order, its θ and φ interpolated at each rpm; the --theta-amp "
                        "values are replaced")
    s.add_argument("--orders-harmonics", dest="orders_harmonics", type=int, default=3,
                   metavar="K", help="harmonics taken from --orders-from (default 3: orders 2, 4, 6 "
                                     "with --order 2)")
    s.add_argument("--out", required=True, metavar="FILE", help="output file: .npz, .csv or .parquet")
    s.add_argument("--png", metavar="FILE", help="PNG of the diagram (default: OUT with .png)")
    s.add_argument("--no-png", dest="no_png", action="store_true", help="do not write a PNG")
    s.add_argument("--no-cache", dest="no_cache", action="store_true",
                   help="recompute even when the disk cache holds this sweep, and do not store it")
    d = p.add_argument_group("parallel (default: all local cores)")
    d.add_argument("--dask", metavar="local", help="'local': run on a Dask LocalCluster started here")
    d.add_argument("--workers", type=int, default=2, help="workers of --dask local (default 2)")
    d.add_argument("--scheduler", metavar="tcp://HOST:PORT", help="run on this Dask scheduler")


def _values(args: argparse.Namespace, suffix: str = "", default_num: int = 200) -> np.ndarray:
    import numpy as np
    values, start, stop, num = (getattr(args, f"{k}{suffix}") for k in ("values", "start", "stop", "num"))
    if values is not None:
        if start is not None or stop is not None or num is not None:
            raise CLIError(f"give --values{suffix} or --start{suffix}/--stop{suffix}/--num{suffix}, "
                           "not both")
        return np.asarray(values, dtype=np.float64)
    if start is None or stop is None:
        raise CLIError(f"sweep: give --start{suffix} and --stop{suffix} (and --num{suffix}), "
                       f"or --values{suffix}")
    finite(start, f"--start{suffix}")
    finite(stop, f"--stop{suffix}")
    num = default_num if num is None else num
    if not 1 <= num <= 1_000_000:
        raise CLIError(f"--num{suffix} {num} is outside the allowed range [1, 1000000]")
    return np.linspace(start, stop, num)


def _scheduler(args: argparse.Namespace) -> str | None:
    """The Dask scheduler the command runs on (None: this machine's cores)."""
    if args.dask is None and args.scheduler is None:
        return None
    if args.dask is not None and args.scheduler is not None:
        raise CLIError("give --dask local or --scheduler ADDRESS, not both")
    if args.dask is not None and args.dask != "local":
        raise CLIError(f"--dask {args.dask!r}: the only value is 'local' (use --scheduler for a cluster)")
    if args.mode == "continuation":
        raise CLIError("continuation sweeps run value after value on one core; drop --dask/--scheduler "
                       "or use --mode fresh")
    return args.scheduler or "local"


def _run_on(args: argparse.Namespace, scheduler: str | None, job) -> Any:
    """``job(executor)`` on the Dask cluster asked for (or here), closing it afterwards."""
    from rattle_core.batch.executor import dask_session
    with contextlib.ExitStack() as stack:
        try:
            executor = stack.enter_context(dask_session(scheduler, args.workers))
        except (ConnectionError, ValueError) as exc:
            where = f"--scheduler {args.scheduler!r}" if args.scheduler else "--dask local"
            raise CLIError(f"{where}: {exc}") from None
        return job(executor)


def run(args: argparse.Namespace) -> int:
    """Sweep one parameter; record every impulse after a transient.  --out .npz is the cache's
    format (loadable by the dashboard); .csv/.parquet write one row per impact to OUT and
    one row per value (regime, period, Lyapunov exponent, intensity, ...) to OUT_summary.  A
    PNG of the diagram goes next to OUT unless --no-png.  Results are cached on disk
    ($RATTLE_CACHE_DIR; see 'rattle cache').  One request may run up to 1e8 forcing periods
    (values × (transient + record)), 5 to 10 minutes on two cores
    (rattle_core.batch.sweep.PERIOD_BUDGET)."""
    from rattle_core.batch.sweep import sweep, validate_sweep_args
    from rattle_core.model.units import rpm_sweep
    from rattle_core.paper.drawing import sweep_png
    from rattle_core.store.cache import cached_sweep
    from rattle_core.store.exports import TABLE_SUFFIXES, sweep_frames, write_table
    from rattle_core.store.files import save_result
    suffixes = (".npz",) + TABLE_SUFFIXES
    if not 1 <= args.workers <= 256:
        raise CLIError(f"--workers {args.workers} is outside the allowed range [1, 256]")
    if args.no_png and args.png is not None:
        raise CLIError(f"--no-png and --png {args.png!r} contradict each other; give one")
    out = check_output(args.out, suffixes, "--out")
    png = summary = None
    if not args.no_png:
        png = (check_output(args.png, (".png",), "--png") if args.png is not None else
               check_output(str(out.with_suffix(".png")), (".png",), "the PNG beside --out (--no-png: none)"))
    if out.suffix.lower() != ".npz":
        summary = check_output(str(out.with_name(out.stem + "_summary" + out.suffix)),
                               suffixes, "the summary beside --out")
    distinct_outputs(out, png, summary)
    for flag in ("x0", "v0"):
        finite(getattr(args, flag), f"--{flag.replace('_', '-')}")
    params, phys = build_params(args)
    follow = _follow(args, phys)
    if args.param2 is not None:
        return _run_map(args, out, png, params, phys, follow)
    for flag in ("start2", "stop2", "num2", "values2"):
        if getattr(args, flag) is not None:
            raise CLIError(f"--{flag} needs --param2")
    values = _values(args)
    name = args.param
    rpm = None
    columns = None
    if name == "rpm":
        if phys is None:
            raise CLIError("--param rpm needs physical units (--inertia, --radius, --drag-torque, "
                           "--backlash-um, --rpm, --theta-amp or --alpha-amp)")
        if follow is not None:
            columns = follow.columns(phys, values)
        else:
            rpm = values
            name, values = rpm_sweep(phys, rpm)
    elif follow is not None:
        raise CLIError("--orders-from takes harmonics at each engine speed: use it with --param rpm")
    transient = 500 if args.transient is None else args.transient
    record = 200 if args.record is None else args.record
    # Reject bad requests before any progress bar or worker starts, so the error stays one line.
    values, transient, record = validate_sweep_args(name, values, transient, record, args.mode,
                                                    columns)
    if columns is None:
        for v in (float(values.min()), float(values.max())):
            params.with_value(name, v)
    scheduler = _scheduler(args)
    progress = Progress(f"sweep {args.param}", enabled=not args.quiet, total=len(values))
    compute = sweep if args.no_cache else cached_sweep
    try:
        result = _run_on(args, scheduler, lambda executor: compute(
            params, name, values, transient=transient, record=record, mode=args.mode, x0=args.x0,
            v0=args.v0, progress=progress, executor=executor, columns=columns))
    finally:
        progress.close()
    if columns is not None:
        table, summary = sweep_frames(result)
        table.insert(0, "rpm", table["value"])
        summary.insert(0, "rpm", summary["value"])
        scale = {v: follow.follow(phys, v).impulse_scale for v in values.tolist()}
        table["impulse_Ns"] = table["impulse"] * table["rpm"].map(scale)
    else:
        table, summary = sweep_frames(result, phys, None if rpm is None else (values, rpm))
    settings = dict(result.settings)
    if phys is not None:
        settings["physical"] = dataclasses.asdict(phys)
    if rpm is not None:
        settings["rpm"] = rpm.tolist()
    if columns is not None:
        settings["orders_from"] = str(args.orders_from)
        settings["rpm"] = values.tolist()
    result = dataclasses.replace(result, settings=settings)
    summary_path = out.with_name(out.stem + "_summary" + out.suffix)
    if out.suffix.lower() == ".npz":
        save_result(out, result)
        user_permissions(out)
    else:
        m = {"name": result.name, "swept": args.param, "params": result.params.to_dict(),
             "settings": settings}
        write_table(table, out, m)
        write_table(summary, summary_path, m)
    if png is not None:
        title = label(params, phys, (args.param, result.name))
        if args.param == "rpm":
            title += f"\nrpm sweep = sweep of {result.name}"
        x = table["rpm" if args.param == "rpm" else "value"]
        sweep_png(png, x, table["impulse"], result.table["flank"], axis_label(args.param), title)
    info(args, f"{label(params, phys, (args.param, result.name))}: swept {args.param} over "
               f"{len(result.values)} values, {len(table)} impacts recorded"
               f"{' (cancelled)' if result.cancelled else ''}")
    if len(summary):
        counts = summary["regime"].value_counts().sort_index()
        info(args, "regimes: " + ", ".join(f"{k} {v}" for k, v in counts.items()))
        kinds = result.summary["sticking"].value_counts()
        if len(kinds.drop("", errors="ignore")):
            how = ("strict model: loops chosen by rounding" if params.noise == 0
                   else f"statistics at noise {params.noise:g}, one run per value")
            info(args, "through sticking: " + ", ".join(
                f"{kind} {n}" for kind, n in kinds.items() if kind)
                + (f" ({how})" if "chaos-through-sticking" in kinds else ""))
    info(args, f"wrote {out}" + ("" if out.suffix.lower() == ".npz" else f" and {summary_path}"))
    if png is not None:
        info(args, f"wrote {png}")
    return 0


def _follow(args: argparse.Namespace, phys):
    """The excitation that follows engine speed (``--orders-from``), or None."""
    from rattle_core.model.gearbox import Excitation
    from rattle_core.model.orders import OrderMap
    if args.orders_from is None:
        return None
    if phys is None:
        raise CLIError("--orders-from needs physical units (--inertia, --radius, --drag-torque, "
                       "--backlash-um, --rpm, --theta-amp)")
    k = args.orders_harmonics
    if not 1 <= k <= 32:
        raise CLIError(f"--orders-harmonics {k} is outside the allowed range [1, 32]")
    omap = OrderMap.read(args.orders_from, [phys.order * n for n in range(1, k + 1)])
    return Excitation(engine_order=phys.order, harmonics=k, order_map=omap)


def _run_map(args: argparse.Namespace, out: Path, png: Path | None, params, phys,
             follow=None) -> int:
    """A 2-D regime/intensity map, or basins of attraction, to a file plus PNG."""
    import numpy as np
    from rattle_core.analysis.vocabulary import LETTERS
    from rattle_core.batch.plan import plan_map
    from rattle_core.batch.sweep import check_budget
    from rattle_core.paper.drawing import map_png
    from rattle_core.store.exports import write_table
    from rattle_core.store.files import save_map
    from rattle_core.store.requests import run_map
    names = (args.param, args.param2)
    if args.mode != "fresh":
        raise CLIError("2-D maps start every point from the same state; drop --mode continuation")
    xv = _values(args, "", default_num=100)
    yv = _values(args, "2", default_num=100)
    transient = 300 if args.transient is None else args.transient
    record = 100 if args.record is None else args.record
    labels = ("--param", "--param2")
    # Work out (and reject) how the grid maps onto the model before starting any workers.
    basin = plan_map(params, phys, names[0], xv, names[1], yv, labels, follow)[0] == "basin"
    check_budget(xv.size * yv.size * (transient + record), "points × (transient + record)")
    scheduler = _scheduler(args)
    progress = Progress(f"map {names[0]} × {names[1]}", enabled=not args.quiet,
                        total=xv.size * yv.size, unit="point")
    common: dict[str, Any] = {"transient": transient, "record": record, "progress": progress}
    if not basin and (args.x0 is not None or args.v0 != 0.0):
        common.update(x0=args.x0, v0=args.v0)
    try:
        result = _run_on(args, scheduler, lambda executor: run_map(
            params, phys, names[0], xv, names[1], yv, use_cache=not args.no_cache, labels=labels,
            executor=executor, follow=follow, **common))
    finally:
        progress.close()
    if out.suffix.lower() == ".npz":
        save_map(out, result)
        user_permissions(out)
    else:
        m = {"kind": result.kind, "x_name": names[0], "y_name": names[1],
             "params": params.to_dict(), "settings": result.settings,
             "attractors": result.attractors}
        write_table(result.table(), out, m)
    if png is not None:
        map_png(png, result, axis_label(result.x_name), axis_label(result.y_name),
                label(params, phys, names))
    reg = result.fields["regime"]
    counts = {LETTERS[int(c)]: int((reg == c).sum()) for c in np.unique(reg) if c >= 0}
    kind = "basins" if basin else "regime map"
    info(args, f"{label(params, phys, names)}: {kind} over {names[0]} × {names[1]}, "
               f"{xv.size} × {yv.size} points{' (cancelled)' if result.cancelled else ''}")
    info(args, "regimes: " + ", ".join(f"{k} {v}" for k, v in sorted(counts.items())))
    if basin:
        info(args, f"{len(result.attractors)} attractors: " + "; ".join(
            f"{a['regime']} period {a['period']} ({100 * a['share']:.1f}%)" for a in result.attractors[:6]))
    info(args, f"wrote {out}")
    if png is not None:
        info(args, f"wrote {png}")
    return 0
