"""The diagram's raster is shaded once per data, ranges and axes, and each plot gets its own copy.

:func:`app.ui.shading.shaded` against datashader called directly on the same points; a second
request with the same data is served from the kept raster (no new entry) as a separate
object; changed data or ranges shade anew; no more than ``KEEP`` rasters are kept.
"""
from __future__ import annotations

import datashader as ds
import holoviews as hv
import numpy as np
import pandas as pd
import pytest
from holoviews.operation.datashader import datashade, dynspread

from app.ui import shading
from app.work.diagram_data import Diagram

KDIMS = [hv.Dimension("x", label="Λ"), hv.Dimension("y", label="impulse Ĩ")]


def diagram(seed: int, n: int = 2000, nudge: float = 0.0) -> Diagram:
    """Random impacts; ``nudge`` added to the first impulse."""
    rng = np.random.default_rng(seed)
    impulse = rng.normal(0, 3, n)
    impulse[0] += nudge
    return Diagram("lam", (0.5, 4.0), rng.uniform(0.5, 4.0, n), impulse,
                   rng.choice(np.array([-1, 1], dtype=np.int8), n), np.zeros(0), np.zeros(0), "test")


@pytest.fixture(autouse=True)
def _empty():
    shading._SHADED.clear()
    yield
    shading._SHADED.clear()


def test_a_raster_equals_datashader_and_is_shaded_once():
    d = diagram(1)
    xr, yr = (0.5, 4.0), (-10.0, 10.0)
    first = shading.shaded(d, KDIMS, xr, yr)
    side = np.where(d.flank > 0, "active", "reverse")
    df = pd.DataFrame({"x": d.x, "y": d.impulse,
                       "side": pd.Categorical(side, categories=list(shading.COLORS))})
    w, h = shading.PIXELS
    direct = dynspread(datashade(hv.Points(df, KDIMS, ["side"]), aggregator=ds.count_cat("side"),
                                 color_key=shading.COLORS, min_alpha=90, x_range=xr, y_range=yr,
                                 width=w, height=h, dynamic=False),
                       max_px=2, threshold=0.5, dynamic=False)
    assert all(np.array_equal(first.dimension_values(v), direct.dimension_values(v))
               for v in first.vdims)
    kept = list(shading._SHADED.values())
    second = shading.shaded(diagram(1), KDIMS, xr, yr)  # equal data, another object
    assert list(shading._SHADED.values()) == kept and len(kept) == 1
    assert second is not first and second is not kept[0]
    assert all(np.array_equal(second.dimension_values(v), first.dimension_values(v))
               for v in first.vdims)


def test_other_data_or_ranges_shade_anew_and_few_are_kept():
    d = diagram(2)
    shading.shaded(d, KDIMS, (0.5, 4.0), (-10.0, 10.0))
    shading.shaded(diagram(2, nudge=1e-9), KDIMS, (0.5, 4.0), (-10.0, 10.0))  # one impact's last digits
    shading.shaded(d, KDIMS, (1.0, 2.0), (-10.0, 10.0))
    assert len(shading._SHADED) == 3
    for k in range(shading.KEEP + 3):
        shading.shaded(diagram(10 + k, 50), KDIMS, (0.5, 4.0), (-10.0, 10.0))
    assert len(shading._SHADED) == shading.KEEP
