"""Whether the current run's chaotic statistics depend on the noise level: a background check.

On a run that is not periodic, :class:`NoiseView` asks the session's job pool for
``rattle_core.noise_sensitivity`` (8 runs per level, levels 1e-12 … 1e-4 and the state's own)
and shows the answer as a badge: which statistic moves, over which levels, and what that means
for a real gearbox; or that the statistics hold, with the ensemble's interval at the state's
noise level. A periodic run needs no check: its statistics are exact. A newer run replaces the
check (the pool keeps one job per session and kind).

Where the ensemble's runs end on several attractors, the badge says so and how many runs each
took; the figures it shows are those of the attractor the run on screen is on (matched by
regime, period and impulse), with that attractor's own interval, and each attractor gets its
own noise verdict. When no run of the ensemble reached the run on screen's attractor, the
badge says that instead of borrowing another attractor's numbers.
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
        run = self.state.result
        cls = run.cls if run is not None and run.params.key() == params.key() else None
        self._show(*badge_text(out, params.noise, cls))

    def _error(self, msg: str) -> None:
        self._show(f"the noise check could not run: {msg}", "failed")

    def _show(self, text: str, kind: str) -> None:
        self.badge.object = (f'<div class="noise-check" data-kind="{kind}">'
                             f"{html.escape(text)}</div>")
        self.badge.visible = True


def _interval(value: float, ci95: float) -> str:
    """A value with its 95 % half-width, or why it has none."""
    if not math.isfinite(value):
        return "–"
    if ci95 == 0.0:
        return f"{num(value)} (exact: a periodic orbit)"
    if not math.isfinite(ci95):
        return f"{num(value)} (one run: no interval)"
    return f"{num(value)} ± {num(ci95, 2)}"


def _names(attractors: list[dict]) -> list[str]:
    """Short names for the badge: the regime letter where it tells the attractors apart."""
    letters = [a["regime"] for a in attractors]
    labels = [a["label"] for a in attractors]
    out = []
    for a in attractors:
        if letters.count(a["regime"]) == 1:
            out.append(a["regime"])
        elif labels.count(a["label"]) == 1:
            out.append(a["label"])
        else:
            k = sum(1 for b in attractors[:attractors.index(a)] if b["label"] == a["label"])
            out.append(f"{a['label']} #{k + 1}")
    return out


def match_attractor(attractors: list[dict], level: int, cls: Any) -> int | None:
    """Which of ``attractors`` the classified run ``cls`` is on, at level index ``level``.

    A periodic run matches an attractor of its regime and period whose mean active impulse
    agrees within 1 % (the widest blur the ensemble still calls periodic); a non-periodic run
    matches a non-periodic attractor, of its own regime letter first (a short run's Lyapunov
    estimate may name the same cloud otherwise).  The nearest impulse wins; ``None`` when no
    attractor reached at that level fits.
    """
    best, gap = None, (math.inf, math.inf)
    mine = cls.mean_impulse_active
    for k, a in enumerate(attractors):
        if a["runs"][level] == 0 or a["period"] != cls.period:
            continue
        if cls.period > 0 and a["regime"] != cls.regime:
            continue
        v = a["estimates"]["mean_active_impulse"][level][0]
        if math.isfinite(v) and math.isfinite(mine):
            d = abs(v - mine) / max(abs(mine), 1e-12)
        else:
            d = 0.0 if math.isfinite(v) == math.isfinite(mine) else math.inf
        if cls.period > 0 and d > 1e-2:
            continue
        key = (0 if a["regime"] == cls.regime else 1, d)
        if key < gap:
            best, gap = k, key
    return best


def badge_text(out: dict, noise: float, cls: Any = None) -> tuple[str, str]:
    """The badge's sentence and kind (``sensitive`` or ``steady``) for a noise check's ``out``.

    ``noise``: the run on screen's level; ``cls``: its classification (``None`` when it is not
    known, and then the largest attractor's figures are shown, named as such).
    """
    levels = list(out["levels"])
    runs = int(out.get("runs", RUNS))
    i = min(range(len(levels)), key=lambda k: abs(levels[k] - noise))
    span = f"{levels[0]:g}…{levels[-1]:g}"
    here = [a for a in out.get("attractors", []) if a["runs"][i] > 0]
    here.sort(key=lambda a: -a["runs"][i])
    if not here:
        return (f"{out['describe']}. {MEANING}", "sensitive") if out["sensitive"] else (
            out["describe"], "steady")
    names = _names(here)
    k = match_attractor(here, i, cls) if cls is not None else 0
    parts = []
    if len(here) > 1:
        parts.append(f"{len(here)} attractors at noise {levels[i]:g}: " + ", ".join(
            f"{n} ({a['runs'][i]} of {runs} runs)" if j == 0 else f"{n} ({a['runs'][i]})"
            for j, (n, a) in enumerate(zip(names, here))) + ".")
    if k is None:
        parts.append(f"The run on screen ({cls.regime}) is on an attractor none of the {runs} "
                     "runs reached: it has no interval here.")
        sensitive = out["sensitive"]
    else:
        a = here[k]
        v, ci = a["estimates"]["mean_active_impulse"][i]
        whose = "The run on screen is on" if cls is not None else "Most runs are on"
        if len(here) > 1:
            parts.append(f"{whose} {names[k]}: mean active impulse {_interval(v, ci)} over "
                         f"its {a['runs'][i]} runs.")
        else:
            parts.append(f"{a['label']}: mean active impulse {_interval(v, ci)} over "
                         f"{a['runs'][i]} runs at noise {levels[i]:g}.")
        sensitive = a["sensitive"] if len(here) > 1 else (a["sensitive"] or out["sensitive"])
    verdicts = []
    for j, (n, a) in enumerate(zip(names, here)):
        who = f"{n}: " if len(here) > 1 else ""
        if a["sensitive"] or (len(here) == 1 and out["sensitive"]):
            reasons = a["reasons"] or list(out.get("reasons", []))
            verdicts.append(f"{who}noise-sensitive: " + "; ".join(reasons))
        else:
            verdicts.append(f"{who}not noise-sensitive over noise {span}")
    if k is not None and len(here) > 1:
        verdicts.insert(0, verdicts.pop(k))
    parts.append("; ".join(verdicts) + ".")
    if sensitive:
        parts.append(MEANING)
    return " ".join(parts), "sensitive" if sensitive else "steady"
