"""``rattle units``: physical inputs beside the dimensionless numbers they become."""
from __future__ import annotations

import argparse

from ..common import add_command, info, label
from ..options import add_model_options, build_params

HELP = "show physical and dimensionless parameters side by side"


def add_parser(sub) -> None:
    p = add_command(sub, run, HELP)
    add_model_options(p)


def run(args: argparse.Namespace) -> int:
    """Convert physical inputs to Λ, j, h_k, φ_k and print both sets."""
    from rattle_core.analysis.vocabulary import physical_table
    params, phys = build_params(args)
    if phys is None:
        info(args, f"dimensionless: {label(params, phys)}, v_stick = {params.v_stick:g}")
        info(args, "(give physical inputs, e.g. --inertia --radius --drag-torque --backlash-um "
                   "--rpm --theta-amp, to see them side by side)")
        return 0
    rows = physical_table(phys, params.noise)
    w0 = max(len(r[0]) for r in rows)
    w1 = max(len(r[1]) for r in rows)
    print(f"{'quantity':<{w0}}  {'physical':<{w1}}  dimensionless")
    for a, b, c in rows:
        print(f"{a:<{w0}}  {b:<{w1}}  {c}")
    return 0
