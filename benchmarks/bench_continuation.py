"""Benchmark of continuation: branch points per second, beside a brute-force sweep of the range.

For two branches of the harmonic model (r = 0.65, j = 8):

* **C**: the closed-form one-sided orbit from Λ = 0.9 up to 1.5, through its period doubling
  at Λ = 1.2394 (stable, then unstable);
* **E**: the orbit with one impact on each flank, found by simulation at Λ = 3.3 and followed
  down to Λ = 1.6, where it is stable all the way.

``continue_orbit`` (after compilation, best of ``--repeat`` runs) gives the number of branch
points and their rate.  In the same run, ``sweep`` covers the same range with as many values as
the branch has points, with the sweep defaults (500 transient + 200 recorded periods per
value), on all numba threads and on one.  Printed: points per second, values per second, and
the ratios.  Continuation runs on one thread; it also returns the unstable part of the branch
and the bifurcations, which no sweep sees.

Usage: ``python benchmarks/bench_continuation.py [--repeat N]``.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import numba  # noqa: E402

from rattle_core import RattleParams, sweep  # noqa: E402
from rattle_core.analysis.continuation import c_orbit, continue_orbit, find_orbit  # noqa: E402

TRANSIENT, RECORD = 500, 200


def best(fn, repeat: int):
    out, t_best = None, np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        t_best = min(t_best, time.perf_counter() - t0)
    return out, t_best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()

    cases = {
        "C": (lambda: c_orbit(RattleParams(lam=0.9)), (0.9, 1.5), 1),
        "E": (lambda: find_orbit(RattleParams(lam=3.3)), (1.6, 3.3), -1),
    }
    threads = numba.get_num_threads()
    print(f"numba threads: {threads}; sweep: {TRANSIENT} + {RECORD} periods per value")
    print(f"{'branch':<7}{'points':>7}{'cont s':>9}{'points/s':>10}{'sweep s':>9}"
          f"{'values/s':>10}{'ratio':>8}{'sweep 1 thr s':>15}{'ratio':>8}  bifurcations")
    for name, (make, bounds, direction) in cases.items():
        start = make()
        base = start.params
        continue_orbit(start, "lam", bounds=bounds, direction=direction)  # compile, warm caches
        res, t_cont = best(lambda: continue_orbit(start, "lam", bounds=bounds,
                                                  direction=direction), args.repeat)
        n = len(res.points)
        values = np.linspace(bounds[0], bounds[1], n)
        sweep(base, "lam", values[:4], transient=TRANSIENT, record=RECORD)
        _, t_sw = best(lambda: sweep(base, "lam", values, transient=TRANSIENT, record=RECORD),
                       args.repeat)
        numba.set_num_threads(1)
        try:
            _, t_sw1 = best(lambda: sweep(base, "lam", values, transient=TRANSIENT,
                                          record=RECORD), args.repeat)
        finally:
            numba.set_num_threads(threads)
        bifs = ", ".join(f"{b.kind} {b.value:.6f}" for b in res.bifurcations) or "none"
        print(f"{name:<7}{n:>7d}{t_cont:>9.4f}{n / t_cont:>10.0f}{t_sw:>9.4f}{n / t_sw:>10.0f}"
              f"{t_sw / t_cont:>8.1f}{t_sw1:>15.4f}{t_sw1 / t_cont:>8.1f}  {bifs}")
    print("ratio = sweep time / continuation time for the same number of parameter values")


if __name__ == "__main__":
    main()
