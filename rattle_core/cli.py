"""The ``rattle`` command: serve the dashboard, simulate, sweep, synthesise sound, reproduce the paper.

Every model parameter can be given dimensionless (``--lam --r --j --h2 --phi2 --harmonics
--harmonic --v-stick``) or in physical units (``--inertia --radius --drag-torque --backlash-um
--rpm --order --theta-amp ...``, see :mod:`rattle_core.units`); the two sets cannot be mixed.
Bad arguments print one line, ``rattle: error: ...``, on stderr and exit with status 2; a run
that stops at a solver limit exits with status 1.  Never a traceback.

The subcommands that need optional layers (``serve``: the dashboard in ``app``; ``sweep``:
``rattle_core.sweep`` and ``rattle_core.cache``; ``paper``: ``rattle_core.paper``) import them
only when run, so the rest of the command works without them.
"""
from __future__ import annotations

import argparse
import importlib
import inspect
import json
import os
import sys
from pathlib import Path
from typing import Any, Callable, NoReturn, Sequence

PROG = "rattle"
TABLE_SUFFIXES = (".csv", ".parquet")
SWEEP_SUFFIXES = (".npz", ".csv", ".parquet")
#: Most rows a sampled time history may have (periods × samples per period).
MAX_HISTORY_ROWS = 5_000_000

EPILOG = """\
examples:
  rattle serve --port 5006
  rattle serve --dask local
  rattle simulate --lam 3.3 --h2 0.25 --phi2 45 --periods 100 --impacts imp.csv --history hist.parquet
  rattle sweep --param lam --start 0.5 --stop 4 --num 400 --out fig2.npz
  rattle sweep --inertia 2e-4 --radius 0.04 --drag-torque 0.02 --backlash-um 160 --rpm 1500 \\
      --theta-amp 5e-4,1.25e-4 --theta-phase 0,45 --param rpm --start 800 --stop 6000 --out rpm.csv
  rattle sound --lam 3.3 --out rattle.wav
  rattle paper --out paper/
  rattle units --inertia 2e-4 --radius 0.04 --drag-torque 0.02 --backlash-um 160 --rpm 1500 --theta-amp 5e-4

Exit status: 0 success, 1 the run stopped at a solver limit or could not write, 2 bad arguments.
"""

MODEL_HELP = """\
The default (paper eq. 8-11): Λ ẍ = −1 between the walls y and y + j,
y(t) = Σ h_k cos(k t − φ_k) with h_1 = 1.  Harmonics are set by --harmonics, then --harmonic,
then --h2/--phi2, each overriding the previous."""

PHYSICAL_HELP = """\
Any of these options selects physical units (rattle_core.units); they cannot be mixed with --lam, --j,
--h2, --phi2, --harmonics, --harmonic, --paper-phases).  m = J/Rb², F = C/Rb,
ω = order·2π·rpm/60, H_k = Rd·θ_k or Rd·α_k/(kω)², Λ = m H1 ω²/F, j = b/H1, h_k = H_k/H1.
Harmonic k of the lists is engine order k × ORDER."""


class CLIError(Exception):
    """A bad argument: reported as one line, exit status 2."""


class _Parser(argparse.ArgumentParser):
    """An argparse parser whose errors are raised, so ``main`` prints them as one line."""

    def error(self, message: str) -> NoReturn:
        raise CLIError(f"{message} (see '{self.prog} --help')")


# ----- parsing helpers ---------------------------------------------------------------------

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


def _float_list(what: str) -> Callable[[str], list[float]]:
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


def _add_model_options(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("dimensionless model", MODEL_HELP)
    g.add_argument("--lam", type=float, metavar="Λ",
                   help="Λ = m H1 ω²/F, inertia over drag, in (0, 1e4] (default 3.3)")
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
    u.add_argument("--theta-amp", dest="theta_amp", type=_float_list("--theta-amp"), metavar="RAD[,RAD...]",
                   help="driving gear angular displacement amplitude θ_k [rad] of harmonics 1..K")
    u.add_argument("--theta-phase", dest="theta_phase", type=_float_list("--theta-phase"),
                   metavar="DEG[,DEG...]", help="phases of θ_k [degrees], cos(kωt − φ_k) (default 0)")
    u.add_argument("--alpha-amp", dest="alpha_amp", type=_float_list("--alpha-amp"),
                   metavar="RAD_S2[,...]",
                   help="or: driving gear angular acceleration amplitude α_k [rad/s²] of harmonics 1..K")
    u.add_argument("--alpha-phase", dest="alpha_phase", type=_float_list("--alpha-phase"),
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
    from .params import RattleParams

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
    from . import units

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


# ----- shared pieces ---------------------------------------------------------------------

def _info(args: argparse.Namespace, text: str) -> None:
    if not getattr(args, "quiet", False):
        print(text)


class _Progress:
    """A tqdm bar driven by ``progress(done, total)`` callbacks (on stderr)."""

    def __init__(self, desc: str, enabled: bool = True, total: int | None = None,
                 unit: str = "value") -> None:
        self.desc = desc
        self.enabled = enabled
        self.unit = unit
        self.bar = None
        if total is not None:
            self(0, total)  # start the clock now, so the rate counts the first chunk

    def __call__(self, done: Any = None, total: Any = None, *rest: Any) -> None:
        if not self.enabled:
            return
        if isinstance(done, str):  # a stage name instead of a count
            self.desc = done
            if self.bar is not None:
                self.bar.set_description(done)
            return
        if self.bar is None:
            from tqdm.auto import tqdm
            self.bar = tqdm(total=total, desc=self.desc, unit=self.unit, file=sys.stderr,
                            dynamic_ncols=True)
        if total is not None and self.bar.total != total:
            self.bar.total = total
            self.bar.refresh()
        if done is not None and done != self.bar.n:
            self.bar.update(done - self.bar.n)  # update() honours tqdm's redraw interval

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
            self.bar = None


def _check_output(path_text: str, suffixes: Sequence[str], option: str) -> Path:
    path = Path(path_text)
    if path.suffix.lower() not in suffixes:
        raise CLIError(f"{option} {path_text!r}: the extension must be one of {', '.join(suffixes)}")
    if not path.parent.exists() or not path.parent.is_dir():
        raise CLIError(f"{option} {path_text!r}: directory {str(path.parent)!r} does not exist")
    return path


def _write_table(df, path: Path, meta: dict | None = None) -> None:
    if path.suffix.lower() == ".csv":
        df.to_csv(path, index=False)
        return
    import pyarrow as pa
    import pyarrow.parquet as pq

    table = pa.Table.from_pandas(df, preserve_index=False)
    if meta is not None:
        md = dict(table.schema.metadata or {})
        md[b"rattle"] = json.dumps(meta, default=str).encode()
        table = table.replace_schema_metadata(md)
    pq.write_table(table, path)


def _user_permissions(path: Path) -> None:
    """Give a file written through a private temporary file the user's usual permissions."""
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(path, 0o666 & ~umask)


def _lazy(module: str, what: str):
    """Import an optional layer, or raise a one-line CLIError saying it is not available."""
    try:
        return importlib.import_module(module)
    except ModuleNotFoundError as exc:
        if exc.name and (exc.name == module or module.startswith(exc.name + ".")):
            raise CLIError(f"{what} is not available: module {module!r} is not installed in this "
                           "version of Rattle Explorer") from None
        raise


def _meta(params, phys) -> dict:
    meta: dict[str, Any] = {"params": params.to_dict()}
    if phys is not None:
        import dataclasses
        meta["physical"] = dataclasses.asdict(phys)
    from .trajectory import SOLVER_VERSION
    meta["solver_version"] = SOLVER_VERSION
    return meta


def _label(params, phys, swept: Sequence[str] = ()) -> str:
    """One line naming the parameters, leaving out the swept ones (their base value is moot)."""
    skip = set(swept)
    if skip & {"rpm", "drag_torque", "inertia"}:
        skip.add("lam")
    if "backlash_um" in skip or ("rpm" in skip and phys is not None and phys.excitation == "acceleration"):
        skip.add("j")
    parts = [f"{sym} = {val:{fmt}}" for name, sym, val, fmt in
             (("lam", "Λ", params.lam, ".4g"), ("r", "r", params.r, "g"), ("j", "j", params.j, ".4g"))
             if name not in skip]
    for k in range(2, params.n_harmonics + 1):
        if f"h{k}" not in skip:
            parts.append(f"h{k} = {params.amplitudes[k - 1]:g}")
        if f"phi{k}" not in skip:
            parts.append(f"φ{k} = {params.phases_deg[k - 1]:g}°")
    text = ", ".join(parts)
    if phys is not None:
        held = [text_ for name, text_ in (("rpm", f"{phys.rpm:g} rpm"),
                                          ("drag_torque", f"C = {phys.drag_torque:g} N·m"),
                                          ("inertia", f"J = {phys.inertia:g} kg·m²"),
                                          ("backlash_um", f"b = {phys.backlash_um:.4g} µm"))
                if name not in skip]
        if held:
            text += f"  ({', '.join(held)})"
    return text


def _classify_label(tr) -> str:
    try:
        from .classify import classify
    except ImportError:
        return ""
    try:
        return classify(tr).label
    except Exception:  # a summary line is a courtesy; the files written are what matters
        return ""


# ----- subcommands -----------------------------------------------------------------------

def cmd_serve(args: argparse.Namespace) -> int:
    """Serve the Panel dashboard."""
    if not 1 <= args.port <= 65535:
        raise CLIError(f"--port {args.port} is outside the allowed range [1, 65535]")
    mod = _lazy("app.main", "the dashboard (rattle serve)")
    serve = getattr(mod, "serve", None)
    if serve is None:
        raise CLIError("the dashboard (rattle serve) is not available: app.main has no serve()")
    wanted: dict[str, Any] = {"port": args.port, "address": args.address, "show": args.show,
                              "quiet": args.quiet}
    if args.scheduler is not None and args.dask is not None:
        raise CLIError("give --dask local or --scheduler ADDRESS, not both")
    if args.scheduler is not None:
        if "://" not in args.scheduler or not args.scheduler.split("://", 1)[1]:
            raise CLIError(f"--scheduler {args.scheduler!r}: give a Dask scheduler address such as "
                           "tcp://HOST:PORT")
        wanted["scheduler"] = args.scheduler
    if args.dask is not None:
        wanted["dask"] = args.dask
    try:
        accepted = inspect.signature(serve).parameters
        kwargs = {k: v for k, v in wanted.items() if k in accepted}
    except (TypeError, ValueError):
        kwargs = wanted
    dropped = [f"--{k}" for k in ("scheduler", "dask") if k in wanted and k not in kwargs]
    if dropped:
        raise CLIError(f"{', '.join(dropped)}: this dashboard cannot run maps on Dask")
    try:  # serve() prints the address itself, once the port answers
        serve(**kwargs)
    except KeyboardInterrupt:  # Ctrl+C is how a server is meant to stop
        _info(args, "stopped")
    return 0


def cmd_simulate(args: argparse.Namespace) -> int:
    """Simulate once; write the impacts and a sampled time history."""
    import numpy as np
    import pandas as pd

    from .excitation import excitation
    from .trajectory import simulate

    if args.impacts is None and args.history is None:
        raise CLIError("simulate: give --impacts FILE and/or --history FILE (.csv or .parquet)")
    imp_path = _check_output(args.impacts, TABLE_SUFFIXES, "--impacts") if args.impacts else None
    hist_path = _check_output(args.history, TABLE_SUFFIXES, "--history") if args.history else None
    if not 1 <= args.samples_per_period <= 100_000:
        raise CLIError(f"--samples-per-period {args.samples_per_period} is outside the allowed "
                       "range [1, 100000]")
    rows = args.periods * args.samples_per_period
    if hist_path is not None and rows > MAX_HISTORY_ROWS:
        raise CLIError(f"--periods × --samples-per-period = {rows} history rows is outside the "
                       f"allowed range [1, {MAX_HISTORY_ROWS}]")
    params, phys = build_params(args)
    tr = simulate(params, periods=args.periods, transient=args.transient, x0=args.x0, v0=args.v0,
                  lyapunov=True)
    meta = _meta(params, phys)
    meta.update(periods=args.periods, transient=args.transient, x0=tr.settings["x0"], v0=args.v0)
    if imp_path is not None:
        df = pd.DataFrame({"t": tr.impact_t, "phase": tr.impact_phase, "impulse": tr.impact_impulse,
                           "flank": tr.impact_flank.astype(np.int8), "w": tr.impact_w})
        if phys is not None:
            df["t_s"] = phys.time(tr.impact_t)
            df["impulse_Ns"] = phys.impulse(tr.impact_impulse)
        _write_table(df, imp_path, meta)
    if hist_path is not None:
        n = rows + 1
        t = tr.t_start + (tr.t_end - tr.t_start) * np.arange(n) / rows
        x, v = tr.sample(t)
        y = excitation(t, params.h, params.phi)
        idx = np.clip(np.searchsorted(tr.seg_t, t, side="right") - 1, 0, max(len(tr.seg_t) - 1, 0))
        contact = tr.seg_kind[idx].astype(np.int8) if len(tr.seg_t) else np.zeros(n, np.int8)
        df = pd.DataFrame({"t": t, "x": x, "v": v, "y": y, "y_plus_j": y + params.j,
                           "contact": contact})
        if phys is not None:
            df["t_s"] = phys.time(t)
            df["x_um"] = phys.position(x) * 1e6
            df["v_mps"] = phys.velocity(v)
            df["y_um"] = phys.position(y) * 1e6
        _write_table(df, hist_path, meta)
    _info(args, f"{_label(params, phys)}: {tr.impact_t.size} impacts in {args.periods} periods")
    label = _classify_label(tr)
    if label:
        hint = "" if args.transient >= 100 else " (of a window that includes the start-up; --transient skips it)"
        _info(args, f"regime {label}{hint}")
    for path in (imp_path, hist_path):
        if path is not None:
            _info(args, f"wrote {path}")
    return 0


def _sweep_values(args: argparse.Namespace, suffix: str = "", default_num: int = 200):
    import numpy as np

    values, start, stop, num = (getattr(args, f"{k}{suffix}") for k in ("values", "start", "stop", "num"))
    if values is not None:
        if start is not None or stop is not None or num is not None:
            raise CLIError(f"give --values{suffix} or --start{suffix}/--stop{suffix}/--num{suffix}, "
                           "not both")
        return np.asarray(values, dtype=np.float64)
    if start is None or stop is None:
        raise CLIError(f"sweep: give --start{suffix} and --stop{suffix} (and --num{suffix}), "
                       f"or --values{suffix}")
    num = default_num if num is None else num
    if not 1 <= num <= 1_000_000:
        raise CLIError(f"--num{suffix} {num} is outside the allowed range [1, 1000000]")
    return np.linspace(start, stop, num)


def _make_executor(args: argparse.Namespace, sweep_fn: Callable) -> tuple[Any, Callable[[], None]]:
    """A Dask client for ``--dask local`` or ``--scheduler``, and how to shut it down."""
    if args.dask is None and args.scheduler is None:
        return None, lambda: None
    if args.dask is not None and args.scheduler is not None:
        raise CLIError("give --dask local or --scheduler ADDRESS, not both")
    if args.dask is not None and args.dask != "local":
        raise CLIError(f"--dask {args.dask!r}: the only value is 'local' (use --scheduler for a cluster)")
    if args.mode == "continuation":
        raise CLIError("continuation sweeps run value after value on one core; drop --dask/--scheduler "
                       "or use --mode fresh")
    params = inspect.signature(sweep_fn).parameters
    key = "executor" if "executor" in params else "client" if "client" in params else None
    if key is None:
        raise CLIError("this version's sweep() has no executor argument, so it cannot run on Dask; "
                       "drop --dask/--scheduler")
    try:
        from dask.distributed import Client, LocalCluster
    except ImportError:
        raise CLIError("--dask/--scheduler need dask.distributed, which is not installed") from None
    if args.scheduler is not None:
        try:
            client = Client(args.scheduler, timeout="10s")
        except (OSError, TimeoutError, ValueError) as exc:
            raise CLIError(f"--scheduler {args.scheduler!r}: cannot connect ({exc})") from None
        return client, client.close
    if not 1 <= args.workers <= 256:
        raise CLIError(f"--workers {args.workers} is outside the allowed range [1, 256]")
    cluster = LocalCluster(n_workers=args.workers, threads_per_worker=1, dashboard_address=None)
    client = Client(cluster)

    def close() -> None:
        client.close()
        cluster.close()
    return client, close


def cmd_sweep(args: argparse.Namespace) -> int:
    """A bifurcation diagram: impulses against one parameter, to a file plus a PNG."""
    import dataclasses

    import numpy as np

    out = _check_output(args.out, SWEEP_SUFFIXES, "--out")
    png = None
    if not args.no_png:
        png = _check_output(args.png, (".png",), "--png") if args.png else out.with_suffix(".png")
    params, phys = build_params(args)
    if args.param2 is not None:
        return _cmd_map(args, out, png, params, phys)
    for flag in ("start2", "stop2", "num2", "values2"):
        if getattr(args, flag) is not None:
            raise CLIError(f"--{flag} needs --param2")
    values = _sweep_values(args)
    name = args.param
    rpm = None
    if name == "rpm":
        if phys is None:
            raise CLIError("--param rpm needs physical units (--inertia, --radius, --drag-torque, "
                           "--backlash-um, --rpm, --theta-amp or --alpha-amp)")
        from .units import impulse_scale_from_rpm, rpm_sweep
        rpm = values
        name, values = rpm_sweep(phys, rpm)
    sweep_mod = _lazy("rattle_core.sweep", "sweeping (rattle sweep)")
    transient = 500 if args.transient is None else args.transient
    record = 200 if args.record is None else args.record
    # Reject bad requests before any progress bar or worker starts, so the error stays one line.
    values, transient, record = sweep_mod.validate_sweep_args(name, values, transient, record, args.mode)
    for v in (float(values.min()), float(values.max())):
        params.with_value(name, v)
    if args.no_cache:
        run = sweep_mod.sweep
    else:
        run = getattr(_lazy("rattle_core.cache", "the sweep cache"), "cached_sweep")
    executor, shutdown = _make_executor(args, run)
    progress = _Progress(f"sweep {args.param}", enabled=not args.quiet, total=len(values))
    kwargs: dict[str, Any] = {"transient": transient, "record": record, "mode": args.mode,
                              "x0": args.x0, "v0": args.v0, "progress": progress}
    if executor is not None:
        kwargs["executor" if "executor" in inspect.signature(run).parameters else "client"] = executor
    try:
        result = run(params, name, values, **kwargs)
    finally:
        progress.close()
        shutdown()
    table = result.table.copy()
    summary = result.summary.copy()
    settings = dict(result.settings)
    if phys is not None:
        settings["physical"] = dataclasses.asdict(phys)
    if rpm is not None:
        to_rpm = dict(zip(np.asarray(values, dtype=np.float64).tolist(), rpm.tolist()))
        table.insert(0, "rpm", table["value"].map(to_rpm).to_numpy(dtype=np.float64))
        summary.insert(0, "rpm", summary["value"].map(to_rpm).to_numpy(dtype=np.float64))
        settings["rpm"] = rpm.tolist()
        table["impulse_Ns"] = table["impulse"] * impulse_scale_from_rpm(phys, table["rpm"].to_numpy())
    elif phys is not None:
        table["impulse_Ns"] = table["impulse"] * phys.impulse_scale
    result = dataclasses.replace(result, settings=settings)
    meta = {"name": result.name, "swept": args.param, "params": result.params.to_dict(),
            "settings": settings}
    if out.suffix.lower() == ".npz":
        save = getattr(_lazy("rattle_core.cache", "saving a sweep (.npz)"), "save_result")
        save(out, result)
        _user_permissions(out)
    else:
        _write_table(table, out, meta)
        _write_table(summary, out.with_name(out.stem + "_summary" + out.suffix), meta)
    if png is not None:
        _plot_sweep(png, table, args.param, params, phys, result.name)
    n_values = len(result.values)
    _info(args, f"{_label(params, phys, (args.param, result.name))}: swept {args.param} over {n_values} values, "
                f"{len(table)} impacts recorded{' (cancelled)' if result.cancelled else ''}")
    if "regime" in summary and len(summary):
        counts = summary["regime"].value_counts().sort_index()
        _info(args, "regimes: " + ", ".join(f"{k} {v}" for k, v in counts.items()))
    _info(args, f"wrote {out}" + ("" if out.suffix.lower() == ".npz" else
                                  f" and {out.with_name(out.stem + '_summary' + out.suffix)}"))
    if png is not None:
        _info(args, f"wrote {png}")
    return 0


def _cmd_map(args: argparse.Namespace, out: Path, png: Path | None, params, phys) -> int:
    """A 2-D regime/intensity map, or basins of attraction, to a file plus PNG."""
    import numpy as np

    maps = _lazy("rattle_core.maps", "2-D maps (rattle sweep --param2)")
    if not args.no_cache:
        _lazy("rattle_core.cache", "the map cache")
    names = (args.param, args.param2)
    if args.mode != "fresh":
        raise CLIError("2-D maps start every point from the same state; drop --mode continuation")
    xv = _sweep_values(args, "", default_num=100)
    yv = _sweep_values(args, "2", default_num=100)
    transient = 300 if args.transient is None else args.transient
    record = 100 if args.record is None else args.record
    labels = ("--param", "--param2")
    # Work out (and reject) how the grid maps onto the model before starting any workers.
    plan = maps.plan_map(params, phys, names[0], xv, names[1], yv, labels)
    basin = plan[0] == "basin"
    executor, shutdown = _make_executor(args, maps.basin_map if basin else maps.regime_map)
    progress = _Progress(f"map {names[0]} × {names[1]}", enabled=not args.quiet,
                         total=xv.size * yv.size, unit="point")
    common: dict[str, Any] = {"transient": transient, "record": record, "progress": progress}
    if executor is not None:
        common["executor"] = executor
    if not basin and (args.x0 is not None or args.v0 != 0.0):
        common.update(x0=args.x0, v0=args.v0)
    try:
        result = maps.run_map(params, phys, names[0], xv, names[1], yv,
                              use_cache=not args.no_cache, labels=labels, **common)
    finally:
        progress.close()
        shutdown()
    settings = result.settings
    if out.suffix.lower() == ".npz":
        save_map = getattr(_lazy("rattle_core.cache", "saving a map (.npz)"), "save_map")
        save_map(out, result)
        _user_permissions(out)
    else:
        df = result.table()
        meta = {"kind": result.kind, "x_name": names[0], "y_name": names[1],
                "params": params.to_dict(), "settings": settings,
                "attractors": result.attractors}
        _write_table(df, out, meta)
    if png is not None:
        _plot_map(png, result, params, phys, maps.REGIME_CODES)
    reg = result.fields["regime"]
    codes = {v: k for k, v in maps.REGIME_CODES.items()}
    counts = {codes.get(int(c), "?"): int((reg == c).sum()) for c in np.unique(reg) if c >= 0}
    kind = "basins" if basin else "regime map"
    _info(args, f"{_label(params, phys, names)}: {kind} over {names[0]} × {names[1]}, "
                f"{xv.size} × {yv.size} points{' (cancelled)' if result.cancelled else ''}")
    _info(args, "regimes: " + ", ".join(f"{k} {v}" for k, v in sorted(counts.items())))
    if basin:
        _info(args, f"{len(result.attractors)} attractors: " + "; ".join(
            f"{a['regime']} period {a['period']} ({100 * a['share']:.1f}%)" for a in result.attractors[:6]))
    _info(args, f"wrote {out}")
    if png is not None:
        _info(args, f"wrote {png}")
    return 0


def _plot_map(path: Path, result, params, phys, regime_codes: dict) -> None:
    """PNG of a map: regimes (or attractors) on the left, rattle intensity on the right."""
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        from matplotlib.colors import ListedColormap, LogNorm
        from matplotlib.patches import Patch
    except ImportError:
        raise CLIError("writing the PNG needs matplotlib, which is not installed; "
                       "pass --no-png") from None
    import numpy as np

    x, y = result.x_values, result.y_values
    extent = [x[0], x[-1], y[0], y[-1]] if x.size > 1 and y.size > 1 else None
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(12, 5), dpi=110)
    try:
        if result.kind == "basin":
            att = result.fields["attractor"].astype(float)
            att[att < 0] = np.nan
            n = max(1, len(result.attractors))
            cmap = plt.get_cmap("tab20", max(n, 2))
            ax1.imshow(att, origin="lower", aspect="auto", extent=extent, cmap=cmap,
                       vmin=-0.5, vmax=max(n, 2) - 0.5, interpolation="nearest")
            handles = [Patch(color=cmap(i), label=f"{a['regime']} period {a['period']}")
                       for i, a in enumerate(result.attractors[:10])]
            ax1.set_title("attractor reached", fontsize=10)
        else:
            letters = list(regime_codes)
            from .maps import REGIME_COLOURS
            colours = [REGIME_COLOURS.get(k, "#000000") for k in letters]
            reg = result.fields["regime"].astype(float)
            reg[reg < 0] = np.nan
            ax1.imshow(reg, origin="lower", aspect="auto", extent=extent,
                       cmap=ListedColormap(colours), vmin=-0.5, vmax=len(letters) - 0.5,
                       interpolation="nearest")
            present = {int(c) for c in np.unique(result.fields["regime"]) if c >= 0}
            handles = [Patch(color=colours[c], label=letters[c]) for c in sorted(present)]
            ax1.set_title("regime", fontsize=10)
        ax1.legend(handles=handles, fontsize=7, loc="upper left", bbox_to_anchor=(1.0, 1.0),
                   frameon=False)
        inten = np.asarray(result.fields["intensity"], dtype=float)
        positive = inten[np.isfinite(inten) & (inten > 0)]
        shown = np.where(inten > 0, inten, np.nan)
        # Four decades are enough; the faint chatter tail would otherwise wash out the scale.
        norm = (LogNorm(vmin=max(positive.min(), 1e-4 * positive.max()), vmax=positive.max(), clip=True)
                if positive.size else None)
        im = ax2.imshow(shown, origin="lower", aspect="auto", extent=extent, cmap="magma",
                        norm=norm, interpolation="nearest")
        fig.colorbar(im, ax=ax2, label="rattle intensity Σ Ĩ² per period")
        ax2.set_title("rattle intensity (blank: no impacts)", fontsize=10)
        for ax in (ax1, ax2):
            ax.set_xlabel(_axis_label(result.x_name))
            ax.set_ylabel(_axis_label(result.y_name))
        fig.suptitle(_label(params, phys, (result.x_name, result.y_name)), fontsize=9)
        fig.tight_layout()
        fig.savefig(path)
    finally:
        plt.close(fig)


_AXIS = {"lam": "Λ", "r": "r", "j": "j", "v_stick": "v_stick", "rpm": "engine speed [rpm]",
         "drag_torque": "drag torque [N·m]", "inertia": "inertia [kg·m²]",
         "backlash_um": "backlash [µm]", "x0": "x0 at t = 0", "v0": "ẋ0 at t = 0"}


def _axis_label(name: str) -> str:
    if name in _AXIS:
        return _AXIS[name]
    if name.startswith("phi"):
        return f"φ{name[3:]} [deg]"
    if name.startswith("h"):
        return f"H{name[1:]}/H1"
    return name


def _plot_sweep(path: Path, table, swept: str, params, phys, name: str) -> None:
    """Bifurcation diagram PNG: Ĩ against the swept value, active flank blue, reverse red."""
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        raise CLIError("writing the PNG needs matplotlib, which is not installed; "
                       "pass --no-png") from None
    xcol = "rpm" if swept == "rpm" else "value"
    fig, ax = plt.subplots(figsize=(9, 5.5), dpi=120)
    size = float(min(6.0, max(0.5, 2e4 / max(len(table), 1))))  # dots shrink as points crowd
    try:
        for flank, colour, label in ((1, "#1f5fa8", "active flank"), (-1, "#c0392b", "reverse flank")):
            sel = table[table["flank"] == flank]
            ax.scatter(sel[xcol], sel["impulse"], s=size, c=colour, lw=0, label=label, rasterized=True)
        ax.axhline(0.0, color="0.6", lw=0.5)
        ax.set_xlabel(_axis_label(swept))
        ax.set_ylabel("dimensionless impulse Ĩ")
        title = _label(params, phys, (swept, name))
        if swept == "rpm":
            title += f"\nrpm sweep = sweep of {name}"
        ax.set_title(title, fontsize=9)
        ax.legend(loc="upper left", markerscale=12, fontsize=8, frameon=False)
        fig.tight_layout()
        fig.savefig(path)
    finally:
        plt.close(fig)


def cmd_sound(args: argparse.Namespace) -> int:
    """Synthesise the rattle sound of one run and write it as WAV."""
    from . import sound
    from .trajectory import simulate

    out = _check_output(args.out, (".wav",), "--out")
    params, phys = build_params(args)
    if phys is not None and args.excitation_hz is not None:
        raise CLIError("--excitation-hz is for dimensionless runs; in physical units the engine "
                       "speed (--rpm, --order) sets the time scale")
    modes = sound.parse_modes(args.modes) if args.modes is not None else None
    tr = simulate(params, periods=args.periods, transient=args.transient, x0=args.x0, v0=args.v0)
    signal, rate = sound.synthesize(tr, sample_rate=args.rate, excitation_hz=args.excitation_hz,
                                    physical=phys, modes=modes, tail=args.tail,
                                    polarity=args.polarity)
    sound.write_wav(out, signal, rate)
    freq = phys.frequency_hz if phys is not None else (args.excitation_hz or sound.DEFAULT_EXCITATION_HZ)
    _info(args, f"{_label(params, phys)}: {tr.impact_t.size} impacts, fundamental {freq:g} Hz, "
                f"{signal.size / rate:.3g} s at {rate} Hz")
    _info(args, f"wrote {out}")
    return 0


def cmd_paper(args: argparse.Namespace) -> int:
    """Write the paper's Figures 2 to 8 into a directory."""
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise CLIError(f"--out {args.out!r} exists and is not a directory")
    if not out.parent.exists():
        raise CLIError(f"--out {args.out!r}: directory {str(out.parent)!r} does not exist")
    mod = _lazy("rattle_core.paper", "reproducing the paper (rattle paper)")
    write = getattr(mod, "write_paper_figures", None)
    if write is None:
        raise CLIError("reproducing the paper (rattle paper) is not available: "
                       "rattle_core.paper has no write_paper_figures()")
    out.mkdir(exist_ok=True)
    progress = _Progress("paper figures", enabled=not args.quiet, unit="%")
    try:
        if "progress" in inspect.signature(write).parameters:
            written = write(out, progress=progress)
        else:
            written = write(out)
    finally:
        progress.close()
    if isinstance(written, dict):
        written = list(written.values())
    if isinstance(written, (list, tuple)):
        for path in written:
            _info(args, f"wrote {path}")
    _info(args, f"paper figures in {out}")
    return 0


def cmd_units(args: argparse.Namespace) -> int:
    """Print the physical and dimensionless parameters side by side."""
    params, phys = build_params(args)
    if phys is None:
        _info(args, f"dimensionless: {_label(params, phys)}, v_stick = {params.v_stick:g}")
        _info(args, "(give physical inputs, e.g. --inertia --radius --drag-torque --backlash-um "
                    "--rpm --theta-amp, to see them side by side)")
        return 0
    rows = phys.table()
    w0 = max(len(r[0]) for r in rows)
    w1 = max(len(r[1]) for r in rows)
    print(f"{'quantity':<{w0}}  {'physical':<{w1}}  dimensionless")
    for a, b, c in rows:
        print(f"{a:<{w0}}  {b:<{w1}}  {c}")
    return 0


# ----- the parser ------------------------------------------------------------------------

def _run_parent(transient: int) -> argparse.ArgumentParser:
    """Options of a single run; a fresh parser per subcommand, since argparse shares actions."""
    run = _Parser(add_help=False)
    g = run.add_argument_group("run")
    g.add_argument("--periods", type=int, default=200, help="recorded forcing periods (default 200)")
    g.add_argument("--transient", type=int, default=transient,
                   help=f"unrecorded forcing periods run first (default {transient})")
    g.add_argument("--x0", type=float, default=None,
                   help="initial position at t = 0, in [y(0), y(0) + j] (default: mid-backlash)")
    g.add_argument("--v0", type=float, default=0.0, help="initial velocity (default 0)")
    return run


def build_parser() -> argparse.ArgumentParser:
    """The ``rattle`` argument parser (all subcommands)."""
    parser = _Parser(prog=PROG, formatter_class=argparse.RawDescriptionHelpFormatter, epilog=EPILOG,
                     description="Rattle Explorer: exact gear-rattle (vibro-impact idle gear) "
                                 "dynamics from the command line.")
    try:
        from importlib.metadata import version
        ver = version("rattle-explorer")
    except Exception:
        ver = "unknown"
    parser.add_argument("--version", action="version", version=f"%(prog)s {ver}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    sub.required = True

    fmt = argparse.HelpFormatter
    quiet = _Parser(add_help=False)
    quiet.add_argument("-q", "--quiet", action="store_true", help="print nothing but errors; no progress bar")

    p = sub.add_parser("serve", parents=[quiet], formatter_class=fmt,
                       help="serve the Panel dashboard",
                       description="Serve the Panel dashboard (every script from the local server).")
    p.add_argument("--port", type=int, default=5006, help="TCP port (default 5006)")
    p.add_argument("--address", default="localhost",
                   help="address to listen on (default localhost; 0.0.0.0 for every interface)")
    p.add_argument("--show", action="store_true", help="open a browser tab")
    d = p.add_argument_group("2-D maps on Dask (default: the server's own cores)",
                             "Where every session's maps run; no page can change it.")
    d.add_argument("--scheduler", metavar="tcp://HOST:PORT",
                   help="run the dashboard's maps on this Dask scheduler")
    d.add_argument("--dask", choices=("local",),
                   help="'local': run them on a 2-worker Dask LocalCluster started by the server")
    p.set_defaults(func=cmd_serve)

    p = sub.add_parser("simulate", parents=[quiet, _run_parent(0)], formatter_class=fmt,
                       help="one run: impacts and time history to CSV or Parquet",
                       description="Simulate one run exactly.  --impacts gets one row per impact "
                                   "(t, phase, impulse, flank +1 active/−1 reverse, w; plus t_s and "
                                   "impulse_Ns in physical units).  --history gets the motion sampled "
                                   "uniformly (t, x, v, y, y_plus_j, contact; plus t_s, x_um, v_mps, "
                                   "y_um in physical units).  The format follows the extension "
                                   "(.csv or .parquet; Parquet files carry the parameters as metadata).")
    _add_model_options(p)
    p.add_argument("--impacts", metavar="FILE", help="write the impacts here (.csv or .parquet)")
    p.add_argument("--history", metavar="FILE", help="write the sampled time history here (.csv or .parquet)")
    p.add_argument("--samples-per-period", dest="samples_per_period", type=int, default=64,
                   help="time-history samples per forcing period (default 64)")
    p.set_defaults(func=cmd_simulate)

    p = sub.add_parser("sweep", parents=[quiet], formatter_class=fmt,
                       help="bifurcation diagram (impulses against a parameter) to a file plus PNG",
                       description="Sweep one parameter; record every impulse after a transient.  "
                                   "--out .npz is the cache's format (loadable by the dashboard); "
                                   ".csv/.parquet write one row per impact to OUT and one row per "
                                   "value (regime, period, Lyapunov exponent, intensity, ...) to "
                                   "OUT_summary.  A PNG of the diagram goes next to OUT unless "
                                   "--no-png.  Results are cached on disk ($RATTLE_CACHE_DIR).")
    _add_model_options(p)
    s = p.add_argument_group("sweep")
    s.add_argument("--param", default="lam",
                   help="swept parameter: lam, r, j, v_stick, hK (H_K/H1), phiK (degrees) or rpm "
                        "(physical units; a sweep of Λ with displacement amplitudes, of j with "
                        "acceleration amplitudes) (default lam)")
    s.add_argument("--start", type=float, help="first value")
    s.add_argument("--stop", type=float, help="last value")
    s.add_argument("--num", type=int, help="number of values, evenly spaced (default 200)")
    s.add_argument("--values", type=_float_list("--values"), metavar="V[,V...]",
                   help="explicit values instead of --start/--stop/--num")
    s.add_argument("--transient", type=int,
                   help="unrecorded periods per value (default 500; 300 for 2-D maps)")
    s.add_argument("--record", type=int,
                   help="recorded periods per value (default 200; 100 for 2-D maps)")
    s.add_argument("--mode", choices=("fresh", "continuation"), default="fresh",
                   help="fresh: every value from the same start; continuation: each value from the "
                        "previous one's final state, which reveals coexisting attractors (default fresh)")
    s.add_argument("--x0", type=float, default=None, help="start position (default: mid-backlash)")
    s.add_argument("--v0", type=float, default=0.0, help="start velocity (default 0)")
    m = p.add_argument_group(
        "2-D maps",
        "With --param2, map the regime and the rattle intensity over --param × --param2 instead "
        "of a bifurcation diagram.  Each axis is a dimensionless name (lam, r, j, v_stick, hK, phiK) "
        "or, in physical units, rpm, drag_torque [N·m], inertia [kg·m²] or backlash_um [µm]; e.g. "
        "--param rpm --param2 drag_torque.  --param x0 --param2 v0 maps the basins of attraction "
        "over the initial state at t = 0 instead.  Files: .npz (the cache's map format), or "
        ".csv/.parquet with one row per grid point; the PNG shows the regimes and the intensity.")
    m.add_argument("--param2", metavar="NAME", help="second swept parameter (the map's vertical axis)")
    m.add_argument("--start2", type=float, help="first value of --param2")
    m.add_argument("--stop2", type=float, help="last value of --param2")
    m.add_argument("--num2", type=int, help="number of --param2 values (default 100)")
    m.add_argument("--values2", type=_float_list("--values2"), metavar="V[,V...]",
                   help="explicit --param2 values")
    s.add_argument("--out", required=True, metavar="FILE", help="output file: .npz, .csv or .parquet")
    s.add_argument("--png", metavar="FILE", help="PNG of the diagram (default: OUT with .png)")
    s.add_argument("--no-png", dest="no_png", action="store_true", help="do not write a PNG")
    s.add_argument("--no-cache", dest="no_cache", action="store_true",
                   help="recompute even when the disk cache holds this sweep, and do not store it")
    d = p.add_argument_group("parallel (default: all local cores)")
    d.add_argument("--dask", metavar="local", help="'local': run on a Dask LocalCluster started here")
    d.add_argument("--workers", type=int, default=2, help="workers of --dask local (default 2)")
    d.add_argument("--scheduler", metavar="tcp://HOST:PORT", help="run on this Dask scheduler")
    p.set_defaults(func=cmd_sweep)

    p = sub.add_parser("sound", parents=[quiet, _run_parent(300)], formatter_class=fmt,
                       help="the rattle sound of one run, as WAV",
                       description="Synthesise the rattle: every impact rings the gearbox housing's "
                                   "modes in proportion to its impulse (rattle_core.sound).  In "
                                   "physical units the engine speed sets the time scale.")
    _add_model_options(p)
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
    p.set_defaults(func=cmd_sound)

    p = sub.add_parser("paper", parents=[quiet], formatter_class=fmt,
                       help="reproduce the paper's Figures 2 to 8 into a directory",
                       description="Write pictures matching the paper's Figures 2 to 8 (bifurcation "
                                   "diagrams, time histories, Poincaré maps) into a directory.")
    p.add_argument("--out", default="paper", metavar="DIR", help="output directory (default ./paper)")
    p.set_defaults(func=cmd_paper)

    p = sub.add_parser("units", parents=[quiet], formatter_class=fmt,
                       help="show physical and dimensionless parameters side by side",
                       description="Convert physical inputs to Λ, j, h_k, φ_k and print both sets.")
    _add_model_options(p)
    p.set_defaults(func=cmd_units)
    return parser


def _one_line(text: str) -> str:
    return " ".join(str(text).split())


def main(argv: Sequence[str] | None = None) -> int:
    """Run the ``rattle`` command; returns the exit status (never raises, never a traceback).

    Parameters
    ----------
    argv : sequence of str, optional
        Arguments without the program name; default ``sys.argv[1:]``.

    Returns
    -------
    int
        0 on success, 1 when a run stopped at a solver limit or a file could not be written,
        2 for bad arguments, 130 when interrupted.
    """
    from .trajectory import SolverError

    parser = build_parser()
    try:
        args = parser.parse_args(argv)
        return int(args.func(args) or 0)
    except SystemExit as exc:  # --help and --version
        return exc.code if isinstance(exc.code, int) else 0
    except (CLIError, ValueError) as exc:
        print(f"{PROG}: error: {_one_line(exc)}", file=sys.stderr)
        return 2
    except SolverError as exc:
        print(f"{PROG}: error: {_one_line(exc)}", file=sys.stderr)
        return 1
    except OSError as exc:
        print(f"{PROG}: error: {_one_line(exc)}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print(f"{PROG}: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:  # a bug: still one line, with a way to see the traceback
        if os.environ.get("RATTLE_DEBUG"):
            raise
        print(f"{PROG}: internal error: {type(exc).__name__}: {_one_line(exc)} "
              "(set RATTLE_DEBUG=1 to see the traceback)", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
