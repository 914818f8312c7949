"""The Gearbox tab's work, run in the job pool's worker processes: uploads parsed, verdicts
computed, the gearbox's sound rendered, the report drawn.

Uploaded bytes are untrusted: they are parsed here, in a worker, never in the server process.
A measurement has bounds of its own (:data:`MEASUREMENT_SECONDS`, :data:`MEASUREMENT_MAX_ROWS`),
apart from the compute jobs' limits, and reports its progress. A measurement is written to a temporary file of this module's
own naming (``rattle-upload-*``), read whole and checked by
:meth:`rattle_core.model.orders.OrderMap.from_csv`, and deleted; no name taken from an upload
ever reaches the file system. A gearbox text is parsed with no folder to look in, so it can
open no file (:meth:`rattle_core.model.gearbox.Gearbox.from_text`).
"""
from __future__ import annotations

import base64
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


def measurement(data: bytes | None, orders: tuple, rpm_step: float) -> Any:
    """The order map of uploaded bytes (``None``: the shipped synthetic run-up), with progress;
    ``None`` when the job is cancelled.  An upload over :data:`MAX_MEASUREMENT_BYTES` or
    :data:`MEASUREMENT_MAX_ROWS`, or one whose analysis outlasts :data:`MEASUREMENT_SECONDS`,
    is refused with a message about the file."""
    from ..core import SAMPLE_RUNUP, OrderMap
    if data is None:
        return OrderMap.from_csv(SAMPLE_RUNUP, orders, rpm_step, label="the sample run-up (synthetic)",
                                 progress=report, cancel=cancelled)
    if len(data) > MAX_MEASUREMENT_BYTES:
        raise ValueError(f"the uploaded file has {len(data)} bytes; the allowed size is up to "
                         f"{MAX_MEASUREMENT_BYTES} bytes ({MAX_MEASUREMENT_BYTES / 1e6:g} MB)")
    deadline = time.monotonic() + MEASUREMENT_SECONDS
    late: list[bool] = []

    def stop() -> bool:
        if time.monotonic() > deadline:
            late.append(True)
        return bool(late) or cancelled()
    suffix = ".csv.gz" if data[:2] == b"\x1f\x8b" else ".csv"
    fd, path = tempfile.mkstemp(prefix="rattle-upload-", suffix=suffix)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        return OrderMap.from_csv(path, orders, rpm_step, label="the uploaded file",
                                 progress=report, cancel=stop, max_rows=MEASUREMENT_MAX_ROWS)
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
             variant_text: str = "") -> tuple:
    """The verdict on ``gearbox`` and, if given, on ``variant``, through the disk cache, and
    the report of both (:func:`report_html`; empty when cancelled)."""
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
    return out[0], variant_result, report_html(out[0], variant_result, variant_text)


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


def report_html(base: Any, variant: Any, variant_text: str) -> str:
    """A self-contained HTML report: the inputs, the pictures (PNG inside the file) and the
    tables.  Every text from a user (gear names, file labels) is escaped."""
    from ..core import orders_png, verdict_png
    esc = html.escape

    def png(draw, *args) -> str:
        buf = io.BytesIO()
        draw(buf, *args)
        return f'<img alt="" style="max-width:100%" src="data:image/png;base64,{base64.b64encode(buf.getvalue()).decode()}">'
    box = base.gearbox
    exc = box.excitation
    source = exc.order_map.source if exc.order_map is not None else "constant orders"
    gears = "".join("<tr>" + "".join(f"<td>{esc(str(v))}</td>" for v in (
        g.name, g.inertia_kgm2, g.base_radius_m, g.drag_torque_Nm, g.backlash_um, g.restitution,
        g.speed_ratio, g.drive_radius_m)) + "</tr>" for g in box.gears)
    parts = [
        "<!DOCTYPE html><html><head><meta charset='utf-8'><title>Rattle verdict</title>",
        "<style>body{font-family:sans-serif;margin:2em}table{border-collapse:collapse;font-size:12px}"
        "td,th{border:1px solid #ccc;padding:2px 6px}</style></head><body>",
        "<h1>Gear rattle verdict</h1>",
        f"<p>Excitation: {esc(source)}; model fundamental at engine order {exc.engine_order:g}, "
        f"{exc.harmonics} harmonics. Sound: {box.transfer_pa_per_ns:g} Pa per N·s, "
        f"{box.duration_s:g} s per point. Speeds {base.rpm[0]:g} to {base.rpm[-1]:g} rpm "
        f"({base.rpm.size}).</p>",
        "<h2>Gears</h2><table><tr><th>gear</th><th>J [kg·m²]</th><th>R_b [m]</th><th>C [N·m]</th>"
        "<th>backlash [µm]</th><th>r</th><th>speed ratio</th><th>R_d [m]</th></tr>" + gears + "</table>",
        "<h2>Onsets</h2><ul>" + "".join(
            f"<li>{esc(k)}: {'rattles from %g rpm' % v if math.isfinite(v) else 'never leaves contact'}</li>"
            for k, v in base.onsets.items()) + "</ul>",
    ]
    if exc.order_map is not None:
        parts.append("<h2>Measured orders</h2>" + png(orders_png, exc.order_map, f"orders of {source}"))
    parts.append("<h2>Verdict</h2>" + png(verdict_png, base, "baseline"))
    if variant is not None:
        parts.append(f"<h2>Variant: {esc(variant_text)}</h2>" + png(verdict_png, variant, variant_text))
        parts.append("<ul>" + "".join(
            f"<li>{esc(k)}: {'rattles from %g rpm' % v if math.isfinite(v) else 'never leaves contact'}</li>"
            for k, v in variant.onsets.items()) + "</ul>")
    parts.append("<h2>Table</h2>" + base.table.to_html(index=False, escape=True, float_format="%.4g"))
    if variant is not None:
        parts.append("<h2>Variant table</h2>" + variant.table.to_html(index=False, escape=True,
                                                                     float_format="%.4g"))
    parts.append("</body></html>")
    return "\n".join(parts)
