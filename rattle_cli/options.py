"""The model's options, shared by every command that runs the model, and the parameters they build.

Every model parameter can be given dimensionless (``--lam --r --j --h2 --phi2 --harmonics
--harmonic --v-stick``) or in physical units (``--inertia --radius --drag-torque --backlash-um
--rpm --order --theta-amp ...``, see :mod:`rattle_core.model.units`); the two sets cannot be
mixed.  :func:`build_params` turns them into the one :class:`~rattle_core.RattleParams` (and the
:class:`~rattle_core.model.units.PhysicalParams` it came from, if any).
"""
from __future__ import annotations

import argparse
from typing import Callable, Sequence

from .common import CLIError

MODEL_HELP = """\
The default (paper eq. 8-11): Λ ẍ = −1 between the walls y and y + j,
y(t) = Σ h_k cos(k t − φ_k) with h_1 = 1.  Harmonics are set by --harmonics, then --harmonic,
then --h2/--phi2, each overriding the previous."""

PHYSICAL_HELP = """\
Any of these options selects physical units (rattle_core.model.units); they cannot be mixed with --lam, --j,
--h2, --phi2, --harmonics, --harmonic, --paper-phases).  m = J/Rb², F = C/Rb,
ω = order·2π·rpm/60, H_k = Rd·θ_k or Rd·α_k/(kω)², Λ = m H1 ω²/F, j = b/H1, h_k = H_k/H1.
Harmonic k of the lists is engine order k × ORDER."""


def _floats(text: str, what: str) -> list[float]:
    out = []
    for item in str(text).split(","):
        item = item.strip()
        if not item:
            raise CLIError(f"{what}: empty entry in {text!r}; give comma-separated numbers")
        try:
            out.append(float(item))
        except ValueError:
            raise CLIError(f"{what}: {item!r} is not a number (in {text!r})") from None
    return out


def float_list(what: str) -> Callable[[str], list[float]]:
    def parse(text: str) -> list[float]:
        try:
            return _floats(text, what)
        except CLIError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from None
    parse.__name__ = "comma-separated numbers"
    return parse


def _harmonic_triple(text: str) -> tuple[int, float, float]:
    parts = str(text).split(",")
    if len(parts) not in (2, 3):
        raise argparse.ArgumentTypeError(f"{text!r} must read K,H or K,H,PHI (e.g. 2,0.25,45)")
    try:
        k = int(parts[0])
        h = float(parts[1])
        phi = float(parts[2]) if len(parts) == 3 else 0.0
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} must read K,H or K,H,PHI with K an integer "
                                         "order ≥ 2 and H, PHI numbers") from None
    if k < 2:
        raise argparse.ArgumentTypeError(f"harmonic order K = {k} is outside the allowed range "
                                         "[2, 32] (h_1 = 1 is fixed)")
    return k, h, phi


def _parse_harmonics(text: str) -> tuple[list[float], list[float]]:
    amp_text, sep, phase_text = str(text).partition(":")
    amps = _floats(amp_text, "--harmonics amplitudes")
    phases = _floats(phase_text, "--harmonics phases") if sep else [0.0] * len(amps)
    if len(phases) != len(amps):
        raise CLIError(f"--harmonics {text!r} gives {len(amps)} amplitudes but {len(phases)} phases; "
                       "write AMPS:PHASES with equal counts, e.g. 1,0.25:0,45")
    return amps, phases


# ----- parameter options -----------------------------------------------------------------

_DIMENSIONLESS_DESTS = ("lam", "j", "h2", "phi2", "harmonics", "harmonic", "paper_phases")
_PHYSICAL_DESTS = ("inertia", "radius", "driver_radius", "drag_torque", "backlash_um",
                   "backlash_rad", "backlash_deg", "rpm", "order", "theta_amp", "theta_phase",
                   "alpha_amp", "alpha_phase")


def add_model_options(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("dimensionless model", MODEL_HELP)
    g.add_argument("--lam", type=float, metavar="Λ",
                   help="Λ = m H1 ω²/F, inertia over drag, in (1e-6, 1e4] (default 3.3)")
    g.add_argument("--r", type=float, metavar="R",
                   help="coefficient of restitution, in [0, 1] (default 0.65; also in physical units)")
    g.add_argument("--j", type=float, metavar="J", help="backlash / H1, in (0, 1e4] (default 8)")
    g.add_argument("--h2", type=float, metavar="H", help="second-harmonic ratio H2/H1, in [0, 100]")
    g.add_argument("--phi2", type=float, metavar="DEG", help="second-harmonic phase φ2 in degrees")
    g.add_argument("--harmonics", metavar="AMPS[:PHASES]",
                   help="all harmonics: amplitudes h_1..h_K (h_1 = 1) and phases φ_1..φ_K in degrees, "
                        "e.g. '1,0.25:0,45' (default '1:0', harmonic excitation)")
    g.add_argument("--harmonic", type=_harmonic_triple, action="append", metavar="K,H[,PHI]",
                   help="set harmonic K ≥ 2 to amplitude H and phase PHI degrees; repeatable")
    g.add_argument("--v-stick", dest="v_stick", type=float, metavar="V",
                   help="dimensionless limit impact velocity ending chatter, in [0, 10] "
                        "(default 1e-6; also in physical units)")
    g.add_argument("--paper-phases", dest="paper_phases", action="store_true",
                   help="read the phases in the paper's convention y = Σ h_k sin(k t + φ_k) "
                        "(converted to the core's cos(k t − φ_k)), e.g. the paper's φ2 = 45°")
    g.add_argument("--noise", type=float, metavar="EPS",
                   help="relative scatter of the restitution coefficient at every rebound, "
                        "r·(1 ± EPS) drawn uniformly, in [0, 0.5] (default 1e-12; docs/model.md, "
                        "'Noise'); 0 is the strict deterministic model")
    g.add_argument("--strict", action="store_true",
                   help="the strict deterministic model, the same as --noise 0: a chaotic run "
                        "through sticking then repeats a loop chosen by rounding, and its "
                        "summary says so")

    u = p.add_argument_group("physical units", PHYSICAL_HELP)
    u.add_argument("--inertia", type=float, metavar="KG_M2", help="idle gear inertia J [kg·m²], in (0, 10]")
    u.add_argument("--radius", type=float, metavar="M", help="idle gear base radius Rb [m], in (0, 2]")
    u.add_argument("--driver-radius", dest="driver_radius", type=float, metavar="M",
                   help="driving gear base radius Rd [m] (default: --radius)")
    u.add_argument("--drag-torque", dest="drag_torque", type=float, metavar="NM",
                   help="drag torque C on the idle gear [N·m], in (0, 1e4]")
    b = u.add_mutually_exclusive_group()
    b.add_argument("--backlash-um", dest="backlash_um", type=float, metavar="UM",
                   help="backlash along the line of action [µm]")
    b.add_argument("--backlash-rad", dest="backlash_rad", type=float, metavar="RAD",
                   help="backlash as an angle of the idle gear [rad] (b = Rb·angle)")
    b.add_argument("--backlash-deg", dest="backlash_deg", type=float, metavar="DEG",
                   help="backlash as an angle of the idle gear [degrees]")
    u.add_argument("--rpm", type=float, metavar="RPM", help="engine speed [rev/min], in (0, 1e5]")
    u.add_argument("--order", type=float, metavar="N",
                   help="engine order of the fundamental, excitation cycles per revolution "
                        "(default 2: four-cylinder four-stroke)")
    u.add_argument("--theta-amp", dest="theta_amp", type=float_list("--theta-amp"), metavar="RAD[,RAD...]",
                   help="driving gear angular displacement amplitude θ_k [rad] of harmonics 1..K")
    u.add_argument("--theta-phase", dest="theta_phase", type=float_list("--theta-phase"),
                   metavar="DEG[,DEG...]", help="phases of θ_k [degrees], cos(kωt − φ_k) (default 0)")
    u.add_argument("--alpha-amp", dest="alpha_amp", type=float_list("--alpha-amp"),
                   metavar="RAD_S2[,...]",
                   help="or: driving gear angular acceleration amplitude α_k [rad/s²] of harmonics 1..K")
    u.add_argument("--alpha-phase", dest="alpha_phase", type=float_list("--alpha-phase"),
                   metavar="DEG[,DEG...]", help="phases of α_k [degrees] (default 0)")


def _given(args: argparse.Namespace, dests: Sequence[str]) -> list[str]:
    return [d for d in dests if getattr(args, d, None) not in (None, False)]


def _flag(dest: str) -> str:
    return "--" + dest.replace("_", "-")


def build_params(args: argparse.Namespace):
    """The model parameters from parsed options: ``(RattleParams, PhysicalParams or None)``.

    Raises ``CLIError`` when the two systems are mixed or a physical input is missing, and
    ``ValueError`` (from the parameter classes) for values out of range.
    """
    params, phys = _build(args)
    noise = getattr(args, "noise", None)
    if getattr(args, "strict", False):
        if noise not in (None, 0.0):
            raise CLIError(f"--strict is the model without noise; it cannot be combined with "
                           f"--noise {noise:g}")
        noise = 0.0
    if noise is not None:
        params = params.replace(noise=noise)
    return params, phys


def _build(args: argparse.Namespace):
    from rattle_core import RattleParams
    r = 0.65 if args.r is None else args.r
    v_stick = 1e-6 if args.v_stick is None else args.v_stick
    physical = _given(args, _PHYSICAL_DESTS)
    if physical:
        mixed = _given(args, _DIMENSIONLESS_DESTS)
        if mixed:
            raise CLIError(f"{', '.join(_flag(d) for d in mixed)} cannot be combined with physical units "
                           f"({', '.join(_flag(d) for d in physical)}); use one system")
        phys = _build_physical(args, r, v_stick)
        return phys.to_dimensionless(), phys
    amps, phases = [1.0], [0.0]
    if args.harmonics is not None:
        amps, phases = _parse_harmonics(args.harmonics)
    overrides = list(args.harmonic or [])
    if args.h2 is not None or args.phi2 is not None:
        overrides.append((2, None, None))
    for k, h, phi in overrides:
        if k > 32:
            raise CLIError(f"harmonic order K = {k} is outside the allowed range [2, 32]")
        while len(amps) < k:
            amps.append(0.0)
            phases.append(0.0)
        if h is not None:
            amps[k - 1], phases[k - 1] = h, phi
    if args.h2 is not None:
        amps[1] = args.h2
    if args.phi2 is not None:
        phases[1] = args.phi2
    lam = 3.3 if args.lam is None else args.lam
    j = 8.0 if args.j is None else args.j
    if args.paper_phases:
        return RattleParams.paper(lam=lam, r=r, j=j, amplitudes=amps, phases_deg=phases,
                                  v_stick=v_stick), None
    return RattleParams(lam=lam, r=r, j=j, amplitudes=tuple(amps), phases_deg=tuple(phases),
                        v_stick=v_stick), None


def _build_physical(args: argparse.Namespace, r: float, v_stick: float):
    from rattle_core import units
    if args.theta_amp is not None and args.alpha_amp is not None:
        raise CLIError("give --theta-amp (displacement) or --alpha-amp (acceleration), not both")
    if args.theta_phase is not None and args.alpha_amp is not None:
        raise CLIError("--theta-phase goes with --theta-amp; use --alpha-phase with --alpha-amp")
    if args.alpha_phase is not None and args.theta_amp is not None:
        raise CLIError("--alpha-phase goes with --alpha-amp; use --theta-phase with --theta-amp")
    missing = [flag for flag, val in (("--inertia", args.inertia), ("--radius", args.radius),
                                      ("--drag-torque", args.drag_torque), ("--rpm", args.rpm))
               if val is None]
    if args.backlash_um is None and args.backlash_rad is None and args.backlash_deg is None:
        missing.append("--backlash-um (or --backlash-rad/--backlash-deg)")
    if args.theta_amp is None and args.alpha_amp is None:
        missing.append("--theta-amp (or --alpha-amp)")
    if missing:
        raise CLIError(f"physical units need {', '.join(missing)} as well")
    if args.backlash_um is not None:
        backlash = units.backlash_from_um(args.backlash_um)
    elif args.backlash_rad is not None:
        backlash = units.backlash_from_angle(args.backlash_rad, args.radius, "rad")
    else:
        backlash = units.backlash_from_angle(args.backlash_deg, args.radius, "deg")
    if args.theta_amp is not None:
        kind, amps, phases = "displacement", args.theta_amp, args.theta_phase
    else:
        kind, amps, phases = "acceleration", args.alpha_amp, args.alpha_phase
    return units.PhysicalParams(
        inertia=args.inertia, radius=args.radius, drag_torque=args.drag_torque, backlash=backlash,
        rpm=args.rpm, amplitudes=tuple(amps), phases_deg=None if phases is None else tuple(phases),
        order=2.0 if args.order is None else args.order, excitation=kind, r=r, v_stick=v_stick,
        driver_radius=args.driver_radius)
