"""``rattle gearbox``: the verdict on a gearbox of loose gears, one row per gear and speed; against
a target, at an oil temperature or over several, and beside a second design."""
from __future__ import annotations

import argparse
import contextlib
import math
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # the numerical stack loads in run(), so --help stays light
    import numpy as np

    from rattle_core.model.gearbox import Gearbox
    from rattle_core.model.target import Target

from ..common import CLIError, Progress, add_command, check_output, distinct_outputs, info

HELP = "which loose gears rattle, from which rpm, how loud: GEARBOX.toml to a verdict CSV"
#: Oil temperatures a verdict may be asked at [°C].
OIL_TEMP_RANGE = (-40.0, 150.0)
#: Steps of the default speed grid [rpm], the finest that keeps it within :data:`GRID_SPEEDS`.
GRID_STEPS = (50.0, 100.0, 200.0, 250.0, 500.0, 1000.0)
GRID_SPEEDS = 41
#: The default speeds of a gearbox whose orders are constant (no measured range).
CONSTANT_RANGE = (1000.0, 3000.0)


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


def oil_temp(text: str) -> float:
    """One oil temperature [°C] in :data:`OIL_TEMP_RANGE`."""
    lo, hi = OIL_TEMP_RANGE
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"--oil-temp {text!r} must be a number of °C") from None
    if not (math.isfinite(value) and lo <= value <= hi):
        raise argparse.ArgumentTypeError(f"--oil-temp {text!r} is outside the allowed range "
                                         f"[{lo:g}, {hi:g}] °C")
    return value


def oil_temps(text: str) -> np.ndarray:
    """``A:B:N`` as N evenly spaced oil temperatures [°C] in :data:`OIL_TEMP_RANGE`."""
    import numpy as np
    lo, hi = OIL_TEMP_RANGE
    parts = str(text).split(":")
    try:
        if len(parts) != 3:
            raise ValueError
        a, b, n = float(parts[0]), float(parts[1]), int(parts[2])
    except ValueError:
        raise argparse.ArgumentTypeError(f"--oil-temps {text!r} must read A:B:N, e.g. "
                                         "-20:100:7") from None
    if not (math.isfinite(a) and math.isfinite(b) and lo <= a < b <= hi and 2 <= n <= 50):
        raise argparse.ArgumentTypeError(f"--oil-temps {text!r}: need {lo:g} <= A < B <= {hi:g} "
                                         "°C and N in [2, 50]")
    return np.linspace(a, b, n)


def target_text(text: str) -> Target:
    """A target in the CLI's text form (:meth:`rattle_core.model.target.Target.parse`)."""
    from rattle_core.model.target import Target
    try:
        return Target.parse(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(f"--target: {exc}") from None


def round_grid(gearbox: Gearbox) -> np.ndarray:
    """The default speeds: every 50, 100, ... rpm (:data:`GRID_STEPS`, the finest with at most
    :data:`GRID_SPEEDS` speeds) from the first round speed inside the excitation's range to the
    last, so onsets print as round numbers."""
    import numpy as np
    exc = gearbox.excitation
    lo, hi = exc.rpm_range if exc.order_map is not None else CONSTANT_RANGE
    for step in GRID_STEPS:
        start, stop = math.ceil(lo / step - 1e-9) * step, math.floor(hi / step + 1e-9) * step
        start = max(start, step)
        if stop > start and (stop - start) / step + 1 <= GRID_SPEEDS:
            return np.arange(start, stop + step / 2, step)
    raise CLIError(f"the excitation's speeds {lo:g} to {hi:g} rpm hold no round grid; give --rpm")


def add_parser(sub) -> None:
    p = add_command(sub, run, HELP)
    p.add_argument("file", metavar="GEARBOX.toml", help="the gearbox (see the README for the format)")
    p.add_argument("--rpm", type=rpm_range, metavar="START:STOP:NUM",
                   help="engine speeds, e.g. 1000:3000:41 (default: every 50 or 100 rpm across the "
                        "excitation's range, round numbers)")
    p.add_argument("--out", required=True, metavar="VERDICT.csv",
                   help="one row per gear and speed: gear, rpm, regime, impacts_per_s, intensity, "
                        "loudness_sone, sharpness_acum, onset_rpm, 95 %% intervals, contact_ratio, "
                        "and with a target target_*, margin_*, pass; rattle_ranges")
    p.add_argument("--png", nargs="?", const="", metavar="FILE.png",
                   help="also draw the verdict (default name: OUT with .png)")
    p.add_argument("--target", type=target_text, metavar="'RPM:VALUE,... sone; RPM:VALUE,... dba'",
                   help="limit curves over rpm, e.g. '1000:10,3000:20 sone; 1000:60,3000:70 dba' "
                        "(replaces the file's [target])")
    p.add_argument("--oil-temp", dest="oil_temp", type=oil_temp, metavar="C",
                   help=f"oil temperature [°C], {OIL_TEMP_RANGE[0]:g} to {OIL_TEMP_RANGE[1]:g} "
                        "(default: the file's)")
    p.add_argument("--oil-temps", dest="oil_temps", type=oil_temps, metavar="A:B:N",
                   help="a verdict at N oil temperatures from A to B °C: the CSV gains oil_temp_C, "
                        "the PNG is the map of regime, loudness and pass over rpm × temperature "
                        "(computed afresh, not cached)")
    p.add_argument("--compare", metavar="B.toml",
                   help="a second design run at the same speeds and settings: the CSV gets a "
                        "design column and B - A rows, the PNG draws B dashed")
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


def _settings(gearbox: Gearbox, args: argparse.Namespace, which: str) -> Gearbox:
    """``gearbox`` with the command line's transfer, target and oil temperature: the target
    reaches the verdict only through the gearbox, as the file's [target] does."""
    changes = {"transfer_pa_per_ns": ("--transfer", args.transfer),
               "target": ("--target", args.target), "oil_temp_C": ("--oil-temp", args.oil_temp)}
    for key, (option, value) in changes.items():
        if value is None:
            continue
        try:
            gearbox = gearbox.replace(**{key: value})
        except ValueError as exc:
            raise CLIError(f"{option} ({which}): {exc}") from None
    return gearbox


def run(args: argparse.Namespace) -> int:
    """Run every gear of GEARBOX.toml at every speed as one batch (cached on disk): its regime,
    impacts per second, rattle intensity, the loudness (ISO 532-1, sone) and sharpness
    (DIN 45692, acum) of its rattle and of the whole gearbox, every speed range in which it
    rattles, what keeps it quiet, and with a target its margins and the speeds that fail.
    ``--compare B.toml`` runs a second design beside it; ``--oil-temps`` maps rpm × oil
    temperature."""
    from rattle_core.batch.executor import dask_session
    from rattle_core.batch.gearbox import check_rpm
    from rattle_core.batch.temperatures import verdict_over_temperatures
    from rattle_core.model.gearbox import Gearbox
    from rattle_core.paper.verdict_pictures import designs_png
    from rattle_core.store import verdict_tables as vt
    from rattle_core.store.exports import write_table
    from rattle_core.store.verdicts import cached_verdict
    if not 1 <= args.workers <= 256:
        raise CLIError(f"--workers {args.workers} is outside the allowed range [1, 256]")
    if args.oil_temps is not None and (args.oil_temp is not None or args.compare):
        raise CLIError("--oil-temps maps one design over temperatures; give it without "
                       "--oil-temp and --compare")
    out = check_output(args.out, (".csv", ".parquet"), "--out")
    png = None
    if args.png is not None:
        png = check_output(args.png or str(out.with_suffix(".png")), (".png",), "--png")
    distinct_outputs(out, png)
    if args.dask and args.scheduler:
        raise CLIError("give --dask local or --scheduler ADDRESS, not both")
    gearbox = _settings(Gearbox.from_toml(args.file), args, "A")
    other = None
    if args.compare:
        other = _settings(Gearbox.from_toml(args.compare), args, "B")
    rpm = args.rpm if args.rpm is not None else round_grid(gearbox)
    boxes = [gearbox] + ([other] if other is not None else [])
    for which, box in zip("AB", boxes):
        try:
            check_rpm(rpm, box)
        except ValueError as exc:
            raise CLIError(f"--rpm ({which}: {args.file if which == 'A' else args.compare}): "
                           f"{exc}") from None
    bar = Progress("gearbox", enabled=not args.quiet, unit="point")
    results = []
    run_kw = dict(transient=args.transient, record=args.record, progress=bar,
                  ensemble_runs=args.runs)
    try:
        with contextlib.ExitStack() as stack:
            try:
                executor = stack.enter_context(dask_session(args.scheduler or args.dask,
                                                            args.workers))
            except (ConnectionError, ValueError) as exc:
                raise CLIError(f"{'--scheduler' if args.scheduler else '--dask'}: {exc}") from None
            if args.oil_temps is not None:
                # one computation over all temperatures, not cached: a map is asked for once,
                # while a single verdict is looked at again and again (and is cached)
                try:
                    table = verdict_over_temperatures(gearbox, rpm, args.oil_temps,
                                                      executor=executor, **run_kw)
                except ValueError as exc:
                    raise CLIError(f"--oil-temps: {exc}") from None
            else:
                for box in boxes:
                    results.append(cached_verdict(box, rpm, use_cache=not args.no_cache,
                                                  executor=executor, **run_kw))
    finally:
        bar.close()
    if args.oil_temps is not None:
        return _temperatures(args, gearbox, table, out, png)
    cached = " (from the cache)" if all(r.from_cache for r in results) else ""
    if other is None:
        result = results[0]
        write_table(vt.frame(result), out)
        for line in vt.gear_lines(result):
            info(args, line)
        if cached:
            info(args, cached.strip(" ()"))
        info(args, f"wrote {out}")
        if png is not None:
            designs_png(png, [(result, Path(args.file).name)], f"verdict of {args.file}",
                        vt.target_of(result))
            info(args, f"wrote {png}")
        return 0
    names = vt.design_names(Path(args.file).name, Path(args.compare).name)
    write_table(vt.compare_frame(results[0], results[1], names), out)
    for line in vt.compare_lines(results[0], results[1], names):
        info(args, line)
    for name, res in zip(names, results):
        for line in vt.gear_lines(res):
            info(args, f"[{name}] {line}")
    info(args, f"wrote {out}")
    if png is not None:
        designs_png(png, list(zip(results, names)), f"{names[0]} against {names[1]} (dashed)",
                    vt.target_of(results[0]))
        info(args, f"wrote {png}")
    return 0


def _temperatures(args: argparse.Namespace, gearbox: Gearbox, table, out, png) -> int:
    """The verdicts over oil temperatures as one table (``oil_temp_C``) and one map."""
    from rattle_core.paper.verdict_pictures import temperature_map_png
    from rattle_core.store import verdict_tables as vt
    from rattle_core.store.exports import write_table
    write_table(table, out)
    names = [g.name for g in gearbox.gears]
    for t, rows in table.groupby("oil_temp_C", sort=True):
        onsets = "; ".join(f"{n} {vt.onset_text(float(rows.loc[rows['gear'] == n, 'onset_rpm'].iloc[0]))}"
                           for n in names)
        info(args, f"{t:g} °C: {onsets}")
    info(args, f"wrote {out}")
    if png is not None:
        temperature_map_png(png, table, names, f"{args.file} over oil temperature")
        info(args, f"wrote {png}")
    return 0
