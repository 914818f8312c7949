"""The bifurcation diagram's impacts shaded by flank with datashader (``datashade`` and
``dynspread``), kept for the sessions that ask again.

Every page opens on the same shipped diagram, and HoloViews asks for a plot's raster two or
three times while it builds the plot (its range stream reports the data's own limits): a raster
is shaded once, found by its data's digest, ranges and axes, and each plot gets a copy of its
own, since each sets its options on what it gets (:class:`app.ui.plots.Zoom`).
"""
from __future__ import annotations

import collections
import threading
from typing import Any

import datashader as ds
import holoviews as hv
import numpy as np
import pandas as pd
from holoviews.operation.datashader import datashade, dynspread

from .labels import ACTIVE_COLOR, REVERSE_COLOR

#: The raster's size in pixels (width, height).
PIXELS = (640, 340)
COLORS = {"active": ACTIVE_COLOR, "reverse": REVERSE_COLOR}
#: How many rasters are kept (each about 0.9 MB).
KEEP = 8

_SHADED: collections.OrderedDict[tuple, hv.RGB] = collections.OrderedDict()
_LOCK = threading.Lock()


def shaded(d: Any, kdims: list, xr: tuple, yr: tuple) -> hv.RGB:
    """The impacts of diagram ``d`` (a :class:`app.work.diagram_data.Diagram`: ``x``,
    ``impulse``, ``flank`` and their ``digest``) over ``xr`` × ``yr``."""
    key = (d.digest, tuple(map(float, xr)), tuple(map(float, yr)),
           tuple((k.name, k.label) for k in kdims))
    with _LOCK:
        rgb = _SHADED.get(key)
        if rgb is not None:
            _SHADED.move_to_end(key)
            return rgb.clone()
    w, h = PIXELS
    side = np.where(d.flank > 0, "active", "reverse")
    df = pd.DataFrame({"x": d.x, "y": d.impulse, "side": pd.Categorical(side, categories=list(COLORS))})
    rgb = dynspread(datashade(hv.Points(df, kdims, ["side"]), aggregator=ds.count_cat("side"),
                              color_key=COLORS, min_alpha=90, x_range=xr, y_range=yr,
                              width=w, height=h, dynamic=False),
                    max_px=2, threshold=0.5, dynamic=False)
    with _LOCK:
        _SHADED[key] = rgb
        while len(_SHADED) > KEEP:
            _SHADED.popitem(last=False)
    return rgb.clone()
