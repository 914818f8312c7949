"""The dashboard's noise: the Advanced control and the URL, the metrics' intervals, and the
background noise-sensitivity badge, without a browser (the ``dash`` fixture)."""
from __future__ import annotations

import re

from conftest import wait_for

from app.state import URL_KEYS, rattle_params
from app.ui.labels import metrics_rows
from rattle_core import RattleParams, classify, simulate
from rattle_core.analysis.statistics import batch_means


def test_noise_is_a_state_parameter_in_the_url_and_reaches_the_run(dash):
    """noise has its own control, URL key and range; a new value reruns the model with it, and
    a refused value leaves a message naming noise and [0, 0.5]."""
    s = dash.state
    assert URL_KEYS["noise"] == "noise" and "noise" in dash.controls.fields
    box = dash.controls.fields["noise"].box
    box.value = 1e-6
    wait_for(lambda: s.result is not None and s.result.params.noise == 1e-6, 60, "the rerun")
    assert s.noise == 1e-6 and rattle_params(s).noise == 1e-6
    box.value = 0.9
    assert s.noise == 1e-6
    assert "noise" in s.messages.get("noise", "") and "[0, 0.5]" in s.messages["noise"]


def test_chaotic_metrics_carry_their_interval_and_periodic_ones_do_not():
    """Fig 7's metrics show value ± half-width and say what the interval is; the C orbit's
    show plain numbers (exact)."""
    chaotic = simulate(RattleParams.paper(lam=3.3, amplitudes=(1.0, 0.25), phases_deg=(0.0, 45.0)),
                       periods=400, transient=200, lyapunov=True)
    cls = classify(chaotic)
    rows = dict(metrics_rows(cls, chaotic, None, batch_means(chaotic, cls)))
    assert re.search(r"\d ± \d", rows["mean |Ĩ| (active, reverse)"])
    assert "batch means" in rows["±"]
    periodic = simulate(RattleParams(lam=1.2), periods=100, transient=1500, lyapunov=True)
    pc = classify(periodic)
    rows = dict(metrics_rows(pc, periodic, None, batch_means(periodic, pc)))
    assert "±" not in rows["mean |Ĩ| (active, reverse)"] and "±" not in rows


def test_a_noise_sensitive_run_gets_a_badge_that_says_what_moves(dash):
    """Λ = 2.6, core φ₂ = 315°: the background check flags it and names the statistic and the
    levels; a periodic run (C orbit) shows no badge and starts no check."""
    s = dash.state
    cancel = dash.noise.run.cancel_button
    wait_for(lambda: dash.noise.run.job is None, 300, "the default page's check")
    assert not cancel.visible  # Cancel shows only while a check runs
    s.param.update(phases="core", lam=2.6, r=0.65, j=8.0, h2=0.25, phi2=315.0)
    # running (Cancel offered), unless a cached check has already answered
    assert (cancel.visible and not cancel.disabled) or dash.noise.result is not None
    wait_for(lambda: dash.noise.result is not None, 300, "the noise check")
    assert not cancel.visible
    out = dash.noise.result
    assert out["sensitive"], out
    text = dash.noise.badge.object
    assert "noise-sensitive" in text and "1e-12" in text and "real gearbox" in text
    assert 'data-kind="sensitive"' in text
    s.param.update(lam=1.2, h2=0.0)
    wait_for(lambda: s.result is not None and s.result.params.lam == 1.2, 60, "the C orbit")
    assert not dash.noise.badge.visible and dash.noise.result is None



def test_coexisting_attractors_are_named_and_the_badge_quotes_the_run_on_screens_own(dash):
    """Fig 2's settings at Λ = 1.16: the ensemble splits over B, D and C; the badge names all
    three with their runs, quotes the chaotic D's own mean active impulse (≈ 8.53, with its
    interval) for the chaotic run on screen instead of B's exact 0.0622 "over 8 runs", and
    gives each attractor its own noise verdict."""
    from app.presets import preset_values

    s = dash.state
    s.param.update(**{**preset_values(s, "Fig 2"), "lam": 1.16})
    wait_for(lambda: s.result is not None and s.result.params.lam == 1.16, 120, "the run")
    assert s.result.cls.period == 0 and abs(s.result.cls.mean_impulse_active - 8.53) < 0.05
    wait_for(lambda: dash.noise.result is not None, 300, "the noise check")
    text = dash.noise.badge.object
    assert "3 attractors at noise 1e-12: B (4 of 8 runs), D (3), C (1)." in text, text
    m = re.search(r"The run on screen is on D: mean active impulse ([\d.]+) ± ([\d.]+) over "
                  r"its 3 runs", text)
    assert m and abs(float(m.group(1)) - 8.53) < 0.02 and 0 < float(m.group(2)) < 0.05, text
    assert "0.06218" not in text and "over 8 runs" not in text
    for name in "DBC":
        assert f"{name}: not noise-sensitive over noise 1e-12…0.0001" in text, text
    assert 'data-kind="steady"' in text


def test_each_attractor_is_followed_across_levels_with_its_own_verdict():
    """attractor_verdicts: an exact one-run orbit steady at every level is not noise-sensitive,
    one whose exact value moves by 2 % is (exact values weigh, though one run has no
    interval); a chaotic cloud whose mean moves by 50
    half-widths is; one missing at a level is, and its estimates there are NaN."""
    import math

    from rattle_core.analysis.statistics import Attractor, Estimate, attractor_verdicts

    def att(label, regime, period, runs, v, ci, n):
        est = {k: Estimate(v, ci, n) for k in ("impacts_per_period", "mean_active_impulse",
                                                "mean_reverse_impulse", "intensity")}
        return Attractor(label, regime, period, runs, est)

    levels = [1e-12, 1e-8, 1e-4]
    per_level = [[att("D (chaotic)", "D", 0, (0, 1, 2), 8.5 + 0.5 * i, 0.01, 3),
                  att("C (period 1)", "C", 1, (3,), 5.4, 0.0, 1),
                  att("E (period 1)", "E", 1, (5,), 2.0 + 0.02 * i, 0.0, 1)]
                 + ([att("B (period 1)", "B", 1, (4,), 0.06, 0.0, 1)] if i < 2 else [])
                 for i in range(3)]
    out = {a["label"]: a for a in attractor_verdicts(levels, per_level)}
    assert [a["label"] for a in attractor_verdicts(levels, per_level)] == [
        "D (chaotic)", "C (period 1)", "E (period 1)", "B (period 1)"]
    assert out["E (period 1)"]["sensitive"]
    assert not out["C (period 1)"]["sensitive"] and out["C (period 1)"]["runs"] == [1, 1, 1]
    assert out["D (chaotic)"]["sensitive"]
    assert "mean active impulse 8.5–9.5" in " ".join(out["D (chaotic)"]["reasons"])
    b = out["B (period 1)"]
    assert b["sensitive"] and b["runs"] == [1, 1, 0]
    assert "not at 0.0001" in b["reasons"][0]
    assert math.isnan(b["estimates"]["intensity"][2][0])
    assert b["estimates"]["intensity"][0] == [0.06, 0.0]
