"""The cost of honest chaotic statistics: ``statistics`` and ``noise_sensitivity`` against one run.

Baseline, measured in the same run: one ``simulate`` of the same length (``transient +
periods``), which is what a single number without an interval costs. Printed: seconds of each,
and the ratio. ``statistics`` runs ``runs`` such runs through the chunk runner on every core;
``noise_sensitivity`` runs them at five levels. Also printed: how far the default noise moves
robust periodic orbits from the strict model (docs/model.md, "Noise": the default's evidence).

Usage: ``python benchmarks/bench_noise.py [--quick]``.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from rattle_core import RattleParams, noise_sensitivity, simulate, statistics  # noqa: E402

CASES = {
    "Fig 7 (Λ = 3.3, paper φ₂ = 45°)": RattleParams.paper(lam=3.3, amplitudes=(1.0, 0.25),
                                                         phases_deg=(0.0, 45.0)),
    "Λ = 2.6, core φ₂ = 315° (noise-sensitive)": RattleParams(lam=2.6, amplitudes=(1.0, 0.25),
                                                            phases_deg=(0.0, 315.0)),
}


def best(fn, repeats: int) -> tuple[float, object]:
    """Best wall time of ``repeats`` calls (after one warm-up call), and the last result."""
    out = fn()
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t)
    return min(times), out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="shorter runs, fewer repeats")
    args = ap.parse_args()
    periods, transient, runs = (1000, 200, 8) if args.quick else (4000, 500, 8)
    repeats = 1 if args.quick else 3
    for name, p in CASES.items():
        print(f"== {name}: {runs} runs × ({transient} + {periods}) periods")
        t1, _ = best(lambda: simulate(p, periods=periods, transient=transient), repeats)
        ts, st = best(lambda: statistics(p, runs=runs, periods=periods, transient=transient),
                      repeats)
        tn, ns = best(lambda: noise_sensitivity(p, runs=runs, periods=periods,
                                                transient=transient), max(1, repeats - 2))
        print(f"   one run (baseline)     {t1:8.3f} s")
        print(f"   statistics             {ts:8.3f} s  ({ts / t1:5.1f}× one run, {runs} runs)")
        print(f"   noise_sensitivity      {tn:8.3f} s  ({tn / t1:5.1f}× one run, "
              f"{runs * len(ns.levels)} runs)")
        print(f"   mean active impulse {st.mean_active_impulse}; {ns.describe()}")
    print("== The default noise on robust periodic orbits (largest change from the strict model)")
    for lam in (1.2, 2.5):
        q = RattleParams(lam=lam)
        a = simulate(q, periods=200, transient=2000)
        b = simulate(q.replace(noise=0.0), periods=200, transient=2000)
        print(f"   Λ = {lam}: impulse {np.max(np.abs(a.impact_impulse - b.impact_impulse)):.2e}, "
              f"position {np.max(np.abs(a.strobe_x - b.strobe_x)):.2e}")


if __name__ == "__main__":
    main()
