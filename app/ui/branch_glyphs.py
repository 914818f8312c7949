"""The continued branches drawn on the bifurcation diagram, as Bokeh glyphs written directly.

:class:`BranchGlyphs` puts them on the diagram's figure once and sets their data when the
branch changes: stable parts solid, unstable parts dashed, one colour and one legend entry
per branch (clicking an entry hides that branch), bifurcations marked with a diamond (named on
hover) and labelled once each (:func:`mark_labels`), the legend in the emptiest corner
(:func:`legend_corner`). They are not HoloViews elements, so a page's plot build does not pay
for them.
"""
from __future__ import annotations

import weakref
from typing import Any

import numpy as np
import pandas as pd

from ..work.branch import MAX_SWITCHED, Branch

BRANCH_COLOR = "#6c3483"
#: One colour per branch: the continued orbit's first, then those started at period doublings.
BRANCH_COLORS = (BRANCH_COLOR, "#117a65", "#b9770e", "#1a5276", "#922b21")
#: Most bifurcation labels stacked above one another where their bifurcations crowd.
MAX_STACKED = 3


def legend_corner(segments: list[np.ndarray],
                  limits: tuple[tuple[float, float], tuple[float, float]] | None) -> str:
    """The corner of the view (``limits``) whose box, a third of the width by a third of the
    height, holds the fewest points of the branches' polylines ``segments``: the legend's place."""
    pts = np.concatenate([np.asarray(seg, float).reshape(-1, 2) for seg in segments]
                         or [np.empty((0, 2))])
    pts = pts[np.isfinite(pts).all(axis=1)]
    if limits is None and not len(pts):
        return "bottom_right"
    (x0, x1), (y0, y1) = limits or ((pts[:, 0].min(), pts[:, 0].max()), (pts[:, 1].min(), pts[:, 1].max()))
    wx, wy = (x1 - x0) / 3.0, (y1 - y0) / 3.0
    boxes = {"bottom_right": (x1 - wx, x1, y0, y0 + wy), "top_right": (x1 - wx, x1, y1 - wy, y1),
             "bottom_left": (x0, x0 + wx, y0, y0 + wy), "top_left": (x0, x0 + wx, y1 - wy, y1)}
    x, y = pts[:, 0], pts[:, 1]
    count = {c: int(((x >= a) & (x <= b) & (y >= lo) & (y <= hi)).sum())
             for c, (a, b, lo, hi) in boxes.items()}
    return min(boxes, key=lambda c: count[c])  # ties: the order above


def branch_layers(branch: Branch | None, name: str, limits: Any = None) -> dict[str, Any]:
    """What the diagram draws of ``branch`` (nothing when it is not a branch of diagram
    ``name``): per branch number, its stable and unstable polylines and its legend label; the
    legend's corner; the bifurcation marks; the labels that read rightwards and leftwards."""
    ok = branch is not None and branch.name == name
    held = branch.numbers if ok else []
    lines = {(i, stable): (branch.segments(stable, i) if i in held else [])
             for i in range(1 + MAX_SWITCHED) for stable in (True, False)}
    marks = (branch.marks[["x", "y", "label", "message"]].reset_index(drop=True) if ok
             else pd.DataFrame({"x": [], "y": [], "label": [], "message": []}))
    left, right = mark_labels(branch.marks if ok else None, limits)
    return {"lines": lines,
            "legends": {i: branch.legend(i) if i in held else "" for i in range(1 + MAX_SWITCHED)},
            "corner": legend_corner([seg for segs in lines.values() for seg in segs], limits)
            if ok else "bottom_right",
            "marks": marks, "left": left.dropna(), "right": right.dropna()}


class BranchGlyphs:
    """The continued branches on a figure, as Bokeh glyphs written directly: stable solid,
    unstable dashed, one colour and one legend entry per branch, bifurcations marked (named on
    hover) and labelled (see :func:`branch_layers`).

    They are not HoloViews elements: as elements they were 13 of the diagram's 19 element
    plots, each built under a lock (:func:`~app.work.threads.plot_lock`). The legend is Bokeh's too, so clicking an entry hides that
    branch. The figure is held weakly, so a closed page's figure is not kept.
    """

    def __init__(self) -> None:
        self._models: Any = lambda: None
        #: the legend as drawn: HoloViews takes a figure's first legend as its own at every
        #: redraw (empties it, moves it), and :meth:`attach` puts this back
        self._legend: dict[str, Any] = {}

    @property
    def models(self) -> dict[str, Any] | None:
        """The glyph renderers by name and the legend, once on a figure."""
        return self._models()

    def attach(self, fig: Any) -> bool:
        """Put the glyphs and the legend on ``fig`` (once per figure; at every later call the
        legend as drawn is put back, which HoloViews empties and moves when it redraws the
        figure); True when newly put."""
        from bokeh.core.properties import value
        from bokeh.models import ColumnDataSource, HoverTool, Legend, LegendItem
        models = self._models()
        if models is not None and models["cont-legend"] in fig.center:
            self._restore(models["cont-legend"])
            return False
        made: dict[str, Any] = {}
        items = []
        for i in range(1 + MAX_SWITCHED):
            suffix, colour = (f"-{i}" if i else ""), BRANCH_COLORS[i % len(BRANCH_COLORS)]
            pair = [fig.multi_line(xs=[], ys=[], line_color=colour, line_width=2.5,
                                   name="cont-stable" + suffix),
                    fig.multi_line(xs=[], ys=[], line_color=colour, line_width=2,
                                   line_dash="dashed", name="cont-unstable" + suffix)]
            made.update({r.name: r for r in pair})
            items.append(LegendItem(name=f"cont-branch-{i}", label=value(""), renderers=pair,
                                    visible=False))
        marks = ColumnDataSource({"x": [], "y": [], "label": [], "message": []})
        made["cont-marks"] = fig.scatter("x", "y", source=marks, marker="diamond", size=9,
                                         line_color="black", fill_color="white", line_width=1.5,
                                         name="cont-marks")
        fig.add_tools(HoverTool(renderers=[made["cont-marks"]], name="cont-hover",
                                tooltips=[("bifurcation", "@label"), ("", "@message")]))
        for name, align in (("cont-labels", "left"), ("cont-labels-r", "right")):
            made[name] = fig.text("x", "y", text="label", source=ColumnDataSource(
                {"x": [], "y": [], "label": []}), text_align=align, text_color="black",
                text_baseline="bottom", text_font_size="9pt", name=name)
        self._legend = dict(items=items, location="bottom_right", label_text_font_size="8pt",
                            background_fill_alpha=0.6, padding=4, spacing=0, click_policy="hide",
                            visible=False, title=None)
        made["cont-legend"] = Legend(name="cont-legend", **self._legend)
        fig.add_layout(made["cont-legend"])
        refs = {k: weakref.ref(m) for k, m in made.items()}
        self._models = lambda: (None if any(r() is None for r in refs.values())
                                else {k: r() for k, r in refs.items()})
        return True

    def draw(self, branch: Branch | None, name: str, limits: Any = None,
             large: bool = False) -> None:
        """Show ``branch`` on diagram ``name`` (nothing when it belongs to another), its labels
        placed inside ``limits`` (``large`` ones for a presented diagram)."""
        from bokeh.core.properties import value
        models = self._models()
        if models is None:
            return
        layers = branch_layers(branch, name, limits)
        for (i, stable), segments in layers["lines"].items():
            glyph = models[("cont-stable" if stable else "cont-unstable") + (f"-{i}" if i else "")]
            _set_data(glyph.data_source,
                      {"xs": [np.asarray(seg, float)[:, 0] for seg in segments],
                       "ys": [np.asarray(seg, float)[:, 1] for seg in segments]})
        m = layers["marks"]
        _set_data(models["cont-marks"].data_source,
                  {k: m[k].to_numpy() for k in ("x", "y", "label", "message")})
        size = "13pt" if large else "9pt"
        for key in ("left", "right"):
            glyph = models["cont-labels" + ("" if key == "left" else "-r")]
            frame = layers[key]
            _set_data(glyph.data_source, {k: frame[k].to_numpy() for k in ("x", "y", "label")})
            if glyph.glyph.text_font_size != size:
                glyph.glyph.text_font_size = size
        legend = models["cont-legend"]
        for item, label in zip(legend.items, layers["legends"].values()):
            if getattr(item.label, "value", None) != label:  # a value: a plain string names a column
                item.label = value(label)
            if item.visible != bool(label):
                item.visible = bool(label)
        self._legend.update(visible=any(layers["legends"].values()), location=layers["corner"])
        self._restore(legend)

    def _restore(self, legend: Any) -> None:
        changed = {k: v for k, v in self._legend.items()
                   if (list(getattr(legend, k)) if k == "items" else getattr(legend, k)) != v}
        if changed:
            legend.update(**changed)


def _set_data(source: Any, data: dict) -> None:
    """``source``'s data set to ``data``, unless both are empty: a page with no branch would
    otherwise get a message for each of these glyphs at every redraw."""
    def empty(d: Any) -> bool:
        return all(len(v) == 0 for v in d.values())
    old = source.data
    if empty(data) and empty(old) and set(old) == set(data):
        return
    source.data = data


def mark_labels(marks: Any, limits: Any) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Where the bifurcation labels go: ``(left-aligned, right-aligned)`` frames of x, y, label.

    One label per bifurcation (at its highest impulse); a label whose neighbour on the left is
    closer than a label's width moves up to the first free row, at most :data:`MAX_STACKED`
    rows, and one that finds no row below the top is left out (its diamond stays, named on
    hover); labels in the right quarter of the view read leftwards, so none runs out of the plot.
    """
    blank = pd.DataFrame({"x": [np.nan], "y": [np.nan], "label": [""]})
    if marks is None or not len(marks):
        return blank, blank.copy()
    one = (marks.sort_values("y").drop_duplicates(["kind", "x"], keep="last")
           .sort_values("x").reset_index(drop=True))
    if limits is None:
        (x0, x1), (y0, y1) = (one["x"].min(), one["x"].max()), (one["y"].min(), one["y"].max())
    else:
        (x0, x1), (y0, y1) = limits
    dx, dy = max(x1 - x0, 1e-300), max(y1 - y0, 1e-300)
    rows: list[tuple[float, float, str, bool]] = []
    placed: list[tuple[float, float]] = []
    for x, y, label in zip(one["x"], one["y"], one["label"]):
        near = [yl for xl, yl in placed if x - xl < 0.08 * dx]
        yl = y + 0.015 * dy
        while any(abs(yl - other) < 0.06 * dy for other in near):
            yl += 0.06 * dy
        if yl > y1 - 0.04 * dy or len(near) >= MAX_STACKED:
            continue  # no room: its diamond stays, named on hover, rather than a pile of labels
        placed.append((float(x), yl))
        rows.append((float(x), float(yl), f" {label} ", x > x0 + 0.75 * dx))
    frame = pd.DataFrame(rows, columns=["x", "y", "label", "right"])
    out = [frame[frame["right"] == side][["x", "y", "label"]] for side in (False, True)]
    return tuple(f if len(f) else blank.copy() for f in out)  # type: ignore[return-value]
