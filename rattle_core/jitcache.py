"""Keep numba's on-disk cache consistent across edits of the compiled modules.

Numba checks only the source file of the function it loads from its cache, so a kernel that
calls into another module (the sweep kernel inlines ``solver._integrate``) can be served
stale machine code after that other module changes.  At import, if any compiled module is
newer than the stamp left by the last check, every cached kernel of this package is dropped
and recompiled on first use.
"""
from __future__ import annotations

from pathlib import Path

_COMPILED = ("excitation.py", "events.py", "solver.py", "sweep.py")


def refresh() -> None:
    here = Path(__file__).resolve().parent
    cache = here / "__pycache__"
    stamp = cache / "numba-sources.stamp"
    try:
        newest = max((here / name).stat().st_mtime for name in _COMPILED)
        if stamp.exists() and stamp.stat().st_mtime >= newest:
            return
        cache.mkdir(exist_ok=True)
        for f in list(cache.glob("*.nbi")) + list(cache.glob("*.nbc")):
            f.unlink(missing_ok=True)
        stamp.touch()
    except OSError:
        pass  # a read-only install keeps whatever cache it has; numba then compiles in memory
