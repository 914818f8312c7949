"""Noise as a model input, statistics with their intervals, and the noise-sensitivity verdict.

docs/model.md, "Noise": every rebound's restitution is ``r (1 + ε ξ)``; the ensembles of
``rattle_core.statistics`` give each statistic with its 95 % interval, and
``noise_sensitivity`` says whether the answer depends on ε.  The reference is
``tests/naive.py`` with the same noise model, sharing no code with the solver.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats as sps

from naive import naive_simulate
from rattle_core import RattleParams, noise_sensitivity, simulate, statistics
from rattle_core.analysis.continuation import c_orbit
from rattle_core.analysis.statistics import Estimate, estimate, sensitivity_verdict
from rattle_core.model.excitation import excitation
from rattle_core.model.params import NOISE_DEFAULT

TWO_PI = 2 * np.pi
FIG7 = RattleParams.paper(lam=3.3, amplitudes=(1.0, 0.25), phases_deg=(0.0, 45.0))
#: The case measured to depend on the noise level (docs/model.md, "What the statistics mean").
SENSITIVE = RattleParams(lam=2.6, r=0.65, j=8.0, amplitudes=(1.0, 0.25), phases_deg=(0.0, 315.0))
FLAT = RattleParams(lam=3.6, r=0.65, j=8.0, amplitudes=(1.0, 0.25), phases_deg=(0.0, 315.0))


def test_noise_is_validated_by_name_and_range():
    """noise outside [0, 0.5], NaN, text or a bool is refused with a message naming it."""
    for bad in (-1e-3, 0.6, math.nan, math.inf, "1e-8", True, None):
        with pytest.raises(ValueError, match="noise"):
            RattleParams(lam=3.3, noise=bad)
    assert RattleParams(lam=3.3).noise == NOISE_DEFAULT
    assert RattleParams(lam=3.3, noise=0.5).noise == 0.5


def test_noise_is_in_the_canonical_form_and_round_trips():
    """The noise level is part of the cache key and survives to_dict/from_dict."""
    a, b = RattleParams(lam=3.3), RattleParams(lam=3.3, noise=1e-6)
    assert a.key() != b.key()
    assert RattleParams.from_dict(b.to_dict()) == b
    assert RattleParams.from_dict(b.canonical()) == b


def test_seeds_are_reproducible_and_independent():
    """The same seed gives the same run bit for bit; another seed gives another chaotic run."""
    p = FIG7.replace(noise=1e-6)
    a = simulate(p, periods=300, transient=100, seed=7)
    b = simulate(p, periods=300, transient=100, seed=7)
    c = simulate(p, periods=300, transient=100, seed=8)
    assert np.array_equal(a.impact_impulse, b.impact_impulse)
    assert not np.array_equal(a.impact_impulse[:len(c.impact_impulse)],
                              c.impact_impulse[:len(a.impact_impulse)])
    for bad in (-1, 2**63, 1.5, "3", True):
        with pytest.raises(ValueError, match="seed"):
            simulate(p, periods=5, seed=bad)


def test_the_scatter_of_each_rebound_is_the_documented_law():
    """With r = 0.5 and ε = 0.2, every recorded rebound's restitution −(ẋ⁺ − ẏ)/w lies in
    r (1 ± ε) and spreads over that whole band (uniform: mean r, quartiles near r ± ε r/2)."""
    p = RattleParams(lam=3.3, r=0.5, amplitudes=(1.0, 0.25), phases_deg=(0.0, 315.0), noise=0.2)
    tr = simulate(p, periods=2000, transient=10)
    vplus = tr.impact_impulse + tr.impact_w + excitation(tr.impact_t, p.h, p.phi, 1)
    rk = -(vplus - excitation(tr.impact_t, p.h, p.phi, 1)) / tr.impact_w
    assert len(rk) > 1000
    assert np.all(rk >= 0.5 * 0.8 - 1e-9) and np.all(rk <= 0.5 * 1.2 + 1e-9)
    assert abs(np.mean(rk) - 0.5) < 0.005
    q1, q3 = np.quantile(rk, [0.25, 0.75])
    assert abs(q1 - 0.45) < 0.01 and abs(q3 - 0.55) < 0.01
    assert tr.noise_kicks >= len(rk)


@pytest.mark.parametrize("lam,h2", [(1.2, 0.0), (2.5, 0.0)])
def test_default_noise_leaves_robust_periodic_orbits_exact(lam, h2):
    """At the default noise the C orbit (Λ = 1.2) and the E orbit (Λ = 2.5) keep the strict
    model's impulses to 1e-9 (the closed forms' tolerance)."""
    p = RattleParams(lam=lam, amplitudes=(1.0, h2), phases_deg=(0.0, 0.0))
    noisy = simulate(p, periods=200, transient=2000)
    strict = simulate(p.replace(noise=0.0), periods=200, transient=2000)
    assert noisy.noise_kicks > 0 and strict.noise_kicks == 0
    assert len(noisy.impact_impulse) == len(strict.impact_impulse)
    assert np.max(np.abs(noisy.impact_impulse - strict.impact_impulse)) < 1e-9


def test_a_periodic_orbit_has_zero_spread():
    """Every run on the C orbit at Λ = 1.2 gives its closed-form impulse 2π(1+r)/(Λ(1+r)...);
    the interval's half-width is exactly 0 and the value equals the strict orbit's."""
    p = RattleParams(lam=1.2)
    res = statistics(p, runs=4, periods=200, transient=1500)
    orbit = c_orbit(p)
    c = [a for a in res.attractors if a.regime == "C"]
    assert c, [a.label for a in res.attractors]
    est = c[0].estimates["mean_active_impulse"]
    assert est.ci95 == 0.0
    assert abs(est.value - abs(orbit.impulse[0])) < 1e-9
    assert c[0].estimates["impacts_per_period"].value == 1.0


def test_coexisting_attractors_are_listed_not_averaged():
    """Runs that end on different attractors form separate groups whose run indices partition
    the ensemble; each group's numbers are those of its own runs only."""
    res = statistics(RattleParams(lam=1.2), runs=8, periods=300, transient=500)
    runs = sorted(r for a in res.attractors for r in a.runs)
    assert runs == list(range(8))
    table = res.table()
    assert list(table["runs"]) == [len(a.runs) for a in res.attractors]
    if res.coexisting:
        vals = [a.estimates["impacts_per_period"].value for a in res.attractors]
        assert len(set(np.round(vals, 6))) == len(vals)


def test_a_chaotic_interval_covers_fresh_runs():
    """Fig 7: the 95 % interval from 8 runs is positive and under 10 % of the value, and the
    mean of 8 other runs (other seeds) lies within the 99 % interval of the difference."""
    a = statistics(FIG7, runs=8, periods=2000, transient=300, seed=0)
    b = statistics(FIG7, runs=8, periods=2000, transient=300, seed=1000)
    assert not a.periodic and a.main.regime == "D"
    for key in ("impacts_per_period", "mean_active_impulse", "intensity"):
        ea, eb = getattr(a, key), getattr(b, key)
        assert 0 < ea.ci95 < 0.1 * abs(ea.value)
        assert abs(ea.value - eb.value) <= 2.576 / 1.96 * math.hypot(ea.ci95, eb.ci95), key


def _naive_stats(p: RattleParams, noise: float, runs: int, periods: int, transient: int):
    """Per-run statistics of the naive reference: impacts/period, mean |Ĩ| per flank, ΣĨ²/P."""
    rng = np.random.default_rng(12345)
    y0 = float(np.sum(p.h * np.cos(-p.phi)))
    yd0 = float(np.sum(p.h * np.arange(1, p.n_harmonics + 1) * -np.sin(-p.phi)))
    out = {"impacts_per_period": [], "mean_active_impulse": [], "intensity": []}
    for i in range(runs):
        x0 = y0 + p.j * (i + 0.5) / runs
        run = naive_simulate(p.lam, p.r, p.j, p.h, p.phi, p.v_stick, 0.0, x0, yd0,
                             TWO_PI * (transient + periods), noise=noise, rng=rng)
        sel = run.impact_t >= TWO_PI * transient
        imp, fl = run.impact_impulse[sel], run.impact_flank[sel]
        out["impacts_per_period"].append(len(imp) / periods)
        out["mean_active_impulse"].append(np.mean(np.abs(imp[fl == 1])))
        out["intensity"].append(np.sum(imp ** 2) / periods)
    return out


def _mean_ci(values):
    v = np.asarray(values)
    return v.mean(), sps.t.ppf(0.975, len(v) - 1) * v.std(ddof=1) / math.sqrt(len(v))


@pytest.mark.slow
@pytest.mark.parametrize("case", [FIG7, FLAT], ids=["fig7", "lam3.6"])
@pytest.mark.parametrize("noise", [1e-8, 1e-4])
def test_ensemble_means_agree_with_the_naive_reference(case, noise):
    """At ε = 1e-8 and 1e-4, on two chaotic cases, the project's ensemble means and those of
    the naive absolute-time reference (same noise law, its own random numbers) agree within
    their combined 95 % intervals."""
    # the reference's scan needs rebounds faster than its own rounding of absolute time, so
    # both sides end chatter at v_stick = 1e-3
    case = case.replace(v_stick=1e-3)
    runs, periods, transient = 8, 1200, 200
    ours = statistics(case.replace(noise=noise), runs=runs, periods=periods, transient=transient)
    ref = _naive_stats(case, noise, runs, periods, transient)
    for key, values in ref.items():
        m, ci = _mean_ci(values)
        e = getattr(ours, key)
        assert abs(e.value - m) <= math.hypot(e.ci95, ci), (key, e, m, ci)


def test_a_known_noise_sensitive_case_is_flagged():
    """Λ = 2.6, core φ₂ = 315°: the mean active impulse moves with the noise level, and the
    report says which statistic and over which levels."""
    rep = noise_sensitivity(SENSITIVE, runs=8, periods=3000, transient=300)
    assert rep.sensitive
    assert len(rep.table) == 5 and list(rep.table["noise"]) == sorted(rep.table["noise"])
    assert any("mean active impulse" in r for r in rep.reasons)
    assert rep.describe().startswith("noise-sensitive: ")


def test_a_periodic_orbit_is_not_flagged():
    """The E orbit at Λ = 2.5 is the same at every noise level: not sensitive; exact (zero
    width) where the noise is below the period test's resolution, a tiny width at 1e-4."""
    rep = noise_sensitivity(RattleParams(lam=2.5), levels=(1e-12, 1e-8, 1e-4), runs=4,
                            periods=200, transient=1500)
    assert not rep.sensitive, rep.reasons
    t = rep.table
    assert list(t["attractor"]) == ["E (period 1)"] * 3
    assert (t["mean_active_impulse_ci95"][:2] == 0).all()
    assert 0 < t["mean_active_impulse_ci95"][2] < 1e-3 * t["mean_active_impulse"][2]


def test_the_verdict_follows_the_intervals():
    """Equal means within their intervals are not sensitive; means 10 half-widths apart are;
    a change of attractor is, whatever the numbers."""
    def row(noise, v, ci, att="D (chaotic)"):
        e = Estimate(v, ci, 8)
        return {"noise": noise, "attractor": att, "impacts_per_period": e,
                "mean_active_impulse": e, "mean_reverse_impulse": e, "intensity": e}
    assert not sensitivity_verdict([row(1e-12, 1.0, 0.0, "C"), row(1e-8, 1.0 + 1e-7, 0.0, "C")])[0]
    assert sensitivity_verdict([row(1e-12, 1.0, 0.0, "C"), row(1e-8, 1.01, 0.0, "C")])[0]

    def row(noise, v, ci, att="D (chaotic)"):
        e = Estimate(v, ci, 8)
        return {"noise": noise, "attractor": att, "impacts_per_period": e,
                "mean_active_impulse": e, "mean_reverse_impulse": e, "intensity": e}
    assert not sensitivity_verdict([row(1e-12, 1.0, 0.05), row(1e-8, 1.02, 0.05)])[0]
    assert sensitivity_verdict([row(1e-12, 1.0, 0.05), row(1e-8, 1.5, 0.05)])[0]
    changed = sensitivity_verdict([row(1e-12, 1.0, 0.0, "C (period 1)"), row(1e-8, 1.0, 0.05)])
    assert changed[0] and "attractor changes" in changed[1][0]


def test_estimate_is_students_interval():
    """estimate() is mean ± t₀.₉₇₅,ₙ₋₁ s/√n, and 0 for exact (periodic) values."""
    v = np.array([1.0, 2.0, 3.0, 4.0])
    e = estimate(v)
    assert e.value == 2.5
    assert abs(e.ci95 - sps.t.ppf(0.975, 3) * np.std(v, ddof=1) / 2) < 1e-12
    assert estimate(v, exact=True).ci95 == 0.0


@pytest.mark.parametrize("kw", [dict(runs=1), dict(runs=2.5), dict(runs="8"), dict(periods=0),
                                dict(transient=-1), dict(periods=math.nan), dict(seed=True),
                                dict(runs=10**6)])
def test_statistics_refuses_bad_arguments(kw):
    """runs, periods, transient and seed are checked by name before any run."""
    name = next(iter(kw))
    with pytest.raises(ValueError, match=name):
        statistics(FIG7, **kw)


def test_statistics_keeps_within_the_period_budget():
    """A request over the sweeps' period budget is refused with a message, not run."""
    with pytest.raises(ValueError, match="budget"):
        statistics(FIG7, runs=1000, periods=1_000_000, transient=0)
    with pytest.raises(ValueError, match="levels"):
        noise_sensitivity(FIG7, levels=(1e-8, 0.9))



def test_batch_means_of_one_run():
    """One chaotic run: each statistic is the run's own value with a finite positive half-width
    that covers the ensemble mean of other runs within 99 %; a periodic run's is exact."""
    from rattle_core import classify
    from rattle_core.analysis.statistics import batch_means
    tr = simulate(FIG7, periods=4000, transient=300)
    cls = classify(tr)
    bm = batch_means(tr, cls)
    assert bm["mean_active_impulse"].value == cls.mean_impulse_active
    ens = statistics(FIG7, runs=8, periods=4000, transient=300, seed=50)
    for key in ("impacts_per_period", "mean_active_impulse", "intensity"):
        e = bm[key]
        assert 0 < e.ci95 < 0.1 * e.value
        assert abs(e.value - getattr(ens, key).value) <= 2.576 / 1.96 * math.hypot(
            e.ci95, getattr(ens, key).ci95), key
    periodic = simulate(RattleParams(lam=1.2), periods=200, transient=2000)
    assert all(v.ci95 == 0.0 for v in batch_means(periodic).values())
