"""Order analysis of a measured speed file against its size: CPU, wall and peak memory.

For each size (1e5, 1e6 and 4e6 rows by default) a synthetic run-up 1000 → 3000 rpm sampled at
10 kHz (orders 2, 4, 6, sensor noise; about 19 bytes a row, so 1e6 rows is a 19 MB file) is
written, then read and analysed by :meth:`rattle_core.model.orders.OrderMap.from_csv` in a
fresh process, which reports:

* CPU seconds (user + system, every thread) and wall seconds of the call, the interpreter's
  imports and the compiled kernels' loading done before (one analysis of the shipped sample);
* the process's peak resident memory (``ru_maxrss``) and how much the call added to it.

The baseline, measured in the same run where affordable (``--baseline-max``, default 1e6 rows),
is the slow reference ``tests/naive_orders.py``: the csv module's row-by-row reader and the
whole-matrix least squares.  Printed beside each size: per-row costs, the ratio to the
smallest size's per-row cost (1.0 when the cost is linear) and the ratio to the baseline.
The machines are shared: CPU seconds are the figure to compare, wall time moves with the load.

Usage: ``python benchmarks/bench_orders.py [--sizes 1e5,1e6,4e6] [--baseline-max 1e6]``.
"""
from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
RATE = 10_000.0

PROBE = """
import json, resource, sys, time
sys.path[:0] = [{root!r}, {tests!r}]
from rattle_core.model.orders import SAMPLE_RUNUP, OrderMap
which, path = sys.argv[1], sys.argv[2]
if which == "new":
    run = lambda p: OrderMap.from_csv(p)
else:
    import naive_orders
    def run(p):
        t, w, lines = naive_orders.read_speed_csv(p)
        return naive_orders.analyse(t, w, (2.0, 4.0, 6.0), 100.0, p,
                                    lambda i: "line %d" % lines[i])
run(SAMPLE_RUNUP)          # imports, compiled kernels
usage = lambda: resource.getrusage(resource.RUSAGE_SELF)
before, wall = usage(), time.perf_counter()
m = run(path)
after, wall = usage(), time.perf_counter() - wall
print(json.dumps({{"cpu": after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime,
                  "wall": wall, "peak_mb": after.ru_maxrss / 1024,
                  "added_mb": (after.ru_maxrss - before.ru_maxrss) / 1024, "bins": int(m.rpm.size)}}))
"""


def write_runup(path: Path, rows: int, seed: int = 7) -> None:
    """A run-up 1000 → 3000 rpm over ``rows`` samples at :data:`RATE` with orders 2, 4, 6."""
    import pandas as pd
    t = np.arange(rows) / RATE
    duration = rows / RATE
    w0, acc = 1000 * 2 * math.pi / 60, 2000 * 2 * math.pi / 60 / duration
    psi, omega = w0 * t + 0.5 * acc * t * t, w0 + acc * t
    speed = omega.copy()
    for k, alpha, phase in ((2, 200.0, 20.0), (4, 70.0, -60.0), (6, 24.0, 150.0)):
        speed -= alpha / (k * omega) * np.sin(k * psi - math.radians(phase))
    rpm = speed * 60 / (2 * math.pi) + np.random.default_rng(seed).normal(0.0, 0.2, rows)
    frame = pd.DataFrame({"time_s": t, "speed_rpm": rpm})
    frame["time_s"] = frame["time_s"].map("{:.6f}".format)
    frame.to_csv(path, index=False, float_format="%.3f")


def measure(which: str, path: Path) -> dict:
    probe = PROBE.format(root=str(ROOT), tests=str(ROOT / "tests"))
    r = subprocess.run([sys.executable, "-c", probe, which, str(path)], capture_output=True,
                       text=True, cwd=ROOT)
    if r.returncode != 0:
        return {"error": (r.stderr.strip().splitlines() or ["failed"])[-1]}
    return json.loads(r.stdout.strip().splitlines()[-1])


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sizes", default="1e5,1e6,4e6", help="rows of each file, comma-separated")
    ap.add_argument("--baseline-max", type=float, default=1e6,
                    help="largest size measured with the slow reference too")
    args = ap.parse_args()
    sizes = [int(float(s)) for s in args.sizes.split(",")]
    print(f"{'rows':>9} {'MB':>6} | {'CPU s':>6} {'wall s':>7} {'peak MB':>8} {'added MB':>8} "
          f"{'µs/row':>7} {'B/row':>6} {'linear':>6} | {'ref CPU':>7} {'ref peak':>8} "
          f"{'CPU ×':>6} {'peak ×':>6}")
    first = None
    with tempfile.TemporaryDirectory(prefix="bench-orders-") as tmp:
        for rows in sizes:
            path = Path(tmp) / f"runup_{rows}.csv"
            write_runup(path, rows)
            mb = path.stat().st_size / 1e6
            new = measure("new", path)
            if "error" in new:
                print(f"{rows:>9} {mb:>6.1f} | {new['error']}")
                continue
            per_row = new["cpu"] / rows * 1e6
            first = first or per_row
            line = (f"{rows:>9} {mb:>6.1f} | {new['cpu']:>6.2f} {new['wall']:>7.2f} "
                    f"{new['peak_mb']:>8.0f} {new['added_mb']:>8.0f} {per_row:>7.2f} "
                    f"{new['added_mb'] * 2**20 / rows:>6.0f} {per_row / first:>6.2f} |")
            if rows <= args.baseline_max:
                ref = measure("reference", path)
                if "error" in ref:
                    line += f" reference failed: {ref['error']}"
                else:
                    line += (f" {ref['cpu']:>7.2f} {ref['peak_mb']:>8.0f} "
                             f"{ref['cpu'] / new['cpu']:>6.1f} {ref['peak_mb'] / new['peak_mb']:>6.1f}")
            else:
                line += "  (reference not run: --baseline-max)"
            print(line, flush=True)
            path.unlink()
    print("CPU s, wall s: the read and analysis of one file after imports; peak MB: the whole "
          "process's; added MB: what the call added to it. linear: µs/row over the first "
          "size's. ref: tests/naive_orders.py; × = reference over streamed.")
    return 0


if __name__ == "__main__":
    sys.exit(main())
