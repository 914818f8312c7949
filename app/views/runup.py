"""Replay the run-up: the gearbox driven through the measured run itself, heard and measured.

Under the Gearbox tab.  It takes the gearbox and the measurement the tab describes (the same
:meth:`~app.views.gearbox.GearboxView.gearbox` the verdict runs on, with the tab's oil
temperature), a speed at the start and at the end (below the start: a run-down) and the run's
length, all checked before anything runs.  The driving tooth follows the order reconstruction,
or the measured angle itself low-pass filtered at a cutoff (the CLI's ``--wall angle``): that
run is the measurement's own stretch between the two speeds, so its length is the
measurement's and the duration input is disabled.  The replay runs as the session's
``gearbox-runup`` job (:func:`app.work.runup.replay`, through the disk cache), with progress
and Cancel, and shows

* ``N(t)`` and ``L_AF(t)`` against the run's rpm, with the verdict's N5 over rpm when a verdict
  is shown;
* each gear's rattle intervals, drawn over rpm and as a table;
* the onsets on the run against the verdict's (and on the run-down, if asked), with the text
  saying where the quasi-steady answer holds;
* the run's sound (normalised to 0.99), with a cursor on the loudness plot's rpm axis that
  follows the player: a JavaScript callback reads the audio element's time every frame while
  it plays, so no frame costs a message to the server.

The view draws with Bokeh directly, for the cursor the browser moves.
"""
from __future__ import annotations

import html
import math
from typing import Any

import numpy as np
import pandas as pd
import panel as pn
import param
from bokeh.models import ColumnDataSource, CustomJS, FactorRange, LinearAxis, Range1d, Span
from bokeh.plotting import figure

from ..state import ExplorerState
from ..ui.job_panel import JobPanel
from ..ui.widgets import message
from ..work import runup as work
from ..work.threads import writes_bokeh

#: The audio element's CSS class, which the cursor's callback looks for.
AUDIO_CSS = "gb-runup-audio"

#: Moves the loudness plot's cursor (``cursor``) with the run's player: ``meta`` holds the run's
#: ``rpm_from``, ``rpm_to`` and ``duration``, ``run`` its speed ``rpm`` at the times ``t`` (the
#: cursor is at the run's speed at the player's time, which for a measured angle is the
#: measurement's own, not a straight ramp).  The player is found in the page's shadow roots
#: and listened to once; while it plays, a ``requestAnimationFrame`` loop places the cursor
#: from its ``currentTime``; the cursor is set with ``sync: false``, so nothing is sent.
CURSOR_JS = r"""
const S = meta._runup ?? (meta._runup = {audio: null, raf: 0, tries: 0});
function audio_el() {
  const walk = (root) => {
    for (const el of root.querySelectorAll("*")) {
      if (el.shadowRoot) {
        if (el.classList.contains(css)) {
          const a = el.shadowRoot.querySelector("audio");
          if (a) return a;
        }
        const a = walk(el.shadowRoot);
        if (a) return a;
      }
    }
    return null;
  };
  return walk(document);
}
function place(a) {
  const M = meta.data, t = run.data.t, rpm = run.data.rpm;
  if (!M.duration || M.duration.length == 0 || !(M.duration[0] > 0)) return;
  let x = M.rpm_from[0] + (M.rpm_to[0] - M.rpm_from[0]) * Math.min(1, Math.max(0, a.currentTime / M.duration[0]));
  if (t && t.length > 1 && t.length == rpm.length) {  // the run's own speed at the player's time
    const tau = t[0] + a.currentTime;
    let lo = 0, hi = t.length - 1;
    if (tau <= t[0]) x = rpm[0];
    else if (tau >= t[hi]) x = rpm[hi];
    else {
      while (hi - lo > 1) { const mid = (lo + hi) >> 1; if (t[mid] <= tau) lo = mid; else hi = mid; }
      x = rpm[lo] + (rpm[hi] - rpm[lo]) * (tau - t[lo]) / (t[hi] - t[lo]);
    }
  }
  if (Number.isFinite(x)) cursor.setv({location: x, visible: true}, {sync: false});
}
function loop() {
  const a = S.audio;
  if (a == null) return;
  place(a);
  if (!a.paused && !a.ended) S.raf = requestAnimationFrame(loop);
}
function attach() {
  const a = audio_el();
  if (a == null) return false;
  if (a === S.audio) return true;
  S.audio = a;
  a.addEventListener("play", () => { cancelAnimationFrame(S.raf); S.raf = requestAnimationFrame(loop); });
  for (const ev of ["seeked", "timeupdate", "pause", "ended"]) a.addEventListener(ev, () => place(a));
  return true;
}
if (!attach() && S.tries < 50) { S.tries += 1; setTimeout(() => { S.tries = 0; attach(); }, 200); }
"""


def _intervals_html(df: pd.DataFrame) -> str:
    if df is None or df.empty:
        return "<b>Rattle intervals</b>: none, no gear hits a tooth on this run."
    return "<b>Rattle intervals</b>" + df.to_html(index=False, escape=True, float_format="%.4g")


def _onsets_html(df: pd.DataFrame | None) -> str:
    if df is None:
        return ""
    return "<b>Onsets: run against verdict [rpm]</b>" + df.to_html(
        index=False, escape=True, float_format="%.0f", na_rep="never")


#: What drives the tooth: the order reconstruction, or the measured angle itself, filtered.
WALLS = {"orders (reconstruction)": "orders", "measured angle, low-pass filtered": "angle"}
DURATION_LABEL = (f"duration [s] ({work.DURATION_RANGE_S[0]:g}–"
                  f"{work.DURATION_RANGE_S[1]:g})")
#: The duration's label when the measured angle drives the run, which then lasts as long as
#: the measurement takes between the two speeds.
DURATION_ANGLE_LABEL = "duration [s]: the measurement's own"


class RunupView(pn.viewable.Viewer):
    """"Replay the run-up" under the Gearbox tab (see the module docstring)."""

    state = param.ClassSelector(class_=ExplorerState)
    jobs = param.Parameter()
    #: The Gearbox tab's view: its gearbox, measurement and verdict are what is replayed.
    gearbox = param.Parameter()
    revision = param.Integer(0)

    def __init__(self, **params: Any):
        super().__init__(**params)
        self.result: dict | None = None
        self.intervals = pd.DataFrame()
        self.onsets: pd.DataFrame | None = None
        self.rpm_from = pn.widgets.FloatInput(label="rpm from", value=1500.0, step=50.0,
                                              css_classes=["gb-runup-from"], width=120)
        self.rpm_to = pn.widgets.FloatInput(label="rpm to", value=2500.0, step=50.0,
                                            css_classes=["gb-runup-to"], width=120)
        self.duration = pn.widgets.FloatInput(
            label=DURATION_LABEL, value=5.0, step=1.0, css_classes=["gb-runup-duration"],
            width=160)
        self.wall = pn.widgets.Select(label="driving tooth from", options=WALLS, value="orders",
                                      css_classes=["gb-runup-wall"], width=280)
        self.cutoff = pn.widgets.FloatInput(label="cutoff [Hz]", value=500.0, step=50.0,
                                            css_classes=["gb-runup-cutoff"], width=120,
                                            visible=False)
        self.wall.param.watch(lambda e: self._on_wall(), "value")
        self.rundown = pn.widgets.Checkbox(label="also the run-down (hysteresis)", value=False,
                                           css_classes=["gb-runup-rundown"])
        self.run_button = pn.widgets.Button(label="Replay the run-up", color="primary",
                                            css_classes=["gb-runup-run"], sizing_mode="stretch_width")
        # progress, Cancel and status: ``gb-runup-progress``, ``gb-runup-cancel``, ``gb-runup-status``
        self.panel = JobPanel(self.jobs, "gearbox-runup", "gb-runup")
        self.panel.say("No run-up replayed yet.")
        self.panel.cancel_button.on_click(lambda e: self.cancel("Replay cancelled."))
        self.run_button.on_click(lambda e: self.run())
        # a volume of its own: left unset, every page's player would send it at once
        self.audio = pn.pane.Audio(None, sample_rate=48_000, name="run-up sound", volume=100,
                                   css_classes=[AUDIO_CSS], sizing_mode="stretch_width")
        self.text = pn.pane.HTML("", css_classes=["gb-runup-text"], sizing_mode="stretch_width")
        self.onsets_pane = pn.pane.HTML("", css_classes=["gb-runup-onsets"],
                                        sizing_mode="stretch_width")
        self.intervals_pane = pn.pane.HTML("", css_classes=["gb-runup-intervals"],
                                           sizing_mode="stretch_width")
        self._build_plots()

    # ----- plots ------------------------------------------------------------------------------

    def _build_plots(self) -> None:
        self.run_src = ColumnDataSource({"t": [], "rpm": [], "sone": [], "dba": []})
        self.verdict_src = ColumnDataSource({"rpm": [], "sone": []})
        self.meta_src = ColumnDataSource({"rpm_from": [], "rpm_to": [], "duration": []})
        self.intervals_src = ColumnDataSource({"gear": [], "start_rpm": [], "end_rpm": []})
        f = figure(height=280, sizing_mode="stretch_width", title="Run-up: loudness and level",
                   x_axis_label="engine speed [rpm]", y_axis_label="loudness N(t) [sone]",
                   tools="pan,wheel_zoom,box_zoom,reset,save", css_classes=["gb-runup-loudness"])
        f.line("rpm", "sone", source=self.run_src, color="#1f77b4", legend_label="N(t), run")
        f.scatter("rpm", "sone", source=self.verdict_src, color="#d62728", size=6,
                  legend_label="N5, verdict")
        f.line("rpm", "sone", source=self.verdict_src, color="#d62728", line_dash="dashed")
        f.extra_y_ranges = {"dba": Range1d(0, 100)}
        f.add_layout(LinearAxis(y_range_name="dba", axis_label="L_AF(t) [dB(A)]"), "right")
        f.line("rpm", "dba", source=self.run_src, color="#2ca02c", y_range_name="dba",
               legend_label="L_AF(t), run")
        f.legend.location = "top_left"
        f.legend.click_policy = "hide"
        self.cursor = Span(location=0.0, dimension="height", line_color="#444", line_width=2,
                           visible=False, name="runup_cursor")
        f.add_layout(self.cursor)
        self.loudness_fig = f
        cb = CustomJS(args={"meta": self.meta_src, "run": self.run_src, "cursor": self.cursor,
                            "css": AUDIO_CSS},
                      code=CURSOR_JS)
        self.meta_src.js_on_change("data", cb)
        f.js_on_event("document_ready", cb)
        g = figure(height=160, sizing_mode="stretch_width", title="Rattle intervals",
                   x_axis_label="engine speed [rpm]", y_range=FactorRange(factors=[]),
                   tools="pan,wheel_zoom,reset,save", css_classes=["gb-runup-intervals-plot"])
        g.hbar(y="gear", left="start_rpm", right="end_rpm", height=0.6, source=self.intervals_src,
               color="#ff7f0e")
        self.intervals_fig = g
        self.loudness_pane = pn.pane.Bokeh(f, sizing_mode="stretch_width")
        self.intervals_plot = pn.pane.Bokeh(g, sizing_mode="stretch_width")

    @writes_bokeh
    def _draw(self) -> None:
        r = self.result
        self.run_src.data = {"t": np.asarray(r["time_s"], dtype=float),
                             "rpm": np.asarray(r["rpm_t"]), "sone": np.asarray(r["loudness_t"]),
                             "dba": np.asarray(r["level_dba_t"])}
        dba = np.asarray(r["level_dba_t"])
        dba = dba[np.isfinite(dba)]
        if dba.size:
            lo, hi = float(dba.min()), float(dba.max())
            self.loudness_fig.extra_y_ranges["dba"].update(start=lo - 3, end=hi + 3)
        self.verdict_src.data = self._verdict_series()
        ints = self.intervals
        names = list(dict.fromkeys([g.name for g in self._box.gears] if self._box is not None
                                   else ints["gear"]))
        self.intervals_fig.y_range.factors = names
        self.intervals_src.data = {"gear": list(ints["gear"]),
                                   "start_rpm": ints["start_rpm"].to_numpy(),
                                   "end_rpm": ints["end_rpm"].to_numpy()}
        self.cursor.update(location=float(r["rpm_from"]), visible=False)
        # last: the cursor's callback reads the new run's speeds and finds the player
        self.meta_src.data = {"rpm_from": [float(r["rpm_from"])], "rpm_to": [float(r["rpm_to"])],
                              "duration": [float(r["duration_s"])]}

    def _verdict_series(self) -> dict:
        """The verdict's gearbox N5 over rpm, where the verdict shown is of this gearbox."""
        base = getattr(self.gearbox, "base", None)
        if base is None or self.onsets is None:
            return {"rpm": [], "sone": []}
        from ..core import GEARBOX
        rows = base.gear(GEARBOX)
        return {"rpm": rows["rpm"].to_numpy(float), "sone": rows["loudness_sone"].to_numpy(float)}

    # ----- the request ------------------------------------------------------------------------

    def _on_wall(self) -> None:
        angle = self.wall.value == "angle"
        self.cutoff.visible = angle
        # the measured angle's run is the measurement's own stretch between the two speeds
        self.duration.param.update(disabled=angle,
                                   label=DURATION_ANGLE_LABEL if angle else DURATION_LABEL)

    def request(self) -> tuple:
        """The gearbox and the run asked for: ``(box, rpm_from, rpm_to, duration, samples,
        cutoff_hz)``, ``duration`` None and ``samples`` the measurement's time and speed when
        the measured angle drives the run (else ``samples`` and ``cutoff_hz`` None);
        ``ValueError`` naming the input and its range."""
        tab = self.gearbox
        try:
            box = tab.with_settings(tab.gearbox())
        except ValueError as exc:
            raise ValueError(f"gears: {exc}") from None
        angle = self.wall.value == "angle"
        inputs = [(self.rpm_from, "rpm from"), (self.rpm_to, "rpm to")]
        if not angle:
            inputs.append((self.duration, "duration"))
        values = []
        for w, label in inputs:
            v = w.value
            if v is None or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ValueError(f"{label} = {v!r} must be a number")
            values.append(float(v))
        if not angle:
            rpm_from, rpm_to, duration = values
            work.check(box, rpm_from, rpm_to, duration)
            return box, rpm_from, rpm_to, duration, None, None
        rpm_from, rpm_to = values
        samples = getattr(tab.measurement, "samples", None)
        if samples is None:
            raise ValueError("the measured angle needs the measured time and speed: take the "
                             "sample run-up or upload a measurement (a gearbox file's constant "
                             "orders have no angle)")
        cutoff = self.cutoff.value
        work.check(box, rpm_from, rpm_to, None, samples, cutoff, bool(self.rundown.value))
        return box, rpm_from, rpm_to, None, samples, float(cutoff)

    def run(self) -> bool:
        """Start the replay in the background; False with a message (plain text) if it cannot."""
        st = self.state
        st.clear("gearbox-runup")
        try:
            box, a, b, d, samples, cutoff = self.request()
        except (ValueError, TypeError) as exc:
            st.say("gearbox-runup", str(exc))
            return False
        self._box = box
        base = getattr(self.gearbox, "base", None)
        what = "run-down" if b < a else "run-up"
        how = (f"in {d:g} s" if samples is None else
               f"over the measurement's own stretch, its angle filtered at {cutoff:g} Hz")
        self.panel.submit(
            object(), work.replay,
            (box, a, b, d, bool(self.rundown.value), base, samples, cutoff),
            f"Replaying the {what} {a:g} → {b:g} rpm {how}, {len(box.gears)} gears"
            f"{' and the run-down' if self.rundown.value else ''}…", work.RUNUP_JOB_LIMIT,
            on_done=self._done, on_error=self._error)
        return True

    @property
    def job(self) -> Any:
        return self.panel.job

    def cancel(self, text: str | None = None) -> None:
        self.panel.stop(text)

    def _error(self, msg: str) -> None:
        self.panel.say("No run-up: see the message above.")
        self.state.say("gearbox-runup", f"The run-up could not be replayed: {msg}")

    def _done(self, out: dict | None) -> None:
        if out is None:  # cancelled
            return
        self.result = out
        self.intervals = pd.DataFrame(out["intervals"])
        self.onsets = None if out["onsets"] is None else pd.DataFrame(out["onsets"])
        self._draw()
        self.intervals_pane.object = _intervals_html(self.intervals)
        self.onsets_pane.object = _onsets_html(self.onsets)
        self.text.object = "<br>".join(html.escape(line) for line in out["text"].splitlines())
        self.audio.param.update(object=out["signal"], sample_rate=int(out["rate"]))
        how = "from the disk cache" if out["from_cache"] else "computed"
        n = sum(out["impacts_per_gear"].values())
        wall = ("" if out.get("wall", "orders") == "orders" else
                f", driven by the measured angle filtered at {out['cutoff_hz']:g} Hz")
        self.panel.say(f"Run {out['rpm_from']:g} → {out['rpm_to']:g} rpm in "
                       f"{out['duration_s']:.4g} s{wall} ({how}): {n} impacts; the sound is played "
                       f"normalised (full scale {out['calibration_pa']:.3g} Pa).")
        self.revision += 1

    _box: Any = None

    def __panel__(self):
        controls = pn.Column(
            pn.pane.Markdown("**5. Replay the run-up** (the gears driven through the measured "
                             "run itself; rpm to below rpm from: a run-down)"),
            pn.Row(self.wall, self.cutoff), pn.Row(self.rpm_from, self.rpm_to, self.duration),
            self.rundown,
            pn.Row(self.run_button, self.panel.cancel_button, sizing_mode="stretch_width"),
            message(self.state, "gearbox-runup"), self.panel.progress, self.panel.status,
            self.audio, width=460, margin=(0, 10))
        shown = pn.Column(self.loudness_pane, self.intervals_plot, self.text, self.onsets_pane,
                          self.intervals_pane, sizing_mode="stretch_width")
        return pn.Row(controls, shown, sizing_mode="stretch_width")
