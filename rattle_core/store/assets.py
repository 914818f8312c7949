"""The precomputed diagrams shipped with the package: the paper's bifurcation sweeps.

They are package data (``rattle_core/assets/paper/*.npz``), so an installed wheel has them, and
each carries the content key of the request it answers (:func:`~rattle_core.store.cache.sweep_key`),
so a changed solver never serves a stale one.  Files are read once per process.
"""
from __future__ import annotations

import functools
from pathlib import Path

from ..batch.sweep import SCHEMA_VERSION, SweepResult
from ..model.params import RattleParams
from ..solver.trajectory import SOLVER_VERSION
from .files import load_result

#: Where the shipped diagrams live (inside the package).
ASSETS_DIR = Path(__file__).resolve().parents[1] / "assets" / "paper"


@functools.lru_cache(maxsize=64)
def _read(path: str, stamp: int) -> tuple[SweepResult, dict] | None:
    try:
        return load_result(path)
    except Exception:  # a damaged asset is treated as absent; callers then compute
        return None


def read_asset(name: str) -> tuple[SweepResult, dict] | None:
    """A shipped diagram and its meta record by name (``fig2`` …), or None if absent or unreadable."""
    path = ASSETS_DIR / f"{name}.npz"
    try:
        stamp = path.stat().st_mtime_ns
    except OSError:
        return None
    return _read(str(path), stamp)


def list_assets() -> list[str]:
    """Names of the shipped diagrams (e.g. ``fig2``)."""
    return sorted(p.stem for p in ASSETS_DIR.glob("*.npz"))


def load_asset(name: str) -> SweepResult | None:
    """A shipped diagram by name (``fig2``, ``fig4``, ``fig5``, ``fig6``), or None if absent."""
    found = read_asset(name)
    return None if found is None else found[0]


def find_asset(base: RattleParams, name: str) -> tuple[str, SweepResult] | None:
    """``(asset name, diagram)`` of a shipped diagram that sweeps ``name`` with every other
    parameter equal to ``base``'s, written by this solver and schema version; or None."""
    for asset in list_assets():
        found = read_asset(asset)
        if found is None:
            continue
        res, meta = found
        if (res.name != name or meta.get("solver") != SOLVER_VERSION
                or meta.get("schema") != SCHEMA_VERSION):
            continue
        try:
            same = res.params.with_value(name, base.get(name)).canonical() == base.canonical()
        except ValueError:  # base's value lies outside the swept parameter's range
            same = False
        if same:
            return asset, res
    return None
