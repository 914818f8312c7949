"""How long a slider move takes on the server: the dashboard's whole update path, no browser.

A :class:`app.dashboard.Dashboard` is attached to a Bokeh ``Document``, as a server session
holds it. Each move types a new Λ into the Λ control (the path a slider release takes): param
validation, the session's run (one ``simulate`` with the Lyapunov exponent, the
classification), and every view that follows the run: the time history (Bokeh), the section
and the diagram marker (HoloViews), the badge, the metrics, the units table, the sound card's
description and the map's marker. The Bokeh change events this produces are then serialised
into the PATCH-DOC message the server would send. Both steps are timed together, in wall time
and in CPU time of this process (the machine is shared, so CPU time is the steadier figure).

In the same run, the baseline is the bare ``simulate`` call with the same settings. Beside the
figures, the old dashboard's (hand-written Bokeh views, commit f4e1583, measured with its own
``bench_app.py`` on this machine) are printed for comparison. Target: 150 ms at the 95th
percentile per move at the default 200 recorded periods. The server's part of a first page
(building a session and its document, and serialising it) is printed too.

The last case moves Λ with the physical units on (µm against ms, 1/s and N·s, the SI table),
through the same path and against the same baseline.

    .venv/bin/python benchmarks/bench_app.py [--moves 40]
"""
from __future__ import annotations

import argparse
import math
import os
import statistics
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

TARGET_MS = 150.0
#: The old dashboard's slider move, full update + PATCH-DOC (median, p95) in ms, wall time.
OLD = {"default": (10.6, 13.6), "Fig 3E": (12.0, 14.4), "Fig 7": (23.9, 28.8)}


def _bare_simulate_ms(params, state, repeats: int) -> list[float]:
    from rattle_core import simulate

    out = []
    for _ in range(repeats):
        t = time.perf_counter()
        simulate(params, periods=state.periods, transient=state.transient, v0=state.v0,
                 strobe_phase=math.radians(state.strobe), t0=state.t0, lyapunov=True)
        out.append(1e3 * (time.perf_counter() - t))
    return out


def _moves_ms(dash, doc, values) -> tuple[list[float], list[float], int]:
    from bokeh.protocol import Protocol

    proto = Protocol()
    events: list = []
    doc.on_change(events.append)
    wall, cpu, nbytes = [], [], 0
    box = dash.controls.fields["lam"].box
    for v in values:
        events.clear()
        t, c = time.perf_counter(), time.process_time()
        box.value = float(v)
        msg = proto.create("PATCH-DOC", list(events))
        size = len(msg.content) + sum(len(b.to_bytes()) for b in msg.buffers)
        wall.append(1e3 * (time.perf_counter() - t))
        cpu.append(1e3 * (time.process_time() - c))
        nbytes = max(nbytes, size)
        if dash.state.lam != float(v):
            raise RuntimeError(f"the move to Λ = {v} was refused: {dash.state.messages.get('lam')}")
    doc.remove_on_change(events.append)
    return wall, cpu, nbytes


def _summary(ms: list[float]) -> str:
    q = np.percentile(ms, [50, 95])
    return f"median {q[0]:6.1f} ms   p95 {q[1]:6.1f} ms   max {max(ms):6.1f} ms"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--moves", type=int, default=40, help="slider moves per case")
    args = ap.parse_args()

    from bokeh.document import Document
    from bokeh.protocol import Protocol

    t0 = time.perf_counter()
    from app.main import configure, warm_up
    configure()
    warm_up(pool=False)
    print(f"warm-up (imports, numba, datashader, shipped diagrams): {time.perf_counter() - t0:.2f} s")

    from app.dashboard import Dashboard
    from app.work.jobs import JobPool
    from app.state import rattle_params
    from app.work.tasks import warm_up as warm_worker

    pool = JobPool(size=2, warm=warm_worker)
    cases = [
        ("default", "default: Λ≈3.3, H₂/H₁ = 0.25, φ₂ = 45° paper (chaotic), 200 periods", None, (3.20, 3.40)),
        ("Fig 3E", "Fig 3E: harmonic, period 1, 200 periods", "Fig 3E", (3.20, 3.40)),
        ("Fig 7", "Fig 7: strange attractor, 5000 periods (rasterised map)", "Fig 7", (3.25, 3.35)),
        ("units", "physical units on: µm against ms, 1/s and N·s, the SI table, 200 periods", "units",
         (3.20, 3.40)),
    ]
    worst = 0.0
    try:
        for key, title, preset, (lo, hi) in cases:
            t = time.perf_counter()
            dash = Dashboard(pool=pool)
            doc = Document()
            dash.layout.server_doc(doc)
            Protocol().create("PULL-DOC-REPLY", "bench", doc)
            first_page = time.perf_counter() - t
            if preset == "units":
                dash.state.units = True
            elif preset:
                dash.controls.apply_preset(preset)
            values = np.linspace(lo, hi, args.moves + 1)
            first, first_cpu, _ = _moves_ms(dash, doc, values[:1])
            wall, cpu, nbytes = _moves_ms(dash, doc, values[1:])
            s = dash.state
            base = _bare_simulate_ms(rattle_params(s), s, max(10, args.moves))
            ratio = statistics.median(wall) / statistics.median(base)
            old = OLD.get(key)
            print(f"\n{title}")
            print(f"  session + document + first message on the server: {first_page:.2f} s; "
                  f"{len(doc.models)} models")
            print(f"  slider move, full update + PATCH-DOC, wall: {_summary(wall)}   (first move {first[0]:.1f} ms)")
            print(f"                                        CPU:  {_summary(cpu)}")
            if old:
                print(f"  old dashboard (Bokeh only, f4e1583), wall: median {old[0]:6.1f} ms   p95 {old[1]:6.1f} ms")
            print(f"  baseline, bare simulate():                 {_summary(base)}")
            print(f"  ratio update / bare simulate (medians): {ratio:.1f}×   largest message {nbytes / 1e3:.0f} kB")
            if s.periods == 200:
                worst = max(worst, float(np.percentile(wall, 95)))
            dash.destroy()
    finally:
        pool.shutdown()
    verdict = "meets" if worst <= TARGET_MS else "MISSES"
    print(f"\nat the default 200 periods the slowest p95 is {worst:.1f} ms (wall): "
          f"{verdict} the {TARGET_MS:.0f} ms target")
    return 0



if __name__ == "__main__":
    sys.exit(main())
