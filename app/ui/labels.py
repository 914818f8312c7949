"""Words, colours and safe HTML for the dashboard: the only module that turns results into text.

* The regime colour table and the flank colours live here and nowhere else in ``app``, so a
  shared vocabulary module can replace them in one edit.
* :func:`regime_badge` is the one place that reads the sticking details a ``Classification``
  may carry (``sticking``, ``loop_amplification``); it works with classifications that have
  them and with those that do not.
* :func:`regime_legend_html` and :func:`what_you_see` explain regimes in the vocabulary's own
  words (its meanings and rules, which are ``docs/model.md``'s table), never in a copy of them.
* Every piece of text that may hold user or URL input reaches the page through
  :func:`message_html` or :func:`text_html`, which escape it: no user text is ever HTML.
"""
from __future__ import annotations

import html
import math
from typing import Any

import numpy as np

from ..core import REGIME_CODES, REGIME_COLOURS, REGIME_RULES, REGIMES

#: Regime letter → colour (maps, badge, legends).
REGIME_COLOR = dict(REGIME_COLOURS)
ACTIVE_COLOR = "#c0392b"
REVERSE_COLOR = "#1f5fa8"
STICK_COLOR = "#f39c12"
TOOTH_COLOR = "#9aa5b1"
GEAR_COLOR = "#222222"
MARK_COLOR = "#2ca02c"
#: The pinned run (A), drawn beside the live one (B): muted, so B stays the one in front.
PIN_COLOR = "#8c6bb1"
ONSET_COLOR = "#8e44ad"
CHAOS_COLOR = "#d35400"
#: Flank code → (colour, label), for impacts in every view.
FLANKS = {1: (ACTIVE_COLOR, "active flank"), -1: (REVERSE_COLOR, "reverse flank")}
REGIME_MEANING = {**REGIMES, "error": "solver limit"}

_MSG_STYLE = ("background:#f8d7da;color:#842029;border:1px solid #f5c2c7;border-radius:4px;"
              "padding:6px 10px;margin:2px 0;font-size:13px;white-space:pre-wrap;"
              "overflow-wrap:anywhere")


def short(value: Any, limit: int = 40) -> str:
    """``repr`` of a value a user typed, cut to ``limit`` characters (still to be escaped)."""
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 1] + "…"


def message_html(text: str) -> str:
    """An error message as HTML: the text escaped, never interpreted."""
    return f'<div class="rattle-msg" style="{_MSG_STYLE}"><p style="margin:0">{html.escape(text)}</p></div>'


def text_html(text: str, style: str = "") -> str:
    """Plain text as HTML (escaped), in a ``<div>`` with an optional inline style."""
    return f'<div style="{html.escape(style)}">{html.escape(text)}</div>'


def num(v: float | None, digits: int = 4) -> str:
    """A number for people: ``–`` when missing or not finite."""
    if v is None or not isinstance(v, (int, float)) or not math.isfinite(v):
        return "–"
    return f"{v:.{digits}g}"


def percent(fraction: float) -> str:
    """A fraction of time as a percentage people read (``100 %``, ``12.5 %``, ``< 0.1 %``)."""
    if not math.isfinite(fraction):
        return "–"
    p = 100.0 * fraction
    if p == 0.0:
        return "0 %"
    if p < 0.1:
        return "< 0.1 %"
    return f"{p:.0f} %" if p >= 10 else f"{p:.1f} %"


def lyapunov_text(lyap: float | None) -> str:
    if lyap is None or (isinstance(lyap, float) and math.isnan(lyap)):
        return "n/a"
    if math.isinf(lyap):
        return "−∞ (sticking)" if lyap < 0 else "+∞"
    return f"{lyap:+.4f}"


def sticking_text(cls: Any) -> str:
    """How the gear sticks, if it does: the only reader of ``sticking``/``loop_amplification``."""
    kind = getattr(cls, "sticking", "") or ""
    amp = getattr(cls, "loop_amplification", math.nan)
    amp_text = f", loop amplification 10^{amp:.1f}" if isinstance(amp, float) and math.isfinite(amp) else ""
    if kind == "chaos-through-sticking":
        if getattr(cls, "noisy", True):
            return "chaos through sticking, statistics at this noise level"
        return "loop chosen by rounding: not resolvable (noise off)"
    if kind == "stick-locked" and cls.regime != "A":  # A never leaves the wall: nothing to lock
        period = f", period {cls.period}" if cls.period else ""
        return f"stick-locked, exact{period}" + amp_text
    if cls.stick_fraction > 0:
        return f"sticking {percent(cls.stick_fraction)} of the time"
    return ""


def regime_badge(cls: Any) -> dict[str, str]:
    """The badge's parts: ``letter``, ``color``, ``headline`` and ``detail`` (plain text)."""
    period = f"period {cls.period}" if cls.period else "no period ≤ 32"
    chaos = "chaotic" if cls.chaotic else "not chaotic"
    headline = f"{period} · {chaos} · Lyapunov λ = {lyapunov_text(cls.lyapunov)}"
    parts = [f"{cls.regime}: {REGIME_MEANING.get(cls.regime, '')}"]
    stick = sticking_text(cls)
    if stick:
        parts.append(stick)
    parts.append(f"{num(cls.active_per_period, 3)} active + {num(cls.reverse_per_period, 3)} "
                 "reverse impacts per period")
    return {"letter": cls.regime, "color": REGIME_COLOR.get(cls.regime, "#555555"),
            "headline": headline, "detail": " · ".join(parts)}


def badge_html(cls: Any) -> str:
    """The regime badge as HTML (every part escaped)."""
    b = {k: html.escape(v) for k, v in regime_badge(cls).items()}
    sticking = html.escape(getattr(cls, "sticking", "") or "")
    return (f'<div class="rattle-badge" data-regime="{b["letter"]}" data-sticking="{sticking}" '
            f'style="display:flex;gap:12px;'
            f'align-items:center"><span class="badge-letter" style="background:{b["color"]};color:white;font-size:28px;'
            f'font-weight:bold;border-radius:8px;padding:4px 14px">{b["letter"]}</span>'
            f'<span><b>{b["headline"]}</b><br><span class="badge-detail" style="color:#555">'
            f'{b["detail"]}</span></span></div>')


def regime_legend_html() -> str:
    """Every regime a run can be given: its colour, letter and meaning (the vocabulary's)."""
    chips = "".join(
        f'<span class="legend-regime" data-regime="{k}" title="{html.escape(REGIME_RULES[k])}" '
        f'style="white-space:nowrap;margin-right:10px"><b style="background:{REGIME_COLOR[k]};'
        f'color:white;border-radius:4px;padding:0 5px">{k}</b> {html.escape(meaning)}</span> '
        for k, meaning in REGIMES.items())
    return f'<div class="regime-legend" style="font-size:12px;line-height:1.7">{chips}</div>'


def what_you_see(cls: Any) -> str:
    """One sentence on what the current regime looks like: the vocabulary's rule for it
    (``docs/model.md``, "Regimes", beside the badge that names it) and the run's own period
    (plain text)."""
    if cls is None or cls.regime not in REGIMES:
        return ""
    if cls.period:
        shape = (f"the Poincaré map repeats every {cls.period} period"
                 f"{'s' if cls.period > 1 else ''}: {cls.period} point{'s' if cls.period > 1 else ''}")
    else:
        shape = "the Poincaré map never repeats: a cloud of points"
    return f"What you see: {REGIME_RULES[cls.regime]}; {shape}."


def table_html(rows: list[tuple[str, ...]], css: str, head: tuple[str, ...] | None = None,
               nowrap: bool = False) -> str:
    """Rows of plain text as an HTML table (every cell escaped; the last columns bold; with
    ``nowrap``, each cell on one line)."""
    e = html.escape
    td = "padding-right:12px" + (";white-space:nowrap" if nowrap else "")
    out = [f'<table class="{e(css)}" style="font-size:13px;border-collapse:collapse">']
    if head:
        out.append("<tr>" + "".join(f"<th style='text-align:left;{td}'>{e(h)}</th>"
                                    for h in head) + "</tr>")
    for row in rows:
        cells = [f"<td style='{td}'>{e(row[0])}</td>"]
        cells += [f"<td style='{td}'><b>{e(c)}</b></td>" for c in row[1:]]
        out.append("<tr>" + "".join(cells) + "</tr>")
    out.append("</table>")
    return "".join(out)


def pm(value: float, ci95: float | None = None, scale: float = 1.0) -> str:
    """``value ± half-width`` (scaled), or the value alone when the half-width is 0 or unknown."""
    if value is None or not math.isfinite(value):
        return "–"
    if ci95 is None or not math.isfinite(ci95) or ci95 <= 0.0:
        return num(value * scale)
    return f"{num(value * scale)} ± {num(ci95 * scale, 2)}"


def metrics_rows(cls: Any, tr: Any, phys: Any = None,
                 intervals: dict | None = None) -> list[tuple[str, str]]:
    """Rattle metrics of the recorded window: dimensionless, or in SI units with ``phys``.

    ``intervals`` (statistic → ``Estimate``, from ``batch_means``) adds each statistic's 95 %
    half-width where the run is not periodic, and a row that says what it is.
    """
    est = intervals if intervals is not None and cls.period == 0 else {}

    def ci(key: str) -> float | None:
        e = est.get(key)
        return None if e is None else e.ci95
    f, s = (1.0, 1.0) if phys is None else (phys.frequency_hz, phys.impulse_scale)
    if phys is None:
        names = ("impacts / period (active, reverse)", "mean |Ĩ| (active, reverse)",
                 "RMS Ĩ (active, reverse)", "rattle intensity Σ Ĩ² / period")
        units = ("", "", "", "")
    else:
        names = ("impact rate (active, reverse)", "mean |I| (active, reverse)",
                 "RMS I (active, reverse)", "rattle intensity Σ I² per second")
        units = (" 1/s", " N·s", " N·s", " N²·s")
    total = (f" (total {pm(cls.impacts_per_period, ci('impacts_per_period'), f)})"
             if est else "")
    rows = [
        (names[0], f"{num(cls.active_per_period * f)}, {num(cls.reverse_per_period * f)}"
                   f"{units[0]}{total}"),
        (names[1], f"{pm(cls.mean_impulse_active, ci('mean_active_impulse'), s)}, "
                   f"{pm(cls.mean_impulse_reverse, ci('mean_reverse_impulse'), s)}{units[1]}"),
        (names[2], f"{num(cls.rms_impulse_active * s)}, {num(cls.rms_impulse_reverse * s)}"
                   f"{units[2]}"),
        (names[3], f"{pm(cls.intensity, ci('intensity'), s * s * f)}{units[3]}"),
    ]
    seconds = f" ({num(1e3 * tr.periods * phys.period_s)} ms)" if phys is not None else ""
    rows += [("time in permanent contact", percent(cls.stick_fraction)),
             ("impacts recorded", f"{len(tr.impact_t)} in {tr.periods:.0f} periods{seconds}")]
    if est:
        n = next(iter(est.values())).n
        rows.append(("±", f"95 % interval: {n} batch means of this run"))
    return rows


def what_to_hear(classification, impacts: int, seconds: float, freq_hz: float) -> str:
    """One line: impacts per second and the regime, as the ear meets them."""
    if classification is None:
        return ""
    c = classification
    if impacts == 0:
        if c.regime in ("A", "B") or c.stick_fraction > 0:
            return ("**Silence**: the gear rides the driving tooth (permanent contact), "
                    "so nothing strikes the housing.")
        return "**Silence**: no impact in the periods played."
    rate = c.impacts_per_period * freq_hz
    if c.regime == "B":
        return (f"**Chatter, then silence**: {impacts} impacts in {seconds:.2f} s, then the gear "
                f"sticks to the tooth ({percent(c.stick_fraction)} of the time) and the housing "
                "rings out.")
    if c.regime == "D":
        stick = " with silent stick phases" if c.stick_fraction > 0 else ""
        return f"**Chaotic rattle**{stick}: irregular impacts, about {rate:.4g} per second."
    if c.regime == "Q":
        return f"**Irregular rattle** (non-repeating): about {rate:.4g} impacts per second."
    return (f"**Periodic buzz**: {rate:.4g} impacts per second, repeating every {c.period} "
            f"period{'s' if c.period > 1 else ''} ({freq_hz / max(c.period, 1):.4g} Hz).")


def map_legend(r: Any) -> str:
    """The regimes (or attractors) of a map with their colours and counts (no user text)."""
    def swatch(colour: str) -> str:
        return (f"<span style='display:inline-block;width:14px;height:14px;background:{colour};"
                "border:1px solid #555;margin-right:6px;vertical-align:middle'></span>")
    if r.kind == "basin":
        from bokeh.palettes import Category20
        rows = [f"<div class='map-attractor' data-regime='{a['regime']}'>{swatch(Category20[20][i % 20])}"
                f"<b>{i}</b>: regime {a['regime']}{', period ' + str(a['period']) if a['period'] else ''}, "
                f"{100 * a['share']:.1f} %</div>" for i, a in enumerate(r.attractors[:40])]
        return "<div><b>Attractors</b> (regime, period, share of the grid)</div>" + "".join(rows)
    reg = np.asarray(r.fields["regime"])
    rows = [f"<div class='map-regime' data-regime='{k}'>{swatch(REGIME_COLOR[k])}<b>{k}</b> "
            f"{REGIME_MEANING[k]} ({int((reg == c).sum())})</div>" for k, c in REGIME_CODES.items()]
    return "<div><b>Regimes</b> (points)</div>" + "".join(rows)


#: Regime names short enough for a legend inside a plot.
REGIME_SHORT = {"A": "permanent contact", "B": "impacts, then contact", "C": "one impact per period",
                "D": "chaotic", "E": "one impact per flank", "P": "periodic", "Q": "non-repeating",
                "error": "solver limit"}


def map_colours(field: str, z: np.ndarray) -> dict[str, Any]:
    """The colour scale of a map of ``field`` with values ``z``: the regime colours, a palette
    of attractors, a log scale for the rattle intensity, a linear one for the rest."""
    if field == "regime":
        return {"cmap": [REGIME_COLOR[k] for k in REGIME_CODES], "colorbar": False, "logz": False,
                "clim": (-0.5, len(REGIME_CODES) - 0.5)}
    if field == "attractor":
        from bokeh.palettes import Category20
        return {"cmap": list(Category20[20]), "clim": (-0.5, 19.5), "colorbar": False, "logz": False}
    finite = z[np.isfinite(z)]
    lo, hi = (float(finite.min()), float(finite.max())) if finite.size else (0.0, 1.0)
    if field == "intensity":
        return {"cmap": "magma", "logz": True, "colorbar": True,
                "clim": (max(lo, 1e-4 * hi), max(hi, lo * (1 + 1e-9)))}
    return {"cmap": "viridis", "logz": False, "colorbar": True,
            "clim": (lo, hi if hi > lo else lo + 1.0)}


def map_key(r: Any, field: str) -> list[tuple[str, str]]:
    """The colour key drawn inside a map's figure: ``(label, colour)`` of each regime (or
    attractor) present; none for a field with a colour bar."""
    if r is None:
        return []
    if field not in r.fields:  # as the map's image does
        field = "attractor" if r.kind == "basin" else "regime"
    if field == "attractor":
        from bokeh.palettes import Category20
        return [(f"{i}: {a['regime']}" + (f", period {a['period']}" if a["period"] else ""),
                 Category20[20][i % 20]) for i, a in enumerate(r.attractors[:20])]
    if field != "regime":
        return []
    reg = np.asarray(r.fields["regime"])
    return [(f"{k} {REGIME_SHORT[k]}", REGIME_COLOR[k]) for k, c in REGIME_CODES.items() if (reg == c).any()]


def not_periodic_text(cls: Any) -> str:
    """Why "Continue this orbit" is off for a run that is not periodic (HTML, no user text)."""
    letter = getattr(cls, "regime", "")
    what = f"regime {letter}, {REGIME_MEANING.get(letter, 'not periodic')}" if letter else "not periodic"
    return (f"<div style='font-size:12px;color:#555'>Continuation follows a periodic orbit; this run "
            f"is {html.escape(what)}. Move to a periodic value (C, E or P on the diagram's regimes) "
            f"to continue from there.</div>")


def twin_text(data: Any) -> str:
    """What the twin trajectory shows, in words (HTML, numbers only: no user text)."""
    if data is None:
        return ""
    gap = data["distance"]
    start, end = float(gap[0]), float(np.median(gap[-len(gap) // 8:]))
    lam = data["lyapunov"]
    if end > 1e3 * start:
        what = (f"The twin started {start:.1e} away and is now {end:.2g} away: the gap grew "
                f"{end / start:.1e}-fold. Chaos: a tiny difference in the start decides the "
                "rattle, so only statistics of it can be predicted.")
    elif end < 1e-2 * start:
        what = (f"The twin started {start:.1e} away and is now {end:.1e} away: both gears fall "
                "onto the same periodic orbit, which attracts its neighbours.")
    else:
        what = (f"The twin started {start:.1e} away and is now {end:.2g} away: neither clearly "
                "apart nor together over this time.")
    if math.isfinite(lam):
        what += f" The run's Lyapunov exponent is λ = {lam:+.3g} per unit time (ω t)."
    return f"<div style='font-size:13px'>{html.escape(what)}</div>"
