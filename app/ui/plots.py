"""Plot data and plot helpers: a trajectory in, arrays and names out; no session, no widget.

* :func:`time_history_data` and :func:`section_points` turn a trajectory into arrays (in
  physical units when asked);
* :func:`caption` and :func:`file_stem` name a run's parameters, for plot titles (which are
  part of every saved PNG) and for the save tool's file name (:func:`save_as`);
* :class:`PinMarkers` marks a pinned run (A) and the live run (B) on a figure's x axis;
* :class:`Zoom` keeps a plot on its data until the user zooms or pans, then keeps the
  user's view across redraws until the reset tool is pressed (HoloViews ``RangeXY`` and
  ``PlotReset`` streams; Bokeh reports only the user's range changes as ``rangesupdate``).
"""
from __future__ import annotations

import dataclasses
import math
import weakref
from typing import Any, Callable

import holoviews as hv
import numpy as np
import param
import panel as pn

from ..core import TWO_PI
from ..state import display_phases
from .labels import MARK_COLOR, PIN_COLOR, num
from ..work.threads import later, plot_lock

#: Samples per forcing period of the time history (impact instants are added exactly).
POINTS_PER_PERIOD = 160
TOOLS = ["save", "pan", "wheel_zoom", "box_zoom", "reset"]


# ----- names of a run -----------------------------------------------------------------------

#: What a diagram over each parameter leaves out of its caption: the swept value, and in
#: physical units what the engine speed sets (Λ and j follow the speed).
SWEPT = {"lam": {"lam"}, "phi2": {"phi2"}, "rpm": {"rpm", "lam", "j"}}


def caption(run: Any, swept: str | None = None) -> str:
    """The run's parameters in one line, in the page's phase convention (and SI when on).

    With ``swept``, the caption of a diagram over that parameter: what the diagram runs over
    is left out, since the diagram stays the same while only that changes.
    """
    out = SWEPT.get(swept, set())
    p = run.params
    phases = display_phases(p, run.phases)
    parts = [f"Λ = {num(p.lam, 6)}"] if "lam" not in out else []
    parts += [f"r = {num(p.r, 4)}"] + ([f"j = {num(p.j, 5)}"] if "j" not in out else [])
    for k in range(2, p.n_harmonics + 1):
        if p.amplitudes[k - 1] != 0.0 or k == 2:
            phase = "" if k == 2 and "phi2" in out else f", φ{k} = {num(phases[k - 1], 5)}°"
            parts.append(f"h{k} = {num(p.amplitudes[k - 1], 4)}{phase}")
    parts[-1] += f" ({run.phases})"
    if run.phys is not None:
        ph = run.phys
        speed = "" if "rpm" in out else f"{num(ph.rpm, 6)} rpm, "
        parts.append(f"{speed}C = {num(ph.drag_torque, 4)} N·m")
    return " · ".join(parts)


def run_label(letter: str, run: Any, phases: str) -> str:
    """One run named for a comparison: ``'A: Λ = 3.3, r = 0.65, j = 8, H₂/H₁ = 0.25,
    φ₂ = 45° (chaotic)'`` (phases in the page's convention ``phases``; plain text)."""
    p = run.params
    shown = display_phases(p, phases)
    parts = [f"Λ = {num(p.lam, 6)}", f"r = {num(p.r, 4)}", f"j = {num(p.j, 5)}"]
    if p.n_harmonics > 1:
        parts.append(f"H₂/H₁ = {num(p.amplitudes[1], 4)}, φ₂ = {num(shown[1], 5)}°")
    extra = sum(1 for a in p.amplitudes[2:] if a != 0.0)
    if extra:
        parts.append(f"+{extra} harmonic{'s' if extra > 1 else ''}")
    cls = run.cls
    what = ("chaotic" if cls.chaotic else f"period {cls.period}" if cls.period
            else "no period ≤ 32")
    return f"{letter}: {', '.join(parts)} ({what}, regime {cls.regime})"


def file_stem(run: Any, what: str) -> str:
    """A file name (no extension) holding the run's parameters, safe on every file system."""
    p = run.params
    phi2 = display_phases(p, run.phases)[1] if p.n_harmonics > 1 else 0.0
    h2 = p.amplitudes[1] if p.n_harmonics > 1 else 0.0
    stem = f"rattle_{what}_lam{p.lam:.6g}_r{p.r:.4g}_j{p.j:.5g}_h2-{h2:.4g}_phi2-{phi2:.5g}{run.phases}"
    if p.n_harmonics > 2:
        stem += f"_{p.n_harmonics}harm"
    if run.phys is not None:
        stem += f"_{run.phys.rpm:.6g}rpm"
    return "".join(c if c.isalnum() or c in "._-" else "_" for c in stem)


def name_saved_png(fig: Any, stem: str) -> None:
    """Give ``fig``'s save tool the file name ``stem.png``.

    The extension is written out: the browser adds none to a name that holds a dot already
    (``lam3.3``), and the file would open as nothing.
    """
    from bokeh.models import SaveTool
    name = stem + ".png"
    for tool in fig.toolbar.tools:
        if isinstance(tool, SaveTool) and tool.filename != name:
            tool.filename = name


def full_screen(fig: Any) -> None:
    """Give ``fig`` a full-screen button (a projector shows one plot large)."""
    from bokeh.models import FullscreenTool
    if not any(isinstance(t, FullscreenTool) for t in fig.toolbar.tools):
        fig.add_tools(FullscreenTool())


def save_as(get_stem: Callable[[], str]) -> Callable:
    """A HoloViews hook naming the plot's saved PNG ``get_stem()`` (see :func:`name_saved_png`)
    and offering it full screen."""
    def hook(plot, element) -> None:
        name_saved_png(plot.state, get_stem())
        full_screen(plot.state)
    return hook


def key_legend(fig: Any, entries: list[tuple[str, str]], name: str = "key") -> None:
    """A legend of coloured squares, ``(label, colour)`` each, to the right of ``fig``.

    A key drawn in the figure is part of every PNG saved from it, unlike one beside it on
    the page. The legend is rebuilt only when the entries change.
    """
    from bokeh.models import Legend, LegendItem
    tag = repr(entries)
    legend = next((m for m in fig.right if isinstance(m, Legend) and m.name == name), None)
    if legend is not None and legend.tags == [tag]:
        return
    fig.renderers = [r for r in fig.renderers if r.name != name]
    items = [LegendItem(label=label, renderers=[fig.scatter(x=[], y=[], marker="square", size=11,
                                                            color=colour, name=name)])
             for label, colour in entries]
    if legend is None:
        legend = Legend(name=name, label_text_font_size="8pt", glyph_width=12, glyph_height=12,
                        spacing=1, padding=4, margin=4, border_line_alpha=0.3)
        fig.add_layout(legend, "right")
    legend.update(items=items, tags=[tag], visible=bool(entries))


def named_glyph(glyph: str) -> Callable:
    """A HoloViews hook naming the Bokeh glyph renderer (the page's tests find it by name)."""
    def hook(plot: Any, element: Any) -> None:
        renderer = plot.handles.get("glyph_renderer")
        if renderer is not None:
            renderer.name = glyph
    return hook


class HoloViewsPane(pn.pane.HoloViews):
    """``pn.pane.HoloViews`` whose plots are built under :func:`~app.work.threads.plot_lock`.

    Its axes are its own unless it asks (``linked_axes=True``): Panel otherwise links the
    ranges of every plot on the page whose axes share a name, and the page's plots share
    names ("x", "t / period") with meanings and spans of their own.  Linked, the 2-D map took
    another plot's range while its click stream still clipped taps against its own, and every
    click was dropped as out of range.
    """

    linked_axes = param.Boolean(default=False, doc="Link this plot's axes with other panes'.")

    def _get_model(self, *args: Any, **kwargs: Any) -> Any:
        with plot_lock():
            return super()._get_model(*args, **kwargs)

    def _update_object(self, *args: Any, **kwargs: Any) -> Any:
        with plot_lock():
            return super()._update_object(*args, **kwargs)


def weak_hook(method: Callable) -> Callable:
    """A HoloViews hook calling a view's ``method`` without keeping the view alive.

    HoloViews keeps the options of every customised element in a process-wide store; a hook
    that held its view would keep a closed session's views, state and results for ever.
    """
    ref = weakref.WeakMethod(method)

    def hook(plot, element) -> None:
        bound = ref()
        if bound is not None:
            bound(plot, element)
    return hook


def padded(v: np.ndarray, pad: float = 0.05) -> tuple[float, float]:
    """Finite ``(lo, hi)`` around ``v`` with a margin; a unit range around a single value."""
    v = np.asarray(v, dtype=float)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return -1.0, 1.0
    lo, hi = float(v.min()), float(v.max())
    span = hi - lo
    # a periodic orbit repeats to ~1e-11: treat spans at that level as one point, not a zoom
    if span <= 1e-8 * max(1.0, abs(lo), abs(hi)):
        half = max(0.5, 0.05 * abs(lo))
        return lo - half, hi + half
    return lo - pad * span, hi + pad * span


class Zoom:
    """Follow the data until the user zooms; then keep the user's view (see the module docstring)."""

    def __init__(self, on_reset: Callable[[], None] | None = None):
        self.user = False
        self.shown: tuple[float, ...] | None = None
        self._on_reset = on_reset

    def watch(self, dmap: Any) -> None:
        """Listen to the user's zooms and resets of the plot ``dmap`` is drawn in."""
        hv.streams.RangeXY(source=dmap).add_subscriber(self._ranged)
        hv.streams.PlotReset(source=dmap).add_subscriber(self._reset)

    def apply(self, element: Any, xlim: tuple[float, float], ylim: tuple[float, float]) -> Any:
        """``element`` with the data's limits, or left to the user's view."""
        if self.user:
            return element.opts(framewise=False)
        self.shown = (*xlim, *ylim)
        return element.opts(xlim=tuple(xlim), ylim=tuple(ylim), framewise=True)

    def _ranged(self, x_range=None, y_range=None, **_: Any) -> None:
        if x_range is None or y_range is None or None in (*x_range, *y_range):
            return
        got = (*x_range, *y_range)
        if self.shown is not None:
            span = max(abs(self.shown[1] - self.shown[0]), abs(self.shown[3] - self.shown[2]), 1e-300)
            if all(abs(a - b) <= 1e-6 * span for a, b in zip(got, self.shown)):
                return  # the browser reporting the data's own range (a reset, or a redraw)
        self.user = True

    def _reset(self, resetting: bool = False, **_: Any) -> None:
        if resetting and self.user:
            self.user = False
            if self._on_reset is not None:
                later(self._on_reset)


# ----- time history ----------------------------------------------------------------------------

def tooth_depth(j: float) -> float:
    """Drawn thickness of each tooth: visible at any backlash, never dominating the gap."""
    return max(0.6, 0.25 * float(j))


def time_history_data(tr: Any, shown: int, phys: Any = None, angle: bool = False,
                      points_per_period: int = POINTS_PER_PERIOD) -> dict[str, Any]:
    """Arrays of the time history over the first ``shown`` recorded periods.

    Dimensionless (``t``, position/H₁) by default; with ``phys`` (a ``PhysicalParams``) time
    in ms from the window's start and positions in µm along the line of action, or (``angle``)
    in degrees of the idle gear. The sample grid includes every impact time, so the kinks of
    ``x(t)`` are drawn where they happen. Returns ``motion`` (t, x, y, yj, tooth_lo,
    tooth_hi), ``impacts`` (t, x, impulse, flank), ``stick`` (list of (t, x) arrays) and
    axis ``labels``.
    """
    t_lo = tr.t_start
    t_hi = min(tr.t_end, tr.t_start + TWO_PI * max(1, int(shown)))
    n = max(2, int(math.ceil((t_hi - t_lo) / TWO_PI * points_per_period)) + 1)
    in_win = (tr.impact_t >= t_lo) & (tr.impact_t <= t_hi)
    imp_t = tr.impact_t[in_win]
    stick = tr.stick_intervals
    stick = stick[(stick[:, 1] >= t_lo) & (stick[:, 0] <= t_hi)] if len(stick) else stick
    edges = np.clip(stick.ravel(), t_lo, t_hi) if len(stick) else np.empty(0)
    t = np.union1d(np.linspace(t_lo, t_hi, n), np.concatenate([imp_t, edges]))
    x, _ = tr.sample(t)
    y, yj = tr.walls(t)
    band = tooth_depth(tr.params.j)
    flank = tr.impact_flank[in_win].astype(np.int8)
    wall_y, wall_yj = tr.walls(imp_t)
    imp_x = np.where(flank > 0, wall_y, wall_yj)
    segs = []
    for a, b in stick:
        a, b = max(a, t_lo), min(b, t_hi)
        if b > a:
            ts = np.linspace(a, b, max(2, int((b - a) / TWO_PI * points_per_period) + 2))
            segs.append((ts, tr.sample(ts)[0]))
    impulse = tr.impact_impulse[in_win]
    labels = ("t (= ω t, one period is 2π)", "position / H₁", "Ĩ")
    if phys is not None:
        def tt(v):
            return 1e3 * phys.time(np.asarray(v) - t_lo)
        if angle:
            def xx(v):
                return np.degrees(phys.position(np.asarray(v)) / phys.radius)
            labels = ("t [ms]", "idle-gear angle [°]", "I [N·s]")
        else:
            def xx(v):
                return 1e6 * phys.position(np.asarray(v))
            labels = ("t [ms]", "position along the line of action [µm]", "I [N·s]")
        t, imp_t = tt(t), tt(imp_t)
        x, y, yj, imp_x = xx(x), xx(y), xx(yj), xx(imp_x)
        band = float(xx(band))
        segs = [(tt(a), xx(b)) for a, b in segs]
        impulse = phys.impulse(impulse)
    motion = {"t": t, "x": x, "y": y, "yj": yj, "tooth_lo": y - band, "tooth_hi": yj + band}
    impacts = {"t": imp_t, "x": imp_x, "impulse": impulse, "flank": flank}
    return {"motion": motion, "impacts": impacts, "stick": segs, "labels": labels}


# ----- sections --------------------------------------------------------------------------------

def section_points(tr: Any, mode: str) -> tuple[np.ndarray, np.ndarray, str, str]:
    """Points and axis labels of a section: ``absolute`` ``(x, ẋ)``, ``relative``
    ``(x − y, ẋ − ẏ)`` at the strobe times, or the ``impact`` map ``(t mod 2π, Ĩ)``."""
    if mode == "absolute":
        return tr.strobe_x, tr.strobe_v, "x", "ẋ"
    if mode == "relative":
        x, v = tr.strobe_relative()
        return x, v, "x − y", "ẋ − ẏ"
    if mode == "impact":
        return tr.impact_phase, tr.impact_impulse, "impact phase t mod 2π", "impulse Ĩ"
    raise ValueError(f"section mode = {mode!r}; allowed: absolute, relative, impact")


def first_periods(tr, periods: int):
    """``tr`` cut to its first ``periods`` forcing periods (``tr`` itself if it is not longer).

    Only what the sound uses is kept consistent: the window and the impacts, strobe samples and
    segments inside it.
    """
    if periods >= tr.periods - 1e-9:
        return tr
    t_end = tr.t_start + periods * TWO_PI
    imp = tr.impact_t < t_end
    strobe = tr.strobe_t < t_end
    seg = tr.seg_t < t_end
    return dataclasses.replace(
        tr, t_end=t_end, impact_t=tr.impact_t[imp], impact_phase=tr.impact_phase[imp],
        impact_impulse=tr.impact_impulse[imp], impact_flank=tr.impact_flank[imp],
        impact_w=tr.impact_w[imp], strobe_t=tr.strobe_t[strobe], strobe_x=tr.strobe_x[strobe],
        strobe_v=tr.strobe_v[strobe], seg_t=tr.seg_t[seg], seg_kind=tr.seg_kind[seg],
        seg_x=tr.seg_x[seg], seg_v=tr.seg_v[seg])


class PinMarkers:
    """A dashed vertical line at the pinned run's value (A) and the names A and B at the foot of
    it and of the live run's marker, hand-written Bokeh models on a figure (held weakly, so a closed
    page's figure is not kept). Hidden while there is no pin."""

    def __init__(self) -> None:
        self._models: Callable[[], list | None] = lambda: None

    @property
    def location(self) -> float | None:
        """Where A's line stands (None while it is hidden or not drawn)."""
        models = self._models()
        return None if models is None or not models[0].visible else models[0].location

    @property
    def models(self) -> list | None:
        """A's line and the labels A and B, once on a figure."""
        return self._models()

    def attach(self, fig: Any, a: float | None, b: float) -> None:
        """Put the models on ``fig`` (once per figure) and place them."""
        from bokeh.models import Label, Node, Span
        models = self._models()
        if models is None or models[0] not in fig.center:
            # at the frame's foot: a legend stands at its head
            foot = Node(target="frame", symbol="bottom", offset=-4)
            label = dict(y=foot, x=b, text_font_size="10pt", text_font_style="bold", visible=False,
                         background_fill_color="white", background_fill_alpha=0.8)
            models = [Span(location=b, dimension="height", line_color=PIN_COLOR, line_width=2,
                           line_dash="dashed", name="pinned_value", visible=False),
                      Label(text=" A ", text_color=PIN_COLOR, name="pinned_label", **label),
                      Label(text=" B ", text_color=MARK_COLOR, name="current_label", **label)]
            for model in models:
                fig.add_layout(model)
            refs = [weakref.ref(m) for m in models]
            self._models = lambda: (None if any(r() is None for r in refs) else [r() for r in refs])
        self.place(a, b)

    def place(self, a: float | None, b: float) -> None:
        """A's line at ``a`` (hidden when None) and the names at ``a`` and ``b``."""
        models = self._models()
        if models is None:
            return
        span, label_a, label_b = models
        shown = a is not None
        # the names stand on either side of the lines, so that they do not cover each other
        # when A and B are at the same value
        left = shown and a <= b
        updates = ((span, dict(visible=shown, location=a if shown else b)),
                   (label_a, dict(visible=shown, x=a if shown else b,
                                  anchor="bottom_right" if left else "bottom_left")),
                   (label_b, dict(visible=shown, x=b,
                                  anchor="bottom_left" if left else "bottom_right")))
        for model, values in updates:
            changed = {k: v for k, v in values.items() if getattr(model, k) != v}
            if changed:
                model.update(**changed)
