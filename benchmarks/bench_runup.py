"""Speed of the run-up replay, against the harmonic kernel, in one run.

Prints, after compilation, best of several repeats, CPU seconds beside wall seconds:

* the replay of a steady measurement (constant speed and orders, so the same motion as the
  harmonic model): impacts/s of the replay kernel and of ``simulate()`` on the equivalent
  ``RattleParams``, over the same forcing periods, and their ratio;
* a run-up of the shipped sample measurement, 1000 → 3000 rpm, for each gear of a 5-gear
  gearbox: building the wall, replaying it, impacts/s; and the whole gearbox's total;
* the same run-up heard and measured (``gearbox_runup``: every gear's replay on threads, the
  48 kHz sound, N(t) and L_AF(t)), on one thread and on all, against the replays alone
  measured above (target: <= 10 CPU-s for 30 s).

Run from the repository root::

    .venv/bin/python benchmarks/bench_runup.py            # 30 s run-up
    .venv/bin/python benchmarks/bench_runup.py --quick    # 5 s run-up, fewer repeats
"""
from __future__ import annotations

import os

os.environ["NUMBA_NUM_THREADS"] = "1"

import argparse  # noqa: E402
import math  # noqa: E402
import time  # noqa: E402


from rattle_core.batch.runup import gearbox_runup  # noqa: E402

from rattle_core import simulate  # noqa: E402
from rattle_core.model.gearbox import Excitation, Gear, Gearbox  # noqa: E402
from rattle_core.measure.orders import SAMPLE_RUNUP, OrderMap  # noqa: E402
from rattle_core.solver.replay import run_wall  # noqa: E402
from rattle_core.solver.runup import replay, runup_wall  # noqa: E402

STEADY = """
[excitation]
orders = [{order = 2, amplitude_rad = 0.002, phase_deg = 0}, {order = 4, amplitude_rad = 0.0005, phase_deg = 30}, {order = 6, amplitude_rad = 0.0002, phase_deg = -70}]
engine_order = 2
harmonics = 3

[[gear]]
name = "idler"
inertia_kgm2 = 4e-4
base_radius_m = 0.035
drag_torque_Nm = 0.05
backlash_um = 80
restitution = 0.8
"""

GEARS = (Gear("1st", 4e-4, 0.035, 0.05, 80.0), Gear("2nd", 2.5e-4, 0.03, 0.03, 120.0, speed_ratio=0.8),
         Gear("3rd", 3e-4, 0.032, 0.04, 100.0, speed_ratio=1.2),
         Gear("5th", 2e-4, 0.028, 0.02, 90.0, speed_ratio=1.5),
         Gear("reverse idler", 5e-4, 0.04, 0.06, 150.0, speed_ratio=0.6))


def timed(fn, repeats):
    """Best wall and CPU seconds of ``repeats`` calls, and the last result."""
    best_w = best_c = math.inf
    out = None
    for _ in range(repeats):
        w0, c0 = time.perf_counter(), time.process_time()
        out = fn()
        best_w = min(best_w, time.perf_counter() - w0)
        best_c = min(best_c, time.process_time() - c0)
    return best_w, best_c, out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args()
    repeats = 2 if args.quick else 5
    duration = 5.0 if args.quick else 30.0

    # --- the same motion through both kernels -------------------------------------------------
    box = Gearbox.from_text(STEADY)
    rpm, periods = 4000.0, 4000 if args.quick else 20000
    params = box.physical(0, rpm).to_dimensionless().replace(noise=0.0)
    omega = 2 * 2 * math.pi * rpm / 60
    rw = runup_wall(box, 0, rpm, rpm, periods * 2 * math.pi / omega)
    v0 = float(rw.wall.values(0.0, 1)[0])
    run = lambda: run_wall(rw.wall, rw.r, rw.j, x0=None, v0=v0)  # noqa: E731
    sim = lambda: simulate(params, periods=periods, v0=v0, record_segments=False)  # noqa: E731
    run(), sim()
    w_r, c_r, out_r = timed(run, repeats)
    w_s, c_s, out_s = timed(sim, repeats)
    n_r, n_s = out_r.impact_t.size, out_s.impact_t.size
    print(f"steady replay against the harmonic kernel, {periods} periods at {rpm:g} rpm "
          f"(one core, best of {repeats})")
    print(f"  replay kernel   {n_r:8d} impacts  wall {w_r:7.3f} s  CPU {c_r:7.3f} s  "
          f"{n_r / c_r:12.4g} impacts/CPU-s")
    print(f"  harmonic kernel {n_s:8d} impacts  wall {w_s:7.3f} s  CPU {c_s:7.3f} s  "
          f"{n_s / c_s:12.4g} impacts/CPU-s")
    print(f"  replay / harmonic: {(n_r / c_r) / (n_s / c_s):.3f} of the impacts/s "
          f"(same impacts: {n_r == n_s})")

    # --- a run-up of a 5-gear gearbox ---------------------------------------------------------
    omap = OrderMap.from_csv(SAMPLE_RUNUP, orders=(2, 4, 6), rpm_step=100)
    gbox = Gearbox(Excitation(2.0, 3, omap), GEARS)
    print(f"\nrun-up 1000 -> 3000 rpm in {duration:g} s, sample measurement, 5 gears "
          f"(best of {repeats})")
    tot_w = tot_c = 0.0
    tot_n = 0
    for gi, g in enumerate(GEARS):
        replay(gbox, gi, 1000.0, 3000.0, duration)
        wb, cb, wall = timed(lambda: runup_wall(gbox, gi, 1000.0, 3000.0, duration), repeats)
        wk, ck, res = timed(lambda: run_wall(wall.wall, wall.r, wall.j, mode=1), repeats)
        n = res.impact_t.size
        tot_w += wb + wk
        tot_c += cb + ck
        tot_n += n
        print(f"  {g.name:14s} wall built: wall {wb:6.3f} s CPU {cb:6.3f} s | replay: {n:7d} impacts "
              f"wall {wk:6.3f} s CPU {ck:6.3f} s  {n / max(ck, 1e-9):10.4g} impacts/CPU-s")
    print(f"  gearbox total   {tot_n} impacts  wall {tot_w:.3f} s  CPU {tot_c:.3f} s")

    # --- the same run-up heard and measured ---------------------------------------------------
    gearbox_runup(gbox, 1000.0, 3000.0, 1.0)          # compiled once, outside the timing
    sound_repeats = 1 if not args.quick else 2
    print(f"\nthe same run-up with its sound, N(t) and L_AF(t) (gearbox_runup, best of "
          f"{sound_repeats})")
    for threads in (1, min(len(GEARS), os.cpu_count() or 1)):
        w, c, res = timed(lambda: gearbox_runup(gbox, 1000.0, 3000.0, duration, threads=threads),
                          sound_repeats)
        print(f"  {threads} thread(s): wall {w:7.3f} s  CPU {c:7.3f} s  ({res.pressure_pa.size} "
              f"samples, N max {res.loudness_t.max():.1f} sone); CPU / replays alone "
              f"{c / tot_c:.2f}")
    print("  target for a 30 s run-up: <= 10 CPU-s, sound and loudness included")


if __name__ == "__main__":
    main()
