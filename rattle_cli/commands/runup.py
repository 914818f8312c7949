"""``rattle runup``: every gear of a gearbox driven through a run-up, impact by impact, heard
and measured, and set against the quasi-steady verdict."""
from __future__ import annotations

import argparse
import math

from ..common import CLIError, add_command, check_output, distinct_outputs, info

HELP = "replay a run-up exactly: GEARBOX.toml to every impact (CSV) and the gearbox's sound (WAV)"
WAV_RATE = 48_000
DEFAULT_DURATION_S = 30.0


def add_parser(sub) -> None:
    p = add_command(sub, run, HELP)
    p.add_argument("file", metavar="GEARBOX.toml", help="the gearbox (see the README for the format)")
    p.add_argument("--rpm-from", dest="rpm_from", type=float, metavar="A",
                   help="shaft speed at the start [rpm] (default: the measurement's lowest)")
    p.add_argument("--rpm-to", dest="rpm_to", type=float, metavar="B",
                   help="shaft speed at the end [rpm] (default: the measurement's highest); "
                        "below A, a run-down")
    p.add_argument("--duration", type=float, metavar="S",
                   help=f"length of the linear ramp [s] (default {DEFAULT_DURATION_S:g}; not "
                        "with --wall angle, whose run lasts as long as the measurement's)")
    p.add_argument("--wall", choices=("orders", "angle"), default="orders",
                   help="the driving tooth's motion: the order reconstruction over a linear "
                        "ramp (default), or the measured angle itself, low-pass filtered at "
                        "--cutoff-hz, over the measurement's own stretch from A to B")
    p.add_argument("--cutoff-hz", dest="cutoff_hz", type=float, metavar="F",
                   help="cutoff of the measured angle's zero-phase low-pass [Hz], below the "
                        "sampling's Nyquist frequency (needed with --wall angle)")
    p.add_argument("--out", required=True, metavar="RUNUP.csv",
                   help="one row per impact: t_s, rpm, gear, flank, impulse_Ns")
    p.add_argument("--wav", metavar="RUNUP.wav",
                   help="the whole gearbox's rattle over the run, 48 kHz, normalised to 0.99 "
                        "(the Pa per full scale is printed)")
    p.add_argument("--png", nargs="?", const="", metavar="FILE.png",
                   help="also draw N(t) and dB(A)(t) against rpm with the verdict's loudness and "
                        "the onsets, and the sound's spectrogram with the engine orders "
                        "(default name: OUT with .png)")
    p.add_argument("--compare-verdict", dest="compare", action="store_true",
                   help="set the run against the quasi-steady verdict on a 50-rpm grid and "
                        "against the run-down over the same speeds: onsets and loudness")


def run(args: argparse.Namespace) -> int:
    """Replay every gear of GEARBOX.toml over a linear run-up (or run-down) of the measured
    shaft, exactly (docs/model.md, "A run-up in physical time"): every impact with its time,
    speed, gear, flank and impulse, each gear's rattle intervals, the gearbox's sound, its
    loudness and level over the run, and (on request) the quasi-steady verdict beside it."""
    import numpy as np

    from rattle_core.analysis.sound import normalize, write_wav
    from rattle_core.batch.runup import compare, gearbox_runup, verdict_grid
    from rattle_core.model.gearbox import Gearbox
    from rattle_core.solver.runup import check_run
    from rattle_core.store.exports import write_table
    out = check_output(args.out, (".csv", ".parquet"), "--out")
    intervals_out = out.with_name(f"{out.stem}_intervals{out.suffix}")
    wav = check_output(args.wav, (".wav",), "--wav") if args.wav else None
    png = None
    if args.png is not None:
        png = check_output(args.png or str(out.with_suffix(".png")), (".png",), "--png")
    distinct_outputs(out, intervals_out, wav, png)
    if args.wall == "angle":
        if args.cutoff_hz is None:
            raise CLIError("--wall angle needs --cutoff-hz F (the low-pass cutoff, in Hz)")
        if args.duration is not None:
            raise CLIError("--duration does not apply to --wall angle: the run lasts as long as "
                           "the measurement takes from --rpm-from to --rpm-to")
    elif args.cutoff_hz is not None:
        raise CLIError("--cutoff-hz applies to --wall angle only")
    duration = DEFAULT_DURATION_S if args.duration is None else args.duration
    gearbox = Gearbox.from_toml(args.file)
    angle = None
    if args.wall == "angle":
        angle = _measured_angle(args.file, gearbox, args.cutoff_hz)
        lo_s, hi_s = angle.usable_s
        if args.rpm_from is None or args.rpm_to is None:
            t = angle.time_s[(angle.time_s >= lo_s) & (angle.time_s <= hi_s)]
            if t.size < 2:
                raise CLIError(f"the measurement is too short for --cutoff-hz {args.cutoff_hz:g}")
            rpm = angle.mean_rpm(t)
            lo_r, hi_r = float(rpm.min()), float(rpm.max())
    lo, hi = gearbox.excitation.rpm_range
    if angle is not None:
        if args.rpm_from is None or args.rpm_to is None:
            lo, hi = lo_r, hi_r
    elif gearbox.excitation.order_map is not None:
        lo, hi = float(gearbox.excitation.order_map.rpm[0]), float(gearbox.excitation.order_map.rpm[-1])
    elif args.rpm_from is None or args.rpm_to is None:
        raise CLIError("a gearbox with constant orders needs --rpm-from and --rpm-to")
    rpm_from = lo if args.rpm_from is None else args.rpm_from
    rpm_to = hi if args.rpm_to is None else args.rpm_to
    for name, value in (("--rpm-from", rpm_from), ("--rpm-to", rpm_to), ("--duration", duration)):
        if not math.isfinite(value):
            raise CLIError(f"{name} = {value!r} must be a finite number")
    sound = wav is not None or png is not None or args.compare
    try:
        if angle is None:
            check_run(gearbox, rpm_from, rpm_to, duration)
        grid = verdict_grid(rpm_from, rpm_to) if (png is not None or args.compare) else None
        res = gearbox_runup(gearbox, rpm_from, rpm_to, None if angle else duration,
                            sound=sound, angle=angle)
    except ValueError as exc:
        raise CLIError(str(exc)) from None
    for name, rr in res.replays.items():
        onset = rr.onset_rpm
        info(args, f"{name}: {rr.impact_t.size} impacts, " +
             (f"first at {onset:.1f} rpm" if math.isfinite(onset) else "never leaves contact"))
    write_table(res.impacts, out)
    info(args, f"wrote {out}")
    write_table(res.intervals, intervals_out)
    info(args, f"wrote {intervals_out}")
    if wav is not None:
        write_wav(wav, normalize(res.pressure_pa), WAV_RATE)
        info(args, f"wrote {wav}: full scale (1.0, int16 32767) = {res.calibration_pa:.6g} Pa")
    if sound:
        peak_n = float(np.max(res.loudness_t)) if res.loudness_t.size else 0.0
        finite = res.level_dba_t[np.isfinite(res.level_dba_t)]
        info(args, f"gearbox: N max {peak_n:.2f} sone, L_AF max "
             f"{float(finite.max()) if finite.size else float('nan'):.1f} dB(A)")
    verdict = comparison = None
    if grid is not None:
        from rattle_core.store.verdicts import cached_verdict
        verdict = cached_verdict(gearbox, grid, ensemble_runs=0)
    if args.compare:
        try:
            down = gearbox_runup(gearbox, rpm_to, rpm_from, None if angle else duration,
                                 sound=False, angle=angle)
        except ValueError as exc:
            raise CLIError(f"the run-down: {exc}") from None
        comparison = compare(res, verdict, down)
        for name, row in comparison.onsets.set_index("gear").iterrows():
            info(args, f"{name}: onset on the run {_rpm(row.onset_run_rpm)}, on the run-down "
                       f"{_rpm(row.onset_rundown_rpm)}, in the verdict {_rpm(row.onset_verdict_rpm)}")
        for line in comparison.text.splitlines():
            info(args, line)
    elif verdict is not None:
        for name, onset in res.onsets.items():
            info(args, f"{name}: onset on the run {_rpm(onset)}, in the verdict "
                       f"{_rpm(verdict.onsets[name])}")
    if png is not None:
        from rattle_core.paper.runup_pictures import runup_png
        runup_png(png, res, comparison, verdict)
        info(args, f"wrote {png}")
    return 0


def _measured_angle(path, gearbox, cutoff_hz: float):
    """The filtered angle of the measurement GEARBOX.toml names, read with its options."""
    import tomllib
    from pathlib import Path

    from rattle_core.batch.runup import measured_angle
    from rattle_core.measure.measurement import measurement_options
    from rattle_core.measure.orders import SAMPLE_RUNUP
    with open(path, "rb") as f:
        exc_t = tomllib.load(f).get("excitation", {})
    name = exc_t.get("measurement")
    if not isinstance(name, str):
        raise CLIError("--wall angle needs a gearbox driven by a measurement "
                       "([excitation] measurement = \"FILE.csv\"), not by constant orders")
    file = SAMPLE_RUNUP if name == "sample" else Path(path).parent / name
    try:
        return measured_angle(file, cutoff_hz, gearbox.excitation.engine_order,
                              **measurement_options(exc_t))
    except ValueError as exc:
        raise CLIError(str(exc)) from None


def _rpm(value: float) -> str:
    return "never" if not math.isfinite(value) else f"{value:.0f} rpm"
