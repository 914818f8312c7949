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
