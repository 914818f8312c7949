"""``rattle orders``: a measured shaft speed split into engine orders, per rpm bin."""
from __future__ import annotations

import argparse

from ..common import CLIError, Progress, add_command, check_output, distinct_outputs, info

HELP = "engine orders of a measured speed (or tachometer pulses) per rpm bin, to CSV"
#: rattle_core.measure.orders.DEFAULT_ORDERS, written out so that --help imports nothing heavy
DEFAULT_ORDERS = "2,4,6"


def add_parser(sub) -> None:
    p = add_command(sub, run, HELP)
    p.add_argument("file", metavar="FILE.csv", help="measurement with a time and a speed column, "
                   "recognised by name and unit (time_s, Time [s], speed_rpm, n [1/min], "
                   "omega [rad/s], f [Hz]); delimiter, decimal comma and a units row are "
                   "detected (.csv or .csv.gz; lines starting with # are comments)")
    p.add_argument("--orders", default=DEFAULT_ORDERS,
                   metavar="K[,K...]", help="engine orders to estimate (default 2,4,6)")
    p.add_argument("--rpm-step", dest="rpm_step", type=float, default=100.0,
                   help="width of the rpm bins (default 100)")
    p.add_argument("--out", required=True, metavar="ORDERS.csv",
                   help="one row per rpm bin and order: rpm, order, amplitude_rad, accel_rad_s2, "
                        "phase_deg")
    p.add_argument("--time-column", dest="time_column", metavar="NAME",
                   help="the time column [s], if not recognised")
    p.add_argument("--speed-column", dest="speed_column", metavar="NAME",
                   help="the speed column, if not recognised")
    p.add_argument("--speed-unit", dest="speed_unit", choices=("rpm", "rad/s", "Hz"),
                   help="the speed column's unit, if not recognised (converted to rpm)")
    p.add_argument("--pulse-column", dest="pulse_column", metavar="NAME",
                   help="tachometer pulses instead of a speed: a column of pulse times [s], or a "
                        "sampled tachometer signal beside the time column")
    p.add_argument("--pulses-per-rev", dest="pulses_per_rev", type=int, metavar="N",
                   help="pulses per shaft revolution (with --pulse-column); orders up to N/4 "
                        "are resolved")
    p.add_argument("--from-s", dest="from_s", type=float, metavar="T",
                   help="analyse from this time [s] of the file")
    p.add_argument("--to-s", dest="to_s", type=float, metavar="T",
                   help="analyse up to this time [s] of the file")
    p.add_argument("--campbell", metavar="FILE.png",
                   help="also draw the Campbell diagram: order spectrum against rpm, in dB, "
                        "with the analysed orders marked")
    p.add_argument("--png", nargs="?", const="", metavar="FILE.png",
                   help="also draw the orders against rpm (default name: OUT with .png)")


def run(args: argparse.Namespace) -> int:
    """Integrate the speed to the shaft angle, resample it uniformly in angle and estimate each
    engine order's angular displacement (rad), acceleration (rad/s²) and phase per rpm bin, with
    θ(t) = Σ θ_k cos(k ψ − φ_k), ψ the mean shaft angle from the file's start.  A progress bar
    follows the reading and the analysis; Ctrl-C stops it."""
    from rattle_core.measure.measurement import read_measurement
    from rattle_core.measure.orders import OrderMap, check_orders
    from rattle_core.paper.drawing import orders_png
    from rattle_core.store.exports import write_table
    out = check_output(args.out, (".csv",), "--out")
    png = None
    if args.png is not None:
        png = check_output(args.png or str(out.with_suffix(".png")), (".png",), "--png")
    campbell = check_output(args.campbell, (".png",), "--campbell") if args.campbell else None
    distinct_outputs(out, png, campbell)
    try:
        orders = check_orders(args.orders)
    except ValueError as exc:
        raise CLIError(f"--orders: {exc}") from None
    if (args.pulse_column is None) != (args.pulses_per_rev is None):
        raise CLIError("--pulse-column and --pulses-per-rev go together")
    meas = read_measurement(args.file, time_column=args.time_column,
                            speed_column=args.speed_column, speed_unit=args.speed_unit,
                            pulse_column=args.pulse_column, pulses_per_rev=args.pulses_per_rev,
                            from_s=args.from_s, to_s=args.to_s)
    bar = Progress("orders", enabled=not args.quiet, unit="%")
    try:
        omap = OrderMap.from_measurement(meas, orders, args.rpm_step,
                                         progress=lambda done, total: bar(100 * done // total, 100))
    finally:
        bar.close()
    for line in omap.detected.describe():
        info(args, line)
    for line in omap.notices:
        info(args, line)
    write_table(omap.to_frame(), out)
    info(args, f"{omap.source}: {omap.rpm.size} rpm bins from {omap.rpm[0]:.0f} to "
               f"{omap.rpm[-1]:.0f} rpm, orders {', '.join(f'{k:g}' for k in omap.orders)}")
    info(args, f"wrote {out}")
    if png is not None:
        orders_png(png, omap, f"engine orders of {omap.source}")
        info(args, f"wrote {png}")
    if campbell is not None:
        from rattle_core.measure.campbell import campbell as campbell_data
        from rattle_core.paper.drawing import campbell_png
        data = campbell_data(meas, omap.orders, args.rpm_step)
        campbell_png(campbell, data, f"Campbell diagram of {omap.source}")
        info(args, f"wrote {campbell}")
    return 0
