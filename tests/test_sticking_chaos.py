"""Chaos through sticking: the noisy model's chaotic set, not a loop chosen by rounding.

A stick phase ends at a fixed phase of the period, so every release puts the gear in the same
state; when the flight between captures amplifies perturbations beyond what double precision
resolves, rounding picks a loop that then repeats for ever (docs/model.md, "Sticking erases
the past").  These tests check the treatment: the chaotic set at the default noise,
robust stick orbits exact, reproducible numbers, and the strict model (``noise=0``), flagged.
"""
from __future__ import annotations

import hashlib
import subprocess
import sys

import numpy as np
import pytest

from naive import ReferenceError_, naive_simulate
from rattle_core import RattleParams, classify, simulate, sweep
from rattle_core import excitation

TWO_PI = 2.0 * np.pi
FIG7 = RattleParams.paper(lam=3.3, amplitudes=(1.0, 0.25), phases_deg=(0.0, 45.0))
R05 = RattleParams(lam=3.0, r=0.5, j=6.0, amplitudes=(1.0, 0.4), phases_deg=(0.0, 200.0))
REGIME_B = RattleParams(lam=1.05)


def distinct_points(tr) -> int:
    return len(set(zip(tr.strobe_x.tolist(), tr.strobe_v.tolist())))


def test_fig7_section_is_a_strange_attractor():
    """Fig 7 (Λ = 3.3, paper φ₂ = 45°), 500 + 4000 periods from mid-backlash: ≥ 3000 distinct
    section points, classified D with chaos through sticking and statistics at its noise."""
    tr = simulate(FIG7, periods=4000, transient=500, lyapunov=True)
    assert distinct_points(tr) >= 3000
    assert tr.n_stick_phases > 0 and tr.noise_kicks > 0 and tr.rounding_decided
    c = classify(tr)
    assert (c.regime, c.sticking, c.noisy) == ("D", "chaos-through-sticking", True)
    assert "statistics at this noise level" in c.label


@pytest.mark.parametrize("p", [FIG7, R05], ids=["fig7", "r=0.5"])
def test_strict_model_locks_into_a_loop_and_says_it_is_unresolvable(p):
    """noise=0: the run repeats a loop chosen by rounding (few distinct section points),
    scatters no rebound, and is flagged: capture amplification beyond 1e10, label says so."""
    tr = simulate(p.replace(noise=0.0), periods=4000, transient=500, lyapunov=True)
    assert distinct_points(tr) < 1000
    assert tr.noise_kicks == 0 and tr.rounding_decided and tr.loop_amplification > 10
    c = classify(tr)
    assert c.sticking == "chaos-through-sticking" and not c.noisy
    assert "not resolvable" in c.label


def test_robust_stick_orbit_is_exact_bit_for_bit():
    """Regime B (harmonic, Λ = 1.05): the strict model has one section point and repeats the
    impacts of every period bit for bit; the default noise moves them by under 1e-9; the loop
    amplification is small."""
    off = simulate(REGIME_B.replace(noise=0.0), periods=200, transient=100)
    on = simulate(REGIME_B, periods=200, transient=100)
    assert distinct_points(off) == 1
    np.testing.assert_array_equal(on.impact_flank, off.impact_flank)
    for field in ("impact_t", "impact_impulse", "strobe_x", "strobe_v", "seg_t"):
        np.testing.assert_allclose(getattr(on, field), getattr(off, field), rtol=0, atol=1e-9)
    on = off
    per = len(on.impact_t) // 200
    assert per * 200 == len(on.impact_t) and per > 1
    imp = on.impact_impulse.reshape(200, per)
    assert np.all(imp == imp[0])
    phase = (on.impact_t - on.t_start).reshape(200, per) - TWO_PI * np.arange(200)[:, None]
    np.testing.assert_allclose(phase, np.broadcast_to(phase[0], phase.shape), rtol=0, atol=1e-9)
    assert on.noise_kicks == 0 and not on.rounding_decided
    assert 0 < on.loop_amplification < 5
    c = classify(on)
    assert (c.regime, c.period, c.sticking) == ("B", 1, "stick-locked")
    assert "stick-locked, loop amplification 10^" in c.label


def test_default_noise_is_round_off_sized_at_each_rebound():
    """Noise on and off meet their first impact at the same time; its impulse differs by at
    most the default ε relative, and every rebound of the noisy run is scattered."""
    on = simulate(FIG7, periods=3000)
    off = simulate(FIG7.replace(noise=0.0), periods=3000)
    assert on.noise_kicks > 0 and off.noise_kicks == 0
    assert on.impact_t[0] == off.impact_t[0]
    rel = abs(on.impact_impulse[0] - off.impact_impulse[0]) / abs(off.impact_impulse[0])
    assert 0 < rel <= FIG7.noise
    assert off.rounding_decided


def _digest(tr) -> str:
    h = hashlib.sha256()
    for a in (tr.impact_t, tr.impact_impulse, tr.strobe_x, tr.strobe_v):
        h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()


def test_same_inputs_same_numbers_in_any_call_process_and_thread_count():
    """Two calls give identical arrays; so does a fresh interpreter; and each value of a sweep
    run on many threads in chunks equals a single-threaded simulate of that value."""
    a = simulate(R05, periods=1500, transient=100)
    b = simulate(R05, periods=1500, transient=100)
    assert a.noise_kicks > 0
    assert _digest(a) == _digest(b)
    code = ("import hashlib, numpy as np\n"
            "from rattle_core import RattleParams, simulate\n"
            "tr = simulate(RattleParams(lam=3.0, r=0.5, j=6.0, amplitudes=(1.0, 0.4), "
            "phases_deg=(0.0, 200.0)), periods=1500, transient=100)\n"
            "h = hashlib.sha256()\n"
            "for a in (tr.impact_t, tr.impact_impulse, tr.strobe_x, tr.strobe_v):\n"
            "    h.update(np.ascontiguousarray(a).tobytes())\n"
            "print(h.hexdigest())\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                         env={"NUMBA_NUM_THREADS": "1", "PATH": "/usr/bin:/bin",
                              **{k: v for k, v in __import__("os").environ.items()
                                 if k.startswith(("PYTHON", "NUMBA_CACHE", "HOME"))}})
    assert out.stdout.strip() == _digest(a)
    lams = np.array([2.9, 3.0, 3.1, 3.2])
    for chunk in (1, 4):
        res = sweep(R05, "lam", lams, transient=100, record=300, chunk_size=chunk)
        for lam in lams:
            tr = simulate(R05.with_value("lam", lam), periods=300, transient=100)
            got = res.table[res.table.value == lam]
            np.testing.assert_array_equal(got.impulse.to_numpy(), tr.impact_impulse)
            np.testing.assert_array_equal(got.phase.to_numpy(), tr.impact_phase)


def test_sweep_summary_reports_the_kind_of_answer():
    """The sweep summary carries the sticking kind and loop amplification of each value, and
    noise=0 reproduces the strict model's flag."""
    res = sweep(FIG7, "lam", [1.05, 3.3], transient=300, record=2000)
    kinds = dict(zip(res.summary.value, res.summary.sticking))
    assert kinds[3.3] == "chaos-through-sticking"
    strict = sweep(FIG7.replace(noise=0.0), "lam", [3.3], transient=300, record=2000)
    assert strict.summary.sticking.iloc[0] == "chaos-through-sticking"
    assert strict.summary.loop_amplification.iloc[0] > 10
    harmonic = sweep(REGIME_B, "lam", [1.05], transient=100, record=100)
    assert harmonic.summary.sticking.iloc[0] == "stick-locked"
    assert harmonic.summary.loop_amplification.iloc[0] < 5


def _pooled_stats(runs) -> np.ndarray:
    imp = np.concatenate([r[0] for r in runs])
    fl = np.concatenate([r[1] for r in runs])
    periods = sum(r[2] for r in runs)
    return np.array([len(imp) / periods, np.mean(np.abs(imp[fl == 1])),
                     np.mean(np.abs(imp[fl == -1]))])


# The reference runs in absolute time, where rounding of t ~ 1e4 perturbs every event at the
# 1e-12 level: it is itself a model with vanishing noise.  Its scan needs rebounds faster than
# that rounding, so both sides take v_stick = 1e-3 (rebounds slower than that end in sticking).
@pytest.mark.slow
@pytest.mark.parametrize("p", [FIG7, R05], ids=["fig7", "r=0.5"])
def test_chaotic_statistics_match_the_absolute_time_reference(p):
    """Impacts per period and mean active and reverse impulses, pooled over four initial
    states (200 + 2000 periods each), lie within 6 % of tests/naive.py's reference."""
    p = p.with_value("v_stick", 1e-3)
    y0 = float(excitation(0.0, p.h, p.phi))
    transient, record = 200, 2000
    ours, ref = [], []
    for frac in (0.2, 0.4, 0.6, 0.8, 0.3, 0.5, 0.7, 0.9):
        if len(ref) == 4:
            break
        x0 = y0 + frac * p.j
        try:
            run = naive_simulate(p.lam, p.r, p.j, p.h, p.phi, p.v_stick, 0.0, x0, 0.0,
                                 (transient + record) * TWO_PI)
        except ReferenceError_:
            continue
        keep = run.impact_t >= transient * TWO_PI
        ref.append((run.impact_impulse[keep], run.impact_flank[keep], record))
        tr = simulate(p, periods=record, transient=transient, x0=x0)
        assert tr.noise_kicks > 0
        ours.append((tr.impact_impulse, tr.impact_flank, record))
    assert len(ref) == 4, "the reference could not run four initial states"
    np.testing.assert_allclose(_pooled_stats(ours), _pooled_stats(ref), rtol=0.06)
