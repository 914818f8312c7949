"""Sensitivity shown live: a twin gear started next to the first, and how far apart they drift.

A ``pn.viewable.Viewer`` over the state. With ``twin`` on, the first gear starts from the
clicked point of the Poincaré map (``x0``, ``v0`` at ``t0``) or, if none was clicked, from the
current run's first point on its attractor; the twin starts ``nudge`` away in x, or from a
second click on the map (``twin_x0``, ``twin_v0``). Both are simulated exactly from there
(no transient, so the two clocks agree) over :data:`PERIODS` forcing periods and drawn
together; beside them, their distance in the (x, ẋ) plane against time on a log scale, with
the run's Lyapunov exponent as a slope. Chaos diverges along that slope until the gap is the
backlash; a periodic orbit pulls the twin in.
"""
from __future__ import annotations

import math
from typing import Any

import holoviews as hv
import numpy as np
import panel as pn
import param

from rattle_core import simulate

from ..core import TWO_PI
from ..state import ExplorerState
from ..ui.labels import ACTIVE_COLOR, REVERSE_COLOR, twin_text
from ..ui.plots import TOOLS, HoloViewsPane, named_glyph, save_as
from ..ui.widgets import Choice, Field, built_when_shown, message

#: Forcing periods both gears are followed for, and samples per period.
PERIODS, SAMPLES = 40, 40
#: The smallest distance drawn on the log scale (the floor of double precision).
FLOOR = 1e-16
#: The legend's name for the slope: plain text, since a legend does not typeset mathematics.
SLOPE_LABEL = "exp(λt), the run's λ"


def twin_runs(state: ExplorerState) -> dict[str, Any] | None:
    """Both gears over :data:`PERIODS` periods: times, positions, and their distance.

    Returns None while there is no run. The start is the clicked one (``x0``, ``v0``, ``t0``)
    or the run's first Poincaré point (on its attractor); the twin's is ``twin_x0``/``twin_v0``
    or the first's nudged by ``nudge`` in x.
    """
    run = state.result
    if run is None:
        return None
    tr = run.tr
    if state.x0 is not None:
        x0, v0, t0 = float(state.x0), float(state.v0), float(state.t0)
    elif len(tr.strobe_t):
        x0, v0, t0 = float(tr.strobe_x[0]), float(tr.strobe_v[0]), float(tr.strobe_t[0])
    else:
        return None
    if state.twin_x0 is not None:
        x1, v1 = float(state.twin_x0), float(state.twin_v0)
    else:
        x1, v1 = x0 + state.nudge, v0
    t = t0 + np.linspace(0.0, PERIODS * TWO_PI, PERIODS * SAMPLES + 1)
    out = {"t": (t - t0) / TWO_PI, "start": (x0, v0, x1, v1)}
    for key, (x, v) in (("a", (x0, v0)), ("b", (x1, v1))):
        # a twin outside the backlash is refused by the core, with the value and range named
        tr_k = simulate(run.params, periods=PERIODS, x0=x, v0=v, t0=t0, transient=0)
        out[key] = tr_k.sample(t)
    (xa, va), (xb, vb) = out["a"], out["b"]
    out["distance"] = np.maximum(np.hypot(xa - xb, va - vb), FLOOR)
    out["lyapunov"] = float(getattr(run.cls, "lyapunov", math.nan))
    return out


class SensitivityView(pn.viewable.Viewer):
    """The twin trajectory and the separation plot (see the module docstring)."""

    state = param.ClassSelector(class_=ExplorerState)
    revision = param.Integer(0)

    def __init__(self, **params: Any):
        super().__init__(**params)
        s = self.state
        self.data: dict[str, Any] | None = None
        self.switch = Choice(s, "twin", label="Twin trajectory: start a second gear next to the "
                                               "first (a click on the map while on sets its start)")
        self.nudge = Field(s, "nudge", "nudge · the twin's start, this far in x [H₁]", slider=False)
        self.reset = pn.widgets.Button(label="Nudge again", width=120, css_classes=["twin-reset"])
        self.reset.on_click(lambda e: s.param.update(twin_x0=None, twin_v0=0.0))
        self.text = pn.pane.HTML("", css_classes=["twin-text"], sizing_mode="stretch_width")
        self.paths = hv.DynamicMap(self._paths, streams=[hv.streams.Params(self, ["revision"])])
        self.gap = hv.DynamicMap(self._gap, streams=[hv.streams.Params(self, ["revision"])])
        # the two share their time axis: a zoom in time on one is a zoom on the other
        self.plots = pn.Row(
            HoloViewsPane(self.paths, sizing_mode="stretch_width", height=260,
                          css_classes=["twin-paths"], linked_axes=True),
            HoloViewsPane(self.gap, sizing_mode="stretch_width", height=260,
                          css_classes=["twin-gap"], linked_axes=True),
            sizing_mode="stretch_width", visible=s.twin)
        self.body = pn.Column(pn.Row(self.nudge, self.reset, sizing_mode="stretch_width"),
                              message(s, "twin"), self.text, built_when_shown(self.plots),
                              visible=s.twin, sizing_mode="stretch_width")
        s.param.watch(self._update, ["result", "twin", "nudge", "twin_x0", "twin_v0"])
        self._update()

    def __panel__(self):
        return pn.Card(self.switch, self.body, title="Sensitivity: a twin trajectory",
                       collapsed=False, sizing_mode="stretch_width", css_classes=["twin-card"])

    def _update(self, *_: Any) -> None:
        s = self.state
        self.body.visible = self.plots.visible = bool(s.twin)
        if not s.twin:
            return
        try:
            self.data = twin_runs(s)
            s.clear("twin")
        except ValueError as exc:
            self.data = None
            s.say("twin", f"The twin cannot start there: {exc}")
        self.text.object = twin_text(self.data)
        self.revision += 1

    # Each curve is framewise, not only the overlay: HoloViews re-frames an overlay from its
    # elements' own option, so an overlay first drawn empty (the twin off) kept [0, 1] for ever.
    def _paths(self, revision: int = 0) -> hv.Overlay:
        d = self.data
        t = d["t"] if d else np.zeros(0)
        xa = d["a"][0] if d else np.zeros(0)
        xb = d["b"][0] if d else np.zeros(0)
        return (hv.Curve((t, xa), "t / period", "x", label="first gear").opts(
                    color=ACTIVE_COLOR, framewise=True)
                * hv.Curve((t, xb), "t / period", "x", label="twin").opts(
                    color=REVERSE_COLOR, line_dash="dashed", framewise=True)).opts(
            hv.opts.Overlay(title="Both gears, x(t)", responsive=True, height=250, tools=TOOLS,
                            legend_position="top_left", framewise=True,
                            hooks=[save_as(lambda: "rattle_twin_paths")]))

    def _gap(self, revision: int = 0) -> hv.Overlay:
        d = self.data
        t = d["t"] if d else np.zeros(0)
        gap = d["distance"] if d else np.zeros(0)
        lam = d["lyapunov"] if d else math.nan
        slope = (t, gap[0] * np.exp(lam * t * TWO_PI)) if d and math.isfinite(lam) and lam > 0 \
            else (np.zeros(0), np.zeros(0))
        return (hv.Curve((t, gap), "t / period", "separation", label="|twin − first|").opts(
                    color="#222222", logy=True, framewise=True, hooks=[named_glyph("twin_gap")])
                * hv.Curve(slope, "t / period", "separation", label=SLOPE_LABEL).opts(
                    color="#8e44ad", line_dash="dotted", logy=True, framewise=True)).opts(
            hv.opts.Overlay(title="Separation in (x, ẋ), log scale", responsive=True, height=250,
                            tools=TOOLS, logy=True, legend_position="bottom_right",
                            framewise=True, hooks=[save_as(lambda: "rattle_twin_separation")]))

