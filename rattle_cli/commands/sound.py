"""``rattle sound``: the rattle of one run, as a WAV file."""
from __future__ import annotations

import argparse

from ..common import CLIError, add_command, check_output, info, label, run_parent
from ..options import add_model_options, build_params

HELP = "the rattle sound of one run, as WAV"


def add_parser(sub) -> None:
    p = add_command(sub, run, HELP, run_parent(300))
    add_model_options(p)
    a = p.add_argument_group("sound")
    a.add_argument("--out", required=True, metavar="FILE.wav", help="output WAV file (16-bit PCM, mono)")
    a.add_argument("--rate", type=int, default=44_100, help="sample rate [Hz] (default 44100)")
    a.add_argument("--excitation-hz", dest="excitation_hz", type=float,
                   help="fundamental excitation frequency for dimensionless runs [Hz] (default 50)")
    a.add_argument("--modes", metavar="F:ZETA:GAIN[,...]",
                   help="housing modes, e.g. '1250:0.02:1,2150:0.015:0.8' (default: five modes, "
                        "1.25-5.8 kHz, damping 1-3 %%)")
    a.add_argument("--tail", type=float, default=0.15, help="ring-out after the run [s] (default 0.15)")
    a.add_argument("--polarity", choices=("signed", "absolute"), default="signed",
                   help="impulse strength Ĩ (polarity flips with the flank) or |Ĩ| (default signed)")


def run(args: argparse.Namespace) -> int:
    """Synthesise the rattle: every impact rings the gearbox housing's modes in proportion to its
    impulse (rattle_core.analysis.sound).  In physical units the engine speed sets the time
    scale."""
    from rattle_core import simulate
    from rattle_core.analysis import sound
    from rattle_core.model.params import check_range
    out = check_output(args.out, (".wav",), "--out")
    params, phys = build_params(args)
    if phys is not None and args.excitation_hz is not None:
        raise CLIError("--excitation-hz is for dimensionless runs; in physical units the engine "
                       "speed (--rpm, --order) sets the time scale")
    modes = sound.parse_modes(args.modes) if args.modes is not None else None
    # the rate, the length and the sample count are known before the run: check them first
    rate = sound.check_sample_rate(args.rate)
    tail = check_range("--tail", args.tail, 0.0, 10.0)
    if phys is not None:
        freq = phys.frequency_hz
    else:
        freq = check_range("--excitation-hz", sound.DEFAULT_EXCITATION_HZ if args.excitation_hz
                           is None else args.excitation_hz, *sound.EXCITATION_HZ_RANGE, lo_open=True)
    if args.periods >= 1:
        sound.check_length(args.periods / freq + tail, rate)
    tr = simulate(params, periods=args.periods, transient=args.transient, x0=args.x0, v0=args.v0)
    signal, rate = sound.synthesize(tr, sample_rate=args.rate, excitation_hz=args.excitation_hz,
                                    physical=phys, modes=modes, tail=args.tail,
                                    polarity=args.polarity)
    sound.write_wav(out, signal, rate)
    freq = phys.frequency_hz if phys is not None else (args.excitation_hz or sound.DEFAULT_EXCITATION_HZ)
    info(args, f"{label(params, phys)}: {tr.impact_t.size} impacts, fundamental {freq:g} Hz, "
               f"{signal.size / rate:.3g} s at {rate} Hz")
    info(args, f"wrote {out}")
    return 0
