"""``rattle gearbox``: the verdict on a gearbox of loose gears, one row per gear and speed."""
from __future__ import annotations

import argparse
import contextlib
import math

from ..common import CLIError, Progress, add_command, check_output, distinct_outputs, info

HELP = "which loose gears rattle, from which rpm, how loud: GEARBOX.toml to a verdict CSV"


def rpm_range(text: str) -> np.ndarray:
    """``START:STOP:NUM`` as evenly spaced speeds."""
    import numpy as np
    parts = str(text).split(":")
    try:
        if len(parts) != 3:
            raise ValueError
        start, stop, num = float(parts[0]), float(parts[1]), int(parts[2])
    except ValueError:
        raise argparse.ArgumentTypeError(f"--rpm {text!r} must read START:STOP:NUM, e.g. "
                                         "1000:3000:41") from None
    if not (math.isfinite(start) and math.isfinite(stop) and 0 < start < stop and 1 < num <= 2000):
        raise argparse.ArgumentTypeError(f"--rpm {text!r}: need 0 < START < STOP and NUM in "
                                         "[2, 2000]")
    return np.linspace(start, stop, num)


def add_parser(sub) -> None:
    p = add_command(sub, run, HELP)
    p.add_argument("file", metavar="GEARBOX.toml", help="the gearbox (see the README for the format)")
    p.add_argument("--rpm", type=rpm_range, required=True, metavar="START:STOP:NUM",
                   help="engine speeds, e.g. 1000:3000:41")
    p.add_argument("--out", required=True, metavar="VERDICT.csv",
                   help="one row per gear and speed: gear, rpm, regime, impacts_per_s, intensity, "
                        "loudness_sone, sharpness_acum, onset_rpm, 95 %% intervals, contact_ratio")
    p.add_argument("--png", nargs="?", const="", metavar="FILE.png",
                   help="also draw the verdict (default name: OUT with .png)")
    p.add_argument("--transfer", type=float, metavar="PA_PER_NS",
                   help="sound pressure [Pa] per N·s of impulse (default: the file's, else 5)")
    p.add_argument("--transient", type=int, default=200,
                   help="unrecorded excitation periods per point (default 200)")
    p.add_argument("--record", type=int, default=100,
                   help="recorded periods per point, at least enough for the sound (default 100)")
    p.add_argument("--runs", type=int, default=8,
                   help="independent runs behind the rates and 95 %% intervals of points whose "
                        "motion does not repeat (default 8; 0: one run, intervals from blocks of "
                        "its window)")
    d = p.add_argument_group("parallel (default: all local cores)")
    d.add_argument("--dask", choices=("local",), help="'local': run on a Dask LocalCluster started here")
    d.add_argument("--workers", type=int, default=2, help="workers of --dask local (default 2)")
    d.add_argument("--scheduler", metavar="tcp://HOST:PORT", help="run on this Dask scheduler")
    p.add_argument("--no-cache", dest="no_cache", action="store_true",
                   help="recompute even when the disk cache holds this verdict, and do not store it")


def run(args: argparse.Namespace) -> int:
    """Run every gear of GEARBOX.toml at every speed as one batch (cached on disk): its regime,
    impacts per second, rattle intensity, the loudness (ISO 532-1, sone) and sharpness
    (DIN 45692, acum) of its rattle and of the whole gearbox, and the speed from which it rattles."""
    if not 1 <= args.workers <= 256:
        raise CLIError(f"--workers {args.workers} is outside the allowed range [1, 256]")
    from rattle_core.batch.executor import dask_session
    from rattle_core.model.gearbox import Gearbox
    from rattle_core.paper.drawing import verdict_png
    from rattle_core.store.exports import write_table
    from rattle_core.store.verdicts import cached_verdict
    out = check_output(args.out, (".csv", ".parquet"), "--out")
    png = None
    if args.png is not None:
        png = check_output(args.png or str(out.with_suffix(".png")), (".png",), "--png")
    distinct_outputs(out, png)
    gearbox = Gearbox.from_toml(args.file)
    if args.transfer is not None:
        try:
            gearbox = gearbox.replace(transfer_pa_per_ns=args.transfer)
        except ValueError as exc:
            raise CLIError(f"--transfer: {exc}") from None
    if args.dask and args.scheduler:
        raise CLIError("give --dask local or --scheduler ADDRESS, not both")
    bar = Progress("gearbox", enabled=not args.quiet, unit="point")
    try:
        with contextlib.ExitStack() as stack:
            try:
                executor = stack.enter_context(dask_session(args.scheduler or args.dask,
                                                            args.workers))
            except (ConnectionError, ValueError) as exc:
                raise CLIError(f"{'--scheduler' if args.scheduler else '--dask'}: {exc}") from None
            result = cached_verdict(gearbox, args.rpm, transient=args.transient, record=args.record,
                                    progress=bar, use_cache=not args.no_cache,
                                    ensemble_runs=args.runs, executor=executor)
    finally:
        bar.close()
    write_table(result.table, out)
    for name, onset in result.onsets.items():
        text = f"rattles from {onset:g} rpm" if math.isfinite(onset) else "never leaves contact"
        info(args, f"{name}: {text}")
    loud = result.gear("gearbox")["loudness_sone"]
    info(args, f"gearbox: up to {loud.max():.3g} sone{' (from the cache)' if result.from_cache else ''}")
    info(args, f"wrote {out}")
    if png is not None:
        verdict_png(png, result, f"verdict of {args.file}")
        info(args, f"wrote {png}")
    return 0
