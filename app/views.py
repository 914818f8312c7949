"""View builders: a trajectory or a sweep in, plot data and Bokeh figures out.

Two kinds of functions live here, and neither knows about sessions, widgets or threads:

* data builders (``time_history_data``, ``section_points``, ``rasterize``, ``overlay_lines``,
  ``badge_html``, ``metrics_html``, ``impacts_csv``) turn results into plain arrays, dicts and
  strings, so unit tests can check them without a browser;
* figure builders (``time_history_figure``, ``section_figure``, ``bifurcation_figure``) make
  the Bokeh figures once per session. Updates then replace the data of their
  ``ColumnDataSource``s, never the figures, so the browser keeps the user's zoom and pan:
  a ``DataRange1d`` follows the data until the user zooms, and the reset tool returns to it.

Many points (the bifurcation diagram, long Poincaré maps) are rasterised on the server with
datashader, at the plot's pixel size and over the visible range only.
"""
from __future__ import annotations

import html
import io
import math

import numpy as np
import pandas as pd
from bokeh.models import (ColumnDataSource, DataRange1d, HoverTool, Legend, LegendItem, Span,
                          Title)
from bokeh.plotting import figure

from rattle_core import Trajectory
from rattle_core.analysis.vocabulary import (ACTIVE, FLANK_COLOURS, REGIME_COLOURS, REVERSE,
                                             STICK_COLOUR, UNKNOWN_COLOUR, flank_colours)
from rattle_core.model.excitation import TWO_PI
from rattle_core.store.exports import impacts_frame

ACTIVE_COLOR = FLANK_COLOURS[ACTIVE]
REVERSE_COLOR = FLANK_COLOURS[REVERSE]
STICK_COLOR = STICK_COLOUR
TOOTH_COLOR = "#9aa5b1"
GEAR_COLOR = "#222222"
MARK_COLOR = "#2ca02c"
#: Above this many section points the Poincaré map is rasterised instead of drawn as glyphs.
RASTER_THRESHOLD = 4000
#: Samples per forcing period of the time history (impact instants are added exactly).
POINTS_PER_PERIOD = 160



# ----- data builders --------------------------------------------------------------------------

def time_history_data(tr: Trajectory, shown: int,
                      points_per_period: int = POINTS_PER_PERIOD) -> dict[str, dict]:
    """Columns for the time history over the first ``shown`` recorded periods.

    Returns ``{"motion": {t, x, y, yj, tooth_lo, tooth_hi}, "impacts": {t, x, flank, impulse,
    color}, "stick": {xs, ys}}``. The sample grid includes every impact time, so the kinks of
    ``x(t)`` are drawn where they happen, not up to one sample late.
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
    motion = {"t": t, "x": x, "y": y, "yj": yj, "tooth_lo": y - band, "tooth_hi": yj + band}

    flank = tr.impact_flank[in_win].astype(np.int8)
    wall_y, wall_yj = tr.walls(imp_t)
    impacts = {"t": imp_t, "x": np.where(flank > 0, wall_y, wall_yj), "flank": flank,
               "impulse": tr.impact_impulse[in_win],
               "color": flank_colours(flank),
               "side": np.where(flank > 0, "active flank", "reverse flank").astype(object)}

    xs, ys = [], []
    for a, b in stick:
        a, b = max(a, t_lo), min(b, t_hi)
        if b <= a:
            continue
        ts = np.linspace(a, b, max(2, int((b - a) / TWO_PI * points_per_period) + 2))
        xs.append(ts)
        ys.append(tr.sample(ts)[0])
    return {"motion": motion, "impacts": impacts, "stick": {"xs": xs, "ys": ys}}


def tooth_depth(j: float) -> float:
    """Drawn thickness of each tooth: visible at any backlash, never dominating the gap."""
    return max(0.6, 0.25 * float(j))


def section_points(tr: Trajectory, mode: str) -> tuple[np.ndarray, np.ndarray, str, str]:
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


def padded_range(v: np.ndarray, pad: float = 0.05) -> tuple[float, float]:
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


def rasterize(x: np.ndarray, y: np.ndarray, x_range: tuple[float, float],
              y_range: tuple[float, float], width: int, height: int,
              category: np.ndarray | None = None, colors: dict | None = None,
              spread: int = 0) -> dict:
    """Datashader image of points over a range, as ``image_rgba`` columns.

    With ``category`` (small integers) and ``colors`` ({code: '#rrggbb'}), each category keeps
    its colour; otherwise density is shaded in blues with histogram equalisation, so sparse
    and dense parts of an attractor both show. ``spread`` > 0 grows every pixel by that many
    pixels on each side (datashader's ``spread``), so isolated points of a cloud stay visible.
    """
    import datashader as ds
    import datashader.transfer_functions as tf

    width, height = max(int(width), 8), max(int(height), 8)
    x0, x1 = float(x_range[0]), float(x_range[1])
    y0, y1 = float(y_range[0]), float(y_range[1])
    if not (x1 > x0 and y1 > y0):
        raise ValueError(f"empty raster range x={x_range}, y={y_range}")
    cvs = ds.Canvas(plot_width=width, plot_height=height, x_range=(x0, x1), y_range=(y0, y1))
    df = pd.DataFrame({"x": np.asarray(x, dtype=np.float64), "y": np.asarray(y, dtype=np.float64)})
    if category is not None and colors:
        names = {k: str(k) for k in colors}
        df["c"] = pd.Categorical(pd.Series(np.asarray(category)).map(names),
                                 categories=list(names.values()))
        agg = cvs.points(df, "x", "y", agg=ds.count_cat("c"))
        img = tf.shade(agg, color_key={names[k]: c for k, c in colors.items()}, how="eq_hist",
                       min_alpha=90)
    else:
        agg = cvs.points(df, "x", "y", agg=ds.count())
        img = tf.shade(agg, cmap=["#4a90c8", "#08306b"], how="eq_hist", min_alpha=140)
    if spread:
        # a periodic orbit piles thousands of points into one pixel: draw each as a small dot
        img = tf.spread(img, px=spread)
    rgba = np.ascontiguousarray(img.values, dtype=np.uint32)
    return {"image": [rgba], "x": [x0], "y": [y0], "dw": [x1 - x0], "dh": [y1 - y0]}


EMPTY_IMAGE = {"image": [], "x": [], "y": [], "dw": [], "dh": []}


def overlay_lines(name: str, lam: float, x_range: tuple[float, float], lam_c: float | None,
                  orders: int = 4) -> dict:
    """Analytic overlays for a diagram of Ĩ against ``name`` (``lam`` or ``phi2``).

    One-sided period-n orbits have impulse exactly ``2πn/Λ``: curves against Λ, horizontal
    lines against φ₂. The permanent-contact boundary Λ_c is a vertical line against Λ only
    (against φ₂, Λ is fixed). Returns ``{"curves": {xs, ys, n}, "boundary": Λ_c or None}``.
    """
    lo, hi = float(x_range[0]), float(x_range[1])
    xs, ys, ns = [], [], []
    for n in range(1, orders + 1):
        if name == "lam":
            lam_axis = np.linspace(max(lo, 1e-3), max(hi, 2e-3), 200)
            xs.append(lam_axis)
            ys.append(TWO_PI * n / lam_axis)
        else:
            xs.append(np.array([lo, hi]))
            ys.append(np.full(2, TWO_PI * n / lam))
        ns.append(f"2π·{n}/Λ")
    boundary = lam_c if (name == "lam" and lam_c is not None and math.isfinite(lam_c)) else None
    return {"curves": {"xs": xs, "ys": ys, "n": ns}, "boundary": boundary}


def rpm_overlay_lines(phys, x_range: tuple[float, float], lam_c: float | None,
                      newton_seconds: bool = False, orders: int = 4) -> dict:
    """The overlays of :func:`overlay_lines` for a diagram against engine speed.

    Along an engine-speed sweep of ``phys`` (a ``rattle_core.model.units.PhysicalParams``), Λ(rpm)
    is ``units.lam_from_rpm``, so the one-sided period-n impulses are ``2πn/Λ(rpm)``, times
    ``m ω H₁`` in N·s; the contact boundary Λ_c sits at ``units.rpm_from_lam(Λ_c)`` when Λ
    moves with speed (displacement amplitudes held).
    """
    from rattle_core import units

    lo, hi = max(float(x_range[0]), 1e-3), max(float(x_range[1]), 2e-3)
    rpm = np.linspace(lo, hi, 200)
    lam = units.lam_from_rpm(phys, rpm)
    scale = units.impulse_scale_from_rpm(phys, rpm) if newton_seconds else 1.0
    xs = [rpm] * orders
    ys = [TWO_PI * n / lam * scale for n in range(1, orders + 1)]
    ns = [f"2π·{n}/Λ" for n in range(1, orders + 1)]
    boundary = None
    if phys.excitation == "displacement" and lam_c is not None and math.isfinite(lam_c) and lam_c > 0:
        boundary = float(units.rpm_from_lam(phys, lam_c))
    return {"curves": {"xs": xs, "ys": ys, "n": ns}, "boundary": boundary}


def badge_html(cls) -> str:
    """The regime badge: letter, period, chaotic or not, Lyapunov exponent."""
    color = REGIME_COLOURS.get(cls.regime, UNKNOWN_COLOUR)
    lyap = cls.lyapunov
    if lyap is None or (isinstance(lyap, float) and math.isnan(lyap)):
        lyap_txt = "n/a"
    elif math.isinf(lyap):
        lyap_txt = "−∞ (sticking)" if lyap < 0 else "+∞"
    else:
        lyap_txt = f"{lyap:+.4f}"
    period = f"period {cls.period}" if cls.period else "no period ≤ 32"
    chaos = "chaotic" if cls.chaotic else "not chaotic"
    label = html.escape(cls.label)
    sticking = getattr(cls, "sticking", "")
    kind = STICKING_TEXT.get((sticking, bool(getattr(cls, "noisy", False))), "")
    if sticking == "stick-locked" and math.isfinite(getattr(cls, "loop_amplification", math.nan)):
        kind += f", loop amplification 10^{cls.loop_amplification:.1f}"
    kind_html = f' · <span class="sticking-kind">{html.escape(kind)}</span>' if kind else ""
    return (f'<div class="rattle-badge" data-regime="{cls.regime}" data-sticking="{sticking}" '
            f'style="display:flex;gap:12px;align-items:center">'
            f'<span style="background:{color};color:white;font-size:28px;font-weight:bold;'
            f'border-radius:8px;padding:4px 14px">{cls.regime}</span>'
            f'<span><b>{period}</b> · {chaos} · Lyapunov λ = {lyap_txt}{kind_html}<br>'
            f'<span style="color:#555">{label}</span></span></div>')


#: What the badge says of motion through sticking: (sticking kind, noisy) → text.
STICKING_TEXT = {
    ("stick-locked", False): "stick-locked, exact",
    ("chaos-through-sticking", True): "chaos through sticking, vanishing-noise statistics",
    ("chaos-through-sticking", False): "loop chosen by rounding: not resolvable (noise off)",
}


def metrics_html(cls, tr: Trajectory) -> str:
    """Rattle metrics of the recorded window as a compact table."""
    def f(v: float) -> str:
        return "–" if v is None or not math.isfinite(v) else f"{v:.4g}"
    rows = [
        ("impacts / period (active, reverse)", f"{f(cls.active_per_period)}, {f(cls.reverse_per_period)}"),
        ("mean |Ĩ| (active, reverse)", f"{f(cls.mean_impulse_active)}, {f(cls.mean_impulse_reverse)}"),
        ("RMS Ĩ (active, reverse)", f"{f(cls.rms_impulse_active)}, {f(cls.rms_impulse_reverse)}"),
        ("rattle intensity Σ Ĩ² / period", f(cls.intensity)),
        ("time in permanent contact", f"{100 * cls.stick_fraction:.1f} %"),
        ("impacts recorded", f"{len(tr.impact_t)} in {tr.periods:.0f} periods"),
    ]
    body = "".join(f"<tr><td style='padding-right:10px'>{html.escape(k)}</td><td><b>{v}</b></td></tr>"
                   for k, v in rows)
    return f'<table class="rattle-metrics" style="font-size:13px">{body}</table>'


def impacts_csv(tr: Trajectory) -> str:
    """Every recorded impact as CSV: time, phase, signed impulse, flank, incoming relative velocity."""
    buf = io.StringIO()
    impacts_frame(tr).to_csv(buf, index=False, float_format="%.17g")
    return buf.getvalue()


# ----- figure builders ------------------------------------------------------------------------

_TOOLS = "pan,wheel_zoom,box_zoom,reset,save"


def time_history_figure() -> tuple[figure, dict[str, ColumnDataSource]]:
    """x(t) between the teeth: walls y and y + j, shaded teeth, impacts by flank, stick phases."""
    sources = {"motion": ColumnDataSource({k: [] for k in ("t", "x", "y", "yj", "tooth_lo", "tooth_hi")}),
               "impacts": ColumnDataSource({k: [] for k in ("t", "x", "flank", "impulse", "color", "side")}),
               "stick": ColumnDataSource({"xs": [], "ys": []})}
    p = figure(height=330, sizing_mode="stretch_width", tools=_TOOLS, active_scroll="wheel_zoom",
               x_range=DataRange1d(), y_range=DataRange1d(), output_backend="canvas",
               x_axis_label="t (= ω t, one period is 2π)", y_axis_label="position / H₁",
               name="time_history")
    p.title.text = "Time history: the idle gear x(t) between the driving teeth"
    m = sources["motion"]
    teeth_a = p.varea(x="t", y1="tooth_lo", y2="y", source=m, fill_color=TOOTH_COLOR, fill_alpha=0.55)
    teeth_r = p.varea(x="t", y1="yj", y2="tooth_hi", source=m, fill_color=TOOTH_COLOR, fill_alpha=0.55)
    wall_a = p.line("t", "y", source=m, color="#5d6d7e", line_width=1.5)
    wall_r = p.line("t", "yj", source=m, color="#5d6d7e", line_width=1.5, line_dash="dashed")
    gear = p.line("t", "x", source=m, color=GEAR_COLOR, line_width=1.8)
    stick = p.multi_line("xs", "ys", source=sources["stick"], color=STICK_COLOR, line_width=6,
                         line_alpha=0.8)
    imp = p.scatter("t", "x", source=sources["impacts"], color="color", size=7, line_color="white",
                    marker="circle")
    p.add_tools(HoverTool(renderers=[imp], tooltips=[("t", "@t{0.000}"), ("Ĩ", "@impulse{0.0000}"),
                                                       ("flank", "@side")]))
    legend = Legend(items=[LegendItem(label="gear x(t)", renderers=[gear]),
                           LegendItem(label="active tooth y(t)", renderers=[wall_a, teeth_a]),
                           LegendItem(label="reverse tooth y(t)+j", renderers=[wall_r, teeth_r]),
                           LegendItem(label="impact (red active, blue reverse)", renderers=[imp]),
                           LegendItem(label="permanent contact", renderers=[stick])],
                    location="top_left", click_policy="hide", background_fill_alpha=0.7)
    p.add_layout(legend, "right")
    return p, sources


def update_time_history(sources: dict[str, ColumnDataSource], data: dict[str, dict]) -> None:
    """Replace the time history's data (ranges and zoom untouched)."""
    for key, src in sources.items():
        src.data = data[key]


def section_figure() -> tuple[figure, dict[str, ColumnDataSource]]:
    """Poincaré (or impact) map: glyphs when few points, a datashader image when many."""
    sources = {"points": ColumnDataSource({"x": [], "y": []}),
               "image": ColumnDataSource(dict(EMPTY_IMAGE)),
               "extent": ColumnDataSource({"x": [], "y": []}),
               "start": ColumnDataSource({"x": [], "y": []})}
    p = figure(height=380, sizing_mode="stretch_width", tools=_TOOLS + ",tap",
               active_scroll="wheel_zoom", x_range=DataRange1d(), y_range=DataRange1d(),
               name="section", match_aspect=False)
    p.title.text = "Poincaré map"
    p.add_layout(Title(text="click: start the gear there (x₀, ẋ₀ at the strobe phase)",
                       text_font_style="italic", text_font_size="11px"), "below")
    p.image_rgba(image="image", x="x", y="y", dw="dw", dh="dh", source=sources["image"])
    # invisible corners of the full data, so "reset" returns to the whole map after a zoom
    p.scatter("x", "y", source=sources["extent"], alpha=0.0, size=1)
    p.scatter("x", "y", source=sources["points"], size=4, color=REVERSE_COLOR, alpha=0.8)
    p.scatter("x", "y", source=sources["start"], marker="x", size=14, line_width=3, color=MARK_COLOR)
    return p, sources


def bifurcation_figure() -> tuple[figure, dict]:
    """Ĩ against the swept parameter: raster of impacts, current-value marker, analytic overlays."""
    sources = {"image": ColumnDataSource(dict(EMPTY_IMAGE)),
               "extent": ColumnDataSource({"x": [], "y": []}),
               "curves": ColumnDataSource({"xs": [], "ys": [], "n": []})}
    p = figure(height=380, sizing_mode="stretch_width", tools=_TOOLS + ",tap",
               active_scroll="wheel_zoom", x_range=DataRange1d(), y_range=DataRange1d(),
               name="bifurcation", x_axis_label="Λ", y_axis_label="impulse Ĩ")
    p.title.text = "Bifurcation diagram"
    p.add_layout(Title(text="click: set the parameter · zoom: recompute that region finer",
                       text_font_style="italic", text_font_size="11px"), "below")
    p.image_rgba(image="image", x="x", y="y", dw="dw", dh="dh", source=sources["image"])
    extent = p.scatter("x", "y", source=sources["extent"], alpha=0.0, size=1)
    # auto-range on the data only: the 2πn/Λ curves grow without bound as Λ → 0
    p.x_range.renderers = [extent]
    p.y_range.renderers = [extent]
    curves = p.multi_line("xs", "ys", source=sources["curves"], color="#27ae60", line_width=1.5,
                          line_dash="dotted")
    marker = Span(location=0.0, dimension="height", line_color=MARK_COLOR, line_width=2)
    boundary = Span(location=0.0, dimension="height", line_color="#8e44ad", line_width=2,
                    line_dash="dashed", visible=False)
    p.add_layout(marker)
    p.add_layout(boundary)
    handles = {"sources": sources, "marker": marker, "boundary": boundary, "curves": curves}
    return p, handles
