"""The excitation y(t) = Σ h_k cos(k t − φ_k): compiled and numpy forms, derivatives, bounds."""
from __future__ import annotations

import numpy as np
import pytest

from naive import y_derivative
from rattle_core import RattleParams, excitation
from rattle_core.model.excitation import _bounds, _y_derivs, params_excitation

TWO_PI = 2.0 * np.pi


def random_harmonics(rng, K):
    """Amplitudes with h_1 = 1 and the rest in [0, 1.5], phases anywhere in [−2π, 2π]."""
    h = np.concatenate([[1.0], rng.uniform(0.0, 1.5, K - 1)])
    if K > 2:
        h[rng.integers(1, K)] = 0.0  # a missing harmonic in the middle of the list
    phi = rng.uniform(-TWO_PI, TWO_PI, K)
    return h, phi


@pytest.mark.parametrize("K", [1, 2, 3, 5, 8, 32])
def test_compiled_derivatives_match_numpy_excitation(K):
    """_y_derivs gives y, ẏ, ÿ, y⁽³⁾, y⁽⁴⁾ equal to excitation(order=0..4) to 1e-12 relative."""
    rng = np.random.default_rng(K)
    for _ in range(5):
        h, phi = random_harmonics(rng, K)
        cphi, sphi = np.cos(phi), np.sin(phi)
        taus = np.concatenate([rng.uniform(0.0, TWO_PI, 40), [0.0, np.pi, TWO_PI - 1e-15]])
        scale = _bounds(h)
        for tau in taus:
            got = _y_derivs(tau, h, cphi, sphi)
            for m in range(5):
                want = float(excitation(tau, h, phi, m))
                assert abs(got[m] - want) <= 1e-12 * scale[m], (K, tau, m, got[m], want)


@pytest.mark.parametrize("K", [1, 2, 4])
def test_excitation_matches_the_term_by_term_formula(K):
    """excitation() equals the explicit Σ h_k kᵐ (cos, −sin, −cos, sin)(k t − φ_k) for m = 0..5."""
    rng = np.random.default_rng(100 + K)
    h, phi = random_harmonics(rng, K)
    t = rng.uniform(-50.0, 50.0, 500)
    for m in range(6):
        want = y_derivative(t, h, phi, m)
        got = excitation(t, h, phi, m)
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-11 * _bounds(h)[min(m, 5)])


def test_compiled_form_beyond_one_period():
    """_y_derivs is also exact slightly past 2π (the solver evaluates at tau + s before reducing)."""
    rng = np.random.default_rng(7)
    h, phi = random_harmonics(rng, 3)
    cphi, sphi = np.cos(phi), np.sin(phi)
    for tau in rng.uniform(TWO_PI, 3 * TWO_PI, 30):
        got = _y_derivs(tau, h, cphi, sphi)
        for m in range(5):
            assert abs(got[m] - y_derivative(tau, h, phi, m)) <= 1e-12 * _bounds(h)[m]


@pytest.mark.parametrize("K", [1, 3])
def test_finite_differences_agree_with_derivatives(K):
    """Central differences of y⁽ᵐ⁾ reproduce y⁽ᵐ⁺¹⁾ to O(δ²) for m = 0..3."""
    rng = np.random.default_rng(11 + K)
    h, phi = random_harmonics(rng, K)
    t = rng.uniform(0.0, TWO_PI, 200)
    d = 1e-4
    k = np.arange(1, K + 1)
    for m in range(4):
        fd = (excitation(t + d, h, phi, m) - excitation(t - d, h, phi, m)) / (2 * d)
        exact = excitation(t, h, phi, m + 1)
        # truncation error ≤ d² M_{m+3} / 6, rounding ≤ eps M_m / d
        m_n = [np.sum(k**n * h) for n in range(8)]
        tol = d * d * m_n[m + 3] / 6 + 1e-15 * m_n[m] / d + 1e-12
        assert np.max(np.abs(fd - exact)) <= tol, (m, np.max(np.abs(fd - exact)), tol)


@pytest.mark.parametrize("K", [1, 2, 3, 6])
def test_bounds_really_bound_the_derivatives(K):
    """_bounds gives M_n = Σ kⁿ|h_k| with max |y⁽ⁿ⁾| ≤ M_n, n = 0..5, attained when phases align."""
    rng = np.random.default_rng(21 + K)
    h, phi = random_harmonics(rng, K)
    h[1:] *= rng.choice([-1.0, 1.0], K - 1)  # negative amplitudes: the bound uses |h_k|
    m = _bounds(h)
    k = np.arange(1, K + 1)
    np.testing.assert_allclose(m, [np.sum(k**n * np.abs(h)) for n in range(6)], rtol=1e-15)
    t = np.linspace(0.0, TWO_PI, 20001)
    for n in range(6):
        assert np.max(np.abs(y_derivative(t, h, phi, n))) <= m[n] * (1 + 1e-12)
    # with all phases zero and positive amplitudes, y(0) = Σ h_k: the bound M_0 is sharp
    hp = np.abs(h)
    assert excitation(0.0, hp, np.zeros(K)) == pytest.approx(_bounds(hp)[0], rel=1e-14)
    assert abs(excitation(0.0, hp, np.zeros(K), 2)) == pytest.approx(_bounds(hp)[2], rel=1e-14)


def test_params_excitation_uses_degrees():
    """params_excitation converts phases_deg to radians: φ₂ = 90° turns cos(2t) into sin(2t)."""
    p = RattleParams(lam=3.3, amplitudes=(1.0, 0.25), phases_deg=(0.0, 90.0))
    t = np.linspace(0.0, TWO_PI, 101)
    np.testing.assert_allclose(params_excitation(p, t), np.cos(t) + 0.25 * np.sin(2 * t), atol=1e-14)
