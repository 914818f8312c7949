"""Benchmark: a 200 × 200 (Λ × φ2) regime map, local cores against a 2-worker Dask LocalCluster.

Prints both wall times and the Dask/local ratio (target: Dask within 30% of local at this size),
the CPU time each run consumed (this process, plus the workers' processes for Dask), and the
bytes a map task sends back (its per-point summary) beside the chunk's full per-impact result.  The
cores are shared, so wall times move with the load average printed beside them; CPU time does
not, and CPU time / cores is the wall time the run would take on otherwise idle cores.
Run: ``.venv/bin/python benchmarks/bench_maps.py [--n 200] [--transient 300] [--record 100]``.
"""
from __future__ import annotations

import argparse
import math
import os
import pickle
import time

import numpy as np

from rattle_core import RattleParams
from rattle_core.batch.maps import _map_chunk, regime_map
from rattle_core.batch.chunks import run_chunk


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--n", type=int, default=200, help="grid points per axis")
    ap.add_argument("--transient", type=int, default=300)
    ap.add_argument("--record", type=int, default=100)
    args = ap.parse_args()
    base = RattleParams(lam=2.0, amplitudes=(1.0, 0.25), phases_deg=(0.0, 0.0))
    lams = np.linspace(0.5, 4.0, args.n)
    phis = np.linspace(0.0, 360.0, args.n)
    kw = dict(transient=args.transient, record=args.record)
    regime_map(base, "lam", lams[:2], "phi2", phis[:2], transient=5, record=5)  # compile

    print(f"load average before the local run: {os.getloadavg()[0]:.2f} "
          f"({os.cpu_count()} cores, shared with other processes)")
    cores = os.cpu_count() or 1
    t = time.perf_counter()
    c = time.process_time()
    local = regime_map(base, "lam", lams, "phi2", phis, **kw)
    t_local = time.perf_counter() - t
    c_local = time.process_time() - c
    periods = args.n * args.n * (args.transient + args.record)
    print(f"local   : {t_local:7.2f} s for {args.n}x{args.n} points, {periods:.3g} periods "
          f"({periods / t_local:.3g} periods/s)   target <= 30 s")
    print(f"          CPU {c_local:.1f} s; on {cores} idle cores about {c_local / cores:.1f} s")

    from dask.distributed import Client, LocalCluster
    with LocalCluster(n_workers=2, threads_per_worker=1, dashboard_address=None) as cluster, \
            Client(cluster) as client:
        # workers load the compiled kernels from numba's on-disk cache once
        regime_map(base, "lam", lams[:2], "phi2", phis[:2], transient=5, record=5,
                   executor=client, chunk_size=2)
        print(f"load average before the Dask run: {os.getloadavg()[0]:.2f}")
        w0 = client.run(time.process_time)
        t = time.perf_counter()
        c = time.process_time()
        remote = regime_map(base, "lam", lams, "phi2", phis, executor=client, **kw)
        t_dask = time.perf_counter() - t
        c_main = time.process_time() - c
        w1 = client.run(time.process_time)
        c_workers = sum(w1[k] - w0[k] for k in w1)
    same = all(np.array_equal(local.fields[k], remote.fields[k], equal_nan=True)
               for k in local.fields)
    print(f"dask x2 : {t_dask:7.2f} s   ratio dask/local = {t_dask / t_local:.2f} "
          f"(target <= 1.30); identical results: {same}")
    c_dask = c_workers + c_main
    print(f"          CPU {c_dask:.1f} s (workers {c_workers:.1f} s, client and scheduler "
          f"{c_main:.1f} s); on {cores} idle cores about {c_dask / cores:.1f} s, "
          f"CPU ratio dask/local = {c_dask / c_local:.2f}")

    # the first chunk of the map, as a task runs it: what it returns, against the full result
    n = args.n * args.n
    size = max(64, math.ceil(n / 40))
    gx, gy = np.meshgrid(lams, phis)
    cols = {"lam": gx.ravel()[:size], "phi2": gy.ravel()[:size]}
    rows = np.arange(size, dtype=np.float64)
    summary = len(pickle.dumps(_map_chunk(base, cols, rows, args.transient, args.record, None, 0.0)))
    full = len(pickle.dumps(run_chunk(base, cols, rows, args.transient, args.record, None, 0.0)))
    scale = n / size
    print(f"task results (first chunk, {size} points, pickled): {summary / size:.0f} bytes per "
          f"point, about {summary * scale / 1e6:.2f} MB for the map; the full per-impact result "
          f"would be {full / size:.0f} bytes per point, about {full * scale / 1e6:.0f} MB")


if __name__ == "__main__":
    main()
