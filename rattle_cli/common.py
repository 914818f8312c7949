"""What every ``rattle`` command shares: errors, the progress bar, output checks, labels.

Errors are one line: a bad argument raises :class:`CLIError` (exit 2); :func:`check_output`
rejects an output path before any work starts, so a long run never ends in "cannot write".
"""
from __future__ import annotations

import argparse
import math
import os
import sys
import tempfile
from pathlib import Path
from typing import Any, Callable, NoReturn, Sequence


class CLIError(Exception):
    """A bad argument: reported as one line, exit status 2."""


class Parser(argparse.ArgumentParser):
    """An argparse parser whose errors are raised, so ``main`` prints them as one line."""

    def error(self, message: str) -> NoReturn:
        raise CLIError(f"{message} (see '{self.prog} --help')")


def info(args: argparse.Namespace, text: str) -> None:
    """Print ``text`` unless ``--quiet``."""
    if not getattr(args, "quiet", False):
        print(text)


def finite(value: float | None, option: str) -> float | None:
    """``value`` if it is None or finite; else a CLIError naming ``option``."""
    if value is not None and not math.isfinite(value):
        raise CLIError(f"{option} {value!r} must be a finite number")
    return value


class Progress:
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


def _writable_dir(folder: Path, what: str) -> None:
    if not folder.exists() or not folder.is_dir():
        raise CLIError(f"{what}: directory {str(folder)!r} does not exist")
    try:
        # a real write, since permission bits say nothing to root or on a read-only mount
        with tempfile.TemporaryFile(dir=folder):
            pass
    except OSError as exc:
        raise CLIError(f"{what}: cannot write in directory {str(folder)!r} "
                       f"({exc.strerror or exc})") from None


def check_output(path_text: str, suffixes: Sequence[str], option: str) -> Path:
    """The path of an output file, checked before any work: a known extension, not empty, not
    a directory, in a directory that exists and takes a new file, and writable if it exists."""
    if not str(path_text).strip():
        raise CLIError(f"{option} is empty; give a file name ending in {', '.join(suffixes)}")
    path = Path(path_text)
    if path.suffix.lower() not in suffixes:
        raise CLIError(f"{option} {path_text!r}: the extension must be one of {', '.join(suffixes)}")
    if path.is_dir():
        raise CLIError(f"{option} {path_text!r} is a directory; give a file name")
    if path.exists() and not os.access(path, os.W_OK):
        raise CLIError(f"{option} {path_text!r} exists and cannot be overwritten")
    _writable_dir(path.parent, f"{option} {path_text!r}")
    return path


def distinct_outputs(*paths: Path | None) -> None:
    """Refuse two outputs of one command that are the same file (one would overwrite the other)."""
    seen: dict[Path, Path] = {}
    for p in paths:
        if p is None:
            continue
        key = p.resolve()
        if key in seen:
            raise CLIError(f"{str(seen[key])!r} and {str(p)!r} are the same file; give each "
                           "output its own name")
        seen[key] = p


def check_cache_dir() -> Path:
    """The disk cache's directory, refused when it, or a folder above it, is something other
    than a directory (``RATTLE_CACHE_DIR`` naming a file): every write to it would fail."""
    from rattle_core.store.cache import cache_dir
    folder = cache_dir()
    source = "RATTLE_CACHE_DIR" if os.environ.get("RATTLE_CACHE_DIR") else "the cache directory"
    for p in (folder, *folder.parents):
        if p.exists() or p.is_symlink():
            if not p.is_dir():
                where = "" if p == folder else f" (its parent {str(p)!r})"
                raise CLIError(f"{source} {str(folder)!r}{where} is not a directory")
            break
    return folder


def check_output_dir(path_text: str, option: str) -> Path:
    """An output directory, checked before any work: not empty, not a file, and writable (it
    may be new, inside a directory that exists)."""
    if not str(path_text).strip():
        raise CLIError(f"{option} is empty; give a directory")
    out = Path(path_text)
    if out.exists() and not out.is_dir():
        raise CLIError(f"{option} {path_text!r} exists and is not a directory")
    _writable_dir(out if out.exists() else out.parent, f"{option} {path_text!r}")
    return out


def user_permissions(path: Path) -> None:
    """Give a file written through a private temporary file the user's usual permissions."""
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(path, 0o666 & ~umask)


def meta(params, phys) -> dict:
    """The parameters (and physical inputs) that files written by a command carry."""
    import dataclasses

    from rattle_core import SOLVER_VERSION
    out: dict[str, Any] = {"params": params.to_dict()}
    if phys is not None:
        out["physical"] = dataclasses.asdict(phys)
    out["solver_version"] = SOLVER_VERSION
    return out


def label(params, phys, swept: Sequence[str] = ()) -> str:
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


_AXIS = {"lam": "Λ", "r": "r", "j": "j", "v_stick": "v_stick", "rpm": "engine speed [rpm]",
         "drag_torque": "drag torque [N·m]", "inertia": "inertia [kg·m²]",
         "backlash_um": "backlash [µm]", "x0": "x0 at t = 0", "v0": "ẋ0 at t = 0"}


def axis_label(name: str) -> str:
    """How a plot labels the axis of a swept name."""
    if name in _AXIS:
        return _AXIS[name]
    if name.startswith("phi"):
        return f"φ{name[3:]} [deg]"
    if name.startswith("h"):
        return f"H{name[1:]}/H1"
    return name


def add_command(sub, run: Callable[[argparse.Namespace], int], help: str,
                *parents: argparse.ArgumentParser, name: str | None = None) -> argparse.ArgumentParser:
    """The parser of the subcommand that ``run`` carries out: named after its module (or
    ``name``), described by its docstring, with ``-q/--quiet`` and the shared option groups
    ``parents``."""
    name = name or run.__module__.rsplit(".", 1)[-1]
    p = sub.add_parser(name, parents=[quiet_parent(), *parents], help=help,
                       description=" ".join((run.__doc__ or help).split()),
                       formatter_class=argparse.HelpFormatter)
    p.set_defaults(func=run)
    return p


def quiet_parent() -> argparse.ArgumentParser:
    """The ``-q/--quiet`` option every command has."""
    quiet = Parser(add_help=False)
    quiet.add_argument("-q", "--quiet", action="store_true",
                       help="print nothing but errors; no progress bar")
    return quiet


def run_parent(transient: int) -> argparse.ArgumentParser:
    """Options of a single run; a fresh parser per subcommand, since argparse shares actions."""
    run = Parser(add_help=False)
    g = run.add_argument_group("run")
    g.add_argument("--periods", type=int, default=200, help="recorded forcing periods (default 200)")
    g.add_argument("--transient", type=int, default=transient,
                   help=f"unrecorded forcing periods run first (default {transient})")
    g.add_argument("--x0", type=float, default=None,
                   help="initial position at t = 0, in [y(0), y(0) + j] (default: mid-backlash)")
    g.add_argument("--v0", type=float, default=0.0, help="initial velocity (default 0)")
    return run
