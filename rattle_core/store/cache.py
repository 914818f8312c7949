"""Content-addressed disk cache of sweeps and maps, with a size limit.

Key
    SHA-256 of canonical JSON (floats as ``float.hex()``) of the request: the kind, the base
    parameters, the swept names and values, the settings that change the result,
    :data:`~rattle_core.batch.sweep.SCHEMA_VERSION` and
    :data:`~rattle_core.solver.trajectory.SOLVER_VERSION`.  A changed solver or schema therefore
    never serves a stale result.
Signature
    Every entry is signed with HMAC-SHA-256 under the user's secret cache key
    (:mod:`rattle_core.store.signing`: ``RATTLE_CACHE_KEY``, else a file of mode 0600 in the
    config directory, made on first use) over the request's full key and everything the entry
    holds: every array's name, type, shape and bytes, the stored request among them.  Whoever
    can write to the cache directory but cannot read the key can therefore not make an entry
    that is served: not by changing arrays and recomputing the digest, not by changing the
    stored request, not by copying in an entry of another cache (another key), and not by
    renaming an entry to another request's file name.  When no key can be made (the config
    directory is not writable), nothing is served or stored: results are computed.
Match
    An entry is served only when its declared array sizes pass
    :func:`~rattle_core.store.files.read_checked` before it is loaded, its digest matches its
    content, its signature is this user's for this request, it holds every field its kind
    requires, its stored request equals the one asked, field by field, and its arrays hold the
    values asked for; the file name (the key's first 32 hex digits) only finds it.  An entry
    that is unreadable, truncated, forged, foreign or mismatched is a miss: recomputed and
    overwritten, never an error.  Something else standing at an entry's path (a directory, a
    socket) is left alone: the result is computed and returned without being stored.
Writes
    Compressed ``.npz`` (:mod:`rattle_core.store.files`), atomic; a read-only or full disk costs
    the entry, not the result.  Cancelled results are not stored.
Size
    At most :func:`size_limit` bytes, ``RATTLE_CACHE_SIZE_MB`` megabytes (default
    :data:`DEFAULT_SIZE_MB`, 1024).  After each write the least recently used entries (a hit
    counts as a use) are deleted until the cache fits; the entry just written is kept.
    Temporary files of writers that died (their pid is gone, or a day passed) are deleted too.
Read only
    Inside ``with read_only():`` a miss raises :class:`NotCached` instead of computing: a
    caller may serve a request that ran before without paying for one that did not.
Location
    ``$RATTLE_CACHE_DIR``, else ``$XDG_CACHE_HOME/rattle-explorer``, else
    ``~/.cache/rattle-explorer``.
"""
from __future__ import annotations

import contextlib
import contextvars
import dataclasses
import math
import os
import stat
import time
from pathlib import Path
from typing import Any, Callable

import numpy as np

from ..batch.maps import MapResult, basin_map, regime_map
from ..batch.sweep import SCHEMA_VERSION, SweepResult, sweep, validate_sweep_args
from ..model.params import RattleParams, _canon, canonical_hash
from ..solver.trajectory import SOLVER_VERSION
from .files import (_SUMMARY_TYPES, TMP_PREFIX, load_map, load_result, read_checked,
                    save_map, save_result, signing)
from .signing import secret

#: Default size limit of the cache, in megabytes (``RATTLE_CACHE_SIZE_MB`` overrides it).
DEFAULT_SIZE_MB = 1024
SIZE_MB_RANGE = (0.0, 1.0e7)
#: File-name prefixes of cache entries; nothing else in the directory is ever deleted.
PREFIXES = ("sweep", "map", "cont", "gearbox", "atlas", "runup")
_SWEEP_SETTINGS = ("transient", "record", "mode", "x0", "v0")
_MAP_SETTINGS = ("transient", "record", "x0", "v0", "decimals")
#: What every sweep and map entry must hold (basins also ``f_attractor``).
SWEEP_FIELDS = ("meta", "values", "t_value", "t_impulse", "t_flank", "t_phase",
                *(f"s_{c}" for c in _SUMMARY_TYPES))
MAP_FIELDS = ("meta", "x_values", "y_values", "f_regime", "f_period", "f_lyapunov",
              "f_active_per_period", "f_reverse_per_period", "f_stick_fraction", "f_intensity")
#: A temporary file this old is a dead writer's even when its pid was reused.
TMP_MAX_AGE = 86_400.0


def cache_dir() -> Path:
    """The cache directory (created on the first write)."""
    env = os.environ.get("RATTLE_CACHE_DIR")
    if env:
        return Path(env)
    xdg = os.environ.get("XDG_CACHE_HOME")
    return (Path(xdg) if xdg else Path.home() / ".cache") / "rattle-explorer"


def size_limit() -> int:
    """The cache's size limit in bytes, from ``RATTLE_CACHE_SIZE_MB`` (default 1024 MB)."""
    text = os.environ.get("RATTLE_CACHE_SIZE_MB", "").strip()
    if not text:
        return DEFAULT_SIZE_MB * 1_000_000
    try:
        mb = float(text)
    except ValueError:
        mb = math.nan
    if not SIZE_MB_RANGE[0] <= mb <= SIZE_MB_RANGE[1]:
        raise ValueError(f"RATTLE_CACHE_SIZE_MB = {text!r} is outside the allowed range "
                         f"[{SIZE_MB_RANGE[0]:g}, {SIZE_MB_RANGE[1]:g}] (megabytes)")
    return int(mb * 1_000_000)


# ----- requests and keys --------------------------------------------------------------------

def sweep_request(base: RattleParams, name: str, values, settings: dict,
                  columns: dict | None = None) -> dict:
    """What a sweep's result depends on; its :func:`canonical_hash` is the cache key."""
    keyed = {k: settings[k] for k in _SWEEP_SETTINGS}
    request = {"kind": "sweep", "params": base.canonical(), "name": name,
               "values": np.asarray(values, dtype=np.float64), "settings": keyed,
               "schema": SCHEMA_VERSION, "solver": SOLVER_VERSION}
    if columns is not None:  # absent otherwise, so the keys of plain sweeps stay as they were
        request["columns"] = {k: np.asarray(v, dtype=np.float64) for k, v in columns.items()}
    return request


def sweep_key(base: RattleParams, name: str, values, settings: dict) -> str:
    """Cache key of a sweep request (also the key a shipped diagram carries)."""
    return canonical_hash(sweep_request(base, name, values, settings))


def map_request(kind: str, params: RattleParams, x_name: str, x_values, y_name: str, y_values,
                settings: dict) -> dict:
    """What a map's result depends on; its :func:`canonical_hash` is the cache key."""
    return {"kind": kind, "params": params.canonical(), "x_name": x_name,
            "x_values": np.asarray(x_values, dtype=np.float64), "y_name": y_name,
            "y_values": np.asarray(y_values, dtype=np.float64),
            "settings": {k: v for k, v in settings.items() if k in _MAP_SETTINGS},
            "schema": SCHEMA_VERSION, "solver": SOLVER_VERSION}


# ----- the one wrapper ----------------------------------------------------------------------

class NotCached(LookupError):
    """A request missed the cache inside :func:`read_only`."""


_READ_ONLY: contextvars.ContextVar[bool] = contextvars.ContextVar("read_only", default=False)


@contextlib.contextmanager
def read_only() -> Any:
    """Within the block, a cache miss raises :class:`NotCached` and nothing is computed."""
    token = _READ_ONLY.set(True)
    try:
        yield
    finally:
        _READ_ONLY.reset(token)


def cached(prefix: str, request: dict, compute: Callable[[], Any],
           load: Callable[[Any], tuple[Any, dict]], save: Callable[..., None],
           holds: Callable[[Any], bool], directory: Path | str | None = None,
           required: tuple[str, ...] = ("meta",), limit: int | None = None) -> tuple[Any, bool]:
    """Serve ``request`` from the cache, or ``compute()`` and store it; ``(result, from_cache)``.

    ``load`` reads an entry from a file object (the bytes that passed
    :func:`~rattle_core.store.files.read_checked` with ``required`` and ``limit``);
    ``holds(result)`` checks that a loaded entry's arrays are the ones asked for; the stored
    request must also equal ``request``.  See the module docstring for every other rule.
    """
    key = canonical_hash(request)
    wanted = _canon(request)
    folder = Path(directory) if directory is not None else cache_dir()
    path = folder / f"{prefix}-{key[:32]}.npz"
    context = f"{prefix}:{key}"  # what the signature binds an entry to
    try:
        mac_key: bytes | None = secret()
    except OSError:
        mac_key = None  # no key can be made: nothing can be verified, so nothing is cached
    storable = mac_key is not None
    if mac_key is not None and _is_file(path):
        try:
            result, meta = load(read_checked(path, required, limit, mac_key, context))
            if meta.get("key") == key and meta.get("request") == wanted and holds(result):
                _touch(path)
                return result, True
        except Exception:
            pass  # unreadable, forged or foreign entry: recompute and overwrite it below
    elif os.path.lexists(path) and not _is_file(path):
        storable = False
    if _READ_ONLY.get():
        raise NotCached(f"{prefix} {key[:12]} is not in the cache")
    result = compute()
    if storable and not result.cancelled:
        try:
            folder.mkdir(parents=True, exist_ok=True)
            with signing(mac_key, context):
                save(path, result, key=key, request=wanted)
            evict(folder, keep=(path,))
        except OSError:
            pass  # a read-only or full disk must not cost the user the computed result
    return result, False


def cached_sweep(base: RattleParams, name: str, values, transient: int = 500, record: int = 200,
                 mode: str = "fresh", x0: float | None = None, v0: float = 0.0, progress=None,
                 cancel=None, chunk_size: int | None = None, executor: Any = None,
                 directory: Path | str | None = None, columns: dict | None = None) -> SweepResult:
    """:func:`~rattle_core.batch.sweep.sweep`, served from the disk cache when the same request
    ran before (``result.from_cache``).  A cancelled sweep is returned but not stored."""
    vals, transient, record = validate_sweep_args(name, values, transient, record, mode, columns)
    settings = {"transient": transient, "record": record, "mode": mode,
                "x0": None if x0 is None else float(x0), "v0": float(v0)}

    def compute() -> SweepResult:
        return sweep(base, name, vals, transient=transient, record=record, mode=mode, x0=x0,
                     v0=v0, progress=progress, cancel=cancel, chunk_size=chunk_size,
                     executor=executor, columns=columns)

    def holds(res: SweepResult) -> bool:
        return (res.name == name and res.params.canonical() == base.canonical()
                and np.array_equal(res.values, vals) and not res.cancelled
                and np.array_equal(res.summary["value"].to_numpy(dtype=np.float64), vals)
                and bool(np.isin(res.table["value"].to_numpy(dtype=np.float64), vals).all()))

    result, hit = cached("sweep", sweep_request(base, name, vals, settings, columns), compute,
                         load_result, save_result, holds, directory, SWEEP_FIELDS)
    if hit:
        if progress is not None:
            progress(len(vals), len(vals))
        result = dataclasses.replace(result, from_cache=True)
    return result


def cached_map(kind: str, params: RattleParams, x_name: str, x_values, y_name: str, y_values,
               directory: Path | str | None = None, **kwargs: Any) -> MapResult:
    """:func:`~rattle_core.batch.maps.regime_map` (``kind="regime"``) or
    :func:`~rattle_core.batch.maps.basin_map` (``kind="basin"``; names are ``x0``/``v0``),
    served from the disk cache when the same request ran before (``result.from_cache``).
    A cancelled map is not stored."""
    if kind not in ("regime", "basin"):
        raise ValueError(f"kind = {kind!r}; allowed: 'regime' or 'basin'")
    xv = np.asarray(x_values, dtype=np.float64)
    yv = np.asarray(y_values, dtype=np.float64)

    def compute() -> MapResult:
        if kind == "regime":
            return regime_map(params, x_name, x_values, y_name, y_values, **kwargs)
        return basin_map(params, x_values, y_values, **kwargs)

    def holds(res: MapResult) -> bool:
        return (res.kind == kind and (res.x_name, res.y_name) == (x_name, y_name)
                and res.params.canonical() == params.canonical()
                and np.array_equal(res.x_values, xv) and np.array_equal(res.y_values, yv)
                and all(v.shape == (yv.size, xv.size) for v in res.fields.values()))

    request = map_request(kind, params, x_name, xv, y_name, yv, kwargs)
    required = MAP_FIELDS + (("f_attractor",) if kind == "basin" else ())
    # a map's size follows from its grid: 8 fields of at most 8 bytes a point, axes, the meta
    # (a basin names each attractor, at most one per point)
    limit = max(2 * (xv.size * yv.size * 64 + 8 * (xv.size + yv.size)) + 1_000_000, 64_000_000)
    result, hit = cached("map", request, compute, load_map, save_map, holds, directory,
                         required, limit)
    return dataclasses.replace(result, from_cache=True) if hit else result


# ----- size limit, listing and clearing -----------------------------------------------------

@dataclasses.dataclass(frozen=True)
class Entry:
    """One cache file: its path, kind (``sweep``, ``map``, ``cont``, a continued branch,
    ``gearbox``, a verdict, or ``atlas``, bifurcation curves), size in bytes and last use."""

    path: Path
    kind: str
    size: int
    last_used: float


def _is_file(path: Path) -> bool:
    try:
        return stat.S_ISREG(os.lstat(path).st_mode)
    except OSError:
        return False


def _touch(path: Path) -> None:
    try:
        os.utime(path)
    except OSError:
        pass  # a read-only cache still serves; only the eviction order suffers


def entries(directory: Path | str | None = None) -> list[Entry]:
    """The cache's entries, least recently used first (regular files named like entries only)."""
    folder = Path(directory) if directory is not None else cache_dir()
    out = []
    for prefix in PREFIXES:
        for p in folder.glob(f"{prefix}-*.npz"):
            try:
                st = os.lstat(p)
            except OSError:
                continue
            if stat.S_ISREG(st.st_mode):
                out.append(Entry(p, prefix, st.st_size, st.st_mtime))
    return sorted(out, key=lambda e: (e.last_used, e.path.name))


def evict(directory: Path | str | None = None, limit: int | None = None,
          keep: tuple[Path, ...] = ()) -> list[Path]:
    """Delete the least recently used entries until the cache fits ``limit`` bytes (default
    :func:`size_limit`); entries in ``keep`` stay.  Returns the paths deleted."""
    limit = size_limit() if limit is None else int(limit)
    evict_stale_temporaries(directory)
    found = entries(directory)
    total = sum(e.size for e in found)
    kept = {Path(k) for k in keep}
    gone = []
    for e in found:
        if total <= limit:
            break
        if e.path in kept:
            continue
        try:
            e.path.unlink()
        except OSError:
            continue
        total -= e.size
        gone.append(e.path)
    return gone


def _writer_gone(path: Path) -> bool:
    """True for a temporary file whose writer died: its pid is gone, or it is a day old."""
    try:
        if time.time() - os.lstat(path).st_mtime > TMP_MAX_AGE:
            return True
        pid = int(path.name[len(TMP_PREFIX):].split("-", 1)[0])
    except (OSError, ValueError):
        return False  # an unnamed writer is only judged by age
    if pid == os.getpid():
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    except OSError:
        return False  # alive, someone else's
    return False


def evict_stale_temporaries(directory: Path | str | None = None) -> list[Path]:
    """Delete the temporary files that writers killed mid-write left; returns their paths."""
    folder = Path(directory) if directory is not None else cache_dir()
    gone = []
    for p in folder.glob(f"{TMP_PREFIX}*.npz"):
        if _is_file(p) and _writer_gone(p):
            try:
                p.unlink()
            except OSError:
                continue
            gone.append(p)
    return gone


def clear(directory: Path | str | None = None) -> tuple[int, int]:
    """Delete every entry (and temporary files left by interrupted writes); returns
    ``(files deleted, bytes freed)``.  Nothing else in the directory is touched."""
    folder = Path(directory) if directory is not None else cache_dir()
    victims = [(e.path, e.size) for e in entries(folder)]
    for p in folder.glob(".tmp-*.npz"):
        if _is_file(p):
            victims.append((p, p.stat().st_size))
    n = freed = 0
    for p, size in victims:
        try:
            p.unlink()
        except OSError:
            continue
        n += 1
        freed += size
    return n, freed
