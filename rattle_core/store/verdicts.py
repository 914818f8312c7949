"""Gearbox verdicts on disk: their ``.npz`` format and the cached run.

:func:`cached_verdict` serves :func:`~rattle_core.batch.gearbox.verdict` from the disk cache
(:func:`~rattle_core.store.cache.cached`, prefix ``gearbox``, signed like every entry): the
key covers the whole gearbox (every gear, the excitation's orders at every measured speed, the
sound settings), the speeds, the run settings and the solver and verdict versions, and an entry
is served only when its stored request is that whole request and its table holds every gear of
this gearbox at every speed asked.  A file holds the table's columns and a JSON ``meta``
record, written atomically with its digest (:func:`~rattle_core.store.files.atomic_savez`).
"""
from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import Any, Callable

import numpy as np

from ..batch.gearbox import (COLUMNS, ENSEMBLE_RUNS, GEARBOX, VERDICT_VERSION, Verdict,
                             check_rpm, record_periods, verdict)
from ..model.gearbox import Gearbox
from ..solver.trajectory import SOLVER_VERSION
from .cache import cached
from .files import atomic_savez

_TEXT = {"gear", "regime", "interval", "attractors", "rattle_ranges"}
_BOOL = {"pass"}
VERDICT_FIELDS = ("meta", "rpm") + tuple(f"c_{c}" for c in COLUMNS)


def verdict_request(gearbox: Gearbox, rpm: np.ndarray, settings: dict) -> dict:
    """What a verdict depends on; its canonical hash is the cache key."""
    return {"kind": "gearbox", "gearbox": gearbox.canonical(), "rpm": np.asarray(rpm),
            "settings": {k: settings[k] for k in ("transient", "record", "ensemble_runs")},
            "solver": SOLVER_VERSION, "verdict": VERDICT_VERSION}


def save_verdict(path: Path | str, result: Verdict, key: str | None = None,
                 request: Any = None) -> None:
    """Write a verdict's table atomically."""
    path = Path(path)
    meta = {"settings": result.settings, "key": key, "request": request}
    arrays = {"meta": np.array(json.dumps(meta)), "rpm": np.asarray(result.rpm, dtype=np.float64)}
    for c in COLUMNS:
        kind = str if c in _TEXT else bool if c in _BOOL else np.float64
        arrays[f"c_{c}"] = result.table[c].to_numpy().astype(kind)
    atomic_savez(path, arrays)


def load_verdict(source) -> tuple[Verdict, dict]:
    """Read a verdict written by :func:`save_verdict` (its ``gearbox`` is left None: the cache
    gives it the caller's, whose key matched)."""
    import pandas as pd
    with np.load(source, allow_pickle=False) as z:
        meta = json.loads(str(z["meta"]))
        table = pd.DataFrame({c: z[f"c_{c}"].astype(object if c in _TEXT else
                                                    bool if c in _BOOL else np.float64)
                              for c in COLUMNS})
        rpm = z["rpm"]
    return Verdict(gearbox=None, rpm=rpm, table=table, settings=meta["settings"]), meta


def cached_verdict(gearbox: Gearbox, rpm: Any, *, transient: int = 200, record: int = 100,
                   progress: Callable[[int, int], Any] | None = None,
                   cancel: Callable[[], bool] | None = None, executor: Any = None,
                   chunk_speeds: int | None = None, directory: Path | str | None = None,
                   use_cache: bool = True, ensemble_runs: int = ENSEMBLE_RUNS,
                   target: Any = None) -> Verdict:
    """:func:`~rattle_core.batch.gearbox.verdict`, served from the disk cache when the same
    gearbox ran at the same speeds before (``result.from_cache``); a cancelled one is not
    stored.  Arguments as for the verdict; ``use_cache=False`` computes and stores nothing.
    The key covers the target (``target``, or the gearbox's) and the oil temperature."""
    if target is not None:
        gearbox = gearbox.replace(target=target)
    r = check_rpm(rpm, gearbox)

    def compute() -> Verdict:
        return verdict(gearbox, r, transient=transient, record=record, progress=progress,
                       cancel=cancel, executor=executor, chunk_speeds=chunk_speeds,
                       ensemble_runs=ensemble_runs)
    if not use_cache:
        return compute()
    settings = {"transient": int(transient), "record": record_periods(gearbox, r, int(record)),
                "ensemble_runs": int(ensemble_runs)}

    def holds(res: Verdict) -> bool:
        # the stored request is checked whole by the cache; the table must also be this
        # gearbox's: every gear (and the gearbox rows) at every speed, under these settings
        names = [g.name for g in gearbox.gears] + [GEARBOX]
        t, speeds = res.table, np.sort(r)
        return (np.array_equal(res.rpm, r) and len(t) == r.size * len(names)
                and all(res.settings.get(k) == v for k, v in settings.items())
                and sorted(t["gear"].astype(str)) == sorted(names * r.size)
                and all(np.array_equal(np.sort(t.loc[t["gear"] == n, "rpm"].to_numpy(float)),
                                       speeds) for n in names))

    limit = 64_000_000
    result, hit = cached("gearbox", verdict_request(gearbox, r, settings), compute, load_verdict,
                         save_verdict, holds, directory, VERDICT_FIELDS, limit)
    if hit:
        if progress is not None:
            total = r.size * len(gearbox.gears)
            progress(total, total)
        result = dataclasses.replace(result, gearbox=gearbox, from_cache=True)
    return result


__all__ = ["cached_verdict", "save_verdict", "load_verdict", "verdict_request"]
