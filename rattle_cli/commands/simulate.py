"""``rattle simulate``: one run; its impacts and its sampled motion to CSV or Parquet."""
from __future__ import annotations

import argparse

from ..common import (CLIError, add_command, check_output, distinct_outputs, info, label, meta,
                      run_parent)
from ..options import add_model_options, build_params

HELP = "one run: impacts and time history to CSV or Parquet"
#: Most rows a sampled time history may have (periods × samples per period).
MAX_HISTORY_ROWS = 5_000_000


def add_parser(sub) -> None:
    p = add_command(sub, run, HELP, run_parent(0))
    add_model_options(p)
    p.add_argument("--impacts", metavar="FILE", help="write the impacts here (.csv or .parquet)")
    p.add_argument("--history", metavar="FILE", help="write the sampled time history here (.csv or .parquet)")
    p.add_argument("--samples-per-period", dest="samples_per_period", type=int, default=64,
                   help="time-history samples per forcing period (default 64)")
    p.add_argument("--stats", action="store_true",
                   help="also run --runs independent runs (other noise seeds, starts spread over "
                        "the backlash) and print each rattle statistic with its 95 %% interval, "
                        "per attractor reached")
    p.add_argument("--runs", type=int, default=8,
                   help="independent runs for --stats, in [2, 1000] (default 8)")


def run(args: argparse.Namespace) -> int:
    """Simulate one run exactly.  --impacts gets one row per impact (t, phase, impulse, flank
    active/reverse, w; plus t_s and impulse_Ns in physical units).  --history gets the
    motion sampled uniformly (t, x, v, y, y_plus_j, contact none/active/reverse; plus t_s,
    x_um, v_mps, y_um in physical units).  The format follows the extension (.csv or
    .parquet; Parquet files carry the parameters as metadata)."""
    from rattle_core import classify, simulate, statistics
    from rattle_core.store.exports import TABLE_SUFFIXES, history_frame, impacts_frame, write_table
    if args.impacts is None and args.history is None and not args.stats:
        raise CLIError("simulate: give --impacts FILE and/or --history FILE (.csv or .parquet), "
                       "or --stats")
    if not 2 <= args.runs <= 1000:
        raise CLIError(f"--runs {args.runs} is outside the allowed range [2, 1000]")
    imp_path = check_output(args.impacts, TABLE_SUFFIXES, "--impacts") if args.impacts is not None else None
    hist_path = check_output(args.history, TABLE_SUFFIXES, "--history") if args.history is not None else None
    distinct_outputs(imp_path, hist_path)
    if not 1 <= args.samples_per_period <= 100_000:
        raise CLIError(f"--samples-per-period {args.samples_per_period} is outside the allowed "
                       "range [1, 100000]")
    rows = args.periods * args.samples_per_period
    if hist_path is not None and rows > MAX_HISTORY_ROWS:
        raise CLIError(f"--periods × --samples-per-period = {rows} history rows is outside the "
                       f"allowed range [1, {MAX_HISTORY_ROWS}]")
    params, phys = build_params(args)
    tr = simulate(params, periods=args.periods, transient=args.transient, x0=args.x0, v0=args.v0,
                  lyapunov=True)
    m = meta(params, phys)
    m.update(periods=args.periods, transient=args.transient, x0=tr.settings["x0"], v0=args.v0)
    if imp_path is not None:
        write_table(impacts_frame(tr, phys), imp_path, m)
    if hist_path is not None:
        write_table(history_frame(tr, args.samples_per_period, phys), hist_path, m)
    info(args, f"{label(params, phys)}: {tr.impact_t.size} impacts in {args.periods} periods")
    hint = "" if args.transient >= 100 else " (of a window that includes the start-up; --transient skips it)"
    info(args, f"regime {classify(tr).label}{hint}")
    for path in (imp_path, hist_path):
        if path is not None:
            info(args, f"wrote {path}")
    if args.stats:
        st = statistics(params, runs=args.runs, periods=args.periods, transient=args.transient)
        # the statistics are what was asked for: printed even with --quiet
        print(f"statistics over {args.runs} independent runs at noise {params.noise:g} "
              "(95 % intervals; 'exact' on a periodic orbit):")
        for line in str(st).splitlines():
            print("  " + line)
    return 0
