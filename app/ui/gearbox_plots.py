"""The Gearbox tab's plots as HoloViews elements: a verdict (and its what-if variant) in, plots out.

* :func:`orders_plot`: each measured order's angular acceleration against engine speed;
* :func:`campbell_plot`: the measurement's order spectrum against engine speed in dB (a
  Campbell diagram), the analysed orders marked, so one sees whether they dominate;
* :func:`regime_plot`: each gear's regime against engine speed (one row per gear), its onset
  marked, the variant's regimes as small squares below the baseline's;
* :func:`metric_plot`: a column of the verdict (intensity, loudness) against engine speed per
  gear and for the whole gearbox, the variant (or second design) dashed over the baseline;
  for loudness, the target's limit as a red line and the speeds where the gearbox misses it
  shaded.

No session, no widget: the views (:mod:`app.views.gearbox`,
:mod:`app.views.measurement`) wrap them in DynamicMaps.
"""
from __future__ import annotations

from typing import Any

import holoviews as hv
import numpy as np

from ..core import GEARBOX
from ..core import verdict_tables as vt
from .labels import REGIME_COLOR
from .plots import TOOLS

PALETTE = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2",
           "#7f7f7f", "#bcbd22", "#17becf"]
SIZE = dict(height=260, responsive=True, tools=TOOLS, framewise=True, show_grid=True)


def _named(name: str):
    """A hook giving the Bokeh figure ``name`` (tests and scripts find it by that name)."""
    def hook(plot: Any, element: Any) -> None:
        plot.state.name = name
    return hook


def orders_plot(order_map: Any) -> hv.Overlay:
    """Angular acceleration amplitude of each order against rpm (empty without a map)."""
    if order_map is None:
        return hv.Overlay([hv.Curve([], "rpm", "accel").relabel("no measurement yet")]).opts(
            hv.opts.Curve(**SIZE))
    curves = [hv.Curve((order_map.rpm, order_map.accel_rad_s2[:, j]),
                       hv.Dimension("rpm", label="engine speed [rpm]"),
                       hv.Dimension("accel", label="angular acceleration [rad/s²]"),
                       label=f"order {k:g}").opts(color=PALETTE[j % len(PALETTE)])
              for j, k in enumerate(order_map.orders)]
    return hv.Overlay(curves).opts(hv.opts.Curve(**SIZE, line_width=2),
                                   hv.opts.Overlay(title=f"orders of {order_map.source}",
                                                   legend_position="top_left"))


def campbell_plot(data: Any) -> hv.Overlay:
    """A Campbell diagram: orders across, rpm up, the level [dB re 1 rad] as colour (60 dB
    shown below the peak), each analysed order a dashed white line (empty without data)."""
    if data is None:
        return hv.Overlay([hv.QuadMesh(([0.0, 1.0], [0.0, 1.0], np.zeros((2, 2))),
                                       ["order", "rpm"], "level").relabel("no Campbell view")]
                          ).opts(hv.opts.QuadMesh(**SIZE))
    level = np.asarray(data.level_db, dtype=float)
    top = float(np.nanmax(level)) if np.isfinite(level).any() else 0.0
    mesh = hv.QuadMesh((np.asarray(data.orders, float), np.asarray(data.rpm, float), level),
                       [hv.Dimension("order", label="engine order"),
                        hv.Dimension("rpm", label="engine speed [rpm]")],
                       hv.Dimension("level", label="angular amplitude [dB re 1 rad]"))
    marks = [hv.VLine(float(k)).opts(color="white", line_dash="dashed", line_width=1)
             for k in data.analysed_orders]
    return hv.Overlay([mesh, *marks]).opts(
        hv.opts.QuadMesh(**{**SIZE, "height": 320, "tools": [*TOOLS, "hover"]}, cmap="viridis",
                         colorbar=True, clim=(top - 60.0, top)),
        hv.opts.Overlay(title=f"Campbell view of {data.source} (analysed orders dashed)",
                        hooks=[_named("gb_campbell")]))


def regime_plot(base: Any, variant: Any) -> hv.Overlay:
    """Regimes per gear and speed (baseline circles, variant squares just below)."""
    layers = []
    if base is not None:
        names = [g.name for g in base.gearbox.gears]
        for shift, verdict, marker, size in ((0.0, base, "circle", 9), (-0.3, variant, "square", 6)):
            if verdict is None:
                continue
            t = verdict.table[verdict.table["gear"] != GEARBOX]
            y = t["gear"].map({n: i for i, n in enumerate(names)}).to_numpy(dtype=float) + shift
            colours = [REGIME_COLOR.get(g, "#000000") for g in t["regime"]]
            layers.append(hv.Points((t["rpm"].to_numpy(), y, t["regime"].to_numpy(), colours),
                                    ["rpm", "gear"], ["regime", "colour"]).opts(
                color="colour", marker=marker, size=size, tools=["hover"]))
            on = [(v, i + shift) for i, v in enumerate(verdict.onsets.values()) if np.isfinite(v)]
            layers.append(hv.Points(on, ["rpm", "gear"]).opts(marker="dash", size=22, angle=90,
                                                             color="black", line_width=2))
        ticks = [(i, n) for i, n in enumerate(names)]
    else:
        ticks = []
    if not layers:
        layers = [hv.Points([], ["rpm", "gear"])]
    axes = {"yticks": ticks} if ticks else {}  # Bokeh cannot take an empty tick list
    return hv.Overlay(layers).opts(hv.opts.Points(**SIZE, **axes, ylim=(-0.6, max(len(ticks), 1) - 0.4),
                                                  xlabel="engine speed [rpm]", ylabel=""),
                                   hv.opts.Overlay(title="regime per gear (onset |; variant ■ below)",
                                                   hooks=[_named("gb_regimes")]))


#: The target's limit curve per verdict column.
TARGET_KEYS = {"loudness_sone": "sone", "spl_dba": "dba"}


def metric_plot(base: Any, variant: Any, column: str, label: str, logy: bool = False
                ) -> hv.Overlay:
    """``column`` against rpm for each gear and the gearbox; the variant dashed; the target's
    limit (red) with the baseline's failing speeds shaded, and the variant's hatched."""
    curves = []
    key = TARGET_KEYS.get(column)
    for verdict, alpha in ((base, 0.15), (variant, 0.07)):
        tgt = None if verdict is None else vt.target_of(verdict)
        if tgt is None or key not in tgt.limits:
            continue
        for a, b in vt.failing(verdict).get(GEARBOX, []):
            if b <= a:
                a, b = a - 5.0, b + 5.0
            curves.append(hv.VSpan(a, b).opts(color="#d62728", alpha=alpha, line_alpha=0))
    tgt = None if base is None else vt.target_of(base)
    if tgt is not None and key in tgt.limits:
        rpm = base.rpm
        grid = np.linspace(float(rpm[0]), float(rpm[-1]), 200)
        curves.append(hv.Curve((grid, tgt.limit(key, grid)), "rpm", column, label="target").opts(
            color="#d62728", line_width=2))
    for verdict, dash in ((base, "solid"), (variant, "dashed")):
        if verdict is None:
            continue
        tail = "" if dash == "solid" else " (variant)"
        for i, name in enumerate([g.name for g in verdict.gearbox.gears] + [GEARBOX]):
            rows = verdict.gear(name)
            y = rows[column].to_numpy(dtype=float)
            if logy:
                y = np.where(y > 0, y, np.nan)
            colour = "black" if name == GEARBOX else PALETTE[i % len(PALETTE)]
            curves.append(hv.Curve((rows["rpm"].to_numpy(), y), "rpm", column,
                                   label=f"{name}{tail}").opts(
                color=colour, line_dash=dash, line_width=3 if name == GEARBOX else 1.5))
    if not curves:
        curves = [hv.Curve([], "rpm", column)]
    return hv.Overlay(curves).opts(
        hv.opts.Curve(**SIZE, logy=logy, xlabel="engine speed [rpm]", ylabel=label),
        hv.opts.Overlay(legend_position="right", title=label, hooks=[_named(f"gb_{column}")]))
