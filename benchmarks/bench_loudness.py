"""Benchmark: ISO 532-1 time-varying loudness (and DIN 45692 sharpness) of one sound, compiled
(:func:`rattle_core.analysis.loudness.loudness_zwtv`) against MOSQITO's own ``loudness_zwtv``
measured in the same run, on the same sounds: a rattle of a simulated trajectory, pink noise and a
1 kHz tone, each ``--seconds`` long at 48 kHz.  Prints CPU seconds (``time.process_time``)
beside wall seconds per sound and their ratios; then the compiled kernel on several threads at
once (it releases the GIL), sounds per second of wall time.  The machine may be shared: compare
CPU times.
Run: ``.venv/bin/python benchmarks/bench_loudness.py [--seconds 0.5] [--repeat 20]``.
"""
from __future__ import annotations

import argparse
import math
import os
import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from rattle_core import RattleParams, simulate
from rattle_core.analysis.loudness import SAMPLE_RATE, loudness_zwtv, sharpness_din
from rattle_core.analysis.sound import synthesize


def sounds(seconds: float) -> dict[str, np.ndarray]:
    n = int(round(seconds * SAMPLE_RATE))
    t = np.arange(n) / SAMPLE_RATE
    tr = simulate(RattleParams.paper(3.3, amplitudes=(1.0, 0.25), phases_deg=(0.0, 45.0)),
                  periods=int(seconds * 50) + 2, transient=200)
    s, _ = synthesize(tr, sample_rate=SAMPLE_RATE, excitation_hz=50.0, normalized=False, tail=0)
    rattle = np.zeros(n)
    rattle[:min(n, s.size)] = s[:n] * (2.0 / np.max(np.abs(s)))
    spectrum = np.fft.rfft(np.random.default_rng(1).standard_normal(n))
    f = np.maximum(np.arange(spectrum.size), 1.0)
    noise = np.fft.irfft(spectrum / np.sqrt(f), n)
    return {"rattle": rattle,
            "pink noise": noise * 0.063 / np.std(noise),
            "1 kHz tone": 0.02 * math.sqrt(2) * np.sin(2 * math.pi * 1000 * t)}


def timed(fn, repeat: int) -> tuple[float, float]:
    """Best CPU and wall seconds of ``repeat`` calls (the least disturbed by other load)."""
    cpu, wall = math.inf, math.inf
    for _ in range(repeat):
        c, w = time.process_time(), time.perf_counter()
        fn()
        cpu, wall = min(cpu, time.process_time() - c), min(wall, time.perf_counter() - w)
    return cpu, wall


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--seconds", type=float, default=0.5)
    ap.add_argument("--repeat", type=int, default=20, help="calls of the compiled kernel")
    ap.add_argument("--repeat-mosqito", type=int, default=3)
    args = ap.parse_args()
    from mosqito.sq_metrics import loudness_zwtv as mosqito_zwtv
    from mosqito.sq_metrics import sharpness_din_from_loudness

    sig = sounds(args.seconds)
    loudness_zwtv(sig["rattle"], SAMPLE_RATE)  # the JIT cache is loaded outside the timing
    print(f"{args.seconds:g} s at {SAMPLE_RATE} Hz; load average {os.getloadavg()[0]:.2f} on "
          f"{os.cpu_count()} cores; best of {args.repeat} (compiled) and {args.repeat_mosqito} "
          "(MOSQITO) calls")
    print(f"{'sound':12s} {'compiled CPU':>13s} {'wall':>9s} {'MOSQITO CPU':>12s} {'wall':>9s} "
          f"{'CPU ratio':>10s} {'N5 equal':>9s}")
    for name, x in sig.items():
        def ours():
            N, spec, _, _ = loudness_zwtv(x, SAMPLE_RATE)
            sharpness_din(N, spec)

        def theirs():
            N, spec, _, _ = mosqito_zwtv(x, SAMPLE_RATE)
            with np.errstate(invalid="ignore", divide="ignore"):
                sharpness_din_from_loudness(N, spec, "din")

        c_ours, w_ours = timed(ours, args.repeat)
        c_ref, w_ref = timed(theirs, args.repeat_mosqito)
        same = np.percentile(loudness_zwtv(x, SAMPLE_RATE)[0], 95) == np.percentile(
            mosqito_zwtv(x, SAMPLE_RATE)[0], 95)
        print(f"{name:12s} {c_ours * 1e3:10.2f} ms {w_ours * 1e3:6.2f} ms {c_ref * 1e3:9.0f} ms "
              f"{w_ref * 1e3:6.0f} ms {c_ref / c_ours:9.0f}× {str(same):>9s}")
    threads = os.cpu_count() or 1
    batch = [sig["rattle"]] * (8 * threads)
    c, w = time.process_time(), time.perf_counter()
    for x in batch:
        loudness_zwtv(x, SAMPLE_RATE)
    c1, w1 = time.process_time() - c, time.perf_counter() - w
    c, w = time.process_time(), time.perf_counter()
    with ThreadPoolExecutor(threads) as pool:
        list(pool.map(lambda x: loudness_zwtv(x, SAMPLE_RATE), batch))
    c2, w2 = time.process_time() - c, time.perf_counter() - w
    print(f"{len(batch)} rattles, one thread : {c1:6.3f} CPU-s {w1:6.3f} s wall "
          f"({len(batch) / w1:.0f} sounds/s)")
    print(f"{len(batch)} rattles, {threads} threads: {c2:6.3f} CPU-s {w2:6.3f} s wall "
          f"({len(batch) / w2:.0f} sounds/s, {w1 / w2:.2f}× the wall speed of one thread)")


if __name__ == "__main__":
    main()
