"""Content-addressed disk cache of sweeps, and the precomputed diagrams shipped in ``assets/``.

Key: SHA-256 of canonical JSON (floats as ``float.hex()``) of the base parameters, the swept
name and values, the sweep settings, :data:`~rattle_core.sweep.SCHEMA_VERSION` and
:data:`~rattle_core.trajectory.SOLVER_VERSION`.  A changed solver or schema therefore never
serves a stale diagram.

Entries are compressed ``.npz`` files written to a temporary file and moved into place with
``os.replace`` (atomic), and read with ``allow_pickle=False``.  A corrupt, truncated or
mismatched entry is recomputed and overwritten, never an error.

Location: ``$RATTLE_CACHE_DIR``, else ``$XDG_CACHE_HOME/rattle-explorer``, else
``~/.cache/rattle-explorer``.
"""
from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from .params import RattleParams, canonical_hash
from .sweep import SCHEMA_VERSION, SweepResult, sweep, validate_sweep_args
from .trajectory import SOLVER_VERSION

#: Shipped precomputed diagrams (paper figures), next to the package in the repository.
ASSETS_DIR = Path(__file__).resolve().parent.parent / "assets" / "paper"

_SUMMARY_TYPES = {"value": np.float64, "regime": "U8", "period": np.int32, "n_active": np.int32,
                  "n_reverse": np.int32, "active_per_period": np.float64,
                  "reverse_per_period": np.float64, "chaotic": np.bool_, "lyapunov": np.float64,
                  "stick_fraction": np.float64, "intensity": np.float64,
                  "sticking": "U22", "loop_amplification": np.float64, "status": np.int8}


def cache_dir() -> Path:
    """The cache directory (created on demand)."""
    env = os.environ.get("RATTLE_CACHE_DIR")
    if env:
        return Path(env)
    xdg = os.environ.get("XDG_CACHE_HOME")
    return (Path(xdg) if xdg else Path.home() / ".cache") / "rattle-explorer"


def sweep_key(base: RattleParams, name: str, values: np.ndarray, settings: dict) -> str:
    """Cache key of a sweep request."""
    keyed = {k: settings[k] for k in ("transient", "record", "mode", "x0", "v0")}
    keyed["noise"] = bool(settings.get("noise", True))
    return canonical_hash({"kind": "sweep", "params": base.canonical(), "name": name,
                           "values": np.asarray(values, dtype=np.float64),
                           "settings": keyed, "schema": SCHEMA_VERSION, "solver": SOLVER_VERSION})


def _atomic_savez(path: Path, arrays: dict) -> None:
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


def save_result(path: Path | str, result: SweepResult, compact: bool = False,
                key: str | None = None) -> None:
    """Write ``result`` atomically.  ``compact`` stores impulses and phases as float32."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fdt = np.float32 if compact else np.float64
    meta = {"name": result.name, "params": result.params.to_dict(), "settings": result.settings,
            "key": key, "schema": SCHEMA_VERSION, "solver": SOLVER_VERSION}
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
    _atomic_savez(path, arrays)


def load_result(path: Path | str) -> tuple[SweepResult, dict]:
    """Read a result written by :func:`save_result`; returns ``(result, meta)``."""
    with np.load(path, allow_pickle=False) as z:
        meta = json.loads(str(z["meta"]))
        table = pd.DataFrame({"value": z["t_value"].astype(np.float64),
                              "impulse": z["t_impulse"].astype(np.float64),
                              "flank": z["t_flank"], "phase": z["t_phase"].astype(np.float64)})
        summary = pd.DataFrame({col: z[f"s_{col}"] for col in _SUMMARY_TYPES})
        values = z["values"]
    params = RattleParams.from_dict(meta["params"])
    return SweepResult(name=meta["name"], values=values, params=params, settings=meta["settings"],
                       table=table, summary=summary), meta


def cached_sweep(base: RattleParams, name: str, values, transient: int = 500, record: int = 200,
                 mode: str = "fresh", x0: float | None = None, v0: float = 0.0, progress=None,
                 cancel=None, chunk_size: int | None = None, executor: Any = None,
                 directory: Path | str | None = None, noise: bool = True) -> SweepResult:
    """:func:`~rattle_core.sweep.sweep`, served from the disk cache when the same request ran before.

    A cancelled sweep is returned but not stored.
    """
    vals, transient, record = validate_sweep_args(name, values, transient, record, mode)
    settings = {"transient": transient, "record": record, "mode": mode,
                "x0": None if x0 is None else float(x0), "v0": float(v0), "noise": noise}
    key = sweep_key(base, name, vals, settings)
    path = Path(directory) if directory is not None else cache_dir()
    path = path / f"sweep-{key[:32]}.npz"
    if path.exists():
        try:
            result, meta = load_result(path)
            if (meta.get("key") == key and meta.get("solver") == SOLVER_VERSION
                    and meta.get("schema") == SCHEMA_VERSION):
                if progress is not None:
                    progress(len(vals), len(vals))
                return result
        except Exception:
            pass  # unreadable or foreign entry: recompute and overwrite it below
    result = sweep(base, name, vals, transient=transient, record=record, mode=mode, x0=x0, v0=v0,
                   progress=progress, cancel=cancel, chunk_size=chunk_size, executor=executor,
                   noise=noise)
    if not result.cancelled:
        try:
            save_result(path, result, key=key)
        except OSError:
            pass  # a read-only or full disk must not cost the user the computed diagram
    return result


def list_assets() -> list[str]:
    """Names of the shipped diagrams (e.g. ``fig2``)."""
    return sorted(p.stem for p in ASSETS_DIR.glob("*.npz"))


def load_asset(name: str) -> SweepResult | None:
    """A shipped diagram by name (``fig2``, ``fig4``, ``fig5``, ``fig6``), or None if absent."""
    path = ASSETS_DIR / f"{name}.npz"
    if not path.exists():
        return None
    try:
        return load_result(path)[0]
    except Exception:
        return None


def find_asset(base: RattleParams, name: str) -> SweepResult | None:
    """A shipped diagram that sweeps ``name`` with every other parameter equal to ``base``'s."""
    for asset in list_assets():
        res = load_asset(asset)
        if res is None or res.name != name:
            continue
        if res.params.with_value(name, base.get(name)).canonical() == base.canonical():
            return res
    return None


def save_map(path: Path | str, result, key: str | None = None) -> None:
    """Write a :class:`~rattle_core.maps.MapResult` atomically."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    meta = {"kind": result.kind, "x_name": result.x_name, "y_name": result.y_name,
            "params": result.params.to_dict(), "settings": result.settings,
            "attractors": result.attractors, "key": key, "schema": SCHEMA_VERSION,
            "solver": SOLVER_VERSION}
    arrays = {"meta": np.array(json.dumps(meta)), "x_values": result.x_values,
              "y_values": result.y_values}
    arrays.update({f"f_{k}": v for k, v in result.fields.items()})
    _atomic_savez(path, arrays)


def load_map(path: Path | str):
    """Read a map written by :func:`save_map`; returns ``(result, meta)``."""
    from .maps import MapResult
    with np.load(path, allow_pickle=False) as z:
        meta = json.loads(str(z["meta"]))
        fields = {k[2:]: z[k] for k in z.files if k.startswith("f_")}
        xv, yv = z["x_values"], z["y_values"]
    return MapResult(kind=meta["kind"], x_name=meta["x_name"], y_name=meta["y_name"],
                     x_values=xv, y_values=yv, params=RattleParams.from_dict(meta["params"]),
                     settings=meta["settings"], fields=fields,
                     attractors=[dict(a, section_point=tuple(a["section_point"]))
                                 for a in meta["attractors"]]), meta


def cached_map(kind: str, params: RattleParams, x_name: str, x_values, y_name: str, y_values,
               directory: Path | str | None = None, **kwargs: Any):
    """:func:`~rattle_core.maps.regime_map` (``kind="regime"``) or
    :func:`~rattle_core.maps.basin_map` (``kind="basin"``; names are ``x0``/``v0``), served from
    the disk cache when the same request ran before.  A cancelled map is not stored."""
    from . import maps
    if kind not in ("regime", "basin"):
        raise ValueError(f"kind = {kind!r}; allowed: 'regime' or 'basin'")
    keyed = {k: v for k, v in kwargs.items() if k in ("transient", "record", "x0", "v0", "decimals")}
    key = canonical_hash({"kind": kind, "params": params.canonical(), "x_name": x_name,
                          "x_values": np.asarray(x_values, dtype=np.float64), "y_name": y_name,
                          "y_values": np.asarray(y_values, dtype=np.float64), "settings": keyed,
                          "schema": SCHEMA_VERSION, "solver": SOLVER_VERSION})
    path = (Path(directory) if directory is not None else cache_dir()) / f"map-{key[:32]}.npz"
    if path.exists():
        try:
            result, meta = load_map(path)
            if meta.get("key") == key:
                return result
        except Exception:
            pass  # unreadable entry: recompute and overwrite it below
    if kind == "regime":
        result = maps.regime_map(params, x_name, x_values, y_name, y_values, **kwargs)
    else:
        result = maps.basin_map(params, x_values, y_values, **kwargs)
    if not result.cancelled:
        try:
            save_map(path, result, key=key)
        except OSError:
            pass  # a read-only or full disk must not cost the user the computed map
    return result
