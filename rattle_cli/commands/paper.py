"""``rattle paper``: the paper's Figures 2 to 8 and the phase-convention evidence, into a directory."""
from __future__ import annotations

import argparse

from ..common import Progress, add_command, check_output_dir, info

HELP = "reproduce the paper's Figures 2 to 8 into a directory"


def add_parser(sub) -> None:
    p = add_command(sub, run, HELP)
    p.add_argument("--out", default="paper", metavar="DIR", help="output directory (default ./paper)")


def run(args: argparse.Namespace) -> int:
    """Write pictures matching the paper's Figures 2 to 8 (bifurcation diagrams, time histories,
    Poincaré maps) and phase_convention.md into a directory.  The diagrams come from the
    shipped assets while they match the solver."""
    from rattle_core.paper import figures
    out = check_output_dir(args.out, "--out")
    out.mkdir(exist_ok=True)
    progress = Progress("paper figures", enabled=not args.quiet, unit="%")
    try:
        written = figures.write_paper_figures(out, progress=progress)
    finally:
        progress.close()
    for path in written:
        info(args, f"wrote {path}")
    info(args, f"paper figures in {out}")
    return 0
