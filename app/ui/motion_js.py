"""The browser side of the gear in motion: one JavaScript clock shared by the motion view's controls.

:data:`MOTION_JS` is the body of every ``CustomJS`` callback of :mod:`app.views.motion`; the
argument ``action`` says which control called it (``play``, ``pause``, ``next``, ``speed``,
``data``). The clock lives on the frame source itself (a JavaScript property of the BokehJS
model, never synchronised), and a ``requestAnimationFrame`` loop advances it: no frame costs a
message to the server.

Each frame the clock is turned into positions by linear interpolation between the two frames
around it. The frames are samples of the exact solution that include every impact instant, so
at an impact the drawn gear is the exact one, and in between it cannot cross a tooth: ``x − y``
and ``y + j − x`` are non-negative at both frames, hence along the segment between them.

The drawn teeth and the flash are written into their sources in place (what the page shows,
read back by the browser tests) and painted from them on a plain ``<canvas>`` laid over the
figure's frame, on the figure's HTML overlay layer: a frame repaints neither a Bokeh figure nor
the page's layout. The figure's own teeth and flash renderers are hidden once the canvas is up
(without it, the sources are repainted by Bokeh as before), and a repaint of the figure (a
resize, a new run's range) repaints the canvas. The cursor of the time history (the model named
``th_cursor``, on that figure's overlay layer) moves every third frame while playing, and the
clock's readout, which changes the page's layout, four times a second; both are set with
``sync: false``, so Bokeh sends neither to the server.

The geometry mirrors :func:`app.views.motion.teeth_xs`: on the pitch line (height 0.5) the
active flank of the driving tooth is at ``y``, the idle tooth spans ``[x, x + d]`` and the
opposite tooth's flank is at ``y + j + d``; flanks in contact are parallel, so the gap between
two teeth is the model's gap at every height.
"""
from __future__ import annotations

#: Colours of an impact's flash, by flank code, are passed in ``meta`` (``active``, ``reverse``).
MOTION_JS = r"""
const R = frames._rattle_motion ?? (frames._rattle_motion = {
  t: NaN, playing: false, gen: 0, wall: 0, frames: 0, flash_wall: -1e9, flash_flank: 0,
  flash_x: NaN, audio: null, last_impact: NaN});
const FLASH_MS = 350;

function ctx() {
  const F = frames.data, M = meta.data;
  return {T: F.t, X: F.x, Y: F.y, n: F.t.length, j: M.j[0], d: M.d[0], k: M.k[0],
          rate: M.rate[0], real: M.real[0] == 1, unit: M.unit[0], period: M.period[0],
          IT: impacts.data.t, IF: impacts.data.flank,
          active: M.active[0], reverse: M.reverse[0], tooth: M.tooth[0], gear: M.gear[0]};
}

// the last i with T[i] <= t (0 when t < T[0])
function index(T, t) {
  let lo = 0, hi = T.length - 1;
  if (hi < 0 || t < T[0]) return 0;
  if (t >= T[hi]) return hi;
  while (hi - lo > 1) { const mid = (lo + hi) >> 1; if (T[mid] <= t) lo = mid; else hi = mid; }
  return lo;
}

function at(c, t) {
  const i = Math.min(index(c.T, t), c.n - 2);
  const dt = c.T[i + 1] - c.T[i];
  const s = dt > 0 ? Math.min(1, Math.max(0, (t - c.T[i]) / dt)) : 0;
  if (s == 0) return [c.X[i], c.Y[i]];
  if (s == 1) return [c.X[i + 1], c.Y[i + 1]];
  return [c.X[i] + s * (c.X[i + 1] - c.X[i]), c.Y[i] + s * (c.Y[i + 1] - c.Y[i])];
}

function put(arr, vals) { for (let i = 0; i < vals.length; i++) arr[i] = vals[i]; }

function speed_of() { return Math.pow(10, speed.value); }

// A plain canvas over the figure's frame, on its HTML overlay layer: the teeth and the flash
// are painted there each frame, so that a frame repaints neither the figure nor the page.
function surface() {
  // the figure's view is looked up once: a search of the page's views each frame costs more
  // than the frame's painting
  const S0 = R.surface;
  if (S0 != null && S0.canvas.isConnected && S0.canvas.parentNode === S0.pv.canvas_view.overlays_el) return S0;
  const fig = frames.document == null ? null : frames.document.get_model_by_name("motion");
  const pv = fig == null || window.Bokeh == null || Bokeh.index == null ? null : Bokeh.index.find_one(fig);
  if (pv == null || pv.canvas_view == null) return null;
  const host = pv.canvas_view.overlays_el;
  let S = R.surface;
  if (S == null || S.pv !== pv || !S.canvas.isConnected || S.canvas.parentNode !== host) {
    const canvas = document.createElement("canvas");
    canvas.className = "motion-canvas";
    canvas.style.cssText = "position:absolute;left:0;top:0;pointer-events:none;";
    host.appendChild(canvas);
    S = R.surface = {pv: pv, canvas: canvas, renderers: []};
    for (const r of fig.renderers)
      if (r.name == "motion_patches" || r.name == "motion_burst") { S.renderers.push(r); r.setv({visible: false}, {sync: false}); }
    // a repaint of the figure (a resize, a new run's range) paints the teeth where they now are
    pv.repainted.connect(() => { if (R.surface === S) paint(); });
  }
  return S;
}

function paint() {
  const S = surface();
  if (S == null) { teeth.change.emit(); flash.change.emit(); return; }
  const pv = S.pv, cv = S.canvas, b = pv.frame.bbox, ratio = window.devicePixelRatio || 1;
  const W = Math.max(1, Math.round(pv.canvas_view.bbox.width)), H = Math.max(1, Math.round(pv.canvas_view.bbox.height));
  if (cv.width != Math.round(W * ratio) || cv.height != Math.round(H * ratio)) {
    cv.width = Math.round(W * ratio); cv.height = Math.round(H * ratio);
    cv.style.width = `${W}px`; cv.style.height = `${H}px`;
  }
  const g = cv.getContext("2d");
  g.setTransform(ratio, 0, 0, ratio, 0, 0);
  g.clearRect(0, 0, W, H);
  const xr = pv.model.x_range, yr = pv.model.y_range;
  const sx = (v) => b.left + (v - xr.start) / (xr.end - xr.start) * b.width;
  const sy = (v) => b.top + (1 - (v - yr.start) / (yr.end - yr.start)) * b.height;
  g.save();
  g.beginPath(); g.rect(b.left, b.top, b.width, b.height); g.clip();
  const T = teeth.data;
  g.lineWidth = 3; g.lineJoin = "miter";
  for (let i = 0; i < T.xs.length; i++) {
    const xs = T.xs[i], ys = T.ys[i];
    if (!isFinite(xs[0])) continue;
    g.beginPath();
    for (let m = 0; m < xs.length; m++) { if (m == 0) g.moveTo(sx(xs[m]), sy(ys[m])); else g.lineTo(sx(xs[m]), sy(ys[m])); }
    g.closePath();
    g.globalAlpha = 0.85; g.fillStyle = T.fill[i]; g.fill();
    g.globalAlpha = 1; g.strokeStyle = T.line[i]; g.stroke();
  }
  const F = flash.data;
  if (F.alpha[0] > 0 && isFinite(F.x[0])) {
    g.globalAlpha = F.alpha[0]; g.fillStyle = F.color[0];
    g.beginPath(); g.arc(sx(F.x[0]), sy(F.y[0]), 15, 0, 2 * Math.PI); g.fill();
  }
  g.restore();
}

function draw(c, t, now) {
  const [x, y] = at(c, t), d = c.d, k = c.k, yj = y + c.j;
  const xs = teeth.data.xs;
  put(xs[0], [y - d - 0.7 * k, y + 0.7 * k, y - 0.3 * k, y - d + 0.3 * k]);
  put(xs[1], [x - 0.7 * k, x + d + 0.7 * k, x + d - 0.3 * k, x + 0.3 * k]);
  put(xs[2], [yj + d - 0.7 * k, yj + 2 * d + 0.7 * k, yj + 2 * d - 0.3 * k, yj + d + 0.3 * k]);
  const age = now - R.flash_wall;
  const alpha = age < FLASH_MS ? 0.9 * (1 - age / FLASH_MS) : 0;
  const colour = R.flash_flank > 0 ? c.active : c.reverse;
  const lines = teeth.data.line;
  lines[0] = alpha > 0 && R.flash_flank > 0 ? c.active : c.tooth;
  lines[1] = alpha > 0 ? colour : c.gear;
  lines[2] = alpha > 0 && R.flash_flank < 0 ? c.reverse : c.tooth;
  const fx = R.flash_flank > 0 ? x : x + d;
  put(flash.data.x, [alpha > 0 ? fx : NaN]);
  put(flash.data.alpha, [alpha]);
  flash.data.color[0] = colour;
  paint();
  // the cursor repaints the time history's overlay: every third frame is smooth enough to follow
  const cursor = frames.document == null ? null : frames.document.get_model_by_name("th_cursor");
  R.cursor_n = (R.cursor_n ?? 0) + 1;
  if (cursor != null && (!R.playing || R.cursor_n % 3 == 0 || !cursor.visible))
    cursor.setv(cursor.visible ? {location: t} : {location: t, visible: true}, {sync: false});
  R.t = t;
  // the readout's text changes the page's layout: a few times a second is enough to read it
  if (R.playing && now - (R.readout ?? -1e9) < 250) return;
  R.readout = now;
  const shown = c.real ? `${t.toFixed(2)} ms` : `${t.toFixed(3)} (${((t - c.T[0]) / c.period).toFixed(2)} periods)`;
  const state = R.playing ? "playing" : "paused";
  clock.setv({text: `t = ${shown} · ${speed_of().toPrecision(2)}× · ${state}`}, {sync: false});
}

function impacts_between(c, a, b) {
  // the last impact in (a, b]: its flank flashes
  let i = index(c.IT, b);
  if (c.IT.length == 0 || c.IT[i] > b) return -1;
  return c.IT[i] > a ? i : -1;
}

function audio_element() {
  const walk = (root) => {
    for (const el of root.querySelectorAll("*")) {
      if (el.shadowRoot) {
        if (el.classList.contains("sound-audio")) {
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

// the browser plays audio between 1/16 and 16 times its own speed
function sound_ok(c) { const v = speed_of(); return c.real && sound.active && v >= 0.0625 && v <= 16; }

function sound_start(c) {
  sound_stop();
  if (!sound_ok(c)) return;
  const a = audio_element();
  if (a == null) return;
  a.preservesPitch = false;
  a.playbackRate = speed_of();
  a.currentTime = Math.max(0, (R.t - c.T[0]) / c.rate);
  R.audio = a;
  const p = a.play();
  if (p != null && p.catch) p.catch(() => { R.audio = null; });
}

function sound_stop() { if (R.audio != null) { R.audio.pause(); R.audio = null; } }

function tick(gen) {
  return (now) => {
    if (!R.playing || R.gen != gen) return;
    const c = ctx();
    if (c.n < 2) { R.playing = false; return; }
    const span = c.T[c.n - 1] - c.T[0];
    const dt = Math.min(0.25, Math.max(0, (now - R.wall) / 1000));
    R.wall = now;
    let t0 = R.t, t = R.t + dt * c.rate * speed_of();
    if (t >= c.T[c.n - 1]) {
      if (loop.active && span > 0) {
        t = c.T[0] + ((t - c.T[0]) % span);
        t0 = c.T[0] - 1e-12 * span;
        if (R.audio != null) R.audio.currentTime = (t - c.T[0]) / c.rate;
      } else {
        t = c.T[c.n - 1];
        R.playing = false;
        sound_stop();
      }
    }
    const i = impacts_between(c, t0, t);
    if (i >= 0) { R.flash_wall = now; R.flash_flank = c.IF[i]; R.last_impact = c.IT[i]; }
    draw(c, t, now);
    R.frames += 1;
    if (R.playing) requestAnimationFrame(tick(gen));
  };
}

const c = ctx();
const now = performance.now();
if (c.n >= 2) {
  if (!(R.t >= c.T[0] && R.t <= c.T[c.n - 1])) R.t = c.T[0];
  if (action == "play") {
    if (!R.playing) {
      if (R.t >= c.T[c.n - 1]) R.t = c.T[0];
      R.playing = true;
      R.gen += 1;
      R.wall = now;
      sound_start(c);
      draw(c, R.t, now);
      requestAnimationFrame(tick(R.gen));
    }
  } else if (action == "pause") {
    R.playing = false;
    sound_stop();
    draw(c, R.t, now);
  } else if (action == "next") {
    R.playing = false;
    sound_stop();
    const span = c.T[c.n - 1] - c.T[0];
    const after = R.t + 1e-9 * span;
    let i = index(c.IT, after);
    if (c.IT.length && c.IT[i] <= after) i += 1;
    if (i >= c.IT.length && loop.active) i = 0;
    if (i < c.IT.length) {
      R.flash_wall = now; R.flash_flank = c.IF[i]; R.last_impact = c.IT[i];
      draw(c, c.IT[i], now);
      const fade = (w) => { if (!R.playing && w - R.flash_wall < FLASH_MS + 20) { draw(ctx(), R.t, w); requestAnimationFrame(fade); } };
      requestAnimationFrame(fade);
    }
  } else if (action == "speed") {
    if (R.audio != null) { if (sound_ok(c)) R.audio.playbackRate = speed_of(); else sound_stop(); }
    else if (R.playing) sound_start(c);
    draw(c, R.t, now);
  } else if (action == "sound") {
    if (R.playing) sound_start(c); else sound_stop();
  } else if (action == "data") {
    // a new run: its window starts again
    sound_stop();
    R.t = c.T[0];
    R.flash_wall = -1e9;
    draw(c, R.t, now);
  }
}
"""
