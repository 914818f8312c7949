"""``rattle cache``: what the disk cache holds, and clearing it."""
from __future__ import annotations

import argparse
import time

from ..common import add_command

HELP = "show or clear the disk cache of sweeps and maps"


def add_parser(sub) -> None:
    p = add_command(sub, run, HELP)
    p.add_argument("action", choices=("show", "clear"), nargs="?", default="show",
                   help="show: location, size and entries (default); clear: delete every entry")


def _mb(n: int) -> str:
    return f"{n / 1e6:.1f} MB"


def run(args: argparse.Namespace) -> int:
    """Sweeps and maps are cached on disk ($RATTLE_CACHE_DIR, else $XDG_CACHE_HOME/rattle-explorer,
    else ~/.cache/rattle-explorer), at most RATTLE_CACHE_SIZE_MB megabytes (default
    1024); the least recently used entries go first."""
    from rattle_core.store import cache
    folder = cache.cache_dir()
    if args.action == "clear":
        n, freed = cache.clear(folder)
        print(f"cleared {folder}: {n} files, {_mb(freed)}")
        return 0
    found = cache.entries(folder)
    total = sum(e.size for e in found)
    print(f"cache {folder}")
    print(f"{len(found)} entries ({sum(e.kind == 'sweep' for e in found)} sweeps, "
          f"{sum(e.kind == 'map' for e in found)} maps), {_mb(total)} of {_mb(cache.size_limit())}")
    if not args.quiet:
        for e in reversed(found[-20:]):
            used = time.strftime("%Y-%m-%d %H:%M", time.localtime(e.last_used))
            print(f"  {e.path.name}  {_mb(e.size):>9}  last used {used}")
        if len(found) > 20:
            print(f"  … and {len(found) - 20} older")
    return 0
