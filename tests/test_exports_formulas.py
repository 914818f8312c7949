"""CSV exports never hand a spreadsheet a formula: text cells that start with ``=``, ``+``, ``-``,
``@``, a tab or a carriage return are written with a leading ``'``; numbers are written as they are."""
from __future__ import annotations

import csv
import io

import pandas as pd

from rattle_core.store.exports import csv_text, neutralise_formulas, write_table

CELLS = ["=HYPERLINK(\"http://x\")", "+1", "-2+3", "@SUM(A1)", "\t=1", "5th idler", "", "a=b",
         "1400-1900"]
EXPECTED = ["'=HYPERLINK(\"http://x\")", "'+1", "'-2+3", "'@SUM(A1)", "'\t=1", "5th idler", "",
            "a=b", "1400-1900"]


def _rows(text: str) -> list[dict]:
    return list(csv.DictReader(io.StringIO(text, newline="")))


def test_text_cells_are_neutralised_and_numbers_kept(tmp_path):
    """Each dangerous first character gets a ``'``; harmless text, negative numbers and the
    numeric column come back unchanged, in the written file and in the text export alike."""
    df = pd.DataFrame({"gear": CELLS, "rpm": [-1.5, 2, 3, 4, 5, 6, 7, 8, 9],
                       "n": list(range(-4, 5))})
    path = tmp_path / "v.csv"
    write_table(df, path)
    for text in (path.read_bytes().decode(), csv_text(df)):
        rows = _rows(text)
        assert [r["gear"] for r in rows] == [e if e else "" for e in EXPECTED]
        assert [float(r["rpm"]) for r in rows] == [-1.5, 2, 3, 4, 5, 6, 7, 8, 9]
        assert [int(r["n"]) for r in rows] == list(range(-4, 5))
    assert df["gear"].tolist() == CELLS  # the caller's frame is not changed


def test_object_columns_with_numbers_and_missing_values():
    """In a column of mixed cells only the text is touched: floats, ints and missing values
    pass through; a column name that reads as a formula is neutralised too."""
    df = pd.DataFrame({"=cmd": pd.Series([-3.0, "-x", None, 7, "\r=1"], dtype=object)})
    out = neutralise_formulas(df)
    assert list(out.columns) == ["'=cmd"]
    assert out.iloc[0, 0] == -3.0 and out.iloc[1, 0] == "'-x"
    assert out.iloc[2, 0] is None and out.iloc[3, 0] == 7 and out.iloc[4, 0] == "'\r=1"
