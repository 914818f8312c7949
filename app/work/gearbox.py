"""The Gearbox tab's work, run in the job pool's worker processes: uploads parsed, verdicts
computed, the gearbox's sound rendered, the report drawn.

Uploaded bytes are untrusted: they are parsed here, in a worker, never in the server process.
A measurement has bounds of its own (:data:`MEASUREMENT_SECONDS`, :data:`MEASUREMENT_MAX_ROWS`),
apart from the compute jobs' limits, and reports its progress. A measurement is written to a temporary file of this module's
own naming (``rattle-upload-*``), read whole and checked by
:func:`rattle_core.measure.measurement.read_measurement` (the options given), analysed, and deleted; no name taken from an upload
ever reaches the file system. A gearbox text is parsed with no folder to look in, so it can
open no file (:meth:`rattle_core.model.gearbox.Gearbox.from_text`).
"""
from __future__ import annotations

import base64
import datetime
import hashlib
import html
import io
import math
import os
import tempfile
import time
from typing import Any

import numpy as np

from .jobs import cancelled, report

#: Largest upload taken [bytes]: a measurement, and a gearbox file.
MAX_MEASUREMENT_BYTES = 20_000_000
MAX_TOML_BYTES = 1_000_000
#: An uploaded measurement's own bounds, apart from the compute jobs' limits: the seconds its
#: reading and order analysis may take, and its samples (which bound their memory, about
#: 350 bytes a sample: 700 MB at most).
MEASUREMENT_SECONDS = 60.0
MEASUREMENT_MAX_ROWS = 2_000_000
#: The measurement job's limit in the pool: past it the worker is killed, a backstop only,
#: since the analysis stops itself at MEASUREMENT_SECONDS.
MEASUREMENT_JOB_LIMIT = MEASUREMENT_SECONDS + 30.0
#: Seconds of gearbox sound rendered for listening.
LISTEN_SECONDS = 2.0


def measurement(data: bytes | None, orders: tuple, rpm_step: float, name: str | None = None,
                options: dict | None = None) -> Any:
    """The order map of uploaded bytes (``None``: the shipped synthetic run-up), with progress;
    ``None`` when the job is cancelled.  An upload over :data:`MAX_MEASUREMENT_BYTES` or
    :data:`MEASUREMENT_MAX_ROWS`, or one whose analysis outlasts :data:`MEASUREMENT_SECONDS`,
    is refused with a message about the file.  ``options`` are the reading options of
    :meth:`rattle_core.measure.orders.OrderMap.from_csv` (columns, speed unit, pulses, a time
    window).  With ``name`` (the file's name, shown only escaped), the triple ``(map,
    {"file", "sha256", "bytes"}, extra)``: ``extra`` holds the Campbell data (``campbell``,
    None where the file is too short for one, ``campbell_note`` then says why), the file's
    time ``span`` [s] as read, and its ``samples``: the time [s] and speed [rpm] arrays read (the
    run-up replay's measured angle is built from them)."""
    if name is not None:
        meas = _measurement(data, orders, rpm_step, options or {})
        if meas is None:
            return None
        omap, raw = meas
        extra = {"campbell": None, "campbell_note": "",
                 "span": (float(raw.time_s[0]), float(raw.time_s[-1])) if raw.time_s.size else None,
                 "samples": (np.asarray(raw.time_s, dtype=np.float64),
                             np.asarray(raw.speed_rpm, dtype=np.float64))}
        from ..core import campbell
        try:
            extra["campbell"] = campbell(raw, omap.orders, omap.rpm_step)
        except ValueError as exc:
            extra["campbell_note"] = f"No Campbell view: {exc}."
        return omap, {"file": str(name)[:200], **file_identity(data)}, extra
    out = _measurement(data, orders, rpm_step, options or {})
    return None if out is None else out[0]


def _measurement(data: bytes | None, orders: tuple, rpm_step: float, options: dict) -> Any:
    """``(order map, the measurement read)`` of :func:`measurement`, or None when cancelled."""
    from ..core import SAMPLE_RUNUP, OrderMap, read_measurement
    if data is not None and len(data) > MAX_MEASUREMENT_BYTES:
        raise ValueError(f"the uploaded file has {len(data)} bytes; the allowed size is up to "
                         f"{MAX_MEASUREMENT_BYTES} bytes ({MAX_MEASUREMENT_BYTES / 1e6:g} MB)")
    deadline = time.monotonic() + MEASUREMENT_SECONDS
    late: list[bool] = []

    def stop() -> bool:
        if time.monotonic() > deadline:
            late.append(True)
        return bool(late) or cancelled()

    def analyse(path: Any, label: str, max_rows: int | None) -> tuple:
        raw = read_measurement(path, label, max_rows, **options)
        report(1, 10)  # reading is the first tenth of the bar

        def progress(done: int, n: int) -> None:
            report(n // 10 + done * 9 // 10, n)
        return OrderMap.from_measurement(raw, orders, rpm_step, progress=progress,
                                         cancel=stop), raw
    if data is None:
        return analyse(SAMPLE_RUNUP, "the sample run-up (synthetic)", None)
    suffix = ".csv.gz" if data[:2] == b"\x1f\x8b" else ".csv"
    fd, path = tempfile.mkstemp(prefix="rattle-upload-", suffix=suffix)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        return analyse(path, "the uploaded file", MEASUREMENT_MAX_ROWS)
    except Exception:
        if late:
            raise ValueError(f"the uploaded file took over {MEASUREMENT_SECONDS:g} s to read and "
                             "analyse, the limit for a measurement on this server; upload a "
                             "shorter file or choose a wider rpm step") from None
        if cancelled():  # nobody waits for this result any more
            return None
        raise
    finally:
        os.unlink(path)


def file_error(msg: str) -> str:
    """A measurement job's failure, told about the file: the pool's own time limit speaks
    of compute jobs."""
    if msg.startswith("stopped after"):
        return (f"the uploaded file took too long to read and analyse (over "
                f"{MEASUREMENT_SECONDS:g} s, the limit for a measurement on this server); "
                "upload a shorter file or choose a wider rpm step")
    return msg


def gearbox_text(data: bytes, order_map: Any) -> Any:
    """A gearbox from uploaded TOML bytes; its measurement is ``order_map`` (the one shown)
    or the sample, never a file the text names."""
    from ..core import Gearbox
    if len(data) > MAX_TOML_BYTES:
        raise ValueError(f"the upload has {len(data)} bytes; the allowed size is up to {MAX_TOML_BYTES}")
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ValueError(f"the uploaded gearbox file, byte {exc.start}: the file is not UTF-8 "
                         "text") from None
    # the upload's own name is not used: it is the user's text and could hold anything
    return Gearbox.from_text(text, base_dir=None, measurement=order_map,
                             source="the uploaded gearbox file")


def verdicts(gearbox: Any, variant: Any, rpm: np.ndarray, transient: int, record: int,
             variant_text: str = "", provenance: dict | None = None) -> tuple:
    """The verdict on ``gearbox`` and, if given, on ``variant`` (a what-if or a second design),
    through the disk cache, and the report of both (:func:`report_html`; empty when cancelled)."""
    from ..core import cached_verdict
    boxes = [b for b in (gearbox, variant) if b is not None]
    total = len(boxes)
    out = []
    for i, box in enumerate(boxes):
        def progress(done: int, n: int, i: int = i) -> None:
            report(int(1000 * (i + done / max(n, 1))), 1000 * total)
        out.append(cached_verdict(box, rpm, transient=transient, record=record,
                                  progress=progress, cancel=cancelled))
        if out[-1].cancelled:
            return out[0], None, ""
    variant_result = out[1] if len(out) > 1 else None
    return out[0], variant_result, report_html(out[0], variant_result, variant_text,
                                               provenance)


def gears_of(table: Any, columns: list, drags: dict) -> tuple:
    """The gears of a gear table's rows (``drags``: a gear's drag model by name, for a row
    without a constant drag); ``ValueError`` naming the row."""
    from ..core import Gear

    def missing(v: Any) -> bool:
        return v is None or (isinstance(v, float) and math.isnan(v))
    gears = []
    for i, row in table.iterrows():
        values = {c: row[c] for c in columns}
        values["name"] = str(values["name"])
        if missing(values["driver_radius_m"]):
            values["driver_radius_m"] = None
        if missing(values["drag_torque_Nm"]) and values["name"] in drags:
            values["drag_torque_Nm"], values["drag"] = None, drags[values["name"]]
        try:
            gears.append(Gear(**{k: (v if k in ("name", "drag") or v is None else float(v))
                                 for k, v in values.items()}))
        except (TypeError, ValueError) as exc:
            raise ValueError(f"row {i + 1}: {exc}") from None
    return tuple(gears)


def gear_rows(box: Any) -> list[list]:
    """A gearbox's gears as rows of the gear table."""
    return [[g.name, g.inertia_kgm2, g.base_radius_m, g.drag_torque_Nm, g.backlash_um,
             g.restitution, g.speed_ratio, np.nan if g.driver_radius_m is None else g.driver_radius_m]
            for g in box.gears]


def onsets_text(onsets: dict) -> str:
    """Each gear's onset in words."""
    return "; ".join(f"{k}: {'from %g rpm' % v if math.isfinite(v) else 'no rattle'}"
                     for k, v in onsets.items())


def side_by_side(base: Any, variant: Any) -> Any:
    """Per gear and for the gearbox: onset, ranges, loudness, dB(A) and pass of the first
    design and, if there is one, the second (a DataFrame)."""
    import pandas as pd
    from ..core import verdict_tables as vt
    rows = []
    designs = [("A", base)] + ([("B", variant)] if variant is not None else [])
    for tag, res in designs:
        t = vt.frame(res)
        rng = vt.ranges(res)
        for name in vt.gear_names(res) + [vt.GEARBOX]:
            g = t[t["gear"] == name]
            rows.append({"gear": name, "design": tag,
                         "onset [rpm]": res.onsets.get(name, np.nan),
                         "rattle ranges [rpm]": vt.format_ranges(rng.get(name, [])),
                         "loudness max [sone]": g["loudness_sone"].max(),
                         "L_Aeq max [dB(A)]": g["spl_dba"].max(),
                         "pass": "pass" if g["pass"].astype(bool).all() else "fail"})
    return pd.DataFrame(rows)


def verdict_csv(base: Any, variant: Any, variant_text: str) -> str:
    """The verdict as CSV (empty without one); with a second design, both with a ``design``
    column and the ``B - A`` rows (:func:`rattle_core.store.verdict_tables.compare_frame`);
    formulas neutralised."""
    from ..core import csv_text
    from ..core import verdict_tables as vt
    if base is None:
        return ""
    if variant is None:
        return csv_text(vt.frame(base).assign(design="baseline"))
    return csv_text(vt.compare_frame(base, variant, vt.design_names("baseline", variant_text)))


def file_identity(data: bytes | None) -> dict:
    """The SHA-256 of a measurement's bytes (``None``: the shipped sample's file)."""
    from ..core import SAMPLE_RUNUP
    if data is None:
        with open(SAMPLE_RUNUP, "rb") as f:
            data = f.read()
    return {"sha256": hashlib.sha256(data).hexdigest(), "bytes": len(data)}


def sound(gearbox: Any, rpm: float, seconds: float = LISTEN_SECONDS) -> dict:
    """The whole gearbox at one speed: every gear simulated, its rattle rendered, the sound
    pressures added; returns the signal scaled for playback, its loudness and its peak."""
    from rattle_core import simulate
    from ..core import LOUDNESS_RATE, loudness, normalize, render
    total = np.zeros(int(round(seconds * LOUDNESS_RATE)))
    for g in range(len(gearbox.gears)):
        phys = gearbox.physical(g, rpm)
        periods = int(math.ceil(seconds * phys.frequency_hz)) + 1
        tr = simulate(phys.to_dimensionless(), periods=periods, transient=200)
        t_s = (tr.impact_t - tr.t_start) / phys.omega
        total += gearbox.transfer_pa_per_ns * render(t_s, tr.impact_impulse * phys.impulse_scale,
                                                     seconds, LOUDNESS_RATE)
        report(g + 1, len(gearbox.gears) + 1)
    heard = loudness(total)
    return {"signal": normalize(total).astype(np.float32), "rate": LOUDNESS_RATE,
            "sone": heard.loudness_sone, "peak_pa": float(np.max(np.abs(total))), "rpm": rpm}


def campbell_html(data: Any, source: str = "") -> str:
    """The Campbell view of a measurement (its :func:`rattle_core.measure.campbell.campbell`
    data, drawn by ``campbell_png``); empty without one."""
    from ..core import campbell_png
    if data is None:
        return ""
    return "<h2>Campbell view</h2>" + _png(campbell_png, data, f"Campbell diagram of {source}")


def measurement_rows(order_map: Any) -> list[tuple[str, str]]:
    """How a measurement was read (delimiter, decimal mark, columns, unit, rows, duration,
    sample rate, resampling, warnings) and what its analysis left out, as report rows."""
    det = getattr(order_map, "detected", None)
    rows = [] if det is None else [("measurement read as", "; ".join(det.describe()))]
    notices = tuple(getattr(order_map, "notices", ()) or ())
    if notices:
        rows.append(("orders left out", "; ".join(notices)))
    return rows


def _png(draw, *args, **kwargs) -> str:
    buf = io.BytesIO()
    draw(buf, *args, **kwargs)
    return ('<img alt="" style="max-width:100%" src="data:image/png;base64,'
            f'{base64.b64encode(buf.getvalue()).decode()}">')


def _table(df: Any) -> str:
    """A verdict table as HTML: units in every header, text escaped."""
    from ..core import verdict_tables as vt
    return vt.with_units(df).to_html(index=False, escape=True, float_format="%.4g")


def _drag_text(gear: Any) -> str:
    """A gear's drag as the report's gear table shows it: the constant, or its model."""
    d = gear.drag
    if d.kind == "constant":
        return f"{d.value_Nm:g}"
    if d.kind == "oil":
        return (f"{d.bush_Nm:g} + {d.churn_Nm:g}·ν(T)/ν({d.at_temp_C:g} °C)·rpm/{d.at_rpm:g}")
    over = "rpm × °C" if d.temp_C else "rpm"
    return f"table over {over}"


def report_html(base: Any, variant: Any, variant_text: str,
                provenance: dict | None = None) -> str:
    """A self-contained HTML report to hand on: where the numbers come from (the measurement's
    file name and SHA-256, the date in UTC, the version, the settings), the regime legend, the
    inputs, how the measurement was read, each gear's ranges and sentence, the target's
    failing ranges, the pictures (PNG inside the file; the Campbell view from
    ``provenance["campbell"]``) and the tables with units.  Every text from a user (gear names, file
    names, labels) is escaped."""
    from ..core import REGIME_WORDS, designs_png, orders_png, verdict_png
    from ..core import verdict_tables as vt
    esc = html.escape
    prov = dict(provenance or {})
    box = base.gearbox
    exc = box.excitation
    source = exc.order_map.source if exc.order_map is not None else "constant orders"
    target = vt.target_of(base)
    try:
        from importlib.metadata import version
        ver = version("rattle-explorer")
    except Exception:  # an uninstalled checkout
        ver = "unknown"
    settings = {"speeds [rpm]": f"{base.rpm[0]:g} to {base.rpm[-1]:g} ({base.rpm.size})",
                **{k: v for k, v in base.settings.items()},
                "transfer [Pa/(N·s)]": box.transfer_pa_per_ns, "sound per point [s]": box.duration_s,
                "engine order of the fundamental": exc.engine_order, "harmonics": exc.harmonics}
    if box.oil_temp_C is not None:
        settings["oil temperature [°C]"] = box.oil_temp_C
    if target is not None:
        settings["target"] = vt.target_text(target)
    settings.update(prov.get("settings", {}))
    gears = "".join("<tr>" + "".join(f"<td>{esc(str(v))}</td>" for v in (
        g.name, g.inertia_kgm2, g.base_radius_m, _drag_text(g), g.backlash_um, g.restitution,
        g.speed_ratio, g.drive_radius_m)) + "</tr>" for g in box.gears)
    rows = "".join(f"<tr><th>{esc(str(k))}</th><td>{esc(str(v))}</td></tr>" for k, v in (
        ("measurement file", prov.get("file", source)),
        ("measurement SHA-256", prov.get("sha256", "none (constant orders)")),
        ("date (UTC)", datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")),
        ("rattle-explorer version", ver), *measurement_rows(exc.order_map), *settings.items()))
    legend = "".join(f"<tr><td><b>{esc(r.letter)}</b></td><td>{esc(r.meaning)}</td></tr>"
                     for r in REGIME_WORDS)
    parts = [
        "<!DOCTYPE html><html><head><meta charset='utf-8'><title>Rattle verdict</title>",
        "<style>body{font-family:sans-serif;margin:2em}table{border-collapse:collapse;font-size:12px}"
        "td,th{border:1px solid #ccc;padding:2px 6px}</style></head><body>",
        "<h1>Gear rattle verdict</h1>",
        "<h2>Provenance and settings</h2><table class='provenance'>" + rows + "</table>",
        f"<p>Excitation: {esc(source)}; model fundamental at engine order {exc.engine_order:g}, "
        f"{exc.harmonics} harmonics. Sound: {box.transfer_pa_per_ns:g} Pa per N·s, "
        f"{box.duration_s:g} s per point. Speeds {base.rpm[0]:g} to {base.rpm[-1]:g} rpm "
        f"({base.rpm.size}).</p>",
        "<h2>Regimes</h2><table class='legend'>" + legend + "</table>",
        "<h2>Gears</h2><table><tr><th>gear</th><th>J [kg·m²]</th><th>R_b [m]</th><th>C [N·m]</th>"
        "<th>backlash [µm]</th><th>r</th><th>speed ratio</th><th>R_d [m]</th></tr>" + gears + "</table>",
        "<h2>What rattles, and what keeps it quiet</h2><ul class='summaries'>" + "".join(
            f"<li>{esc(line)}</li>" for line in vt.gear_lines(base)) + "</ul>",
    ]
    if target is not None:
        fails = vt.failing(base)
        parts.append("<h2>Target</h2><p>" + esc(settings["target"]) + "</p><ul class='failing'>"
                     + "".join(f"<li>{esc(n)}: "
                               f"{esc(vt.format_ranges(r)) + ' rpm' if r else 'meets the target'}</li>"
                               for n, r in fails.items()) + "</ul>")
    if exc.order_map is not None:
        parts.append("<h2>Measured orders</h2>" + _png(orders_png, exc.order_map, f"orders of {source}"))
        parts.append(campbell_html(prov.get("campbell"), source))
    parts.append("<h2>Verdict</h2>" + _png(verdict_png, base, "baseline"))
    designs = [(base, "A")] + ([(variant, "B")] if variant is not None else [])
    parts.append("<h2>Loudness" + (" of both designs (B dashed)" if variant is not None else "")
                 + (", target and failing speeds" if target is not None else "") + "</h2>"
                 + _png(designs_png, designs, "A: baseline" + (f"; B: {variant_text}"
                                                                 if variant is not None else ""),
                        target))
    if variant is not None:
        parts.append(f"<h2>B: {esc(variant_text)}</h2>" + _png(verdict_png, variant, variant_text))
        parts.append("<h3>A and B side by side</h3><ul class='compare'>" + "".join(
            f"<li>{esc(line)}</li>" for line in vt.compare_lines(base, variant, ("baseline",
                                                                                 variant_text))) + "</ul>")
    parts.append("<h2>Table</h2>" + _table(vt.frame(base)))
    if variant is not None:
        parts.append("<h2>Both designs, and B - A</h2>"
                     + _table(vt.compare_frame(base, variant, ("A", "B"))))
    parts.append("</body></html>")
    return "\n".join(parts)
