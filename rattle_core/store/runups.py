"""Gearbox run-ups on disk: their ``.npz`` format and the cached run.

:func:`cached_runup` serves :func:`~rattle_core.batch.runup.gearbox_runup` (with its sound) from
the disk cache (:func:`~rattle_core.store.cache.cached`, prefix ``runup``, signed like every
entry).  The key is the gearbox's canonical form (its target left out: a target judges a run,
it does not change it), the speeds at the start and end, the duration, the wall (the order
reconstruction, or the measured angle with its cutoff and a hash of its filtered samples), and
the solver and run-up versions.  A file holds every gear's impacts, the gearbox's sound pressure [Pa], ``N(t)``,
``L_AF(t)`` and each gear's ``N(t)``; read back, each gear's replay is a :class:`StoredReplay`,
which has the impacts a :class:`~rattle_core.solver.runup.RunupReplay` has but not its wall.
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from ..batch.runup import GearboxRunup, gearbox_runup
from ..model.gearbox import Gearbox
from ..solver.angle_wall import FilteredAngle
from ..solver.runup import ImpactRows, check_run, measured_window
from ..solver.trajectory import SOLVER_VERSION
from .cache import cached
from .files import atomic_savez

#: Bumped whenever what a stored run-up holds, or how it is computed, changes.
RUNUP_VERSION = 1
RUNUP_FIELDS = ("meta", "pressure_pa", "time_s", "rpm_t", "loudness_t", "level_dba_t")
_IMPACT = ("t", "rpm", "flank", "impulse")


@dataclasses.dataclass(frozen=True, eq=False)
class StoredReplay(ImpactRows):
    """One gear's impacts over a stored run (as :class:`~rattle_core.solver.runup.RunupReplay`)."""

    gear: str
    impact_t: np.ndarray
    impact_rpm: np.ndarray
    impact_flank: np.ndarray
    impact_impulse: np.ndarray


@dataclasses.dataclass(frozen=True)
class _Entry:
    """What the cache wrapper stores and returns: the run, never a cancelled one."""

    run: GearboxRunup
    cancelled: bool = False


def runup_request(gearbox: Gearbox, rpm_from: float, rpm_to: float, duration_s: float | None,
                  angle: FilteredAngle | None = None) -> dict:
    """What a run-up depends on; its canonical hash is the cache key.  A run driven by the
    measured angle adds the cutoff and a SHA-256 of the filtered samples it is driven by."""
    box = gearbox.canonical()
    box.pop("target", None)
    wall: dict = {"wall": "orders", "cutoff_hz": None}
    if angle is not None:
        digest = hashlib.sha256()
        for a in (angle.time_s, angle.fluctuation_rad, angle.mean_speed.c):
            digest.update(np.ascontiguousarray(a, dtype=np.float64).tobytes())
        wall = {"wall": "angle", "cutoff_hz": float(angle.cutoff_hz),
                "mean_hz": float(angle.mean_hz), "samples": digest.hexdigest()}
    return {"kind": "runup", "gearbox": box, "rpm_from": float(rpm_from), "rpm_to": float(rpm_to),
            "duration_s": None if duration_s is None else float(duration_s), **wall,
            "solver": SOLVER_VERSION, "runup": RUNUP_VERSION}


def save_runup(path: Path | str, entry: _Entry, key: str | None = None,
               request: Any = None) -> None:
    """Write a run-up (with its sound) atomically."""
    run = entry.run
    names = list(run.replays)
    meta = {"key": key, "request": request, "gears": names, "rpm_from": run.rpm_from,
            "rpm_to": run.rpm_to, "duration_s": run.duration_s, "wall": run.wall,
            "cutoff_hz": run.cutoff_hz}
    arrays = {"meta": np.array(json.dumps(meta)), "pressure_pa": run.pressure_pa,
              "time_s": run.time_s, "rpm_t": run.rpm_t, "loudness_t": run.loudness_t,
              "level_dba_t": run.level_dba_t}
    for i, name in enumerate(names):
        r = run.replays[name]
        arrays[f"g{i}_t"] = np.asarray(r.impact_t, dtype=np.float64)
        arrays[f"g{i}_rpm"] = np.asarray(r.impact_rpm, dtype=np.float64)
        arrays[f"g{i}_flank"] = np.asarray(r.impact_flank, dtype=np.int8)
        arrays[f"g{i}_impulse"] = np.asarray(r.impact_impulse, dtype=np.float64)
        arrays[f"g{i}_loudness"] = np.asarray(run.gear_loudness_t[name], dtype=np.float64)
    atomic_savez(path, arrays)


def load_runup(source) -> tuple[_Entry, dict]:
    """Read a run-up written by :func:`save_runup` (its ``gearbox`` is left None: the cache
    gives it the caller's, whose key matched)."""
    with np.load(source, allow_pickle=False) as z:
        meta = json.loads(str(z["meta"]))
        replays, gear_n = {}, {}
        for i, name in enumerate(meta["gears"]):
            replays[name] = StoredReplay(name, *(z[f"g{i}_{k}"] for k in _IMPACT))
            gear_n[name] = z[f"g{i}_loudness"]
        run = GearboxRunup(None, meta["rpm_from"], meta["rpm_to"], meta["duration_s"], replays,
                           pressure_pa=z["pressure_pa"], time_s=z["time_s"], rpm_t=z["rpm_t"],
                           loudness_t=z["loudness_t"], level_dba_t=z["level_dba_t"],
                           gear_loudness_t=gear_n, wall=meta.get("wall", "orders"),
                           cutoff_hz=meta.get("cutoff_hz"))
    return _Entry(run), meta


def cached_runup(gearbox: Gearbox, rpm_from: float, rpm_to: float, duration_s: float | None,
                 *, threads: int | None = None, directory: Path | str | None = None,
                 use_cache: bool = True, angle: FilteredAngle | None = None
                 ) -> tuple[GearboxRunup, bool]:
    """:func:`~rattle_core.batch.runup.gearbox_runup` with its sound, served from the disk
    cache when the same gearbox ran over the same speeds and duration (or, with ``angle``, the
    same filtered measurement) before; returns ``(run, from_cache)``.  Bad input is refused
    (``ValueError``) before the cache is read."""
    if not isinstance(gearbox, Gearbox):
        raise TypeError(f"gearbox must be a Gearbox, got {type(gearbox).__name__}")
    if angle is None:
        check_run(gearbox, rpm_from, rpm_to, duration_s)
        length_s = float(duration_s)
    else:
        if duration_s is not None:
            raise ValueError(f"duration_s = {duration_s!r}: a run driven by the measured angle "
                             "lasts as long as the measurement takes; give duration_s=None")
        a, b = measured_window(angle, rpm_from, rpm_to)
        length_s = b - a

    def compute() -> _Entry:
        return _Entry(gearbox_runup(gearbox, rpm_from, rpm_to, duration_s, sound=True,
                                    threads=threads, angle=angle))
    if not use_cache:
        return compute().run, False
    names = [g.name for g in gearbox.gears]

    def holds(entry: _Entry) -> bool:
        run = entry.run
        return (list(run.replays) == names and run.time_s.size == run.loudness_t.size
                == run.level_dba_t.size == run.rpm_t.size
                and run.pressure_pa.size == int(round(run.duration_s * run.sample_rate))
                and all(run.gear_loudness_t[n].size == run.time_s.size for n in names))

    # the sound at 48 kHz is 8 bytes a sample: an hour's run is under 1.5 GB
    limit = 64_000_000 + int(16 * 48_000 * length_s)
    entry, hit = cached("runup", runup_request(gearbox, rpm_from, rpm_to, duration_s, angle),
                        compute,
                        load_runup, save_runup, holds, directory, RUNUP_FIELDS, limit)
    run = entry.run
    if hit:
        run = dataclasses.replace(run, gearbox=gearbox)
        if angle is not None:
            run = dataclasses.replace(run, mean_rpm=lambda t: angle.mean_rpm(a + np.asarray(t)))
    return run, hit


__all__ = ["cached_runup", "save_runup", "load_runup", "runup_request", "StoredReplay",
           "RUNUP_VERSION"]
