"""The paper's claim 1: harmonic excitation, r = 0.65, j = 8, regimes A, B, C, D, E in order of Λ.

Protocol (one run per Λ): ``simulate(params, periods=100, transient=300, lyapunov=True)`` from
the API's default start, at rest in the middle of the backlash at t = 0.  The regime of the
recorded window comes from ``tests/naive.py``'s ``classify_reference`` (the rules of
docs/model.md in plain numpy), not from ``rattle_core.analysis.classify``, so that the claim is
checked independently of that module.

Several attractors coexist at some Λ (for example a B orbit beside the C orbit near
Λ = 1.2 when the gear starts on the active flank); the claim is about the order in which the
regimes first appear along Λ, which is what the test checks, on more than one grid.
"""
from __future__ import annotations

import numpy as np
import pytest

from naive import classify_trajectory
from rattle_core import RattleParams, simulate

R = 0.65
J = 8.0
PERIODS = 100
TRANSIENT = 300


def classify(tr) -> str:
    """Regime letter of a recorded window, by the reference rules."""
    return classify_trajectory(tr)["regime"]


def scan(lams) -> np.ndarray:
    labels = []
    for lam in lams:
        tr = simulate(RattleParams(lam=float(lam), r=R, j=J), periods=PERIODS,
                      transient=TRANSIENT, lyapunov=True)
        labels.append(classify(tr))
    return np.array(labels)


def grid(offset: float) -> np.ndarray:
    # rounded, so that Λ = 1 (where R̃ = 1 − cos t touches zero) is on the first grid exactly
    return np.round(np.arange(0.5 + offset, 4.0 + 1e-9, 0.02), 10)


@pytest.fixture(scope="module", params=[0.0, 0.01])
def labelled(request):
    lams = grid(request.param)
    return lams, scan(lams)


def describe(lams, labels) -> str:
    return " ".join(f"{lam:.3f}:{c}" for lam, c in zip(lams, labels))


def test_regimes_first_appear_in_order_a_b_c_d_e(labelled):
    """Scanning Λ from 0.5 to 4, regimes A, B, C, D, E each appear, first in that order."""
    lams, labels = labelled
    first = {}
    for regime in "ABCDE":
        hits = np.flatnonzero(labels == regime)
        assert len(hits), f"regime {regime} never appears: {describe(lams, labels)}"
        first[regime] = lams[hits[0]]
    order = [first[k] for k in "ABCDE"]
    assert order == sorted(order) and len(set(order)) == 5, (first, describe(lams, labels))


def test_below_lambda_one_is_permanent_contact(labelled):
    """For Λ ≤ 1 (R̃ = 1 − Λ cos t ≥ 0) every grid point is regime A; B starts just above 1."""
    lams, labels = labelled
    assert np.all(labels[lams <= 1.0] == "A"), describe(lams, labels)
    first_b = lams[np.flatnonzero(labels == "B")[0]]
    assert 1.0 < first_b < 1.1


def test_regime_e_covers_a_large_range(labelled):
    """E holds on at least half of the scanned Λ, and on ≥ 90 % of the points in [2, 4]."""
    lams, labels = labelled
    assert np.mean(labels == "E") >= 0.5, describe(lams, labels)
    upper = (lams >= 2.0) & (lams <= 4.0)
    assert np.mean(labels[upper] == "E") >= 0.9, describe(lams[upper], labels[upper])
    # and E is the last regime to appear: nothing but E (and coexisting B orbits) above it
    first_e = lams[np.flatnonzero(labels == "E")[0]]
    assert set(labels[lams > first_e + 0.1]) <= {"E", "B"}


def test_regime_examples_have_the_defining_features():
    """Representatives: C at Λ = 1.2 (impulse 2π/Λ), D at 1.16 (λ > 0), E at 3.3 (±, one each)."""
    c = simulate(RattleParams(lam=1.2, r=R, j=J), periods=PERIODS, transient=TRANSIENT,
                 lyapunov=True)
    assert classify(c) == "C"
    np.testing.assert_allclose(c.impact_impulse, 2 * np.pi / 1.2, atol=1e-9)
    d = simulate(RattleParams(lam=1.16, r=R, j=J), periods=PERIODS, transient=TRANSIENT,
                 lyapunov=True)
    assert classify(d) == "D"
    assert len(np.unique(np.round(d.impact_impulse, 6))) > 50
    e = simulate(RattleParams(lam=3.3, r=R, j=J), periods=PERIODS, transient=TRANSIENT,
                 lyapunov=True)
    assert classify(e) == "E"
    assert np.all(e.impact_impulse[e.impact_flank == 1] > 0)
    assert np.all(e.impact_impulse[e.impact_flank == -1] < 0)
    b = simulate(RattleParams(lam=1.05, r=R, j=J), periods=PERIODS, transient=TRANSIENT,
                 lyapunov=True)
    assert classify(b) == "B"
    a = simulate(RattleParams(lam=0.8, r=R, j=J), periods=PERIODS, transient=TRANSIENT,
                 lyapunov=True)
    assert classify(a) == "A"
