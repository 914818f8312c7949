"""The gear in motion: the idle gear's tooth between the driving tooth and the opposite tooth, played.

:class:`MotionView` draws three teeth as polygons: a tooth of the driving gear (its active
flank at ``y``), the idle gear's tooth and the driving gear's next tooth (its reverse flank
at ``y + j``). For every run it samples the exact solution (``Trajectory.sample``,
``Trajectory.walls``) at frame times over the window the time history shows, impact
instants included (:func:`motion_frames`), and sends the frames to the browser once, as a
``ColumnDataSource``.

Play, Pause, "Next impact", Loop, the speed and the sound switch are Bokeh widgets whose
``CustomJS`` callbacks share one clock (:mod:`app.ui.motion_js`): a ``requestAnimationFrame``
loop in the page moves the teeth, flashes each impact in its flank's colour (both painted on a
plain canvas over this figure, from the sources ``motion_teeth`` and ``motion_flash``) and
moves a cursor along the time history (the ``Span`` named ``th_cursor``), without a message
to the server per frame. Nothing of the animation is state: it is how the page plays one run.

Speed: from 0.01× to 1× of real time in physical-units mode (time in ms, the engine's time
scale), or of one forcing period per second in dimensionless mode. The rattle sound of the
sound card starts with the animation, at its instant and played at the same speed, in
physical-units mode, where both run on the engine's time, and at speeds the browser's audio
allows (1/16× and above); otherwise the animation plays silent.
"""
from __future__ import annotations

from typing import Any

import numpy as np
import panel as pn
import param
from bokeh.layouts import column, row
from bokeh.models import (Button, ColumnDataSource, CustomJS, CustomJSTickFormatter, Div,
                          Range1d, Slider, Toggle)
from bokeh.plotting import figure

from ..state import ExplorerState
from ..ui.labels import ACTIVE_COLOR, GEAR_COLOR, REVERSE_COLOR, TOOTH_COLOR
from ..ui.motion_js import MOTION_JS
from ..ui.present import figure_fonts, presents
from .present import present_button
from ..ui.plots import time_history_data
from ..work.threads import writes_bokeh

#: Frames per forcing period, and most frames per run (more periods shown: fewer per period).
FRAMES_PER_PERIOD, MIN_FRAMES_PER_PERIOD, MAX_FRAMES = 400, 24, 40_000
#: Speed range, as multiples of real time (physical units) or of one period per second.
SPEED_RANGE = (0.01, 1.0)
DEFAULT_SPEED = 0.1
#: Tooth heights: the driving teeth hang from above, the idle tooth stands from below; they
#: overlap between 0.2 and 0.8, and the pitch line (where the model's flanks are) is at 0.5.
DRIVING_V = (1.2, 1.2, 0.2, 0.2)
IDLE_V = (-0.2, -0.2, 0.8, 0.8)


def tooth_size(j: float) -> tuple[float, float]:
    """Tooth thickness ``d`` on the pitch line and flank slant ``k`` for a drawn backlash ``j``."""
    d = 0.75 * abs(j)
    return d, 0.5 * d


def teeth_xs(x: float, y: float, j: float) -> list[list[float]]:
    """Vertex abscissae of the driving tooth, the idle tooth and the opposite tooth.

    On the pitch line the driving tooth's flank is at ``y``, the idle tooth spans
    ``[x, x + d]`` and the opposite tooth's flank is at ``y + j + d``. Facing flanks are
    parallel, so the drawn gaps are ``x − y`` and ``y + j − x`` at every height.
    """
    d, k = tooth_size(j)
    yj = y + j
    return [[y - d - 0.7 * k, y + 0.7 * k, y - 0.3 * k, y - d + 0.3 * k],
            [x - 0.7 * k, x + d + 0.7 * k, x + d - 0.3 * k, x + 0.3 * k],
            [yj + d - 0.7 * k, yj + 2 * d + 0.7 * k, yj + 2 * d - 0.3 * k, yj + d + 0.3 * k]]


def motion_frames(tr: Any, shown: int, phys: Any = None, angle: bool = False) -> dict[str, Any]:
    """The frames of a run over its first ``shown`` recorded periods, in the time history's units.

    Returns ``frames`` (``t``, ``x``, ``y``: exact samples, every impact instant among
    them), ``impacts`` (``t``, ``flank``), ``meta`` (one row: drawn backlash ``j``, tooth
    size ``d``, ``k``, ``rate`` = time units per second at 1×, ``real``, ``period``,
    ``unit``, colours) and ``labels`` (the time history's axis labels).
    """
    shown = max(1, min(int(shown), int(tr.periods)))
    per = int(np.clip(MAX_FRAMES // shown, MIN_FRAMES_PER_PERIOD, FRAMES_PER_PERIOD))
    data = time_history_data(tr, shown, phys, angle, points_per_period=per)
    m, imp = data["motion"], data["impacts"]
    j = float(m["yj"][0] - m["y"][0])
    d, k = tooth_size(j)
    real = phys is not None
    period = 1e3 * phys.period_s if real else 2.0 * np.pi
    meta = {"j": [j], "d": [d], "k": [k], "rate": [1e3 if real else 2.0 * np.pi],
            "real": [int(real)], "period": [period], "unit": [data["labels"][0]],
            "active": [ACTIVE_COLOR], "reverse": [REVERSE_COLOR], "tooth": [TOOTH_COLOR],
            "gear": [GEAR_COLOR]}
    return {"frames": {"t": np.asarray(m["t"], float), "x": np.asarray(m["x"], float),
                       "y": np.asarray(m["y"], float)},
            "impacts": {"t": np.asarray(imp["t"], float),
                        "flank": np.asarray(imp["flank"], dtype=np.int32)},
            "meta": meta, "labels": data["labels"]}


def motion_figure() -> tuple[Any, dict[str, Any]]:
    """The figure, its sources and its controls, wired to the shared clock."""
    src = {"frames": ColumnDataSource({"t": [], "x": [], "y": []}, name="motion_frames"),
           "impacts": ColumnDataSource({"t": [], "flank": []}, name="motion_impacts"),
           "meta": ColumnDataSource({k: [] for k in ("j", "d", "k", "rate", "real", "period",
                                                     "unit", "active", "reverse", "tooth", "gear")},
                                    name="motion_meta"),
           "teeth": ColumnDataSource({"xs": [[np.nan] * 4] * 3, "ys": [list(DRIVING_V),
                                                                    list(IDLE_V), list(DRIVING_V)],
                                      "fill": [TOOTH_COLOR, GEAR_COLOR, TOOTH_COLOR],
                                      "line": [TOOTH_COLOR, GEAR_COLOR, TOOTH_COLOR],
                                      "part": ["driving tooth", "idle gear", "opposite tooth"]},
                                     name="motion_teeth"),
           "flash": ColumnDataSource({"x": [np.nan], "y": [0.5], "color": [ACTIVE_COLOR],
                                      "alpha": [0.0]}, name="motion_flash")}
    p = figure(height=210, sizing_mode="stretch_width", toolbar_location=None,
               x_range=Range1d(-1, 1), y_range=Range1d(-0.55, 1.55), output_backend="canvas",
               name="motion", title="The gear in motion: driving tooth · idle gear · opposite tooth")
    p.yaxis.visible = False
    p.ygrid.visible = False
    p.title.text_font_size = "10pt"
    p.hbar(y=1.375, height=0.35, left=-1e9, right=1e9, color=TOOTH_COLOR, alpha=0.35)
    p.hbar(y=-0.375, height=0.35, left=-1e9, right=1e9, color=GEAR_COLOR, alpha=0.25)
    p.patches("xs", "ys", source=src["teeth"], fill_color="fill", line_color="line",
              line_width=3, fill_alpha=0.85, name="motion_patches", level="overlay")
    p.scatter("x", "y", source=src["flash"], size=30, fill_color="color", fill_alpha="alpha",
              line_alpha=0.0, name="motion_burst", level="overlay")
    p.add_layout(_pitch_line())
    w = {"play": Button(label="▶ Play", button_type="primary", width=90, name="motion_play",
                        css_classes=["motion-play"]),
         "pause": Button(label="Pause", width=90, name="motion_pause", css_classes=["motion-pause"]),
         "next": Button(label="Next impact", width=120, name="motion_next",
                        css_classes=["motion-next"]),
         "loop": Toggle(label="Loop", active=True, width=70, name="motion_loop",
                        css_classes=["motion-loop"]),
         "sound": Toggle(label="♪ Sound", active=False, width=90, name="motion_sound",
                         css_classes=["motion-sound"]),
         "speed": Slider(start=np.log10(SPEED_RANGE[0]), end=np.log10(SPEED_RANGE[1]),
                         value=np.log10(DEFAULT_SPEED), step=0.01, title="speed", width=220,
                         name="motion_speed", css_classes=["motion-speed"],
                         format=CustomJSTickFormatter(code="return Math.pow(10, tick).toPrecision(2) + '×'")),
         "clock": Div(text="", name="motion_clock", css_classes=["motion-clock"], width=360,
                      styles={"font-size": "12px", "color": "#444", "white-space": "nowrap"})}
    args = {"frames": src["frames"], "impacts": src["impacts"], "meta": src["meta"],
            "teeth": src["teeth"], "flash": src["flash"], "speed": w["speed"], "loop": w["loop"],
            "sound": w["sound"], "clock": w["clock"]}

    def cb(action: str) -> CustomJS:
        return CustomJS(args={**args, "action": action}, code=MOTION_JS)
    for name in ("play", "pause", "next"):
        w[name].js_on_event("button_click", cb(name))
    w["speed"].js_on_change("value", cb("speed"))
    w["sound"].js_on_change("active", cb("sound"))
    src["frames"].js_on_change("data", cb("data"))
    # the controls wrap onto a second line where the page is narrow, never past its edge
    layout = column(p, row(w["play"], w["pause"], w["next"], w["loop"], w["sound"], w["speed"],
                           w["clock"], styles={"flex-wrap": "wrap"}, sizing_mode="stretch_width"),
                    sizing_mode="stretch_width")
    return layout, {**src, **w, "figure": p}


def _pitch_line() -> Any:
    from bokeh.models import Span
    return Span(location=0.5, dimension="width", line_color="#bbbbbb", line_dash="dotted",
                line_width=1)


class MotionView(pn.viewable.Viewer):
    """The current run played as moving teeth (see the module docstring)."""

    state = param.ClassSelector(class_=ExplorerState)

    def __init__(self, **params: Any):
        super().__init__(**params)
        self.layout, self.parts = motion_figure()
        self.pane = pn.pane.Bokeh(self.layout, sizing_mode="stretch_width",
                                  css_classes=["motion"])
        self.present_button = present_button(self.state, "motion")
        self.view = pn.Column(self.present_button, self.pane, sizing_mode="stretch_width",
                              margin=0)
        self.data: dict[str, Any] | None = None
        self.state.param.watch(self.draw, ["result", "shown", "backlash_unit"])
        self.state.param.watch(self._present, ["present", "stage"])
        self.draw()
        self._present()

    def __panel__(self):
        return self.view

    @writes_bokeh
    def _present(self, *_: Any) -> None:
        """Presented, the drawing fills its cell beside the time history, with larger fonts."""
        on = presents(self.state, "motion")
        fig = self.parts["figure"]
        figure_fonts(fig, on)
        mode = "stretch_both" if on else "stretch_width"
        # set on the Bokeh models, not the pane: the pane would copy their stylesheets back
        # into its own parameters, which take only strings
        self.view.sizing_mode = mode
        for model in (self.layout, fig):
            if model.sizing_mode != mode:
                model.sizing_mode = mode
        self.parts["clock"].styles = {**self.parts["clock"].styles,
                                      "font-size": "17px" if on else "12px"}

    @writes_bokeh
    def draw(self, *_: Any) -> None:
        """Send the current run's frames (and its first frame's teeth) to the page."""
        run = self.state.result
        if run is None:
            return
        data = motion_frames(run.tr, self.state.shown, run.phys,
                             angle=self.state.backlash_unit == "deg")
        self.data = data
        f, j = data["frames"], data["meta"]["j"][0]
        d, k = tooth_size(j)
        lo = float(np.min(f["y"])) - d - 0.7 * k
        hi = float(np.max(f["y"])) + j + 2 * d + 0.7 * k
        pad = 0.05 * (hi - lo)
        p = self.parts
        p["figure"].x_range.update(start=lo - pad, end=hi + pad)
        p["figure"].xaxis.axis_label = data["labels"][1]
        p["teeth"].data = {**p["teeth"].data, "xs": teeth_xs(f["x"][0], f["y"][0], j),
                           "line": [TOOTH_COLOR, GEAR_COLOR, TOOTH_COLOR]}
        p["flash"].data = {"x": [np.nan], "y": [0.5], "color": [ACTIVE_COLOR], "alpha": [0.0]}
        p["meta"].data = data["meta"]
        p["impacts"].data = data["impacts"]
        p["frames"].data = data["frames"]  # last: its change restarts the page's clock
