"""Benchmark of the atlas: curve points per second, beside brute-force maps of the same planes.

Two curves of the harmonic model (r = 0.65, j = 8 unless swept), each a boundary a regime
map shows:

* **PD**: the E orbit's period doubling (Λ = 1.5509 at r = 0.65) followed in r over
  [0.62, 0.78], in the plane Λ × r: below it in Λ, E is gone (period 2, chaos);
* **grazing**: where the C orbit's flight reaches the reverse flank, followed over
  Λ ∈ [1.0, 1.2394] in the plane Λ × j (C above it in j, orbits on both flanks below),
  started from the grazing–doubling point of the C orbit's period doubling continued in j.

``continue_bifurcation`` (after compilation, best of ``--repeat`` runs) gives the number of
curve points and their rate; its accuracy is that of the tests (1e-8 against closed forms
and fresh one-parameter continuations); ``error`` prints how well the defining condition
holds (|μ + 1| for PD, the gap at the touch for grazing).  In the same run ``regime_map``
covers the same plane with one row (PD) or column (grazing) per curve point, so that it
samples the boundary as often as the curve does, and ``--pixels`` values across it (300 +
100 periods per point, on all numba threads; the grazing map starts on the C orbit, which a
start at mid-backlash rarely reaches).  Its boundary is read off where the regime changes and
compared with the curve: that error is the map's boundary resolution.  A map reaching a
resolution δ needs (range / δ) values across; its time is extrapolated from the measured one
and printed for δ = 1e-3 and δ = 1e-8.

Usage: ``python benchmarks/bench_atlas.py [--repeat N] [--pixels N]``.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import numba  # noqa: E402

from rattle_core import RattleParams, continue_bifurcation, continue_orbit  # noqa: E402
from rattle_core.analysis.continuation import c_orbit, find_orbit  # noqa: E402
from rattle_core.batch.maps import regime_map  # noqa: E402

from bench_continuation import best  # noqa: E402  (best of N runs, as there)

TRANSIENT, RECORD = 300, 100


def last_entry(values: np.ndarray, inside: np.ndarray) -> float:
    """Midpoint of the last step from outside a regime into it, scanning ``values``."""
    k = np.nonzero(~inside[:-1] & inside[1:])[0]
    return 0.5 * (values[k[-1]] + values[k[-1] + 1]) if len(k) else np.nan


def first_exit(values: np.ndarray, inside: np.ndarray) -> float:
    """Midpoint of the first step out of a regime, scanning ``values``."""
    k = np.nonzero(inside[:-1] & ~inside[1:])[0]
    return 0.5 * (values[k[0]] + values[k[0] + 1]) if len(k) else np.nan


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--pixels", type=int, default=48, help="map values across the boundary")
    args = ap.parse_args()
    from rattle_core.analysis.vocabulary import REGIME_CODES

    e_branch = continue_orbit(find_orbit(RattleParams(lam=3.3)), "lam", bounds=(1.2, 3.3),
                              direction=-1, max_points=80)
    pd_e = next(b for b in e_branch.bifurcations if b.kind == "period_doubling")
    pd_c = next(b for b in continue_orbit(c_orbit(RattleParams(lam=1.2)), "lam",
                                          bounds=(1.2, 1.5)).bifurcations
                if b.kind == "period_doubling")
    gp = next(c for c in continue_bifurcation(pd_c, "j", bounds=(1.0, 8.0)).codim2
              if c.kind == "grazing_period_doubling")
    x0, v0 = (float(v) for v in c_orbit(RattleParams(lam=1.15)).state_at(0.0))

    def pd_curve():
        return continue_bifurcation(pd_e, "r", bounds=(0.62, 0.78))

    def graze_curve():
        return continue_bifurcation(gp, bounds=(5.0, 8.0), bounds1=(1.0, pd_c.value))

    pd_curve(), graze_curve()  # compile
    print(f"numba threads: {numba.get_num_threads()}; map: {TRANSIENT} + {RECORD} periods per "
          f"point, {args.pixels} values across the boundary")
    print(f"{'curve':<9}{'points':>7}{'curve s':>9}{'points/s':>10}{'error':>10}"
          f"{'map pts':>9}{'map s':>8}{'pixel':>8}{'map error':>11}{'map@1e-3 s':>12}{'map@1e-8 s':>12}")
    for name, make in (("PD", pd_curve), ("grazing", graze_curve)):
        curve, t_curve = best(make, args.repeat)
        pts = curve.points
        n = len(pts)
        if name == "PD":
            err = float(np.max(np.abs(pts["mu1_re"].to_numpy() + 1.0)))
            r = pts["r"].to_numpy()
            order = np.argsort(r)
            rows = r[order]
            across = np.linspace(1.2, 2.6, args.pixels)  # Λ across, one row per curve point
            m, t_map = best(lambda: regime_map(RattleParams(lam=1.2), "lam", across, "r", rows,
                                               transient=TRANSIENT, record=RECORD), 1)
            reg = m.fields["regime"] == REGIME_CODES["E"]
            est = np.array([last_entry(across, reg[i]) for i in range(len(rows))])
            ref = pts["lam"].to_numpy()[order]
        else:
            err = float(np.max(np.abs(pts["gap_min"].to_numpy())))
            lam = pts["lam"].to_numpy()
            order = np.argsort(lam)
            cols = lam[order]
            across = np.linspace(8.0, 5.0, args.pixels)  # j downwards, one column per point
            m, t_map = best(lambda: regime_map(RattleParams(lam=1.2), "lam", cols, "j", across,
                                               transient=TRANSIENT, record=RECORD, x0=x0,
                                               v0=v0), 1)
            reg = m.fields["regime"] == REGIME_CODES["C"]
            est = np.array([first_exit(across, reg[:, i]) for i in range(len(cols))])
            ref = pts["j"].to_numpy()[order]
        span = abs(across[-1] - across[0])
        map_err = float(np.nanmax(np.abs(est - ref)))
        per_value = t_map / args.pixels  # one more value across costs this (all rows)
        print(f"{name:<9}{n:>7}{t_curve:>9.3f}{n / t_curve:>10.0f}{err:>10.1e}"
              f"{m.fields['regime'].size:>9}{t_map:>8.2f}{span / (args.pixels - 1):>8.3f}{map_err:>11.1e}"
              f"{per_value * span / 1e-3:>12.0f}{per_value * span / 1e-8:>12.1e}")
    print("error: |μ + 1| (PD) or the gap at the touch (grazing) at the curve's points; pixel: "
          "the map's step across; map error: largest distance of the map's boundary from the "
          "curve (more than a pixel where the attractor reached depends on the start); map@δ: "
          "the map's time extrapolated to δ across (the curve is exact to 1e-8)")


if __name__ == "__main__":
    main()
