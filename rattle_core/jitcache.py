"""Keep numba's on-disk cache consistent across edits of the compiled modules.

Numba checks only the source file of the function it loads from its cache, so a kernel that
calls into another module (the sweep kernel inlines ``solver.kernel._integrate``) can be served
stale machine code after that other module changes.  At import, if any compiled module is
newer than the stamp left by the last check, every cached kernel of this package is dropped
and recompiled on first use.
"""
from __future__ import annotations

from pathlib import Path

_COMPILED = ("model/excitation.py", "solver/events.py", "solver/noise.py", "solver/kernel.py",
             "analysis/classify.py", "analysis/continuation/shooting.py",
             "analysis/continuation/stability.py", "analysis/continuation/admissibility.py",
             "batch/chunks.py")


def refresh() -> None:
    here = Path(__file__).resolve().parent
    stamp = here / "__pycache__" / "numba-sources.stamp"
    try:
        newest = max((here / name).stat().st_mtime for name in _COMPILED)
        if stamp.exists() and stamp.stat().st_mtime >= newest:
            return
        for cache in {(here / name).parent / "__pycache__" for name in _COMPILED}:
            for f in list(cache.glob("*.nbi")) + list(cache.glob("*.nbc")):
                f.unlink(missing_ok=True)
        stamp.parent.mkdir(exist_ok=True)
        stamp.touch()
    except OSError:
        pass  # a read-only install keeps whatever cache it has; numba then compiles in memory
