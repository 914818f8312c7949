"""Reading a measurement file, as a data-acquisition system writes it.

Bytes
    A file (``.gz`` decompressed a chunk at a time) is read up to :data:`MAX_BYTES`; it is
    refused, with the line named, as soon as it holds a NUL or other binary byte, text that is
    not UTF-8, a line over :data:`MAX_LINE_BYTES`, or more lines than the row limit (blank and
    comment lines count), so a gzip bomb stops after a bounded amount of work and memory.
    A UTF-8 byte-order mark is dropped; CRLF and CR line ends are read.
Layout, sniffed (:mod:`rattle_core.measure.sniff`)
    Comment lines start with ``#``; the first other line is the header.  The delimiter (``,``
    ``;`` tab or spaces) is the one that splits the header and the first rows into the same
    number of fields; a decimal comma is recognised where the delimiter is not a comma.  A line
    of units under the header (``s; rpm``) is read as units.  The time and speed columns are
    recognised by name and unit, and the speed converted to rpm; explicit options override.
Numbers
    Parsed by pandas' C reader; every sample keeps its line number for messages.
Refusals
    ``ValueError`` naming the file, the line, what was expected there, and the option that
    would read the file.
"""
from __future__ import annotations

import codecs
import csv
import dataclasses
import gzip
import io
import os
import zlib
from pathlib import Path
from typing import Any

import numpy as np

from .sniff import find_columns, sniff_layout, split_fields

MAX_ROWS = 5_000_000
MAX_BYTES = 256_000_000
#: The longest line read [bytes]; a longer one is refused (a binary file, or no line ends).
MAX_LINE_BYTES = 65_536
#: Decompressed a chunk at a time [bytes].
CHUNK_BYTES = 1 << 20
COLUMNS = ("time_s", "speed_rpm")
#: Lines a file may hold beyond its row limit: the header and a units row (blank and comment
#: lines count as rows, so that no file holds unbounded lines that are not samples).
EXTRA_LINES = 2

#: Spellings of NaN that ``float()`` reads, taken as numbers (and refused later as not finite).
_NAN_TEXTS = ["nan", "NaN", "NAN", "Nan", "-nan", "+nan", "-NaN", "+NaN", "-NAN", "+NAN"]
#: Bytes that make a text file binary: controls other than tab, line ends, form feeds.
_BINARY = np.zeros(256, bool)
_BINARY[[c for c in range(32) if c not in (9, 10, 11, 12, 13)] + [127]] = True


@dataclasses.dataclass(frozen=True)
class Detected:
    """What a measurement file was read as: shown to the user and kept with the result.

    ``speed_unit`` is the unit of the file's speed column (converted to rpm on reading);
    ``notes`` say what was done to the samples (a units row skipped, a time window, a
    resampling), ``warnings`` where a value looks wrong for its unit.
    """

    source: str = ""
    delimiter: str = ","
    decimal: str = "."
    columns: tuple[str, ...] = ()
    time_column: str = ""
    speed_column: str = ""
    speed_unit: str = "rpm"
    pulse_column: str = ""
    pulses_per_rev: int = 0
    units_row: bool = False
    rows: int = 0
    duration_s: float = 0.0
    sample_rate_hz: float = 0.0
    resampling: str = ""
    notes: tuple[str, ...] = ()
    warnings: tuple[str, ...] = ()

    def describe(self) -> list[str]:
        """One line per fact, for a terminal or a page."""
        delim = {",": "comma", ";": "semicolon", "\t": "tab", " ": "spaces"}.get(self.delimiter,
                                                                                   self.delimiter)
        out = [f"{self.source}: {delim}-separated, decimal mark {self.decimal!r}"
               + (", a units row under the header" if self.units_row else "")
               + f"; columns {', '.join(self.columns)[:200]}"]
        if self.pulse_column:
            out.append(f"speed from the pulses of {self.pulse_column!r}, "
                       f"{self.pulses_per_rev} per revolution")
        else:
            out.append(f"time {self.time_column!r} [s], speed {self.speed_column!r} "
                       f"[{self.speed_unit}]" + ("" if self.speed_unit == "rpm" else
                                                " converted to rpm"))
        out.append(f"{self.rows} samples over {self.duration_s:.6g} s at "
                   f"{self.sample_rate_hz:.6g} Hz")
        out += [n for n in (self.resampling, *self.notes) if n]
        out += [f"warning: {w}" for w in self.warnings]
        return out


def _check_size(path: str | os.PathLike) -> None:
    p = Path(path)
    if not p.is_file():
        raise ValueError(f"measurement file {str(p)!r} does not exist or is not a file")
    size = p.stat().st_size
    if size > MAX_BYTES:
        raise ValueError(f"measurement file {p.name!r} has {size} bytes; the allowed size is up "
                         f"to {MAX_BYTES} bytes")


def _line_of(data: bytes | bytearray, pos: int, before: int = 0) -> int:
    """The 1-based line holding byte ``pos`` of ``data`` (``before`` lines precede ``data``)."""
    return before + data.count(b"\n", 0, pos) + 1


def _read_bytes(path: str | os.PathLike, name: str, max_lines: int | None = None) -> bytes:
    """The file's bytes (decompressed if ``.gz``), checked a chunk at a time (module docstring)."""
    _check_size(path)
    limit_lines = (MAX_ROWS if max_lines is None else max_lines) + EXTRA_LINES
    out = bytearray()
    lines = 0        # line ends before the current chunk
    run = 0          # bytes since the last line end
    try:
        f = gzip.open(path, "rb") if str(path).lower().endswith(".gz") else open(path, "rb")
        with f:
            while True:
                chunk = f.read(CHUNK_BYTES)
                if not chunk:
                    break
                if len(out) + len(chunk) > MAX_BYTES:
                    raise ValueError(f"{name}, line {lines + chunk.count(b'\n') + 1}: the file "
                                     f"holds more than {MAX_BYTES} bytes (decompressed); the "
                                     f"allowed size is up to {MAX_BYTES} bytes; cut it, or "
                                     "analyse part of it with from_s/to_s in a smaller file")
                buf = np.frombuffer(chunk, np.uint8)
                binary = np.flatnonzero(_BINARY[buf])
                if binary.size:
                    pos = int(binary[0])
                    what = "a NUL byte" if chunk[pos] == 0 else f"the byte 0x{chunk[pos]:02x}"
                    raise ValueError(f"{name}, line {_line_of(chunk, pos, lines)}: {what}; a "
                                     "measurement is a text file (CSV) — export it as text")
                ends = np.flatnonzero(buf == 10)
                gaps = np.diff(np.concatenate([[-run - 1], ends, [len(chunk)]]))
                if gaps.max() - 1 > MAX_LINE_BYTES:
                    i = int(np.argmax(gaps > MAX_LINE_BYTES + 1))
                    raise ValueError(f"{name}, line {lines + i + 1}: a line of over "
                                     f"{MAX_LINE_BYTES} bytes; a measurement has one sample per "
                                     "line (is it a CSV file with line ends?)")
                run = len(chunk) - int(ends[-1]) - 1 if ends.size else run + len(chunk)
                lines += ends.size
                if lines > limit_lines:
                    raise ValueError(f"{name}, line {limit_lines + 1}: more than {limit_lines} "
                                     f"lines (blank and comment lines count); the allowed size "
                                     f"is up to {limit_lines - EXTRA_LINES} rows; cut the file, "
                                     "or analyse part of it with from_s/to_s")
                out += chunk
    except (OSError, EOFError, zlib.error, gzip.BadGzipFile) as exc:
        raise ValueError(f"{name} cannot be read: {exc}") from None
    data = bytes(out)
    del out
    if not data.isascii():
        try:
            data.decode("utf-8")
        except UnicodeDecodeError as exc:
            raise ValueError(f"{name}, line {_line_of(data, exc.start)}: text that is not UTF-8; "
                             "save the file as UTF-8") from None
    if data.startswith(codecs.BOM_UTF8):
        data = data[len(codecs.BOM_UTF8):]
    if b"\n" not in data and b"\r" in data:  # old Mac line ends
        data = data.replace(b"\r", b"\n")
    return data


def _header(path: str | os.PathLike) -> list[str]:
    """The header's fields (comma-separated), for telling an order table from a measurement."""
    _check_size(path)
    p = Path(path)
    opener = gzip.open if str(p).lower().endswith(".gz") else open
    with opener(p, "rb") as f:
        for _ in range(1000):
            line = f.readline(MAX_LINE_BYTES).decode("utf-8", errors="replace").strip()
            if line.startswith("\ufeff"):
                line = line[1:]
            if line and not line.startswith("#"):
                return [c.strip() for c in line.split(",")]
    return []


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


def _is_data(text: str, delimiter: str) -> bool:
    """A line that holds data, or the header: not blank, no ``#`` comment, not empty fields."""
    s = text.strip()
    if not s or s.startswith("#"):
        return False
    return bool("".join(split_fields(text, delimiter)).strip())


@dataclasses.dataclass
class Table:
    """Columns of a measurement file read as numbers, each sample with its file line."""

    columns: dict[str, np.ndarray]
    lines: np.ndarray
    detected: Detected


def read_table(path: str | os.PathLike, label: str | None = None, max_rows: int | None = None,
               *, time_column: str | None = None, speed_column: str | None = None,
               speed_unit: str | None = None, pulse_column: str | None = None,
               pulses_per_rev: int | None = None) -> Table:
    """The file's time and speed (or pulse) columns as numbers, the layout sniffed
    (module docstring); the speed in rpm.  Options as in :func:`read_speed_csv`."""
    import pandas as pd

    name = Path(path).name if label is None else label
    limit = MAX_ROWS if max_rows is None else min(int(max_rows), MAX_ROWS)
    lines = _Lines(_read_bytes(path, name, limit))
    layout = sniff_layout(lines, name)
    delim = layout.delimiter
    keep = (lines.first != ord("#")) & (lines.first != 10) & (lines.first != 13)
    odd = np.frombuffer(b' \t,;"\x0b\x0c', dtype=np.uint8)
    for i in np.flatnonzero(keep & np.isin(lines.first, odd)):
        keep[i] = _is_data(lines.text(i), delim)
    keep[:layout.first_data] = False
    body = np.flatnonzero(keep)
    if body.size > limit:
        raise ValueError(f"{name}, line {int(body[limit]) + 1}: more than {limit} samples; "
                         f"the allowed size is up to {limit} rows; cut the file, or analyse "
                         "part of it with from_s/to_s")
    cols = find_columns(layout, name, time_column=time_column, speed_column=speed_column,
                        speed_unit=speed_unit, pulse_column=pulse_column,
                        pulses_per_rev=pulses_per_rev)
    wanted = [j for j in (cols.time, cols.speed, cols.pulse) if j is not None]
    detected = Detected(source=name, delimiter=delim, decimal=layout.decimal,
                        columns=tuple(layout.header), units_row=layout.units_row,
                        time_column=layout.header[cols.time] if cols.time is not None else "",
                        speed_column=layout.header[cols.speed] if cols.speed is not None else "",
                        speed_unit=cols.unit, pulses_per_rev=int(pulses_per_rev or 0),
                        pulse_column=layout.header[cols.pulse] if cols.pulse is not None else "",
                        rows=int(body.size), notes=tuple(cols.notes))
    if body.size == 0:
        return Table({j: np.empty(0) for j in wanted}, np.empty(0, np.int64), detected)
    text = lines.keep_bytes(keep)
    del keep
    sep = r"\s+" if delim == " " else delim
    try:
        frame = pd.read_csv(io.BytesIO(text), header=None, sep=sep, decimal=layout.decimal,
                            names=list(range(max(wanted) + 1)), usecols=wanted, index_col=False,
                            engine="c", keep_default_na=False, na_values=_NAN_TEXTS,
                            skip_blank_lines=False, encoding="utf-8")
    except (pd.errors.ParserError, pd.errors.EmptyDataError, ValueError) as exc:
        _first_bad_row(lines, body, wanted, layout, name, range(body.size))
        raise ValueError(f"{name}: not a CSV file ({' '.join(str(exc).split())})") from None
    del text
    columns = {}
    for j in wanted:
        col = frame[j]
        if col.size != body.size:
            _first_bad_row(lines, body, wanted, layout, name, range(body.size))
            raise ValueError(f"{name}: not a CSV file (read {col.size} rows of {body.size})")
        if pd.api.types.is_numeric_dtype(col.dtype):
            columns[j] = col.to_numpy(dtype=np.float64)
            continue
        if j == cols.pulse:  # pulse times fill some rows only: the others are blank
            values = pd.to_numeric(col.replace("", np.nan), errors="coerce").to_numpy(np.float64)
            columns[j] = values
            continue
        values = pd.to_numeric(col, errors="coerce").to_numpy(dtype=np.float64)
        unread = np.flatnonzero(np.isnan(values))
        _first_bad_row(lines, body, wanted, layout, name, unread)
        for i in unread:  # every one reads as a float (NaN spelt out, or "1_000")
            values[i] = float(str(col.iloc[i]).replace(layout.decimal, "."))
        columns[j] = values
    if cols.speed is not None:
        columns[cols.speed] = columns[cols.speed] * cols.to_rpm
    out = {"time_s": columns[cols.time] * cols.time_scale if cols.time is not None else None,
           "speed_rpm": columns.get(cols.speed), "pulse": columns.get(cols.pulse)}
    return Table({k: v for k, v in out.items() if v is not None}, body + 1, detected)


def _first_bad_row(lines: _Lines, body: np.ndarray, wanted: list[int], layout: Any, name: str,
                   rows) -> None:
    """Raise the message of the first of ``rows`` (indices of samples, increasing) whose
    columns are not numbers; return if they all are."""
    names = " and ".join(layout.header[j] for j in wanted)
    for r in rows:
        row = split_fields(lines.text(body[r]), layout.delimiter)
        try:
            for j in wanted:
                float(row[j].strip().replace(layout.decimal, "."))
        except (ValueError, IndexError):
            hint = "" if layout.delimiter != "," or layout.decimal != "." else \
                " (a file with decimal commas needs another delimiter)"
            raise ValueError(f"{name}, line {int(body[r]) + 1}: {names} must be numbers, got "
                             f"{lines.text(body[r])[:80]!r}{hint}; comment the line out with #, "
                             "or name the columns with time_column/speed_column") from None


def read_speed_csv(path: str | os.PathLike, label: str | None = None,
                   max_rows: int | None = None, **options: Any
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(time_s, speed_rpm, line numbers)`` of a measurement file, read whole and checked.

    ``max_rows`` (default :data:`MAX_ROWS`) bounds the samples, and with them the memory of
    the reading and of an analysis; lines are counted as the file is read.  ``options``:
    ``time_column``, ``speed_column`` (header names), ``speed_unit`` (``rpm``, ``rad/s`` or
    ``Hz``) override what is recognised.  Raises ``ValueError`` naming the file (or
    ``label``) and the line at fault (module docstring, "Refusals")."""
    table = read_table(path, label, max_rows, **options)
    if "speed_rpm" not in table.columns:
        raise ValueError(f"{table.detected.source}: read_speed_csv reads a speed column; "
                         "pulses are read by OrderMap.from_csv with pulse_column")
    return table.columns["time_s"], table.columns["speed_rpm"], table.lines


__all__ = ["Detected", "Table", "read_table", "read_speed_csv", "split_fields", "MAX_ROWS",
           "MAX_BYTES", "MAX_LINE_BYTES"]
