"""Tables for people and other programs: runs, sweeps and maps as CSV or Parquet.

One row per impact (``t, phase, impulse, flank, w``), per time sample (``t, x, v, y,
y_plus_j, contact``), per swept value or per map point.  Flanks and contact states are spelled
as in :mod:`rattle_core.analysis.vocabulary` (``active``, ``reverse``, ``none``).  In physical
units the rows gain SI columns (``t_s``, ``impulse_Ns``, ``x_um``, ...).  Parquet files carry
the parameters and settings as JSON in their schema metadata (key ``rattle``).

A CSV is opened in spreadsheets, which run a cell that starts with ``=``, ``+``, ``-`` or ``@``
(or a tab or carriage return before one) as a formula.  Text cells such as gear names come from
users, so every text cell that starts with one of these is written with a leading ``'``
(:func:`neutralise_formulas`); numbers are written as they are.
"""
from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..analysis.vocabulary import contact_values, flank_values
from ..model.excitation import excitation
from ..model.units import PhysicalParams, impulse_scale_from_rpm
from ..solver.trajectory import Trajectory

if TYPE_CHECKING:
    import pandas as pd

#: File types a table may be written as.
TABLE_SUFFIXES = (".csv", ".parquet")
#: First characters that make a spreadsheet read a text cell as a formula.
FORMULA_STARTS = ("=", "+", "-", "@", "\t", "\r")


def neutralise_formulas(df: "pd.DataFrame") -> "pd.DataFrame":
    """``df`` with every text cell that a spreadsheet would run as a formula prefixed by ``'``
    (module docstring); columns of numbers, and the column names' order, are untouched."""
    out = df.copy()
    out.columns = [_neutral(c) if isinstance(c, str) else c for c in df.columns]
    for name in out.columns:
        col = out[name]
        if col.dtype == object or str(col.dtype) in ("string", "str", "category"):
            out[name] = col.map(_neutral, na_action="ignore").astype(object)
    return out


def _neutral(value: Any) -> Any:
    if isinstance(value, str) and value.startswith(FORMULA_STARTS):
        return "'" + value
    return value


def csv_text(df: "pd.DataFrame") -> str:
    """``df`` as CSV text, formulas neutralised (:func:`neutralise_formulas`)."""
    return neutralise_formulas(df).to_csv(index=False)


def write_table(df: "pd.DataFrame", path: Path | str, meta: dict | None = None) -> None:
    """Write ``df`` as CSV or Parquet, by the extension of ``path``; ``meta`` goes into Parquet
    metadata (CSV has no place for it).  The file appears whole or not at all: it is written
    beside ``path`` and then moved into place, so an interrupted run leaves no half a table."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=".tmp-", suffix=path.suffix)
    os.close(fd)
    try:
        if path.suffix.lower() == ".csv":
            neutralise_formulas(df).to_csv(tmp, index=False)
        else:
            import pyarrow as pa
            import pyarrow.parquet as pq

            table = pa.Table.from_pandas(df, preserve_index=False)
            if meta is not None:
                md = dict(table.schema.metadata or {})
                md[b"rattle"] = json.dumps(meta, default=str).encode()
                table = table.replace_schema_metadata(md)
            pq.write_table(table, tmp)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def impacts_frame(tr: Trajectory, phys: PhysicalParams | None = None) -> "pd.DataFrame":
    """Every recorded impact: time, phase, signed impulse, flank, incoming relative velocity."""
    import pandas as pd
    df = pd.DataFrame({"t": tr.impact_t, "phase": tr.impact_phase, "impulse": tr.impact_impulse,
                       "flank": flank_values(tr.impact_flank), "w": tr.impact_w})
    if phys is not None:
        df["t_s"] = phys.time(tr.impact_t)
        df["impulse_Ns"] = phys.impulse(tr.impact_impulse)
    return df


def history_frame(tr: Trajectory, samples_per_period: int,
                  phys: PhysicalParams | None = None) -> "pd.DataFrame":
    """The motion sampled uniformly over the recorded window, ends included."""
    import pandas as pd
    rows = int(round(tr.periods)) * samples_per_period
    t = tr.t_start + (tr.t_end - tr.t_start) * np.arange(rows + 1) / rows
    x, v = tr.sample(t)
    p = tr.params
    y = excitation(t, p.h, p.phi)
    idx = np.clip(np.searchsorted(tr.seg_t, t, side="right") - 1, 0, max(len(tr.seg_t) - 1, 0))
    kind = tr.seg_kind[idx] if len(tr.seg_t) else np.zeros(t.size, np.int8)
    df = pd.DataFrame({"t": t, "x": x, "v": v, "y": y, "y_plus_j": y + p.j,
                       "contact": contact_values(kind)})
    if phys is not None:
        df["t_s"] = phys.time(t)
        df["x_um"] = phys.position(x) * 1e6
        df["v_mps"] = phys.velocity(v)
        df["y_um"] = phys.position(y) * 1e6
    return df


def sweep_frames(result: Any, phys: PhysicalParams | None = None,
                 rpm: tuple[np.ndarray, np.ndarray] | None = None
                 ) -> tuple["pd.DataFrame", "pd.DataFrame"]:
    """A sweep's impact table and summary as exported: flanks spelled out; for an engine-speed
    sweep (``rpm``: the swept values and their engine speeds) an ``rpm`` column first; in
    physical units the impulse in N·s."""
    table = result.table.copy()
    summary = result.summary.copy()
    if rpm is not None:
        to_rpm = dict(zip(np.asarray(rpm[0], dtype=np.float64).tolist(),
                          np.asarray(rpm[1], dtype=np.float64).tolist()))
        table.insert(0, "rpm", table["value"].map(to_rpm).to_numpy(dtype=np.float64))
        summary.insert(0, "rpm", summary["value"].map(to_rpm).to_numpy(dtype=np.float64))
        table["impulse_Ns"] = table["impulse"] * impulse_scale_from_rpm(phys, table["rpm"].to_numpy())
    elif phys is not None:
        table["impulse_Ns"] = table["impulse"] * phys.impulse_scale
    table["flank"] = flank_values(table["flank"].to_numpy())
    return table, summary
