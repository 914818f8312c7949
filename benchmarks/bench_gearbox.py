"""Benchmark: the verdict on a 6-gear gearbox over 100 engine speeds, as one batch (cold and
cached) beside the same work done gear by gear, speed by speed, in the same run.

The batch is :func:`rattle_core.store.verdicts.cached_verdict`: every gear at every speed in
chunks through the chunk runner (one parallel kernel per chunk), each chunk's rattle sounds and
loudness computed where it runs.  "Cold" starts from an empty cache directory, "cached" asks
again.  The baseline does the same work one point at a time: ``simulate`` and ``classify`` per
gear and speed, ``statistics`` over 8 runs where the motion does not repeat, the rattle
rendered and its loudness measured with MOSQITO's own ``loudness_zwtv`` (the Python loop the
batch compiles), then the gearbox's summed sound.  The
excitation is the shipped synthetic run-up (orders 2, 4, 6).  Wall times move with the load of
the shared cores, printed beside them.
Run: ``.venv/bin/python benchmarks/bench_gearbox.py [--speeds 100] [--gears 6] [--baseline-speeds 100]``.
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
from rattle_core.batch.gearbox import ENSEMBLE_RUNS, record_periods
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


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--speeds", type=int, default=100)
    ap.add_argument("--gears", type=int, default=6)
    ap.add_argument("--baseline-speeds", type=int, default=None,
                    help="speeds of the gear-by-gear baseline (default: all); fewer are scaled "
                         "up to the full count")
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
        cached_verdict(box, rpm[:2], transient=5, record=5, directory=cache, use_cache=False)
        print(f"{args.gears} gears × {args.speeds} speeds = {points} points, "
              f"{args.transient} + {record} periods each; load average "
              f"{os.getloadavg()[0]:.2f} on {os.cpu_count()} cores")
        t = time.perf_counter()
        cold = cached_verdict(box, rpm, transient=args.transient, record=args.record,
                              directory=cache)
        t_cold = time.perf_counter() - t
        t = time.perf_counter()
        warm = cached_verdict(box, rpm, transient=args.transient, record=args.record,
                              directory=cache)
        t_warm = time.perf_counter() - t
    assert warm.from_cache and not cold.from_cache
    onsets = ", ".join(f"{k} {v:.0f}" if math.isfinite(v) else f"{k} -"
                       for k, v in cold.onsets.items())
    print(f"batch, cold   : {t_cold:8.2f} s  ({points / t_cold:.1f} points/s)")
    print(f"batch, cached : {t_warm:8.2f} s  ({t_cold / t_warm:.0f}× faster than cold)")
    print(f"onsets [rpm]  : {onsets}")
    n = args.baseline_speeds or args.speeds
    sub = rpm[np.linspace(0, rpm.size - 1, n).round().astype(int)]
    print(f"load average before the baseline: {os.getloadavg()[0]:.2f}")
    t = time.perf_counter()
    gear_by_gear(box, sub, args.transient, record)
    t_seq = (time.perf_counter() - t) * args.speeds / n
    scaled = "" if n == args.speeds else f" (measured on {n} speeds, scaled)"
    print(f"gear by gear  : {t_seq:8.2f} s{scaled}")
    print(f"ratio         : batch cold {t_seq / t_cold:.1f}× faster than gear by gear; "
          f"cached {t_seq / t_warm:.0f}×")


if __name__ == "__main__":
    main()
