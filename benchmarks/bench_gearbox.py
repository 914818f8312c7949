"""Benchmark: the verdict on a 6-gear gearbox over 100 engine speeds, as one batch (cold and
cached, its sounds on every core and on one thread) beside the same work done gear by gear,
speed by speed, with MOSQITO's loudness, in the same run.

The batch is :func:`rattle_core.store.verdicts.cached_verdict`: every gear at every speed in
chunks through the chunk runner (one parallel kernel per chunk), each chunk's rattle sounds and
their loudness on threads over compiled ``nogil`` kernels.  "Cold" starts from an empty cache
directory with the JIT cache warm, "cached" asks again; "one thread" is the cold verdict with
``threads=1``.  The baseline, the MOSQITO path, does the same work one point at a time:
``simulate`` and ``classify`` per gear and speed, ``statistics`` over 8 runs where the motion
does not repeat, the rattle rendered and its loudness measured with MOSQITO's own
``loudness_zwtv``, then the gearbox's summed sound; it runs on ``--baseline-speeds`` speeds
spread over the range and is scaled to the full count.  The excitation is the shipped synthetic
run-up (orders 2, 4, 6).  CPU seconds (``time.process_time``, all threads) are printed beside
wall seconds: wall times move with the load of the shared cores.
Run: ``.venv/bin/python benchmarks/bench_gearbox.py [--speeds 100] [--gears 6] [--baseline-speeds 10]``.
"""
from __future__ import annotations

import argparse
import math
import os
import tempfile
import time

import numpy as np

from rattle_core import classify, simulate
from rattle_core.analysis.loudness import SAMPLE_RATE
from rattle_core.analysis.sound import render
from rattle_core.batch.ensemble import statistics
from rattle_core.batch.executor import default_threads
from rattle_core.batch.gearbox import ENSEMBLE_RUNS, record_periods, verdict
from rattle_core.model.gearbox import Gear, Gearbox
from rattle_core.store.verdicts import cached_verdict

GEARS = [
    Gear("1st", 6e-4, 0.040, 0.08, 90, 0.65, 0.30),
    Gear("2nd", 5e-4, 0.038, 0.06, 80, 0.65, 0.55),
    Gear("3rd", 4e-4, 0.035, 0.05, 80, 0.65, 0.80),
    Gear("4th", 3e-4, 0.033, 0.04, 70, 0.60, 1.00),
    Gear("5th", 2.5e-4, 0.030, 0.03, 70, 0.60, 1.25),
    Gear("reverse idler", 2.5e-4, 0.030, 0.03, 120, 0.65, 0.80),
]


def gear_by_gear(box: Gearbox, rpm: np.ndarray, transient: int, record: int) -> float:
    """The verdict's work one point at a time; returns the loudest gearbox sound [sone]."""
    from mosqito.sq_metrics import loudness_zwtv
    samples = int(round(box.duration_s * SAMPLE_RATE))
    loudest = 0.0
    for r in rpm:
        total = np.zeros(samples)
        for g in range(len(box.gears)):
            phys = box.physical(g, float(r))
            tr = simulate(phys.to_dimensionless(), periods=record, transient=transient,
                          lyapunov=True)
            cl = classify(tr)
            if cl.regime == "A" or tr.impact_t.size == 0:
                continue
            if cl.period == 0:
                statistics(phys.to_dimensionless(), runs=ENSEMBLE_RUNS, periods=record,
                           transient=transient)
            t_s = (tr.impact_t - tr.t_start) / phys.omega
            p = box.transfer_pa_per_ns * render(t_s, tr.impact_impulse * phys.impulse_scale,
                                                box.duration_s, SAMPLE_RATE)
            loudness_zwtv(p, SAMPLE_RATE)
            total += p
        if np.any(total):
            loudest = max(loudest, float(np.percentile(loudness_zwtv(total, SAMPLE_RATE)[0], 95)))
    return loudest


class Clock:
    """CPU seconds (every thread of the process) and wall seconds of a ``with`` block."""

    def __enter__(self):
        self.cpu, self.wall = time.process_time(), time.perf_counter()
        return self

    def __exit__(self, *exc):
        self.cpu = time.process_time() - self.cpu
        self.wall = time.perf_counter() - self.wall


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--speeds", type=int, default=100)
    ap.add_argument("--gears", type=int, default=6)
    ap.add_argument("--baseline-speeds", type=int, default=10,
                    help="speeds of the gear-by-gear MOSQITO baseline, scaled up to the full "
                         "count (0: skip it)")
    ap.add_argument("--transient", type=int, default=200)
    ap.add_argument("--record", type=int, default=100)
    args = ap.parse_args()
    text = '[excitation]\nmeasurement = "sample"\nengine_order = 2\nharmonics = 3\n'
    box = Gearbox.from_text(text + "[[gear]]\nname = 'x'\ninertia_kgm2 = 1e-4\n"
                            "base_radius_m = 0.03\ndrag_torque_Nm = 0.02\nbacklash_um = 50\n")
    box = box.replace(gears=tuple(GEARS[:args.gears]))
    rpm = np.linspace(1000.0, 3000.0, args.speeds)
    record = record_periods(box, rpm, args.record)
    points = args.gears * args.speeds
    with tempfile.TemporaryDirectory() as cache:
        # the JIT cache is loaded (or filled) outside the timings
        cached_verdict(box, rpm[:2], transient=5, record=5, directory=cache, use_cache=False)
        print(f"{args.gears} gears × {args.speeds} speeds = {points} points, "
              f"{args.transient} + {record} periods each, {box.duration_s:g} s of sound; "
              f"{default_threads()} threads; load average {os.getloadavg()[0]:.2f} on "
              f"{os.cpu_count()} cores")
        with Clock() as cold:
            first = cached_verdict(box, rpm, transient=args.transient, record=args.record,
                                   directory=cache)
        with Clock() as warm:
            again = cached_verdict(box, rpm, transient=args.transient, record=args.record,
                                   directory=cache)
    assert again.from_cache and not first.from_cache
    with Clock() as serial:
        one = verdict(box, rpm, transient=args.transient, record=args.record, threads=1)
    same = one.table.equals(first.table)
    onsets = ", ".join(f"{k} {v:.0f}" if math.isfinite(v) else f"{k} -"
                       for k, v in first.onsets.items())
    print(f"batch, cold        : {cold.cpu:7.2f} CPU-s {cold.wall:7.2f} s wall "
          f"({points / cold.wall:.0f} points/s)")
    print(f"batch, cached      : {warm.cpu:7.2f} CPU-s {warm.wall:7.2f} s wall")
    print(f"batch, one thread  : {serial.cpu:7.2f} CPU-s {serial.wall:7.2f} s wall "
          f"(same table as on threads: {same}; threads {serial.wall / cold.wall:.2f}× faster "
          "in wall time)")
    print(f"onsets [rpm]       : {onsets}")
    if args.baseline_speeds:
        n = min(args.baseline_speeds, args.speeds)
        sub = rpm[np.linspace(0, rpm.size - 1, n).round().astype(int)]
        print(f"load average before the baseline: {os.getloadavg()[0]:.2f}")
        with Clock() as base:
            gear_by_gear(box, sub, args.transient, record)
        scale = args.speeds / n
        scaled = "" if n == args.speeds else f" (measured on {n} speeds, scaled ×{scale:g})"
        print(f"MOSQITO path       : {base.cpu * scale:7.2f} CPU-s {base.wall * scale:7.2f} s "
              f"wall{scaled}")
        print(f"ratio              : batch cold uses {base.cpu * scale / cold.cpu:.0f}× less CPU "
              f"and {base.wall * scale / cold.wall:.0f}× less wall time than the MOSQITO path; "
              f"cached {base.wall * scale / warm.wall:.0f}× less wall time")


if __name__ == "__main__":
    main()
