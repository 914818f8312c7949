"""``rattle runup``: every gear of a gearbox driven through a run-up, impact by impact."""
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
    p.add_argument("--duration", type=float, default=DEFAULT_DURATION_S, metavar="S",
                   help=f"length of the linear ramp [s] (default {DEFAULT_DURATION_S:g})")
    p.add_argument("--out", required=True, metavar="RUNUP.csv",
                   help="one row per impact: t_s, rpm, gear, flank, impulse_Ns")
    p.add_argument("--wav", metavar="RUNUP.wav",
                   help="the whole gearbox's rattle over the run, 48 kHz, normalised to 0.99")


def run(args: argparse.Namespace) -> int:
    """Replay every gear of GEARBOX.toml over a linear run-up (or run-down) of the measured
    shaft, exactly (docs/model.md, "A run-up in physical time"): every impact with its time,
    speed, gear, flank and impulse, and each gear's first impact."""
    import numpy as np
    import pandas as pd

    from rattle_core.analysis.sound import normalize, render, write_wav
    from rattle_core.model.gearbox import Gearbox
    from rattle_core.solver.runup import check_run, replay
    from rattle_core.store.exports import write_table
    out = check_output(args.out, (".csv", ".parquet"), "--out")
    wav = check_output(args.wav, (".wav",), "--wav") if args.wav else None
    distinct_outputs(out, wav)
    gearbox = Gearbox.from_toml(args.file)
    lo, hi = gearbox.excitation.rpm_range
    if gearbox.excitation.order_map is not None:
        lo, hi = float(gearbox.excitation.order_map.rpm[0]), float(gearbox.excitation.order_map.rpm[-1])
    elif args.rpm_from is None or args.rpm_to is None:
        raise CLIError("a gearbox with constant orders needs --rpm-from and --rpm-to")
    rpm_from = lo if args.rpm_from is None else args.rpm_from
    rpm_to = hi if args.rpm_to is None else args.rpm_to
    for name, value in (("--rpm-from", rpm_from), ("--rpm-to", rpm_to), ("--duration", args.duration)):
        if not math.isfinite(value):
            raise CLIError(f"{name} = {value!r} must be a finite number")
    try:
        check_run(gearbox, rpm_from, rpm_to, args.duration)
    except ValueError as exc:
        raise CLIError(str(exc)) from None
    frames = []
    sound = np.zeros(int(round(args.duration * WAV_RATE))) if wav is not None else None
    for gi, gear in enumerate(gearbox.gears):
        res = replay(gearbox, gi, rpm_from, rpm_to, args.duration)
        frames.append(res.to_frame())
        onset = res.onset_rpm
        info(args, f"{gear.name}: {res.impact_t.size} impacts, " +
             (f"first at {onset:.1f} rpm" if math.isfinite(onset) else "never leaves contact"))
        if sound is not None and res.impact_t.size:
            sound += gearbox.transfer_pa_per_ns * render(res.impact_t, res.impact_impulse,
                                                         args.duration, WAV_RATE)
    table = pd.concat(frames, ignore_index=True).sort_values("t_s", kind="stable")
    write_table(table.reset_index(drop=True), out)
    info(args, f"wrote {out}")
    if wav is not None:
        write_wav(wav, normalize(sound), WAV_RATE)
        info(args, f"wrote {wav}")
    return 0
