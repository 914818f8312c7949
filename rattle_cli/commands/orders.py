"""``rattle orders``: a measured shaft speed split into engine orders, per rpm bin."""
from __future__ import annotations

import argparse

from ..common import CLIError, Progress, add_command, check_output, distinct_outputs, info

HELP = "engine orders of a measured speed (time_s, speed_rpm) per rpm bin, to CSV"
#: rattle_core.model.orders.DEFAULT_ORDERS, written out so that --help imports nothing heavy
DEFAULT_ORDERS = "2,4,6"


def add_parser(sub) -> None:
    p = add_command(sub, run, HELP)
    p.add_argument("file", metavar="FILE.csv", help="measurement with columns time_s and speed_rpm "
                   "(.csv or .csv.gz; lines starting with # are comments)")
    p.add_argument("--orders", default=DEFAULT_ORDERS,
                   metavar="K[,K...]", help="engine orders to estimate (default 2,4,6)")
    p.add_argument("--rpm-step", dest="rpm_step", type=float, default=100.0,
                   help="width of the rpm bins (default 100)")
    p.add_argument("--out", required=True, metavar="ORDERS.csv",
                   help="one row per rpm bin and order: rpm, order, amplitude_rad, accel_rad_s2, "
                        "phase_deg")
    p.add_argument("--png", nargs="?", const="", metavar="FILE.png",
                   help="also draw the orders against rpm (default name: OUT with .png)")


def run(args: argparse.Namespace) -> int:
    """Integrate the speed to the shaft angle, resample it uniformly in angle and estimate each
    engine order's angular displacement (rad), acceleration (rad/s²) and phase per rpm bin, with
    θ(t) = Σ θ_k cos(k ψ − φ_k), ψ the mean shaft angle from the file's start.  A progress bar
    follows the reading and the analysis; Ctrl-C stops it."""
    from rattle_core.model.orders import OrderMap, check_orders
    from rattle_core.paper.drawing import orders_png
    from rattle_core.store.exports import write_table
    out = check_output(args.out, (".csv",), "--out")
    png = None
    if args.png is not None:
        png = check_output(args.png or str(out.with_suffix(".png")), (".png",), "--png")
    distinct_outputs(out, png)
    try:
        orders = check_orders(args.orders)
    except ValueError as exc:
        raise CLIError(f"--orders: {exc}") from None
    bar = Progress("orders", enabled=not args.quiet, unit="%")
    try:
        omap = OrderMap.from_csv(args.file, orders, args.rpm_step,
                                 progress=lambda done, total: bar(100 * done // total, 100))
    finally:
        bar.close()
    write_table(omap.to_frame(), out)
    info(args, f"{omap.source}: {omap.rpm.size} rpm bins from {omap.rpm[0]:.0f} to "
               f"{omap.rpm[-1]:.0f} rpm, orders {', '.join(f'{k:g}' for k in omap.orders)}")
    info(args, f"wrote {out}")
    if png is not None:
        orders_png(png, omap, f"engine orders of {omap.source}")
        info(args, f"wrote {png}")
    return 0
