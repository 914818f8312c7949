"""Benchmark of the analysis layer: the Figure 2 sweep and a 2-D regime map, with ratios.

Prints, after compilation:

1. The Figure 2 sweep (harmonic, r = 0.65, j = 8): 1000 values of Λ in [0.5, 4], each
   500 transient + 200 recorded periods, through :func:`rattle_core.sweep` (kernel, impact
   table and per-value classification).  Wall time with all numba threads and with one
   thread (``numba.set_num_threads(1)``), and the speed-up.  Target: ≤ 3 s.
2. A baseline: the same model integrated by ``scipy.integrate.solve_ivp`` (DOP853) with
   terminal events on both gaps and the impact law applied between calls.  It is timed on a
   subsample (three Λ values in regime E, fewer periods), checked against the exact solver
   there, and extrapolated per forcing period to the full sweep.  The baseline handles
   flights and impacts only (no chatter or stick phases), and regime E has the fewest events
   per period, so the extrapolation favours the baseline.
3. A 2-D regime map, 200 × 200 points of Λ ∈ [0.5, 4] × φ2 ∈ [0°, 360°) (core convention,
   H2/H1 = 0.25), each 300 + 100 periods, through :func:`rattle_core.batch.maps.regime_map`.
   Target: ≤ 30 s.

Usage: ``python benchmarks/bench_sweep.py [--repeat N] [--skip-grid | --grid-only]``.
"""
from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import numba  # noqa: E402
from scipy.integrate import solve_ivp  # noqa: E402

from rattle_core import RattleParams, excitation, simulate, sweep  # noqa: E402

FIG2_VALUES = np.linspace(0.5, 4.0, 1000)
TRANSIENT, RECORD = 500, 200
GRID_N, GRID_TRANSIENT, GRID_RECORD = 200, 300, 100


def ivp_run(p: RattleParams, periods: float, x0: float, v0: float, rtol=1e-10, atol=1e-10,
            max_step=0.1):
    """Impacts of ``periods`` forcing periods by ``solve_ivp`` with events (the baseline).

    ``max_step`` keeps the integrator from stepping over a contact: the right-hand side is a
    constant, so its error estimate alone would allow steps of any length.
    """
    h, phi, j, r = p.h, p.phi, p.j, p.r
    inv_lam = 1.0 / p.lam

    def y(t, m=0):
        return float(excitation(t, h, phi, m))

    def rhs(_t, z):
        return (z[1], -inv_lam)

    def gap_a(t, z):
        return z[0] - y(t)

    def gap_r(t, z):
        return y(t) + j - z[0]

    for ev in (gap_a, gap_r):
        ev.terminal = True
        ev.direction = -1
    t, x, v = 0.0, x0, v0
    t_end = periods * 2 * np.pi
    times, impulses = [], []
    while t < t_end:
        sol = solve_ivp(rhs, (t, t_end), (x, v), method="DOP853", events=(gap_a, gap_r),
                        rtol=rtol, atol=atol, max_step=max_step)
        if sol.status != 1:
            break
        hits = [(te[0], s, ye[0]) for te, ye, s in zip(sol.t_events, sol.y_events, (1, -1))
                if len(te)]
        t, sigma, z = min(hits, key=lambda e: e[0])
        yd = y(t, 1)
        w = z[1] - yd
        if abs(w) < p.v_stick:
            # chatter ends in a stick phase, which this baseline does not model; without this
            # stop it would restart on the wall at the same time forever
            raise RuntimeError(f"Λ = {p.lam}: chatter at t = {t:.6g}, outside the baseline")
        vplus = yd - r * w
        times.append(t)
        impulses.append(vplus - z[1])
        x = y(t) + (j if sigma == -1 else 0.0)
        v = vplus
    return np.array(times), np.array(impulses)


def timed(fn, repeat: int):
    best = np.inf
    out = None
    for _ in range(repeat):
        t = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t)
    return best, out


def line(label: str, value: str, target: str = "") -> None:
    print(f"  {label:<46} {value:>14}   {target}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3, help="timed repetitions (best is shown)")
    ap.add_argument("--skip-grid", action="store_true", help="leave out the 2-D map")
    ap.add_argument("--grid-only", action="store_true", help="only the 2-D map")
    args = ap.parse_args(argv)
    if args.skip_grid and args.grid_only:
        ap.error("--skip-grid and --grid-only exclude each other")

    threads = numba.get_num_threads()
    print(f"rattle-explorer sweep benchmark: {os.cpu_count()} cores, numba {numba.__version__} "
          f"({threads} threads, layer {numba.config.THREADING_LAYER}); load average before "
          f"the run {os.getloadavg()[0]:.2f} (other processes share the cores)")
    if not args.grid_only:
        base = RattleParams(lam=1.0)
        sweep(base, "lam", np.linspace(0.5, 4, 16), transient=5, record=5)  # compile
        simulate(base, periods=5)

        def fig2():
            return sweep(base, "lam", FIG2_VALUES, transient=TRANSIENT, record=RECORD)

        n_periods = len(FIG2_VALUES) * (TRANSIENT + RECORD)
        print(f"\nFigure 2 sweep: {len(FIG2_VALUES)} values × ({TRANSIENT} + {RECORD}) periods "
              f"= {n_periods:,} periods")
        t_all, res = timed(fig2, args.repeat)
        numba.set_num_threads(1)
        try:
            t_one, res1 = timed(fig2, max(1, args.repeat - 1))
        finally:
            numba.set_num_threads(threads)
        assert np.array_equal(res.table["impulse"].to_numpy(), res1.table["impulse"].to_numpy())
        line(f"wall time, {threads} threads", f"{t_all:.3f} s", f"target ≤ 3 s: "
             f"{'met' if t_all <= 3 else 'MISSED'}")
        line("wall time, 1 thread", f"{t_one:.3f} s")
        line("speed-up over one thread", f"{t_one / t_all:.2f} ×")
        line("throughput", f"{n_periods / t_all / 1e6:.2f} M periods/s")
        line("impacts recorded", f"{len(res.table):,}")
        regimes = res.summary["regime"].value_counts().to_dict()
        print("  regimes: " + ", ".join(f"{k} {v}" for k, v in sorted(regimes.items())))

        # solve_ivp baseline on a subsample, checked against the exact solver
        sub_lams = (2.0, 2.5, 3.0)  # regime E from the first period on: no chatter
        sub_periods = 30
        t0 = time.perf_counter()
        worst = 0.0
        for lam in sub_lams:
            p = base.replace(lam=lam)
            x0 = float(excitation(0.0, p.h, p.phi)) + 0.5 * p.j
            ts, imp = ivp_run(p, sub_periods, x0, 0.0)
            tr = simulate(p, periods=sub_periods)
            m = min(len(imp), len(tr.impact_impulse), 20)
            worst = max(worst, float(np.max(np.abs(imp[:m] - tr.impact_impulse[:m]))))
        t_ivp = time.perf_counter() - t0
        per_period = t_ivp / (len(sub_lams) * sub_periods)
        t_ivp_full = per_period * n_periods
        print(f"\nsolve_ivp baseline (DOP853, rtol = atol = 1e-10, max_step = 0.1, events): "
              f"Λ = {sub_lams}, {sub_periods} periods each")
        line("measured", f"{t_ivp:.2f} s")
        line("per forcing period", f"{per_period * 1e3:.2f} ms")
        line("largest impulse difference to the exact solver", f"{worst:.1e}")
        line("extrapolated to the Figure 2 sweep", f"{t_ivp_full:,.0f} s")
        line("ratio baseline / rattle_core (all threads)", f"{t_ivp_full / t_all:,.0f} ×")

    if not args.skip_grid:
        from rattle_core.batch.maps import regime_map
        base2 = RattleParams(lam=1.0, amplitudes=(1.0, 0.25), phases_deg=(0.0, 0.0))
        lam_v = np.linspace(0.5, 4.0, GRID_N)
        phi_v = np.linspace(0.0, 360.0, GRID_N, endpoint=False)
        regime_map(base2, "lam", lam_v[:4], "phi2", phi_v[:4], transient=5, record=5)
        n_grid = GRID_N * GRID_N * (GRID_TRANSIENT + GRID_RECORD)
        print(f"\n2-D regime map: {GRID_N} × {GRID_N} (Λ × φ2) × ({GRID_TRANSIENT} + "
              f"{GRID_RECORD}) periods = {n_grid:,} periods")
        print(f"  load average before the map: {os.getloadavg()[0]:.2f}")
        t_grid, m = timed(lambda: regime_map(base2, "lam", lam_v, "phi2", phi_v,
                                             transient=GRID_TRANSIENT, record=GRID_RECORD), 1)
        line(f"wall time, {threads} threads", f"{t_grid:.2f} s",
             f"target ≤ 30 s: {'met' if t_grid <= 30 else 'MISSED'}")
        line("throughput", f"{n_grid / t_grid / 1e6:.2f} M periods/s")
        codes = m.fields["regime"]
        names = {0: "A", 1: "B", 2: "C", 3: "D", 4: "E", 5: "P", 6: "Q", 7: "error"}
        u, c = np.unique(codes, return_counts=True)
        print("  regimes: " + ", ".join(f"{names.get(int(k), k)} {n}" for k, n in zip(u, c)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
