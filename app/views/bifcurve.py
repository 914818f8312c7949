"""A bifurcation of the continued branch, traced in a second parameter.

:class:`CurveView` sits under "Continue this orbit". A click on a marked bifurcation of the
branch (a fold, a period doubling, a grazing, an onset of sticking) moves the diagram's
parameter onto it; the view then records it in the state (``curve_kind``, ``curve_at``, with
``curve_param2`` chosen from a list: all three in the URL) and runs
:func:`app.work.atlas.bifurcation_curve` as the session's ``curve`` job (progress, cancel,
disk cache). The curve is drawn with the diagram's parameter across and the second one up,
in its kind's line style, with its codimension-two points and the current parameters marked.
"""
from __future__ import annotations

from typing import Any

import holoviews as hv
import numpy as np
import panel as pn
import param

from ..core import CURVE_STYLES
from ..state import ExplorerState
from ..ui.job_panel import JobPanel
from ..ui.plots import HoloViewsPane
from ..ui.widgets import Choice, built_when_shown, message
from ..work.atlas import Curves, bifurcation_curve, from_job, to_core
from ..work.branch import FIND_TRANSIENT
from ..work.diagram_data import current_value, full_range
from .atlas import curves_overlay
from .continuation import core_bounds, swept

PARAMS2 = {"Λ": "lam", "r": "r", "j": "j", "H₂/H₁": "h2", "φ₂ [°]": "phi2"}
RANGES2 = {"lam": (0.5, 4.0), "r": (0.3, 0.95), "j": (2.0, 16.0), "h2": (0.0, 1.0),
           "phi2-paper": (0.0, 360.0), "phi2-core": (-180.0, 180.0)}
KINDS = ("fold", "period_doubling", "grazing", "stick_onset", "stick_end")
#: A click lands on a mark when it is this close, as a share of the diagram's range.
CLICK_TOLERANCE = 0.004


class CurveView(pn.viewable.Viewer):
    """Trace a marked bifurcation of the branch in a second parameter (module docstring)."""

    state = param.ClassSelector(class_=ExplorerState)
    jobs = param.Parameter()
    revision = param.Integer(0)

    def __init__(self, **params: Any):
        super().__init__(**params)
        self.curves: Curves | None = None
        self.run = JobPanel(self.jobs, "curve", "curve")
        self.hide_button = pn.widgets.Button(label="Hide curve", width=100,
                                             css_classes=["curve-hide"])
        self.run.cancel_button.on_click(lambda e: self.cancel("Tracing cancelled."))
        self.hide_button.on_click(lambda e: self.state.param.update(curve_kind="", curve_at=None))
        self.run.say("Click a marked bifurcation of the continued branch to trace its curve in "
                     "a second parameter.")
        self.element = hv.DynamicMap(self._element, streams=[
            hv.streams.Params(self, ["revision"]), hv.streams.Params(self.state, ["result"])])
        # shown once a curve is traced: before that it would be an empty 0–1 plot
        self.pane = HoloViewsPane(self.element, css_classes=["curve-plot"], width=380, height=300,
                                  visible=False)
        self.holder = built_when_shown(self.pane)
        self.param.watch(lambda e: setattr(self.pane, "visible", self.curves is not None),
                         "revision")
        self.state.param.watch(self._on_click, ["result", "branch"])
        self.state.param.watch(self._update, ["curve_kind", "curve_at", "curve_param2",
                                              "branch"])
        self._update()

    def __panel__(self):
        return pn.Column(
            pn.Row(Choice(self.state, "curve_param2", PARAMS2, select=True, width=160),
                   self.run.cancel_button, self.hide_button),
            message(self.state, "curve"), self.run.progress, self.run.status, self.holder,
            sizing_mode="stretch_width", css_classes=["bifurcation-curve"])

    # ----- which bifurcation ------------------------------------------------------------------

    def marked(self) -> tuple[str, float] | None:
        """The bifurcation of the branch the diagram's parameter sits on, if any."""
        s = self.state
        b = s.branch
        if b is None or s.result is None or not len(b.marks):
            return None
        value = current_value(swept(s), s)
        lo, hi = full_range(swept(s), s.phases, value)
        # the continued orbit's own bifurcations: the tracer starts from that branch alone
        marks = b.marks[b.marks["kind"].isin(KINDS) & (b.marks["branch"] == 0)]
        if not len(marks):
            return None
        d = np.abs(marks["x"].to_numpy() - value)
        i = int(np.argmin(d))
        if d[i] > CLICK_TOLERANCE * (hi - lo):
            return None
        return str(marks["kind"].iloc[i]), float(marks["x"].iloc[i])

    def _on_click(self, *_: Any) -> None:
        hit = self.marked()
        s = self.state
        if hit is not None and (hit[0] != s.curve_kind or hit[1] != s.curve_at):
            s.param.update(curve_kind=hit[0], curve_at=hit[1])

    # ----- the job ------------------------------------------------------------------------------

    def request(self) -> tuple | None:
        s, b, run = self.state, self.state.branch, self.state.result
        if not s.curve_kind or s.curve_at is None or b is None or run is None:
            return None
        name = swept(s)
        if s.curve_param2 == name:
            s.say("curve", f"The second parameter must differ from the diagram's ({name}).")
            return None
        start = b.start
        phys = run.phys.with_rpm(start) if name == "rpm" else None
        core_start = to_core(name, s.phases, start, start)[0]
        params = (phys.to_dimensionless() if phys is not None
                  else run.params.with_value(name, core_start))
        bounds = core_bounds(name, s.phases, *full_range(name, s.phases, start))
        find = {"x0": s.x0, "v0": s.v0, "t0": s.t0, "transient": max(s.transient, FIND_TRANSIENT)}
        p2 = s.curve_param2
        lo, hi = RANGES2[f"phi2-{s.phases}" if p2 == "phi2" else p2]
        at = to_core(name, s.phases, s.curve_at, s.curve_at)[0]
        return (params, phys, name, bounds, find, s.curve_kind, at, p2,
                to_core(p2, s.phases, lo, hi))

    def _update(self, *_: Any) -> None:
        s = self.state
        self.hide_button.visible = bool(s.curve_kind)
        req = self.request()
        if req is None:
            if not s.curve_kind and (self.run.key is not None or self.curves is not None):
                self._drop()
            return
        key = (repr(req[0].canonical()), repr(req[1]), *req[2:4], tuple(req[4].items()),
               *req[5:8], req[8])
        if key == self.run.key:
            return
        s.clear("curve")
        self.run.submit(key, bifurcation_curve, req,
                        f"Tracing the {s.curve_kind.replace('_', ' ')} at {s.curve_at:.6g} in "
                        f"{req[7]}…", 180.0, lambda out: self._done(out, req[2], req[7]),
                        lambda msg: s.say("curve", f"The curve could not be traced: {msg}"))

    def _done(self, out: dict, name: str, p2: str) -> None:
        self.curves = from_job(out, self.state.phases, name, p2)
        meta = out["meta"]
        self.run.say(f"{meta.get('from', '')} Traced in {p2}: {self.curves.summary()}. "
                     f"{meta.get('message', '')}")
        self.revision += 1

    def cancel(self, text: str | None = None) -> None:
        """Stop tracing and forget the bifurcation chosen."""
        self._drop(text)
        self.state.param.update(curve_kind="", curve_at=None)

    def _drop(self, text: str | None = None) -> None:
        self.run.stop(text)
        self.curves = None
        self.revision += 1

    def _element(self, revision: int = 0, result: Any = None) -> hv.Overlay:
        s = self.state
        here = hv.Points([]).opts(marker="circle_cross", size=12, fill_color=None,
                              line_color="black", line_width=2)
        if self.curves is not None and s.result is not None:
            y = s.phi2 if s.curve_param2 == "phi2" else getattr(s, s.curve_param2)
            here = hv.Points([(current_value(swept(s), s), float(y))]).opts(
                marker="circle_cross", size=12, fill_color=None, line_color="black",
                line_width=2)
        kind = CURVE_STYLES.get(s.curve_kind)
        return (curves_overlay(self.curves, "curve") * here).opts(hv.opts.Overlay(
            title=f"{kind.label if kind else ''}", fontsize={"title": "9pt"}, toolbar=None))

