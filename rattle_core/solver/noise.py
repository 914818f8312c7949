"""The model's noise stream: its seed and its random numbers.

The restitution coefficient of every rebound is scattered by a relative ``ε ξ``, ``ξ`` uniform
in (−1, 1] (``RattleParams.noise``; docs/model.md, "Noise").  The scatter is reproducible: a
counter-based generator (SplitMix64) gives the k-th number from ``(seed, k)`` alone, and the
seed either derives from the inputs that decide the motion or is chosen by the caller
(:func:`user_seed`).
"""
from __future__ import annotations

import numpy as np
from numba import njit

#: Largest seed :func:`user_seed` takes (seeds are unsigned 64-bit numbers).
MAX_SEED = 2**63 - 1


@njit(cache=True, nogil=True)
def _splitmix(z):
    """SplitMix64: a counter-based generator, so each kick depends only on (seed, index)."""
    z = z + np.uint64(0x9E3779B97F4A7C15)
    z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return z ^ (z >> np.uint64(31))


@njit(cache=True, nogil=True)
def _seed(lam, r, j, h, phi, v_stick, n0, tau0, x0, v0, eps):
    """Default seed of the noise stream, from the inputs that decide the motion.

    Harmonics with ``h_k = 0`` are skipped, so padding with empty harmonics (as sweeps do) keeps
    the seed; the run length is left out, so a longer run extends a shorter one.
    """
    vals = np.empty(9 + 3 * h.shape[0])
    vals[8] = eps
    vals[0] = lam
    vals[1] = r
    vals[2] = j
    vals[3] = v_stick
    vals[4] = float(n0)
    vals[5] = tau0
    vals[6] = x0
    vals[7] = v0
    m = 9
    for i in range(h.shape[0]):
        if h[i] != 0.0:
            vals[m] = i + 1.0
            vals[m + 1] = h[i]
            vals[m + 2] = phi[i]
            m += 3
    bits = vals[:m].view(np.uint64)
    z = np.uint64(0x6A09E667F3BCC908)
    for i in range(m):
        z = _splitmix(z ^ bits[i])
    return z


@njit(cache=True, nogil=True)
def _uniform(seed, k):
    """The k-th number of the stream ``seed``, uniform in (0, 1]."""
    z = _splitmix(seed + np.uint64(k) * np.uint64(0xD1B54A32D192ED03))
    return ((z >> np.uint64(11)) + np.uint64(1)) * (1.0 / 9007199254740992.0)


def user_seed(seed: int) -> np.uint64:
    """The stream of a caller's seed (an int in [0, MAX_SEED]), distinct from derived seeds."""
    return np.uint64(_splitmix(np.uint64(seed) ^ np.uint64(0x5851F42D4C957F2D)))
