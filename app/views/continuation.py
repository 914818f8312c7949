"""Continuation in the Explorer: "Continue this orbit", the branch on the diagram, its multipliers.

:class:`ContinuationView` sits under the bifurcation diagram. On a periodic regime its button
records in the state where the orbit is taken (``continuation``, ``cont_from``: both in the
URL), and the view runs :func:`app.work.branch.continue_both_ways` as the session's
``continuation`` job (progress, cancel, killed with the session; disk-cached, so a reopened
link redraws the branch from the cache). The result goes to ``state.branch``, which the
diagram draws with :class:`app.ui.branch_glyphs.BranchGlyphs`: stable parts solid, unstable
parts dashed, bifurcations marked and labelled, each branch in its own colour with a legend
entry that names its period and where it starts (the branches that period doublings start, the cascade,
are followed in the same job). Beside the status, a small plot shows the Floquet
multipliers of the branch point nearest the current value of the swept parameter against the
unit circle.

The branch belongs to the parameters it was computed for: moving the swept parameter keeps
it (and moves the multipliers' point along it), any other change drops it.
"""
from __future__ import annotations

import html
from typing import Any

import holoviews as hv
import numpy as np
import panel as pn
import param

from ..work.branch import FIND_TRANSIENT, Branch, from_job, continue_both_ways, is_periodic
from ..core import paper_phi2_to_core
from ..work.diagram_data import current_value, diagram_key, full_range
from ..state import ExplorerState
from ..ui.plots import HoloViewsPane, named_glyph
from ..ui.labels import not_periodic_text
from ..ui.widgets import message

STABLE_COLOR, UNSTABLE_COLOR = "#1e8449", "#c0392b"


def swept(state: ExplorerState) -> str:
    """The diagram's swept parameter (Λ while the physical side is not available)."""
    run = state.result
    return "lam" if state.bif == "rpm" and (run is None or run.phys is None) else state.bif


def core_bounds(name: str, phases: str, lo: float, hi: float) -> tuple[float, float]:
    """The diagram's axis range in the continuation's units (φ₂ in the core's convention)."""
    if name == "phi2" and phases == "paper":
        a, b = paper_phi2_to_core(np.array([lo, hi]))
        return float(min(a, b)), float(max(a, b))
    return float(lo), float(hi)


_named = named_glyph


def multipliers_element(branch: Branch | None, value: float) -> hv.Overlay:
    """The Floquet multipliers of the branch point nearest ``value`` and the unit circle."""
    th = np.linspace(0.0, 2.0 * np.pi, 181)
    circle = hv.Curve((np.cos(th), np.sin(th)), "Re μ", "Im μ").opts(color="#7f8c8d", line_width=1)
    point = branch.nearest(value) if branch is not None else None
    mu = point["multipliers"] if point is not None else np.array([complex(np.nan, np.nan)])
    stable = point is not None and point["stable"]
    pts = hv.Points((mu.real, mu.imag), ["Re μ", "Im μ"]).opts(
        color=STABLE_COLOR if stable else UNSTABLE_COLOR, size=9, hooks=[_named("cont-multipliers")])
    title = ("Floquet multipliers" if point is None else
             f"μ at {point['x']:.5g} ({'stable' if stable else 'unstable'})")
    lim = max(1.15, float(np.max(np.abs(mu))) * 1.1 if point is not None else 1.15)
    return (circle * pts).opts(hv.opts.Overlay(
        title=title, width=230, height=230, xlim=(-lim, lim), ylim=(-lim, lim),
        data_aspect=1, toolbar=None, fontsize={"title": "9pt"}))


class ContinuationView(pn.viewable.Viewer):
    """Continue the current periodic orbit over the diagram's range; see the module docstring."""

    state = param.ClassSelector(class_=ExplorerState)
    jobs = param.Parameter()
    point = param.Number(default=None, allow_None=True,
                         doc="the branch point whose multipliers are drawn (its parameter value)")

    def __init__(self, **params: Any):
        super().__init__(**params)
        self._key: tuple | None = None
        self._job = None
        self.button = pn.widgets.Button(label="Continue this orbit", color="primary",
                                        css_classes=["cont-button"], width=170)
        self.cancel_button = pn.widgets.Button(label="Cancel", disabled=True, width=80,
                                               css_classes=["cont-cancel"])
        self.clear_button = pn.widgets.Button(label="Hide branch", width=110,
                                              css_classes=["cont-clear"])
        self.button.on_click(lambda e: self.start())
        self.cancel_button.on_click(lambda e: self.cancel("Continuation cancelled."))
        self.clear_button.on_click(lambda e: self.state.param.update(continuation=False))
        self.progress = pn.indicators.Progress(value=0, max=100, visible=False, bar_color="info",
                                               height=14, sizing_mode="stretch_width",
                                               css_classes=["cont-progress"])
        self.status = pn.pane.HTML("", css_classes=["cont-status"], margin=(0, 10),
                                   sizing_mode="stretch_width")
        self.why = pn.pane.HTML("", css_classes=["cont-why"], margin=(0, 10),
                                sizing_mode="stretch_width")
        # redrawn when the nearest branch point changes, not on every run: a slider move
        # without a branch costs the multipliers plot nothing
        self.multipliers = hv.DynamicMap(self._multipliers, streams=[
            hv.streams.Params(self.state, ["branch"]), hv.streams.Params(self, ["point"])])
        self.state.param.watch(self._follow_point, ["result", "branch"])
        self.pane = HoloViewsPane(self.multipliers, css_classes=["cont-multipliers"],
                                  width=240, height=240)
        self.state.param.watch(self._update, ["result", "bif", "phases", "continuation",
                                              "cont_from"])
        self._update()

    def __panel__(self):
        # the buttons wrap in a narrow column instead of running over the multipliers' plot
        buttons = pn.FlexBox(self.button, self.cancel_button, self.clear_button, flex_wrap="wrap",
                             sizing_mode="stretch_width")
        # and the multipliers' plot goes below them when the two do not fit side by side
        return pn.FlexBox(
            pn.Column(buttons, self.why, message(self.state, "continuation"), self.progress,
                      self.status, sizing_mode="stretch_width", min_width=200),
            self.pane, flex_wrap="wrap", sizing_mode="stretch_width", css_classes=["continuation"])

    # ----- what to compute ----------------------------------------------------------------------

    def context(self) -> tuple | None:
        """What the branch depends on besides its start: the diagram and the run's start state."""
        s, run = self.state, self.state.result
        if run is None:
            return None
        name = swept(s)
        return (diagram_key(name, s.phases, run.params, run.phys), s.x0, s.v0, s.t0,
                max(s.transient, FIND_TRANSIENT))

    def start(self) -> None:
        """Continue the orbit of the current run (the button)."""
        s = self.state
        if s.result is None or not is_periodic(s.result.cls):
            s.say("continuation", "Continuation starts from a periodic regime; this run is not periodic.")
            return
        value = current_value(swept(s), s)
        if s.continuation and s.cont_from == value and self._key is not None:
            return
        s.param.update(continuation=True, cont_from=value)

    def _update(self, *_: Any) -> None:
        s, run = self.state, self.state.result
        computing = self._job is not None
        self.button.disabled = computing or run is None or not is_periodic(run.cls)
        why = "" if run is None or is_periodic(run.cls) else not_periodic_text(run.cls)
        if self.why.object != why:
            self.why.object = why
        self.clear_button.visible = bool(s.continuation)
        if run is None:
            return
        if not s.continuation:
            if self._key is not None or s.branch is not None:
                self._drop()
            return
        ctx = self.context()
        start = s.cont_from if s.cont_from is not None else current_value(swept(s), s)
        if self._key is not None and self._key[0] != ctx:
            self._drop("The continued branch was for other parameters; it is hidden.")
            s.param.update(continuation=False, cont_from=None)
            return
        if self._key == (ctx, start):
            return
        self._key = (ctx, start)
        self._submit(ctx, start)

    def _submit(self, ctx: tuple, start: float) -> None:
        s, run = self.state, self.state.result
        name = swept(s)
        phys = run.phys.with_rpm(start) if name == "rpm" else None
        params = (phys.to_dimensionless() if phys is not None
                  else run.params.with_value(name, _core_value(name, s.phases, start)))
        bounds = core_bounds(name, s.phases, *full_range(name, s.phases, start))
        find = {"x0": s.x0, "v0": s.v0, "t0": s.t0, "transient": ctx[-1]}
        key = self._key
        s.clear("continuation")
        s.branch = None
        self.status.object = _text(f"Continuing the orbit found at {start:.6g} over "
                                   f"[{bounds[0]:.4g}, {bounds[1]:.4g}], both ways…")
        self.progress.param.update(value=0, visible=True)
        try:
            self._job = self.jobs.submit(
                "continuation", continue_both_ways, (params, phys, name, bounds, find),
                time_limit=120.0, on_progress=lambda f: self._progress(key, f),
                on_done=lambda out: self._done(key, out, name, run.phys, start),
                on_error=lambda msg: self._error(key, msg))
        except RuntimeError as exc:
            self._error(key, str(exc))
            return
        self.button.disabled, self.cancel_button.disabled = True, False

    # ----- the job's outcome --------------------------------------------------------------------

    def _progress(self, key: tuple, fraction: float) -> None:
        if key == self._key:
            self.progress.value = int(100 * fraction)

    def _done(self, key: tuple, out: dict, name: str, phys: Any, start: float) -> None:
        if key != self._key:
            return
        self._finished()
        branch = from_job(name, self.state.phases, phys, key, start, out)
        self.status.object = _text(branch.summary())
        self.state.branch = branch

    def _error(self, key: tuple, msg: str) -> None:
        if key != self._key:
            return
        self._finished()
        self._key = None
        self.status.object = ""
        self.state.say("continuation", f"The orbit could not be continued: {msg}")
        self.state.param.update(continuation=False, cont_from=None)

    def _finished(self) -> None:
        self._job = None
        self.progress.visible = False
        self.cancel_button.disabled = True
        run = self.state.result
        self.button.disabled = run is None or not is_periodic(run.cls)

    def cancel(self, text: str | None = None) -> None:
        """Stop the running continuation and hide the branch."""
        if self._job is not None:
            self._job.cancel()
        self._drop(text)
        self.state.param.update(continuation=False, cont_from=None)

    def _drop(self, text: str | None = None) -> None:
        if self._job is not None:
            self._job.cancel()
        self._finished()
        self._key = None
        if self.state.branch is not None:
            self.state.branch = None
        self.status.object = _text(text) if text else ""

    # ----- elements -----------------------------------------------------------------------------

    def _follow_point(self, *_: Any) -> None:
        s = self.state
        near = (s.branch.nearest(current_value(swept(s), s))
                if s.branch is not None and s.result is not None else None)
        self.point = None if near is None else float(near["x"])

    def _multipliers(self, branch: Any = None, point: float | None = None) -> hv.Overlay:
        return multipliers_element(branch, np.nan if point is None else point)


def _core_value(name: str, phases: str, value: float) -> float:
    """An axis value of the swept parameter in the core's terms (φ₂ in its convention)."""
    if name == "phi2" and phases == "paper":
        return float(paper_phi2_to_core(np.array([value]))[0])
    return float(value)


def _text(text: str) -> str:
    return f'<div style="font-size:12px;color:#444">{html.escape(text)}</div>'
