"""Regimes, periods, Lyapunov exponents and metrics; analytic overlays against simulation."""
from __future__ import annotations

import math

import numpy as np
import pytest

from rattle_core import RattleParams, classify, contact_boundary, excitation, simulate
from naive import classify_reference
from rattle_core.analysis.classify import (LYAP_CHAOS, MAX_PERIOD, PERIOD_TOL, REGIME_LETTERS,
                                           STICKING_KINDS, Classification, classify_arrays,
                                           classify_batch, detect_period)
from rattle_core.analysis.overlays import (one_sided_impulse, one_sided_orbits,
                                           period1_limits_harmonic)
from rattle_core.model.excitation import TWO_PI

TWO_HARMONICS = [
    RattleParams(lam=1.0, amplitudes=(1.0, 0.25), phases_deg=(0.0, -135.0)),
    RattleParams(lam=1.0, amplitudes=(1.0, 0.25), phases_deg=(0.0, 180.0)),
    RattleParams(lam=1.0, amplitudes=(1.0, 0.3, 0.1), phases_deg=(0.0, 20.0, 200.0)),
]


def _orbit_start(p: RattleParams, theta: float, n: int = 1, dv: float = 0.0):
    """State at t = 0 on the one-sided period-n orbit with impact phase θ (flight 2πn).

    After the impact at θ − 2π the gear leaves the wall at ``ẋ⁺ = nπ/Λ`` on the parabola
    ``x = y(θ) + ẋ⁺ s − s²/(2Λ)``; starting at t = 0 keeps the recording window's edges away
    from the impacts.
    """
    s = TWO_PI - theta
    vp = n * math.pi / p.lam
    x = float(excitation(theta, p.h, p.phi)) + vp * s - 0.5 * s * s / p.lam
    return x, vp - s / p.lam + dv


def _stable_orbit(p: RattleParams, n: int = 1):
    orbs = [o for o in one_sided_orbits(p, n) if o.stable and o.fits]
    assert len(orbs) == 1, orbs
    return orbs[0]


# ----- regimes ------------------------------------------------------------------------------

@pytest.mark.parametrize("r, lam", [(0.65, 1.13), (0.5, 1.2), (0.8, 0.9)])
def test_regime_c_lyapunov_is_log_r_over_two_pi(r, lam):
    """On the C orbit (complex multipliers of modulus r) the exponent is ln(r)/(2π) to 1e-3."""
    p = RattleParams(lam=lam, r=r)
    o = _stable_orbit(p)
    assert o.trace ** 2 < 4 * o.det  # complex pair: both multipliers have modulus √det = r
    x0, v0 = _orbit_start(p, o.theta, dv=1e-3)
    tr = simulate(p, periods=2000, transient=300, x0=x0, v0=v0, lyapunov=True)
    c = classify(tr)
    assert c.regime == "C" and c.period == 1 and not c.chaotic
    assert c.active_per_period == pytest.approx(1.0) and c.reverse_per_period == 0.0
    assert abs(c.lyapunov - math.log(r) / TWO_PI) < 1e-3


@pytest.mark.parametrize("params", [RattleParams(lam=3.3), RattleParams(lam=2.0),
                                    RattleParams.paper(3.3, amplitudes=(1, 0.25),
                                                       phases_deg=(0, 90))],
                         ids=["harmonic-3.3", "harmonic-2.0", "paper-90-3.3"])
def test_regime_e_periodic_negative_exponent(params):
    """Regime E: period 1, one impact on each flank per period, negative exponent."""
    c = classify(simulate(params, periods=300, transient=500, lyapunov=True))
    assert c.regime == "E" and c.period == 1
    assert c.active_per_period == pytest.approx(1.0) and c.reverse_per_period == pytest.approx(1.0)
    assert c.lyapunov < -1e-3 and not c.chaotic and c.stick_fraction == 0.0
    assert "E" in c.label and "period 1" in c.label


@pytest.mark.parametrize("params", [RattleParams(lam=1.16),
                                    RattleParams.paper(3.3, amplitudes=(1, 0.25),
                                                       phases_deg=(0, 45))],
                         ids=["harmonic-1.16", "paper-45-3.3"])
def test_chaotic_case_positive_exponent_no_period(params):
    """A chaotic response: positive exponent, no period ≤ 32, impacts on both flanks: D."""
    c = classify(simulate(params, periods=1000, transient=500, lyapunov=True))
    assert c.period == 0
    assert c.lyapunov > 0.02
    assert c.chaotic and c.regime == "D"
    assert c.active_per_period > 0.5 and c.reverse_per_period > 0.3


def test_chaos_needs_an_exponent():
    """Without the exponent (lyapunov=False) a non-repeating window is not called chaotic."""
    c = classify(simulate(RattleParams(lam=1.16), periods=300, transient=500))
    assert math.isnan(c.lyapunov) and c.period == 0 and not c.chaotic and c.regime == "Q"


@pytest.mark.parametrize("x0", [None, "wall"])
def test_regime_a_permanent_contact(x0):
    """Λ < 1, harmonic: the gear ends on the active flank for good (A), with no impact."""
    p = RattleParams(lam=0.8)
    start = {} if x0 is None else {"x0": 1.0, "v0": 0.0}  # y(0) = 1, ẏ(0) = 0
    tr = simulate(p, periods=50, transient=100, lyapunov=True, **start)
    c = classify(tr)
    assert c.regime == "A" and c.stick_fraction == pytest.approx(1.0, abs=1e-12)
    assert c.impacts_per_period == 0.0 and len(tr.impact_t) == 0 and c.lyapunov == -math.inf
    x, _ = tr.sample(np.linspace(tr.t_start, tr.t_end, 500))
    np.testing.assert_allclose(x, tr.walls(np.linspace(tr.t_start, tr.t_end, 500))[0], atol=1e-12)


def test_regime_b_impacts_then_contact():
    """Λ = 1.05, harmonic: active-flank impacts followed by permanent contact (B)."""
    tr = simulate(RattleParams(lam=1.05), periods=100, transient=300, lyapunov=True)
    c = classify(tr)
    assert c.regime == "B" and c.period == 1
    assert 0.3 < c.stick_fraction < 0.95
    assert c.active_per_period >= 1 and c.reverse_per_period == 0
    assert len(tr.stick_intervals) >= 99 and np.all(tr.stick_flank == 1)


def test_metrics_definitions():
    """Intensity is Σ Ĩ² per period; mean and RMS |Ĩ| per flank; impacts per period by flank."""
    tr = simulate(RattleParams(lam=1.16), periods=400, transient=200, lyapunov=True)
    c = classify(tr)
    imp, fl = tr.impact_impulse, tr.impact_flank
    assert c.intensity == pytest.approx(np.sum(imp ** 2) / 400, rel=1e-12)
    a, r = np.abs(imp[fl == 1]), np.abs(imp[fl == -1])
    assert c.mean_impulse_active == pytest.approx(a.mean(), rel=1e-12)
    assert c.rms_impulse_active == pytest.approx(np.sqrt(np.mean(a ** 2)), rel=1e-12)
    assert c.mean_impulse_reverse == pytest.approx(r.mean(), rel=1e-12)
    assert c.rms_impulse_reverse == pytest.approx(np.sqrt(np.mean(r ** 2)), rel=1e-12)
    assert c.active_per_period == pytest.approx(len(a) / 400) and c.reverse_per_period == pytest.approx(len(r) / 400)
    assert c.impacts_per_period == pytest.approx(len(imp) / 400)
    d = c.as_dict()
    assert d["regime"] == "D" and d["impacts_per_period"] == c.impacts_per_period


def test_detect_period():
    """The section period is the smallest repeat; a non-repeating sequence gives 0."""
    k = np.arange(200)
    assert detect_period(np.cos(np.pi * k), np.zeros(200)) == 2
    assert detect_period(np.cos(2 * np.pi * k / 5), np.sin(2 * np.pi * k / 5)) == 5
    assert detect_period(np.ones(200), np.ones(200)) == 1
    rng = np.random.default_rng(1)
    assert detect_period(rng.normal(size=200), rng.normal(size=200)) == 0
    assert detect_period(np.ones(3), np.ones(3)) == 0


def _window(rng, record, period, n_act, n_rev, stick=0.0, lyap=np.nan, noise=0.0, j=8.0):
    """A synthetic recorded window: impacts on each flank per period, a section repeating
    every ``period`` samples (0: random), stick time in periods, exponent."""
    if period:
        cyc = rng.normal(size=(2, period)) * 3
        sx, sv = np.tile(cyc, record // period + 1)[:, :record]
        sx = sx + noise * rng.normal(size=record)
    else:
        sx, sv = rng.normal(size=(2, record)) * 3
    fl = np.concatenate([np.ones(n_act, np.int8), -np.ones(n_rev, np.int8)])
    rng.shuffle(fl)
    # impulses spread over decades, so a different summation order would change the last bits
    imp = fl * 10.0 ** rng.uniform(-3, 2, len(fl))
    return imp, fl, sx, sv, stick * TWO_PI, lyap, j


def _varied_windows(record):
    rng = np.random.default_rng(11)
    P = record
    tol = 1e-6 * 9.0
    return [
        _window(rng, P, 1, 0, 0, stick=P),                      # A
        _window(rng, P, 1, 0, 0, stick=0.995 * P),              # A at the threshold
        _window(rng, P, 1, 0, 0, stick=0.98 * P),               # B with no impacts
        _window(rng, P, 1, 3 * P, 0, stick=0.4 * P),            # B
        _window(rng, P, 2, 5, 2, stick=1e-9),                   # B, barely sticking
        _window(rng, P, 1, P, 0),                               # C
        _window(rng, P, 1, P + 1, 0),                           # C, just inside 2 %
        _window(rng, P, 1, int(1.03 * P), 0),                   # P: too many impacts for C
        _window(rng, P, 1, int(1.02 * P), 0),                   # P, at the 2 % edge
        _window(rng, P, 0, 7 * P, 3 * P, lyap=0.2),             # D, 1000 impacts
        _window(rng, P, 0, 3 * P, P, stick=0.2 * P, lyap=0.05),  # D with sticking
        _window(rng, P, 0, 2 * P, P, lyap=1e-3),                # Q: exponent at the threshold
        _window(rng, P, 0, 2 * P, P, lyap=-0.3),                # Q
        _window(rng, P, 0, 2 * P, P),                           # Q, no exponent (NaN)
        _window(rng, P, 1, P, P, lyap=-0.1),                    # E
        _window(rng, P, 1, P, P - 1, lyap=-0.1),                # E, one reverse impact short
        _window(rng, P, 3, 2 * P, P, lyap=0.5),                 # P, period 3 (not chaotic)
        _window(rng, P, 32, 37, 0),                             # P, the longest period
        _window(rng, P, 1, P, 0, noise=0.4 * tol),              # C, noise under the tolerance
        _window(rng, P, 1, P, 0, noise=3 * tol),                # noise above it: not period 1
        _window(rng, P, 5, 129, 257, j=0.5),                    # pairwise splits of the sums
        _window(rng, P, 1, 0, 1, stick=2 * P),                  # stick time beyond the window
    ]


def test_the_rules_numbers_are_those_of_the_model_document():
    """The library's period search and chaos threshold are docs/model.md's (as tests/naive.py
    states them), and its regime letters are the vocabulary's, in code order."""
    import naive
    from rattle_core.analysis.vocabulary import LETTERS, REGIME_CODES
    assert (MAX_PERIOD, PERIOD_TOL, LYAP_CHAOS) == (naive.MAX_PERIOD, naive.PERIOD_TOL,
                                                    naive.LYAP_CHAOS)
    assert REGIME_LETTERS == tuple("ABCDEPQ") and LETTERS == REGIME_LETTERS + ("error",)
    assert [REGIME_CODES[g] for g in LETTERS] == list(range(len(LETTERS)))


@pytest.mark.parametrize("record", [100, 41, 3])
def test_classify_batch_equals_classify_arrays(record):
    """The compiled batch classification gives exactly the numbers of ``classify_arrays`` and
    of the slow numpy reference (``tests/naive.py``), field by field, on windows of every
    regime, sticking, chaotic and borderline ones."""
    wins = _varied_windows(record)
    imp, fl, sx, sv, st, ly, j = wins[13]
    sx = sx.copy()
    sx[-1] = np.nan  # a NaN in the section never counts as repeating
    wins.append((imp, fl, sx, sv, st, ly, j))
    ref = [classify_arrays(imp, fl, sx, sv, record, st, ly, j)
           for imp, fl, sx, sv, st, ly, j in wins]
    slow = [classify_reference(imp, fl, sx, sv, record, st, ly, j)
            for imp, fl, sx, sv, st, ly, j in wins]
    got = classify_batch(np.array([len(w[0]) for w in wins]), np.concatenate([w[0] for w in wins]),
                         np.concatenate([w[1] for w in wins]), np.stack([w[2] for w in wins]),
                         np.stack([w[3] for w in wins]), record, np.array([w[4] for w in wins]),
                         np.array([w[5] for w in wins]), np.array([w[6] for w in wins]))
    if record == 100:
        assert {c.regime for c in ref} == set(REGIME_LETTERS)
        assert any(c.regime == "D" and c.stick_fraction > 0 for c in ref)
    for i, c in enumerate(ref):
        assert REGIME_LETTERS[got["regime"][i]] == c.regime, i
        assert got["n_active"][i] == np.sum(wins[i][1] == 1)
        assert got["n_reverse"][i] == np.sum(wins[i][1] == -1)
        for field, want in c.as_dict().items():
            if field in ("regime", "impacts_per_period"):
                continue
            have = got[field][i]
            if field == "sticking":
                want = STICKING_KINDS.index(want)
            assert have == want or (np.isnan(want) and np.isnan(have)), (i, field, have, want)
            # and both are the definitions' plain numpy expressions, bit for bit
            plain = slow[i][field]
            if field == "sticking":
                plain = STICKING_KINDS.index(plain)
            assert have == plain or (np.isnan(plain) and np.isnan(have)), (i, field, have, plain)


def test_classify_batch_checks_counts():
    """Counts that do not add up to the impacts are refused."""
    with pytest.raises(ValueError, match="counts"):
        classify_batch(np.array([2]), np.ones(3), np.ones(3, np.int8), np.zeros((1, 8)),
                       np.zeros((1, 8)), 8, np.zeros(1), np.zeros(1), np.ones(1))


def test_classification_label_lists_the_facts():
    """The label names the regime, period, impacts per flank and the exponent."""
    c = Classification("C", 1, 1.0, 0.0, 0.0, -0.0686, False, 39.5, 6.28, 6.28, 0.0, 0.0)
    text = c.label
    assert text.startswith("C: one active-flank impact") and "period 1" in text
    assert "1 active + 0 reverse" in text and "λ = -0.0686" in text


# ----- overlays ----------------------------------------------------------------------------

def _rest_start_at_max_reaction(p: RattleParams):
    """Time of the largest reaction R̃ = 1 + Λÿ, and the wall state there (at rest on it)."""
    t = np.linspace(0, TWO_PI, 20001)
    t0 = float(t[np.argmax(excitation(t, p.h, p.phi, 2))])
    return t0, float(excitation(t0, p.h, p.phi)), float(excitation(t0, p.h, p.phi, 1))


def test_contact_boundary_harmonic_is_one():
    """Harmonic: ``Λc = 1 / max(−ÿ) = 1`` exactly."""
    assert contact_boundary(RattleParams(lam=2.0)) == pytest.approx(1.0, abs=1e-12)


@pytest.mark.parametrize("base", [RattleParams(lam=1.0)] + TWO_HARMONICS,
                         ids=["harmonic", "2h-135", "2h-180", "3h"])
def test_contact_boundary_against_simulation(base):
    """Just below Λc a gear at rest on the active flank stays stuck; just above it leaves."""
    lc = contact_boundary(base)
    t = np.linspace(0, TWO_PI, 200001)
    assert lc == pytest.approx(1.0 / np.max(-excitation(t, base.h, base.phi, 2)), rel=1e-8)
    below = base.replace(lam=0.995 * lc)
    t0, x0, v0 = _rest_start_at_max_reaction(below)
    tr = simulate(below, periods=20, t0=t0, x0=x0, v0=v0)
    assert len(tr.impact_t) == 0
    assert tr.n_stick_phases == 1 and tr.stick_time == pytest.approx(20 * TWO_PI, rel=1e-12)
    above = base.replace(lam=1.005 * lc)
    t0, x0, v0 = _rest_start_at_max_reaction(above)
    tr = simulate(above, periods=20, t0=t0, x0=x0, v0=v0)
    first_release = tr.stick_intervals[0, 1]
    assert first_release < t0 + TWO_PI  # leaves within the first period
    # it leaves where the reaction 1 + Λÿ crosses zero
    assert 1 + above.lam * float(excitation(first_release, above.h, above.phi, 2)) == \
        pytest.approx(0.0, abs=1e-9)
    assert tr.stick_time < 20 * TWO_PI * 0.999


@pytest.mark.parametrize("lam", [1.13, 1.19])
def test_one_sided_orbit_matches_simulated_c(lam):
    """The stable one-sided orbit's phase θ and impulse 2π/Λ are those of the simulated C orbit."""
    p = RattleParams(lam=lam)
    o = _stable_orbit(p)
    r = p.r
    assert math.sin(o.theta) == pytest.approx(-(1 - r) * math.pi / ((1 + r) * lam), abs=1e-12)
    assert o.impulse == pytest.approx(one_sided_impulse(lam), rel=1e-15)
    assert o.det == pytest.approx(r * r)
    assert o.trace == pytest.approx(1 + r * r - (1 + r) ** 2 * lam * math.cos(o.theta), abs=1e-12)
    tr = simulate(p, periods=100, transient=500)  # fresh from mid-backlash, not from the orbit
    c = classify(tr)
    assert c.regime == "C"
    np.testing.assert_allclose(tr.impact_impulse, TWO_PI / lam, rtol=1e-9)
    np.testing.assert_allclose(tr.impact_phase, o.theta, atol=1e-8)
    assert np.all(tr.impact_flank == 1)


@pytest.mark.parametrize("lam", [0.9, 1.0, 1.2])
def test_one_sided_orbits_two_harmonics(lam):
    """With two harmonics (core φ2 = 90°) every stable one-sided orbit that fits is simulated
    as it is predicted (here up to two coexist): phase θ, impulse 2π/Λ, negative exponent."""
    p = RattleParams(lam=lam, amplitudes=(1.0, 0.25), phases_deg=(0.0, 90.0))
    orbs = [o for o in one_sided_orbits(p) if o.stable and o.fits]
    assert orbs
    for o in orbs:
        assert float(excitation(o.theta, p.h, p.phi, 1)) == \
            pytest.approx((1 - p.r) * math.pi / ((1 + p.r) * lam), abs=1e-12)
        x0, v0 = _orbit_start(p, o.theta, dv=1e-3)
        tr = simulate(p, periods=100, transient=1000, x0=x0, v0=v0, lyapunov=True)
        c = classify(tr)
        assert c.regime == "C" and c.lyapunov < 0
        np.testing.assert_allclose(tr.impact_impulse, TWO_PI / lam, rtol=1e-9)
        np.testing.assert_allclose(tr.impact_phase, o.theta, atol=1e-8)


def test_period_doubling_limit_harmonic():
    """Period 1 just below the analytic period-doubling limit, period 2 just above."""
    r = 0.65
    lo, hi = period1_limits_harmonic(r)
    assert lo == pytest.approx((1 - r) * math.pi / (1 + r), rel=1e-15)
    assert hi == pytest.approx(1.2394, abs=1e-4)
    below = RattleParams(lam=hi - 0.01, r=r)
    above = RattleParams(lam=hi + 0.01, r=r)
    ob = _stable_orbit(below)
    assert ob.trace > -(1 + r * r)
    oa = [o for o in one_sided_orbits(above) if o.fits and math.cos(o.theta) > 0]
    assert len(oa) == 1 and not oa[0].stable and oa[0].trace < -(1 + r * r)
    # the limit is where the trace reaches −(1 + det)
    at = [o for o in one_sided_orbits(RattleParams(lam=hi, r=r)) if math.cos(o.theta) > 0][0]
    assert at.trace == pytest.approx(-(1 + r * r), abs=1e-9)
    x0, v0 = _orbit_start(below, ob.theta, dv=1e-3)
    cb = classify(simulate(below, periods=200, transient=3000, x0=x0, v0=v0))
    assert cb.regime == "C" and cb.period == 1
    x0, v0 = _orbit_start(above, oa[0].theta, dv=1e-3)
    tr = simulate(above, periods=200, transient=3000, x0=x0, v0=v0)
    ca = classify(tr)
    assert ca.period == 2 and ca.reverse_per_period == 0 and ca.active_per_period == pytest.approx(1.0)
    # the period-2 orbit straddles the period-1 one: impulses alternate around 2π/Λ
    imp = tr.impact_impulse
    assert np.ptp(imp) > 1e-2
    assert imp.min() < TWO_PI / above.lam < imp.max()


def test_period_two_one_sided_orbit():
    """The 2·2π/Λ curve: at j = 8 no period-2 one-sided orbit fits the backlash for any Λ
    (its apex 2π²/Λ > j), so the test uses j = 40, where the simulated orbit (one impact every
    two periods) has impulse 4π/Λ and the analytic phase."""
    for lam in np.arange(1.3, 1.75, 0.02):
        assert not any(o.fits for o in one_sided_orbits(RattleParams(lam=lam), 2))
    p = RattleParams(lam=1.5, j=40.0)
    o = _stable_orbit(p, 2)
    assert o.impulse == pytest.approx(one_sided_impulse(1.5, 2), rel=1e-15)
    x0, v0 = _orbit_start(p, o.theta, n=2, dv=1e-3)
    tr = simulate(p, periods=200, transient=2000, x0=x0, v0=v0, lyapunov=True)
    c = classify(tr)
    assert c.period == 2 and c.active_per_period == pytest.approx(0.5) and c.reverse_per_period == 0
    assert c.lyapunov < 0
    np.testing.assert_allclose(tr.impact_impulse, 2 * TWO_PI / 1.5, rtol=1e-9)
    np.testing.assert_allclose(tr.impact_phase, o.theta, atol=1e-8)
    np.testing.assert_allclose(np.diff(tr.impact_t), 2 * TWO_PI, rtol=1e-9)
