"""The ``.npz`` files sweeps and maps are kept in: the disk cache, the shipped diagrams, ``--out``.

A file holds the result's arrays and a JSON ``meta`` record (parameters, settings, schema and
solver versions, and for cache entries the content key and the request it answers).  Files are
written to a temporary file beside the target and moved into place with ``os.replace``, so a
reader never sees half a file, and read with ``allow_pickle=False``.
"""
from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

from ..batch.maps import MapResult
from ..batch.sweep import SCHEMA_VERSION, SweepResult
from ..model.params import RattleParams
from ..solver.trajectory import SOLVER_VERSION

_SUMMARY_TYPES = {"value": np.float64, "regime": "U8", "period": np.int32, "n_active": np.int32,
                  "n_reverse": np.int32, "active_per_period": np.float64,
                  "reverse_per_period": np.float64, "chaotic": np.bool_, "lyapunov": np.float64,
                  "stick_fraction": np.float64, "intensity": np.float64,
                  "sticking": "U22", "loop_amplification": np.float64, "status": np.int8}


def atomic_savez(path: Path, arrays: dict) -> None:
    """Write a compressed npz to a temporary file beside ``path``, then move it into place."""
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=".tmp-", suffix=".npz")
    try:
        with os.fdopen(fd, "wb") as f:
            np.savez_compressed(f, **arrays)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def _meta(result: Any, key: str | None, request: Any) -> dict:
    meta = {"params": result.params.to_dict(), "settings": result.settings, "key": key,
            "schema": SCHEMA_VERSION, "solver": SOLVER_VERSION}
    if request is not None:
        meta["request"] = request
    return meta


def save_result(path: Path | str, result: SweepResult, compact: bool = False,
                key: str | None = None, request: Any = None) -> None:
    """Write a sweep atomically.  ``compact`` stores impulses and phases as float32."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fdt = np.float32 if compact else np.float64
    meta = {"name": result.name, **_meta(result, key, request)}
    arrays: dict[str, Any] = {
        "meta": np.array(json.dumps(meta)),
        "values": np.asarray(result.values, dtype=np.float64),
        # the swept value stays float64 even in compact form: it identifies the row's value
        # (``table.value == summary.value``); runs of equal values cost almost nothing compressed
        "t_value": result.table["value"].to_numpy(dtype=np.float64),
        "t_impulse": result.table["impulse"].to_numpy(dtype=fdt),
        "t_flank": result.table["flank"].to_numpy(dtype=np.int8),
        "t_phase": result.table["phase"].to_numpy(dtype=fdt),
    }
    for col, dt in _SUMMARY_TYPES.items():
        arrays[f"s_{col}"] = result.summary[col].to_numpy().astype(dt)
    atomic_savez(path, arrays)


#: Summary columns added after schema 1, and the value a file without them stands for.
_ADDED_COLUMNS = {"sticking": "", "loop_amplification": -np.inf}


def _missing(col: str, z) -> np.ndarray:
    """A column an older file lacks, filled with what its absence meant (or a KeyError)."""
    if col not in _ADDED_COLUMNS:
        raise KeyError(f"s_{col}")
    return np.full(len(z["values"]), _ADDED_COLUMNS[col], dtype=_SUMMARY_TYPES[col])


def load_result(path: Path | str) -> tuple[SweepResult, dict]:
    """Read a sweep written by :func:`save_result`; returns ``(result, meta)``.  A file written
    before the ``sticking`` columns existed reads with them empty; its ``meta`` still says which
    schema and solver wrote it, so the cache and the assets never serve it as current."""
    import pandas as pd
    with np.load(path, allow_pickle=False) as z:
        meta = json.loads(str(z["meta"]))
        table = pd.DataFrame({"value": z["t_value"].astype(np.float64),
                              "impulse": z["t_impulse"].astype(np.float64),
                              "flank": z["t_flank"], "phase": z["t_phase"].astype(np.float64)})
        summary = pd.DataFrame({col: z[f"s_{col}"] if f"s_{col}" in z.files else _missing(col, z)
                                for col in _SUMMARY_TYPES})
        values = z["values"]
    params = RattleParams.from_dict(meta["params"])
    return SweepResult(name=meta["name"], values=values, params=params, settings=meta["settings"],
                       table=table, summary=summary), meta


def save_map(path: Path | str, result: MapResult, key: str | None = None,
             request: Any = None) -> None:
    """Write a :class:`~rattle_core.batch.maps.MapResult` atomically."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    meta = {"kind": result.kind, "x_name": result.x_name, "y_name": result.y_name,
            "attractors": result.attractors, **_meta(result, key, request)}
    arrays = {"meta": np.array(json.dumps(meta)), "x_values": result.x_values,
              "y_values": result.y_values}
    arrays.update({f"f_{k}": v for k, v in result.fields.items()})
    atomic_savez(path, arrays)


def load_map(path: Path | str) -> tuple[MapResult, dict]:
    """Read a map written by :func:`save_map`; returns ``(result, meta)``."""
    with np.load(path, allow_pickle=False) as z:
        meta = json.loads(str(z["meta"]))
        fields = {k[2:]: z[k] for k in z.files if k.startswith("f_")}
        xv, yv = z["x_values"], z["y_values"]
    return MapResult(kind=meta["kind"], x_name=meta["x_name"], y_name=meta["y_name"],
                     x_values=xv, y_values=yv, params=RattleParams.from_dict(meta["params"]),
                     settings=meta["settings"], fields=fields,
                     attractors=[dict(a, section_point=tuple(a["section_point"]))
                                 for a in meta["attractors"]]), meta
