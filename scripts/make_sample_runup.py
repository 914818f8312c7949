"""Make the shipped sample run-up: a synthetic encoder speed signal, labelled as such.

Writes ``rattle_core/assets/measurements/runup_4cyl_synthetic.csv.gz`` (package data): the
instantaneous crankshaft speed of a four-cylinder four-stroke engine running up from 1000 to
3000 rpm in 16 s, sampled at 6400 Hz (over 20 samples per cycle of order 6 at 3000 rpm).

It is made, not measured:

* the mean speed rises linearly, ``ψ(t) = Ω₀ t + a t² / 2``;
* the angular fluctuation is ``θ(t) = Σ_k θ_k(rpm) (1 + c(ψ)) cos(k ψ − φ_k)`` for orders
  2, 4 and 6, with angular-acceleration amplitudes ``α₂`` rising from 120 to 300 rad/s² over
  the run-up (towards a driveline resonance), ``α₄ = 0.35 α₂``, ``α₆ = 0.12 α₂``, and
  ``θ_k = α_k / (k Ω)²``; phases ``φ₂ = 20°``, ``φ₄ = −60°``, ``φ₆ = 150°``
  (:mod:`rattle_core.measure.orders`' convention);
* cycle-to-cycle variation ``c(ψ)``: each firing (every half revolution) scales the
  fluctuation by a random factor of standard deviation 5 %, blended smoothly between firings;
* sensor noise: white, 0.2 rpm standard deviation.

The seed is fixed, so the file is reproducible.  Usage: ``python scripts/make_sample_runup.py``.
"""
from __future__ import annotations

import gzip
import math
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "rattle_core" / "assets" / "measurements" / "runup_4cyl_synthetic.csv.gz"
RPM0, RPM1, DURATION, RATE = 1000.0, 3000.0, 16.0, 6400
ORDERS = (2, 4, 6)
PHASES_DEG = (20.0, -60.0, 150.0)
ACCEL_SHARE = (1.0, 0.35, 0.12)
CYCLE_VARIATION = 0.05
NOISE_RPM = 0.2
SEED = 20_261_124


def alpha2(rpm: np.ndarray) -> np.ndarray:
    """Order-2 angular-acceleration amplitude [rad/s²] of the sample at each speed."""
    return 120.0 + 180.0 * (rpm - RPM0) / (RPM1 - RPM0)


def make() -> tuple[np.ndarray, np.ndarray]:
    """``(time_s, speed_rpm)`` of the sample."""
    rng = np.random.default_rng(SEED)
    fine = 4
    t = np.arange(int(DURATION * RATE * fine)) / (RATE * fine)
    w0 = RPM0 * 2 * math.pi / 60
    acc = (RPM1 - RPM0) * 2 * math.pi / 60 / DURATION
    psi = w0 * t + 0.5 * acc * t * t
    omega = w0 + acc * t
    rpm = omega * 60 / (2 * math.pi)
    firings = rng.normal(0.0, CYCLE_VARIATION, int(psi[-1] / math.pi) + 3)
    c = np.interp(psi / math.pi, np.arange(firings.size), firings)
    theta = np.zeros_like(t)
    for k, ph, share in zip(ORDERS, PHASES_DEG, ACCEL_SHARE):
        amp = share * alpha2(rpm) / (k * omega) ** 2
        theta += amp * (1 + c) * np.cos(k * psi - math.radians(ph))
    speed = (omega + np.gradient(theta, t)) * 60 / (2 * math.pi)
    t, speed = t[::fine], speed[::fine]
    speed = speed + rng.normal(0.0, NOISE_RPM, speed.size)
    return t, speed


def main() -> int:
    t, speed = make()
    OUT.parent.mkdir(parents=True, exist_ok=True)
    lines = ["# SYNTHETIC sample, not a measurement: made by scripts/make_sample_runup.py",
             "# four-cylinder four-stroke run-up 1000 -> 3000 rpm in 16 s, orders 2, 4, 6,",
             "# 5 % cycle-to-cycle variation, 0.2 rpm sensor noise, sampled at 6400 Hz",
             "time_s,speed_rpm"]
    body = "\n".join(f"{a:.6f},{b:.3f}" for a, b in zip(t, speed))
    with gzip.GzipFile(OUT, "wb", mtime=0) as f:
        f.write(("\n".join(lines) + "\n" + body + "\n").encode())
    print(f"wrote {OUT.relative_to(ROOT)} ({OUT.stat().st_size} bytes, {t.size} samples)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
