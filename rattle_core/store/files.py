"""The ``.npz`` files sweeps and maps are kept in: the disk cache, the shipped diagrams, ``--out``.

A file holds the result's arrays, a JSON ``meta`` record (parameters, settings, schema and
solver versions, and for cache entries the content key and the request it answers) and a
``digest``: the SHA-256 of every other array's name, type, shape and bytes.  Files are
written to a temporary file beside the target (``.tmp-<pid>-*``, so that one left by a killed
writer can be told from one being written) and moved into place with ``os.replace``, so a
reader never sees half a file, and read with ``allow_pickle=False``.  :func:`read_checked`
reads a file only after its declared array sizes passed a limit, and returns it only when
its digest matches.

A cache entry is also signed: HMAC-SHA-256 (:func:`content_mac`) under the user's cache key
(:mod:`rattle_core.store.signing`) of the entry's request key and the same content, kept as
the zip's comment (so readers of the arrays see no extra member).  An entry changed by anyone
without the key, written under another key, or moved to another request's name fails
:func:`read_checked`.  Inside ``with signing(key, context):`` every file :func:`atomic_savez`
writes is signed; the cache does this around its writes.
"""
from __future__ import annotations

import contextlib
import contextvars
import hashlib
import hmac
import io
import json
import math
import os
import tempfile
import zipfile
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


#: The temporary files of :func:`atomic_savez` start with this, then the writer's pid and "-".
TMP_PREFIX = ".tmp-"
#: Declared (uncompressed) bytes a file may hold whatever its size: 64 MB ...
DECLARED_FLOOR = 64_000_000
#: ... or this many times its size on disk (results compress 2 to 20 times; a forged header
#: or a deflate bomb claims up to a thousand).
DECLARED_RATIO = 100


class CorruptFile(ValueError):
    """A file that is not what its writer wrote: sizes out of bounds, a missing or wrong digest."""


def content_digest(arrays: dict) -> str:
    """SHA-256 of the arrays' names, dtypes, shapes and bytes (the ``digest`` excluded)."""
    h = hashlib.sha256()
    for name in sorted(arrays):
        if name == "digest":
            continue
        a = np.ascontiguousarray(arrays[name])
        h.update(json.dumps([name, a.dtype.str, list(a.shape)]).encode())
        h.update(a.tobytes())
    return h.hexdigest()


#: The array that describes the content rather than belongs to it.
_SEALS = ("digest",)
#: What the zip comment of a signed file starts with, before the MAC's hex.
_MAC_PREFIX = "hmac-sha256:"
#: Domain of the MAC, so it signs nothing but an entry of this format.
_MAC_DOMAIN = b"rattle-explorer npz entry, HMAC-SHA-256, v1\0"


def content_mac(arrays: dict, key: bytes, context: str) -> str:
    """HMAC-SHA-256 under ``key`` of ``context`` (what the entry answers: its cache key) and
    every array's name, dtype, shape and bytes (the ``digest`` excluded)."""
    h = hmac.new(key, _MAC_DOMAIN, "sha256")
    ctx = context.encode()
    h.update(len(ctx).to_bytes(8, "big") + ctx)
    for name in sorted(arrays):
        if name in _SEALS:
            continue
        a = np.ascontiguousarray(arrays[name])
        head = json.dumps([name, a.dtype.str, list(a.shape)]).encode()
        h.update(len(head).to_bytes(8, "big") + head)
        h.update(a.tobytes())
    return h.hexdigest()


_SIGNER: contextvars.ContextVar[tuple[bytes, str] | None] = contextvars.ContextVar(
    "signer", default=None)


@contextlib.contextmanager
def signing(key: bytes, context: str):
    """Within the block, :func:`atomic_savez` signs what it writes (:func:`content_mac`)."""
    token = _SIGNER.set((key, context))
    try:
        yield
    finally:
        _SIGNER.reset(token)


def atomic_savez(path: Path, arrays: dict) -> None:
    """Write a compressed npz with its :func:`content_digest` (and, inside :func:`signing`,
    its :func:`content_mac`) to a temporary file beside ``path``, then move it into place."""
    arrays = {k: np.asarray(v) for k, v in arrays.items() if k not in _SEALS}
    signer = _SIGNER.get()
    mac = content_mac(arrays, *signer) if signer is not None else None
    arrays["digest"] = np.array(content_digest(arrays))
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f"{TMP_PREFIX}{os.getpid()}-",
                               suffix=".npz")
    try:
        with os.fdopen(fd, "w+b") as f:
            np.savez_compressed(f, **arrays)
            if mac is not None:
                f.seek(0)
                with zipfile.ZipFile(f, "a") as zf:
                    zf.comment = (_MAC_PREFIX + mac).encode()
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def _declared(data: bytes, limit: int) -> None:
    """Refuse an npz whose members declare more than ``limit`` bytes, or other sizes than
    their headers say, reading only the headers."""
    total = 0
    with zipfile.ZipFile(io.BytesIO(data)) as zf:
        for info in zf.infolist():
            total += info.file_size
            if total > limit:
                raise CorruptFile(f"{info.filename} takes the file's declared size to {total} "
                                  f"bytes, over the limit of {limit}")
            with zf.open(info) as f:
                version = np.lib.format.read_magic(f)
                readers = {(1, 0): np.lib.format.read_array_header_1_0,
                           (2, 0): np.lib.format.read_array_header_2_0}
                if version not in readers:
                    raise CorruptFile(f"{info.filename}: npy format {version} is not written here")
                shape, _, dtype = readers[version](f)
                if dtype.hasobject:
                    raise CorruptFile(f"{info.filename} holds Python objects")
                body = math.prod(shape) * dtype.itemsize
                if f.tell() + body != info.file_size:
                    raise CorruptFile(f"{info.filename} declares {body} bytes of data in a "
                                      f"member of {info.file_size}")


def read_checked(path: Path | str, required: tuple[str, ...] = (),
                 limit: int | None = None, key: bytes | None = None,
                 context: str = "") -> io.BytesIO:
    """The bytes of an npz written by :func:`atomic_savez`, checked, for ``np.load``.

    Before any array is loaded, the declared sizes must agree with the headers and stay within
    ``limit`` bytes (default: :data:`DECLARED_FLOOR`, or :data:`DECLARED_RATIO` times the
    file's size if more).  Then the ``digest`` must match the content, every name in
    ``required`` must be present and, given a ``key``, the ``mac`` must be the
    :func:`content_mac` of ``context`` and the content under that key.  Raises
    :class:`CorruptFile` otherwise.
    """
    size = os.stat(path).st_size
    if limit is None:
        limit = max(DECLARED_FLOOR, DECLARED_RATIO * size)
    if size > limit:
        raise CorruptFile(f"{size} bytes on disk, over the limit of {limit}")
    with open(path, "rb") as f:
        data = f.read(limit + 1)
    try:
        _declared(data, limit)
        with zipfile.ZipFile(io.BytesIO(data)) as zf:
            comment = zf.comment
        with np.load(io.BytesIO(data), allow_pickle=False) as z:
            arrays = {k: z[k] for k in z.files}
    except CorruptFile:
        raise
    except Exception as exc:  # not a zip, not npy members, truncated
        raise CorruptFile(f"unreadable ({type(exc).__name__}: {exc})") from None
    missing = [k for k in required if k not in arrays]
    if missing:
        raise CorruptFile(f"{', '.join(missing)} missing")
    if "digest" not in arrays or str(arrays["digest"]) != content_digest(arrays):
        raise CorruptFile("the digest does not match the content")
    if key is not None:
        expected = (_MAC_PREFIX + content_mac(arrays, key, context)).encode()
        if not hmac.compare_digest(comment, expected):
            raise CorruptFile("the signature does not match: changed, signed with another "
                              "key, or stored under another request's name")
    return io.BytesIO(data)


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
