"""Whether the current run's chaotic statistics depend on the noise level: a background check.

On a run that is not periodic, :class:`NoiseView` asks the session's job pool for
``rattle_core.noise_sensitivity`` (8 runs per level, levels 1e-12 … 1e-4 and the state's own)
and shows the answer as a badge: which statistic moves, over which levels, and what that means
for a real gearbox; or that the statistics hold, with the ensemble's interval at the state's
noise level. A periodic run needs no check: its statistics are exact. A newer run replaces the
check (the pool keeps one job per session and kind).
"""
from __future__ import annotations

import html
import math
from typing import Any

import panel as pn
import param

from ..state import ExplorerState
from ..ui.job_panel import JobPanel
from ..ui.labels import num
from ..work import tasks

RUNS, PERIODS, TRANSIENT = 8, 2000, 300
MEANING = ("For a real gearbox this means the rattle level depends on how much the impacts "
           "scatter, which the model cannot know: read the range as the answer, or measure "
           "the scatter.")


class NoiseView(pn.viewable.Viewer):
    """The noise-sensitivity badge of the current run (see the module docstring)."""

    state = param.ClassSelector(class_=ExplorerState)
    jobs = param.Parameter()

    def __init__(self, **params: Any):
        super().__init__(**params)
        self.badge = pn.pane.HTML("", css_classes=["noise-badge"], sizing_mode="stretch_width",
                                  visible=False)
        # the check's job: its progress and Cancel (``noise-progress``, ``noise-cancel``)
        self.run = JobPanel(self.jobs, "noise", "noise")
        self.run.cancel_button.on_click(lambda e: self._cancel())
        # Cancel shows only while a check runs: most runs are periodic and never start one
        self.run.cancel_button.visible = False
        self.run.progress.param.watch(
            lambda e: setattr(self.run.cancel_button, "visible", e.new), "visible")
        self.result: dict | None = None
        self._key: str | None = None
        self.state.param.watch(self._check, "result")
        self._check()

    def __panel__(self):
        return pn.Row(self.badge, self.run.progress, self.run.cancel_button,
                      sizing_mode="stretch_width")

    def _check(self, *_: Any) -> None:
        run = self.state.result
        if run is None:
            return
        key = run.params.key()
        if key == self._key:
            return
        self._key, self.result = key, None
        if run.cls.period > 0 or run.cls.impacts_per_period == 0:
            self.run.stop()
            self.badge.visible = False
            return
        self._show("checking whether the statistics depend on the noise level "
                   f"({RUNS} runs at each of 6 levels)…", "pending")
        self.run.submit(key, tasks.noise_check, (run.params, RUNS, PERIODS, TRANSIENT), "",
                        180.0, on_done=lambda out, p=run.params: self._done(p, out),
                        on_error=self._error)

    def _cancel(self) -> None:
        self.run.stop()
        self._show("noise check cancelled", "cancelled")

    def _done(self, params: Any, out: dict) -> None:
        self.result = out
        if out["sensitive"]:
            self._show(f"{out['describe']}. {MEANING}", "sensitive")
            return
        table = out["table"]
        i = min(range(len(table["noise"])), key=lambda k: abs(table["noise"][k] - params.noise))
        v, ci = table["mean_active_impulse"][i], table["mean_active_impulse_ci95"][i]
        where = (f"mean active impulse {num(v)} ± {num(ci, 2)} over {RUNS} runs at noise "
                 f"{params.noise:g}" if math.isfinite(v) else "")
        self._show(f"{out['describe']}: {where}", "steady")

    def _error(self, msg: str) -> None:
        self._show(f"the noise check could not run: {msg}", "failed")

    def _show(self, text: str, kind: str) -> None:
        self.badge.object = (f'<div class="noise-check" data-kind="{kind}">'
                             f"{html.escape(text)}</div>")
        self.badge.visible = True
