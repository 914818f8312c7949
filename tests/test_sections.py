"""Poincaré sections: the stroboscopic map at any phase, its relative form, the impact map."""
from __future__ import annotations

import numpy as np
import pytest

from rattle_core import RattleParams, excitation, impact_map, poincare, simulate
from rattle_core.model.excitation import TWO_PI

CASES = [
    RattleParams(lam=3.3),                                                     # E, harmonic
    RattleParams(lam=1.16),                                                    # chaotic
    RattleParams(lam=1.05),                                                    # sticking
    RattleParams(lam=2.2, amplitudes=(1.0, 0.25, 0.1), phases_deg=(0.0, -135.0, 30.0)),
]


def _angle_gap(a, b):
    d = np.mod(np.asarray(a) - np.asarray(b), TWO_PI)
    return np.minimum(d, TWO_PI - d)


@pytest.mark.parametrize("params", CASES, ids=["E", "D", "B", "3harm"])
@pytest.mark.parametrize("theta", [0.7, 2.0, 5.9])
def test_strobe_at_other_phase_is_exact_sample(params, theta):
    """A section at another phase equals ``tr.sample`` at ``2πn + θ`` and the solver's own strobe."""
    tr = simulate(params, periods=60, transient=40)
    x, v = poincare(tr, phase=theta)
    t = np.arange(np.ceil((tr.t_start - theta) / TWO_PI), np.floor((tr.t_end - theta) / TWO_PI) + 1)
    t = t * TWO_PI + theta
    t = t[(t >= tr.t_start) & (t < tr.t_end)]
    xs, vs = tr.sample(t)
    assert len(x) == len(t) >= 59
    np.testing.assert_array_equal(x, xs)
    np.testing.assert_array_equal(v, vs)
    # the solver samples the section itself when run with that phase: same states
    tr2 = simulate(params, periods=60, transient=40, strobe_phase=theta)
    assert len(tr2.strobe_x) == len(x)
    np.testing.assert_allclose(tr2.strobe_t, t, rtol=0, atol=1e-9)
    np.testing.assert_allclose(tr2.strobe_x, x, rtol=0, atol=1e-9)
    np.testing.assert_allclose(tr2.strobe_v, v, rtol=0, atol=1e-9)


def test_default_phase_is_the_simulated_strobe():
    """Without a phase (or with the simulated one) the section is the solver's strobe record."""
    tr = simulate(CASES[0], periods=30, transient=10, strobe_phase=1.25)
    for ph in (None, 1.25, 1.25 + TWO_PI):
        x, v = poincare(tr, phase=ph)
        np.testing.assert_array_equal(x, tr.strobe_x)
        np.testing.assert_array_equal(v, tr.strobe_v)


@pytest.mark.parametrize("params", CASES, ids=["E", "D", "B", "3harm"])
@pytest.mark.parametrize("theta", [None, 3.1])
def test_relative_form(params, theta):
    """The relative section is ``(x − y, ẋ − ẏ)`` at the section times, inside ``[0, j]``."""
    tr = simulate(params, periods=50, transient=20)
    x, v = poincare(tr, phase=theta)
    xr, vr = poincare(tr, relative=True, phase=theta)
    th = tr.strobe_phase if theta is None else theta
    t = tr.t_start + np.mod(th - tr.t_start, TWO_PI) + TWO_PI * np.arange(len(x))
    np.testing.assert_allclose(xr, x - excitation(t, params.h, params.phi), rtol=0, atol=1e-12)
    np.testing.assert_allclose(vr, v - excitation(t, params.h, params.phi, 1), rtol=0, atol=1e-12)
    assert np.all(xr >= -1e-9) and np.all(xr <= params.j + 1e-9)
    if theta is None:
        xr2, vr2 = tr.strobe_relative()
        np.testing.assert_array_equal(xr, xr2)
        np.testing.assert_array_equal(vr, vr2)


@pytest.mark.parametrize("params", CASES, ids=["E", "D", "B", "3harm"])
def test_impact_map_phase_and_impulse(params):
    """Impact-map phases equal ``impact_t mod 2π``; impulses are signed by flank, |Ĩ| = (1+r)|w|."""
    tr = simulate(params, periods=80, transient=20)
    ph, imp = impact_map(tr)
    assert len(ph) == len(tr.impact_t) > 0
    assert np.all((ph >= 0) & (ph < TWO_PI))
    assert np.max(_angle_gap(ph, np.mod(tr.impact_t, TWO_PI))) < 1e-9
    np.testing.assert_array_equal(np.sign(imp), tr.impact_flank)
    np.testing.assert_allclose(np.abs(imp), (1 + params.r) * np.abs(tr.impact_w),
                               rtol=1e-12, atol=1e-14)
    # every impact is on its wall: x = y (active) or y + j (reverse)
    x, _ = tr.sample(tr.impact_t)
    y = excitation(tr.impact_t, params.h, params.phi)
    wall = y + np.where(tr.impact_flank == -1, params.j, 0.0)
    np.testing.assert_allclose(x, wall, rtol=0, atol=1e-8)


def test_bad_phase_names_the_parameter():
    """A non-finite section phase raises ``ValueError`` naming ``phase``."""
    tr = simulate(CASES[0], periods=5)
    with pytest.raises(ValueError, match="phase"):
        poincare(tr, phase=float("nan"))
