"""Browser tests of the gear in motion: the teeth and the time history's cursor move in the page.

The drawn teeth are read from the page's own Bokeh models (``motion_teeth``, the cursor
``th_cursor``, the clock on ``motion_frames``), so a test passes only if the browser's
animation moved them; the canvas they are painted on is read back pixel by pixel. Impact times are computed here, independently of the page, by
simulating the default page's parameters.

The default page's checks share one page (a page load is the costly part of a browser test),
in an order where none spoils the next: "Next impact" from the clock's first position, then
Play and Pause at the default speed, then play at 1× between the teeth, then Loop from the
window's end. The sound, in physical units, has a page of its own (``?units=true``).
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from test_ui import open_dashboard

from app.state import ExplorerState, rattle_params
from rattle_core import simulate

pytestmark = [pytest.mark.ui, pytest.mark.timeout(300)]

READY = """() => { const m = Bokeh.documents[0].get_model_by_name('motion_frames');
  return m != null && m.get_length() > 0; }"""

#: The drawn picture: the idle tooth's left vertex, the cursor, the clock and the drawn gaps
#: on the pitch line (driving flank → idle tooth, idle tooth → opposite flank).
DRAWN = """() => {
  const doc = Bokeh.documents[0];
  const xs = doc.get_model_by_name('motion_teeth').data.xs;
  const m = doc.get_model_by_name('motion_meta').data;
  const d = m.d[0], k = m.k[0];
  const c = doc.get_model_by_name('motion_frames')._rattle_motion;
  const drv = xs[0][1] - 0.7 * k, idle = xs[1][0] + 0.7 * k, opp = xs[2][0] + 0.7 * k;
  return {idle: idle, cursor: doc.get_model_by_name('th_cursor').location,
          t: c == null ? null : c.t, playing: c != null && c.playing,
          frames: c == null ? 0 : c.frames, wall: c == null ? null : c.wall,
          gap_active: idle - drv, gap_reverse: opp - idle - d, j: m.j[0]};
}"""

#: Resolves after ``n`` animation frames of the page (a condition, not a delay).
AFTER_FRAMES = """(n) => new Promise((done) => { let i = 0;
  const f = () => { i += 1; if (i >= n) done(true); else requestAnimationFrame(f); };
  requestAnimationFrame(f); })"""

#: The smallest drawn gaps over ``n`` frames of play, read at every frame.
MIN_GAPS = """(n) => new Promise((done) => {
  const doc = Bokeh.documents[0];
  const k = doc.get_model_by_name('motion_meta').data.k[0];
  const d = doc.get_model_by_name('motion_meta').data.d[0];
  let i = 0, a = Infinity, r = Infinity;
  const f = () => {
    const xs = doc.get_model_by_name('motion_teeth').data.xs;
    const idle = xs[1][0] + 0.7 * k;
    a = Math.min(a, idle - (xs[0][1] - 0.7 * k));
    r = Math.min(r, xs[2][0] + 0.7 * k - idle - d);
    i += 1; if (i >= n) done([a, r]); else requestAnimationFrame(f); };
  requestAnimationFrame(f); })"""

#: Every frame sent: the smallest x − y and y + j − x.
SENT_GAPS = """() => {
  const doc = Bokeh.documents[0];
  const f = doc.get_model_by_name('motion_frames').data, j = doc.get_model_by_name('motion_meta').data.j[0];
  let a = Infinity, r = Infinity;
  for (let i = 0; i < f.t.length; i++) { a = Math.min(a, f.x[i] - f.y[i]); r = Math.min(r, f.y[i] + j - f.x[i]); }
  return [a, r, f.t.length]; }"""


#: The canvas the teeth are painted on: its painted pixels' count and mean abscissa, and
#: whether the figure's own teeth renderer is hidden.
CANVAS = """() => {
  const doc = Bokeh.documents[0], fig = doc.get_model_by_name('motion');
  const cv = Bokeh.index.find_one(fig).canvas_view.overlays_el.querySelector('canvas.motion-canvas');
  if (cv == null || cv.width == 0) return null;
  const px = cv.getContext('2d').getImageData(0, 0, cv.width, cv.height).data;
  let n = 0, sx = 0;
  for (let i = 3; i < px.length; i += 4) if (px[i] > 0) { n += 1; sx += ((i - 3) / 4) % cv.width; }
  const bokeh = fig.renderers.find((r) => r.name == 'motion_patches');
  return {painted: n, mean_x: n ? sx / n : null, hidden: !bokeh.visible};
}"""


def press(page, what: str) -> None:
    page.locator(f".motion-{what} button").first.click()


def open_motion(page, server) -> list[str]:
    # a first page of a freshly started server on a loaded two-core machine can take over 30 s
    page.set_default_navigation_timeout(180_000)
    errors = open_dashboard(page, server)
    page.wait_for_function(READY, timeout=60_000)
    page.locator(".motion-play button").first.wait_for(timeout=60_000)
    return errors


def default_impacts() -> np.ndarray:
    """Impact times of the default page's shown window, from a simulation made here."""
    s = ExplorerState()
    tr = simulate(rattle_params(s), periods=s.periods, x0=s.x0, v0=s.v0, t0=s.t0,
                  strobe_phase=math.radians(s.strobe), transient=s.transient, lyapunov=True)
    end = tr.t_start + 2 * math.pi * s.shown
    return tr.impact_t[tr.impact_t <= end]


def _step_next_impact(page, errors: list[str]) -> None:
    """"Next impact" steps the clock and the cursor to the first, then the second impact of
    the window (simulated here), each time with the drawn gear touching a flank."""
    want = default_impacts()
    assert len(want) >= 3
    for expected in want[:2]:
        press(page, "next")
        page.wait_for_function(f"() => ({DRAWN})().t == {float(expected)!r}", timeout=20_000)
        got = page.evaluate(DRAWN)
        assert got["cursor"] == pytest.approx(expected, abs=1e-12)
        assert min(abs(got["gap_active"]), abs(got["gap_reverse"])) <= 1e-9 * got["j"]
        assert not got["playing"]
    assert errors == []


def _step_play_and_pause(page, errors: list[str]) -> None:
    """Play advances the clock, the drawn idle tooth and the time history's cursor at the
    chosen speed; Pause stops all three."""
    before = page.evaluate(DRAWN)
    assert before["playing"] is False
    press(page, "play")
    page.wait_for_function(f"() => {{ const d = ({DRAWN})(); return d.frames > 20 && "
                           f"Math.abs(d.idle - {before['idle']!r}) > 1e-6 && d.cursor > d.t - 1 "
                           "&& d.cursor > 0; }", timeout=60_000)
    a = page.evaluate(DRAWN)
    page.evaluate(AFTER_FRAMES, 10)
    b = page.evaluate(DRAWN)
    # the cursor follows every third frame: it lags the clock by two frames at most
    assert b["t"] > a["t"] and 0 <= b["t"] - b["cursor"] < 0.5 * (b["t"] - a["t"])
    # the default speed is 0.1× of one forcing period (2π) per second of the page's clock
    rate = (b["t"] - a["t"]) / ((b["wall"] - a["wall"]) / 1000)
    assert 0.5 * 0.2 * math.pi <= rate <= 0.2 * math.pi * (1 + 1e-6)
    # painted on the plain canvas, not by the figure; the picture moves with the teeth
    shot = page.evaluate(CANVAS)
    assert shot is not None and shot["painted"] > 500 and shot["hidden"], shot
    page.wait_for_function(f"() => {{ const s = ({CANVAS})(); return s != null && s.painted > 500 "
                           f"&& Math.abs(s.mean_x - {shot['mean_x']!r}) > 0.5; }}", timeout=30_000)
    press(page, "pause")
    page.wait_for_function(f"() => !({DRAWN})().playing", timeout=20_000)
    c = page.evaluate(DRAWN)
    page.evaluate(AFTER_FRAMES, 15)
    d = page.evaluate(DRAWN)
    assert (d["t"], d["idle"], d["cursor"], d["frames"]) == (c["t"], c["idle"], c["cursor"], c["frames"])
    assert errors == []


def _step_the_gear_stays_between_the_teeth(page, errors: list[str]) -> None:
    """Every frame sent satisfies y ≤ x ≤ y + j, and the drawn gaps stay ≥ 0 over 60 frames
    of play at 1× (many impacts)."""
    a, r, n = page.evaluate(SENT_GAPS)
    assert n > 1000 and a >= -1e-9 and r >= -1e-9
    page.evaluate("() => { Bokeh.documents[0].get_model_by_name('motion_speed').value = 0; }")
    press(page, "play")
    page.wait_for_function(f"() => ({DRAWN})().playing", timeout=20_000)
    a, r = page.evaluate(MIN_GAPS, 60)
    j = page.evaluate(DRAWN)["j"]
    assert a >= -1e-9 * j and r >= -1e-9 * j
    press(page, "pause")
    assert errors == []


def _step_loop(page, errors: list[str]) -> None:
    """With the clock at the window's end, "Next impact" goes to the first impact when Loop is
    on and stays when it is off; Play at 1× from near the end wraps to the start with Loop on."""
    want = default_impacts()
    to_end = """() => { const f = Bokeh.documents[0].get_model_by_name('motion_frames');
      f._rattle_motion.t = f.data.t[f.data.t.length - 1]; return f._rattle_motion.t; }"""
    press(page, "pause")  # the clock stands still, wherever it is
    page.wait_for_function(f"() => ({DRAWN})().t != null", timeout=20_000)
    end = page.evaluate(to_end)
    press(page, "next")
    page.wait_for_function(f"() => ({DRAWN})().t == {float(want[0])!r}", timeout=20_000)
    press(page, "loop")  # off
    page.wait_for_function("() => !Bokeh.documents[0].get_model_by_name('motion_loop').active",
                           timeout=20_000)
    assert page.evaluate(to_end) == end
    press(page, "next")
    page.evaluate(AFTER_FRAMES, 5)
    assert page.evaluate(DRAWN)["t"] == end
    press(page, "loop")  # on again
    page.wait_for_function("() => Bokeh.documents[0].get_model_by_name('motion_loop').active",
                           timeout=20_000)
    page.evaluate("""() => { const f = Bokeh.documents[0].get_model_by_name('motion_frames');
      Bokeh.documents[0].get_model_by_name('motion_speed').value = 0;
      f._rattle_motion.t = f.data.t[f.data.t.length - 1] - 0.5; }""")
    press(page, "play")
    page.wait_for_function(f"() => {{ const d = ({DRAWN})(); return d.playing && d.t < {end - 1.0!r}; }}",
                           timeout=30_000)
    press(page, "pause")
    assert errors == []


def test_the_gear_in_motion_on_the_default_page(page, dashboard_server):
    """On the default page: "Next impact" steps the clock and the cursor to the window's first
    two impacts with the gear on a flank; Play moves the clock, the gear and the cursor at the
    default 0.1× and Pause stops them; at 1× the drawn gear stays between the teeth; with
    Loop, "Next impact" and Play wrap from the window's end to its start, and without it,
    "Next impact" stays at the end."""
    errors = open_motion(page, dashboard_server)
    _step_next_impact(page, errors)
    _step_play_and_pause(page, errors)
    _step_the_gear_stays_between_the_teeth(page, errors)
    _step_loop(page, errors)


AUDIO_STATE = """() => {
  const c = Bokeh.documents[0].get_model_by_name('motion_frames')._rattle_motion;
  const a = c == null ? null : c.audio;
  return {on: a != null, paused: a == null ? null : a.paused, rate: a == null ? null : a.playbackRate,
          time: a == null ? null : a.currentTime, clock_s: c == null ? null : c.t / 1000};
}"""


def test_the_rattle_sound_plays_in_step_in_physical_units(page, dashboard_server):
    """Units mode, Sound on, Play at 0.1×: the sound card's audio plays at rate 0.1 from the
    clock's instant (ms of the window ↔ s of the sound), and Pause stops it."""
    page.set_default_navigation_timeout(180_000)
    errors = open_dashboard(page, dashboard_server, "?units=true")
    page.wait_for_function(READY, timeout=60_000)
    page.wait_for_function("(el) => el.src.length > 100",
                           arg=page.locator(".sound-audio audio").first.element_handle(),
                           timeout=60_000)
    press(page, "sound")
    press(page, "play")
    page.wait_for_function(f"() => {{ const a = ({AUDIO_STATE})(); return a.on && !a.paused "
                           "&& a.time > 0.005; }", timeout=30_000)
    a = page.evaluate(AUDIO_STATE)
    assert a["rate"] == pytest.approx(0.1, rel=1e-12)
    # the clock in ms and the sound's position in s stay together (within a few frames)
    assert abs(a["time"] - a["clock_s"]) < 0.05
    press(page, "pause")
    page.wait_for_function(f"() => !({AUDIO_STATE})().on", timeout=20_000)
    paused = page.evaluate("(el) => el.paused", page.locator(".sound-audio audio").first.element_handle())
    assert paused
    assert errors == []
