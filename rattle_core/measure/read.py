"""Reading a measurement file: its bytes checked, its lines classified, its numbers parsed by
pandas' C reader, each sample keeping its line number for messages."""
from __future__ import annotations

import codecs
import csv
import gzip
import io
import os
import zlib
from pathlib import Path

import numpy as np

MAX_ROWS = 5_000_000
MAX_BYTES = 256_000_000
COLUMNS = ("time_s", "speed_rpm")


def _open_text(path: str | os.PathLike):
    p = Path(path)
    if str(p).lower().endswith(".gz"):
        return io.TextIOWrapper(gzip.open(p, "rb"), encoding="utf-8", newline="")
    return open(p, encoding="utf-8", newline="")


def _check_size(path: str | os.PathLike) -> None:
    p = Path(path)
    if not p.is_file():
        raise ValueError(f"measurement file {str(p)!r} does not exist or is not a file")
    size = p.stat().st_size
    if size > MAX_BYTES:
        raise ValueError(f"measurement file {p.name!r} has {size} bytes; the allowed size is up "
                         f"to {MAX_BYTES} bytes")


def _header(path: str | os.PathLike) -> list[str]:
    _check_size(path)
    with _open_text(path) as f:
        for line in f:
            if line.strip() and not line.lstrip().startswith("#"):
                return [c.strip() for c in line.strip().split(",")]
    return []


#: Spellings of NaN that ``float()`` reads, taken as numbers (and refused later as not finite).
_NAN_TEXTS = ["nan", "NaN", "NAN", "Nan", "-nan", "+nan", "-NaN", "+NaN", "-NAN", "+NAN"]
#: First bytes of a line that may still make it blank or a comment (after spaces, in quotes, or
#: a row of empty fields): such lines are looked at one by one.
_ODD_FIRST = np.frombuffer(b' \t,"\r\x0b\x0c', dtype=np.uint8)


def _read_bytes(path: str | os.PathLike, name: str) -> bytes:
    """The file's bytes (decompressed if ``.gz``), at most :data:`MAX_BYTES` of them."""
    _check_size(path)
    try:
        if str(path).lower().endswith(".gz"):
            with gzip.open(path, "rb") as f:
                data = f.read(MAX_BYTES + 1)
            if len(data) > MAX_BYTES:
                raise ValueError(f"{name} decompresses to more than {MAX_BYTES} bytes; the allowed "
                                 f"size is up to {MAX_BYTES} bytes")
        else:
            data = Path(path).read_bytes()
    except (OSError, EOFError, zlib.error) as exc:
        raise ValueError(f"{name} cannot be read: {exc}") from None
    if not data.isascii():
        try:
            data.decode("utf-8")
        except UnicodeDecodeError:
            raise ValueError(f"{name} is not a UTF-8 text file") from None
    if data.startswith(codecs.BOM_UTF8):
        data = data[len(codecs.BOM_UTF8):]
    if b"\n" not in data and b"\r" in data:  # old Mac line ends
        data = data.replace(b"\r", b"\n")
    return data


def _csv_row(text: str) -> list[str]:
    return next(csv.reader([text]), [])


def _is_data(row: list[str]) -> bool:
    """A row that holds data, or the header: not blank and not a ``#`` comment."""
    return bool(row) and bool("".join(row).strip()) and not row[0].lstrip().startswith("#")


class _Lines:
    """Where each line of a file's bytes starts, found a slice at a time (no byte-sized index
    of the whole file); a line's text on demand, for messages."""

    SLICE = 1 << 24

    def __init__(self, data: bytes) -> None:
        self.data = data
        buf = np.frombuffer(data, dtype=np.uint8)
        parts = [np.zeros(1, np.int64)]
        for c0 in range(0, len(data), self.SLICE):
            parts.append(np.flatnonzero(buf[c0:c0 + self.SLICE] == 10) + (c0 + 1))
        starts = np.concatenate(parts)
        if starts[-1] == len(data):  # nothing after the last line end
            starts = starts[:-1]
        self.starts = starts
        #: each line's first byte (a line end for an empty line)
        self.first = buf[np.minimum(starts, max(len(data) - 1, 0))] if len(data) else buf[:0]

    def text(self, i: int) -> str:
        i = int(i)
        end = int(self.starts[i + 1]) if i + 1 < self.starts.size else len(self.data)
        return self.data[int(self.starts[i]):end].decode("utf-8", errors="replace").rstrip("\r\n")

    def keep_bytes(self, keep: np.ndarray) -> bytes:
        """The bytes of the lines where ``keep`` is True."""
        sizes = np.diff(np.append(self.starts, len(self.data)))
        buf = np.frombuffer(self.data, dtype=np.uint8)
        return buf[np.repeat(keep, sizes)].tobytes()


def read_speed_csv(path: str | os.PathLike, label: str | None = None,
                   max_rows: int | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(time_s, speed_rpm, line numbers)`` of a measurement CSV, read whole and checked.

    ``max_rows`` (default :data:`MAX_ROWS`) bounds the samples, and with them the memory of
    the reading and of an analysis; it is checked before any number is parsed.

    Lines are classified (header, data, blank, comment) on the raw bytes first, so that every
    sample keeps its line number for messages; the numbers are parsed by pandas' C reader.
    Raises ``ValueError`` naming the file (or ``label``) and the line at fault (module
    docstring, "Refusals")."""
    import pandas as pd

    name = Path(path).name if label is None else label
    lines = _Lines(_read_bytes(path, name))
    keep = (lines.first != ord("#")) & (lines.first != 10)
    for i in np.flatnonzero(keep & np.isin(lines.first, _ODD_FIRST)):
        keep[i] = _is_data(_csv_row(lines.text(i)))
    data_lines = np.flatnonzero(keep)
    if data_lines.size == 0:
        raise ValueError(f"{name} holds no header line; it needs the columns time_s and speed_rpm")
    h = int(data_lines[0])
    header = [c.strip() for c in _csv_row(lines.text(h))]
    missing = [c for c in COLUMNS if c not in header]
    if missing:
        raise ValueError(f"{name}, line {h + 1}: the header lacks the column(s) "
                         f"{', '.join(missing)}; it needs time_s and speed_rpm, "
                         f"found {', '.join(header)[:200]}")
    it, iw = header.index("time_s"), header.index("speed_rpm")
    body = data_lines[1:]  # index of each sample's line
    limit = MAX_ROWS if max_rows is None else min(int(max_rows), MAX_ROWS)
    if body.size > limit:
        raise ValueError(f"{name}, line {int(body[limit]) + 1}: more than {limit} samples; "
                         f"the allowed size is up to {limit} rows")
    if body.size == 0:
        return np.empty(0), np.empty(0), np.empty(0, np.int64)
    if body.size == lines.starts.size - h - 1:  # every line after the header holds data
        text, skip = lines.data, h + 1      # bytes: BytesIO shares them, no copy
    else:
        keep[:h + 1] = False
        text, skip = lines.keep_bytes(keep), 0
    del keep, data_lines
    try:
        frame = pd.read_csv(io.BytesIO(text), header=None, skiprows=skip,
                            names=list(range(max(it, iw) + 1)), usecols=[it, iw], index_col=False,
                            engine="c", keep_default_na=False, na_values=_NAN_TEXTS,
                            skip_blank_lines=False, encoding="utf-8")
    except (pd.errors.ParserError, pd.errors.EmptyDataError, ValueError) as exc:
        # a row too short or a quote left open: the first row that does not read says which
        _first_bad_row(lines, body, it, iw, name, range(body.size))
        raise ValueError(f"{name}: not a CSV file ({' '.join(str(exc).split())})") from None
    del text
    columns = []
    for j in (it, iw):
        col = frame[j]
        if col.size != body.size:
            _first_bad_row(lines, body, it, iw, name, range(body.size))
            raise ValueError(f"{name}: not a CSV file (read {col.size} rows of {body.size})")
        if pd.api.types.is_numeric_dtype(col.dtype):
            columns.append(col.to_numpy(dtype=np.float64))
            continue
        values = pd.to_numeric(col, errors="coerce").to_numpy(dtype=np.float64)
        unread = np.flatnonzero(np.isnan(values))
        _first_bad_row(lines, body, it, iw, name, unread)
        for i in unread:  # every one reads as a float (NaN spelt out, or "1_000")
            values[i] = float(col.iloc[i])
        columns.append(values)
    return columns[0], columns[1], body + 1


def _first_bad_row(lines: _Lines, body: np.ndarray, it: int, iw: int, name: str, rows) -> None:
    """Raise the message of the first of ``rows`` (indices of samples, increasing) whose
    time or speed is not a number; return if they all are."""
    for r in rows:
        row = _csv_row(lines.text(body[r]))
        try:
            float(row[it]), float(row[iw])
        except (ValueError, IndexError):
            raise ValueError(f"{name}, line {int(body[r]) + 1}: time_s and speed_rpm must be "
                             f"numbers, got {','.join(row)[:80]!r}") from None


