"""``rattle atlas``: follow one bifurcation in a second parameter; its curve to CSV.

``--from START:PARAM[+|-]:KIND[:N]`` says which bifurcation: the orbit to start from (``c``,
the closed-form one-sided C orbit; ``c-unstable``, its unstable twin; ``simulate``, the orbit
a simulation settles on), the parameter it is continued in (``+`` towards larger values, the
default, ``-`` towards smaller), and the N-th bifurcation of kind ``KIND`` met on the way
(``pd`` or ``period_doubling``, ``fold``, ``grazing``, ``stick_onset``, ``stick_end``).  ``contact:PARAM``
is the contact boundary Λ_c, where rattle starts.  The model options give the start's
parameters.  The curve is written to ``OUT`` (one row per point) and its codimension-two
points to ``OUT_codim2``; ``--png`` draws them.
"""
from __future__ import annotations

import argparse
import sys

from ..common import (CLIError, Progress, add_command, axis_label, check_output,
                      distinct_outputs, finite, info, label, meta)
from ..options import add_model_options, build_params

HELP = "follow a bifurcation in a second parameter: its curve to CSV"
#: Most periods simulated before the orbit of START simulate is taken (find_orbit's bound).
MAX_TRANSIENT = 1_000_000

STARTS = ("c", "c-unstable", "simulate", "contact")
KINDS = {"pd": "period_doubling", "period_doubling": "period_doubling", "fold": "fold",
         "grazing": "grazing", "stick_onset": "stick_onset", "sticking": "stick_onset",
         "stick_end": "stick_end"}


def add_parser(sub) -> None:
    p = add_command(sub, run, HELP)
    add_model_options(p)
    a = p.add_argument_group("atlas")
    a.add_argument("--from", dest="spec", required=True, metavar="START:PARAM[+|-]:KIND[:N]",
                   help="the bifurcation: START c, c-unstable, simulate or contact; PARAM the "
                        "parameter it is found in (+ up, - down; default up); KIND pd, fold, "
                        "grazing, stick_onset or stick_end; N the N-th met (default 1). Examples: "
                        "c:lam:pd, simulate:lam-:pd, c:lam-:fold, contact:lam")
    a.add_argument("--param2", required=True, help="the second parameter: lam, r, j, hK, phiK "
                                                   "(degrees), rpm or drag_torque")
    a.add_argument("--bounds", required=True, metavar="LO,HI",
                   help="range of the second parameter (its units)")
    a.add_argument("--bounds1", metavar="LO,HI",
                   help="range of the first parameter, for the search and the curve "
                        "(default: the model's range)")
    a.add_argument("--x0", type=float, default=None, help="start position for START simulate "
                                                          "(default: mid-backlash)")
    a.add_argument("--transient", type=int, default=2000,
                   help="periods simulated before the orbit is taken (default 2000)")
    a.add_argument("--max-points", dest="max_points", type=int, default=1000,
                   help="most curve points, in [1, 20000] (default 1000)")
    a.add_argument("--out", required=True, metavar="FILE",
                   help="curve points (.csv or .parquet); OUT_codim2 is written beside it")
    a.add_argument("--png", metavar="FILE", help="also draw the curve into this PNG")


def parse_spec(text: str) -> tuple[str, str, int, str, int]:
    """``(start, param, direction, kind, n)`` from ``START:PARAM[+|-]:KIND[:N]``."""
    parts = [s.strip() for s in str(text).split(":")]
    if len(parts) < 2 or parts[0] not in STARTS:
        raise CLIError(f"--from {text!r}: give START:PARAM[+|-]:KIND[:N] with START one of "
                       f"{', '.join(STARTS)} (e.g. c:lam:pd)")
    start, param = parts[0], parts[1]
    direction = 1
    if param.endswith(("+", "-")):
        direction = 1 if param[-1] == "+" else -1
        param = param[:-1]
    if start == "contact":
        if len(parts) > 2:
            raise CLIError(f"--from {text!r}: the contact boundary takes no KIND (contact:lam)")
        return start, param, direction, "permanent_contact", 1
    if len(parts) not in (3, 4) or parts[2] not in KINDS:
        raise CLIError(f"--from {text!r}: KIND must be one of {', '.join(KINDS)}")
    n = 1
    if len(parts) == 4:
        try:
            n = int(parts[3])
        except ValueError:
            n = 0
        if not 1 <= n <= 100:
            raise CLIError(f"--from {text!r}: N = {parts[3]!r} must be an integer in [1, 100]")
    return start, param, direction, KINDS[parts[2]], n


def _pair(text: str | None, option: str):
    if text is None:
        return None
    try:
        lo, hi = (float(v) for v in text.split(","))
    except ValueError:
        raise CLIError(f"{option} {text!r}: give two numbers LO,HI") from None
    return lo, hi


def run(args: argparse.Namespace) -> int:
    """Find a bifurcation by one-parameter continuation (--from), then follow it in a second
    parameter (--param2 within --bounds): the extended system of the orbit and the
    bifurcation's defining condition, solved exactly, with the codimension-two points where
    the curve meets another. Writes OUT (one row per point: both parameters, impulses,
    multipliers) and OUT_codim2, as .csv or .parquet; --png draws the curve."""
    from rattle_core.analysis import continuation as cont
    from rattle_core.analysis.continuation.plane import _Plane
    from rattle_core.paper.drawing import atlas_png
    from rattle_core.store.exports import TABLE_SUFFIXES, write_table
    import pandas as pd

    out = check_output(args.out, TABLE_SUFFIXES, "--out")
    c2_path = check_output(str(out.with_name(out.stem + "_codim2" + out.suffix)), TABLE_SUFFIXES,
                           "the codim2 table beside --out")
    png = check_output(args.png, (".png",), "--png") if args.png else None
    distinct_outputs(out, c2_path, png)
    start, param, direction, kind, nth = parse_spec(args.spec)
    bounds = _pair(args.bounds, "--bounds")
    bounds1 = _pair(args.bounds1, "--bounds1")
    finite(args.x0, "--x0")
    if not 0 <= args.transient <= MAX_TRANSIENT:
        raise CLIError(f"--transient {args.transient} is outside the allowed range "
                       f"[0, {MAX_TRANSIENT}]")
    if not 1 <= args.max_points <= cont.MAX_CURVE_POINTS:
        raise CLIError(f"--max-points {args.max_points} is outside the allowed range "
                       f"[1, {cont.MAX_CURVE_POINTS}]")
    params, phys = build_params(args)
    for name in (param, args.param2):
        if name in ("rpm", "drag_torque") and phys is None:
            raise CLIError(f"{name} needs physical units (--inertia, --radius, --drag-torque, "
                           "--backlash-um, --rpm, --theta-amp or --alpha-amp)")
    # unknown or conflicting parameters fail before any work
    spec1 = cont._Param.make(param, params, phys if param in ("rpm", "drag_torque") else None)
    spec2 = cont._Param.make(args.param2, params,
                             phys if args.param2 in ("rpm", "drag_torque") else None)
    _Plane(spec1, spec2, params)
    for b, opt in ((bounds, "--bounds"), (bounds1, "--bounds1")):
        if b is not None and not b[0] < b[1]:
            raise CLIError(f"{opt} {b[0]:g},{b[1]:g}: LO must be below HI")
    physical = phys if param in ("rpm", "drag_torque") else None
    try:
        if start == "contact":
            bif = cont.contact_bifurcation(params, param, physical=physical)
        else:
            bif = _find(params, start, param, direction, kind, nth, bounds1, physical, args)
        info(args, f"{label(params, phys)}: {bif.message}")
        bar = Progress("following", enabled=not getattr(args, "quiet", False), unit="point")
        try:
            curve = cont.continue_bifurcation(
                bif, args.param2, bounds=bounds, bounds1=bounds1, max_points=args.max_points,
                physical=phys if args.param2 in ("rpm", "drag_torque") else None,
                progress=lambda n, _t: bar(n, None))
        finally:
            bar.close()
    except cont.ContinuationError as exc:
        print(f"rattle: error: {' '.join(str(exc).split())}", file=sys.stderr)
        return 1
    file_meta = meta(params, phys)
    file_meta.update(kind=curve.kind, param1=curve.param1, param2=curve.param2,
                     provenance=curve.provenance)
    write_table(curve.points, out, file_meta)
    write_table(pd.DataFrame(curve.codim2_table()), c2_path, file_meta)
    info(args, f"{curve.kind} curve: {len(curve.points)} points, {curve.status}: "
               f"{curve.message}")
    for c in curve.codim2:
        info(args, f"  {c.message}")
    if png is not None:
        atlas_png(png, [curve], axis_label(curve.param1), axis_label(curve.param2),
                  f"{curve.kind.replace('_', ' ')} curve, {label(params, phys, (param, args.param2))}")
    info(args, f"wrote {out} and {c2_path}" + (f"; {png}" if png else ""))
    return 0


def _find(params, start, param, direction, kind, nth, bounds1, physical, args):
    """The ``nth`` bifurcation of ``kind`` on the branch of the start orbit."""
    from rattle_core.analysis import continuation as cont
    if start == "simulate":
        orb = cont.find_orbit(params, x0=args.x0, transient=args.transient)
    else:
        orb = cont.c_orbit(params, which="stable" if start == "c" else "unstable")
    res = cont.continue_orbit(orb, param, bounds=bounds1, direction=direction,
                              max_points=2000, physical=physical)
    found = [b for b in res.bifurcations if b.kind == kind]
    if len(found) < nth:
        raise cont.ContinuationError(
            f"the branch from the {start} orbit ({orb.summary()}) met {len(found)} {kind} "
            f"bifurcation(s) in {param} before it stopped ({res.message}); asked for number "
            f"{nth}")
    return found[nth - 1]
