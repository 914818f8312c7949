"""Rattle sound synthesis: onsets at impacts, linear loudness, regimes that sound different."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy.io import wavfile

from rattle_core import RattleParams, simulate
from rattle_core.analysis.sound import (DEFAULT_MODES, HousingMode, normalize, parse_modes, render,
                               synthesize, write_wav)
from rattle_core.model.units import PhysicalParams, example

FS = 44_100
F_EXC = 50.0


@pytest.fixture(scope="module")
def periodic():
    """Regime E (harmonic, Λ = 3.3): two impacts per period, one per flank."""
    return simulate(RattleParams(lam=3.3), periods=60, transient=300)


@pytest.fixture(scope="module")
def chaotic():
    """Λ = 3.3, H2/H1 = 0.25, φ2 = 45° in the paper's reading: the paper's strange attractor."""
    p = RattleParams.paper(3.3, amplitudes=(1.0, 0.25), phases_deg=(0.0, 45.0))
    return simulate(p, periods=120, transient=300)


@pytest.fixture(scope="module")
def sticking():
    """Harmonic, Λ = 0.8, from mid-backlash: a fall, chatter, then permanent contact (regime A)."""
    return simulate(RattleParams(lam=0.8), periods=60)


def envelope_max(signal: np.ndarray, t0: float, t1: float) -> float:
    a, b = max(0, int(math.floor(t0 * FS))), int(math.ceil(t1 * FS))
    return float(np.max(np.abs(signal[a:b]))) if b > a else 0.0


def per_period_rms(signal: np.ndarray, n_periods: int) -> np.ndarray:
    per = int(round(FS / F_EXC))
    return np.array([np.sqrt(np.mean(signal[i * per:(i + 1) * per] ** 2)) for i in range(n_periods)])


def test_single_impact_matches_closed_form_modal_response():
    """One impact between samples rings each mode exactly as g·exp(−ζωτ)·sin(ω_d τ)."""
    t0 = 0.0123456789  # deliberately between samples
    modes = (HousingMode(1500.0, 0.02, 1.0), HousingMode(4200.0, 0.01, 0.5))
    s = render([t0], [2.5], 0.05, FS, modes)
    t = np.arange(s.size) / FS
    tau = t - t0
    expected = np.zeros_like(t)
    for m in modes:
        w = 2 * math.pi * m.freq_hz
        wd = w * math.sqrt(1 - m.damping**2)
        expected += np.where(tau >= 0, 2.5 * m.gain * np.exp(-m.damping * w * tau) * np.sin(wd * tau), 0.0)
    assert np.max(np.abs(s - expected)) < 1e-9 * np.max(np.abs(expected))
    assert np.all(s[t < t0] == 0.0)


@pytest.mark.parametrize("which", ["periodic", "chaotic"])
def test_impact_times_are_onsets(which, request):
    """The envelope jumps within 1 ms after every impact and is silent before the first one."""
    tr = request.getfixturevalue(which)
    s, fs = synthesize(tr, sample_rate=FS, excitation_hz=F_EXC)
    assert fs == FS
    times = (tr.impact_t - tr.t_start) / (2 * math.pi * F_EXC)
    assert times.size > 100
    # Before the first impact: exact silence (the recorded window starts between impacts).
    assert times[0] > 1e-3
    assert envelope_max(s, 0.0, times[0] - 1e-4) == 0.0
    # Every impact 4 ms or more after the previous one is a clear onset (closer ones can hide
    # in the ringing of a larger predecessor, as they would to the ear).
    gaps = np.diff(times, prepend=-1.0)
    checked = 0
    for t_n, gap in zip(times, gaps):
        if gap < 4e-3:
            continue
        before = envelope_max(s, t_n - 1.5e-3, t_n - 1e-4)
        after = envelope_max(s, t_n, t_n + 1e-3)
        assert after > 1.5 * before, (t_n, before, after)
        checked += 1
    assert checked > 0.9 * times.size


def test_onset_follows_engine_speed_in_physical_mode(periodic):
    """In physical units impact n sounds at (t_n − t_start)/ω s, and twice the rpm halves it."""
    held = example()
    phys = PhysicalParams.from_dimensionless(periodic.params, held, "rpm")
    s, _ = synthesize(periodic, sample_rate=FS, physical=phys)
    t1 = (periodic.impact_t[0] - periodic.t_start) / phys.omega
    first = int(np.flatnonzero(s)[0])
    assert first == math.ceil(t1 * FS - 1e-9)
    # At the same dimensionless trajectory, the rpm of an equivalent physical set fixes the time
    # scale: the signal length is (t_end − t_start)/ω + tail.
    assert s.size == round(((periodic.t_end - periodic.t_start) / phys.omega + 0.15) * FS)
    raw_phys, _ = synthesize(periodic, sample_rate=FS, physical=phys, normalized=False)
    raw_dim, _ = synthesize(periodic, sample_rate=FS, excitation_hz=phys.frequency_hz,
                            normalized=False)
    # Physical impulses are Ĩ m ω H1 newton-seconds.
    expected = phys.impulse_scale * raw_dim
    assert np.max(np.abs(raw_phys - expected)) < 1e-12 * np.max(np.abs(expected))


def test_loudness_grows_with_impulse(periodic):
    """Doubling every impulse doubles the peak and the RMS of the unnormalised sound."""
    doubled = dataclasses.replace(periodic, impact_impulse=2.0 * periodic.impact_impulse)
    s1, _ = synthesize(periodic, sample_rate=FS, normalized=False)
    s2, _ = synthesize(doubled, sample_rate=FS, normalized=False)
    assert np.max(np.abs(s2)) == pytest.approx(2 * np.max(np.abs(s1)), rel=1e-12)
    assert np.sqrt(np.mean(s2**2)) == pytest.approx(2 * np.sqrt(np.mean(s1**2)), rel=1e-12)
    # Larger single impulses are louder, in proportion.
    peaks = [np.max(np.abs(render([0.01], [a], 0.05, FS))) for a in (0.5, 1.0, 3.0)]
    assert peaks[1] == pytest.approx(2 * peaks[0], rel=1e-12)
    assert peaks[2] == pytest.approx(6 * peaks[0], rel=1e-12)


def test_normalised_to_peak_099(periodic):
    """The returned signal peaks at exactly 0.99, so int16 conversion cannot clip."""
    s, _ = synthesize(periodic, sample_rate=FS)
    assert np.max(np.abs(s)) == pytest.approx(0.99, rel=1e-12)


def test_deterministic(chaotic):
    """The same trajectory and settings give bit-identical sound."""
    a, _ = synthesize(chaotic, sample_rate=22_050)
    b, _ = synthesize(chaotic, sample_rate=22_050)
    assert np.array_equal(a, b)


def test_silence_without_impacts():
    """A gear resting on the active flank (Λ < 1, started on the wall) makes no sound at all."""
    p = RattleParams(lam=0.5)
    y0 = math.cos(0.0)
    tr = simulate(p, periods=20, x0=y0, v0=0.0)
    assert tr.impact_t.size == 0
    s, _ = synthesize(tr, sample_rate=FS)
    assert s.size > 0 and np.all(s == 0.0)
    assert np.all(normalize(np.zeros(10)) == 0.0)


def test_regimes_sound_different(periodic, chaotic, sticking):
    """Periodic is a steady buzz, chaotic fluctuates period to period, sticking falls silent."""
    n = 50
    e_per = per_period_rms(synthesize(periodic, sample_rate=FS)[0], n)
    e_cha = per_period_rms(synthesize(chaotic, sample_rate=FS)[0], n)
    cv_per = np.std(e_per) / np.mean(e_per)
    cv_cha = np.std(e_cha) / np.mean(e_cha)
    assert cv_per < 0.02
    assert cv_cha > 0.15
    s_stick, _ = synthesize(sticking, sample_rate=FS)
    assert sticking.impact_t.size > 5 and sticking.stick_intervals.shape[0] >= 1
    last = (sticking.impact_t[-1] - sticking.t_start) / (2 * math.pi * F_EXC)
    assert last < 0.25 * s_stick.size / FS  # the chatter is over early in the run
    assert np.max(np.abs(s_stick[: int(last * FS)])) > 0.5
    quiet = s_stick[int((last + 0.15) * FS):]
    assert quiet.size > FS // 2 and np.max(np.abs(quiet)) < 1e-5


def test_write_wav_round_trip(tmp_path, periodic):
    """write_wav writes 16-bit mono PCM at the sample rate, peak 0.99 × 32767, same waveform."""
    s, fs = synthesize(periodic, sample_rate=22_050)
    path = tmp_path / "rattle.wav"
    write_wav(path, s, fs)
    rate, data = wavfile.read(path)
    assert rate == 22_050 and data.dtype == np.int16 and data.ndim == 1 and data.size == s.size
    assert int(np.max(np.abs(data))) == round(0.99 * 32767)
    assert np.max(np.abs(data / 32767.0 - s)) < 1.0 / 32767


def test_parse_modes_and_defaults():
    """Mode text parses to HousingMode objects; defaults lie in 1-6 kHz with 1-3 % damping."""
    assert parse_modes("1000:0.02:1, 2500:0.01") == (HousingMode(1000.0, 0.02, 1.0),
                                                    HousingMode(2500.0, 0.01, 1.0))
    assert all(1000 <= m.freq_hz <= 6000 and 0.01 <= m.damping <= 0.03 for m in DEFAULT_MODES)
    for bad in ("", "abc", "1000:0.02:1:5", "1000:1.5", "-5"):
        with pytest.raises(ValueError):
            parse_modes(bad)


@pytest.mark.parametrize("kwargs, pattern", [
    ({"sample_rate": 1000}, r"sample_rate = 1000.0 is outside the allowed range \[4000, 384000\]"),
    ({"sample_rate": 44100.5}, r"sample_rate = 44100.5 must be a whole number"),
    ({"excitation_hz": 0.0}, r"excitation_hz = 0.0 is outside the allowed range \(0, 10000\]"),
    ({"excitation_hz": 0.05}, r"duration = .* s is outside the allowed range \(0, 600\] s"),
    ({"tail": -1.0}, r"tail = -1.0 is outside the allowed range \[0, 10\]"),
    ({"sample_rate": 8000}, r"mode freq_hz = 4300.0 is outside the allowed range \(0, 4000\)"),
    ({"polarity": "loud"}, r"polarity = 'loud' is not allowed"),
    ({"excitation_hz": 50.0, "physical": example()}, r"give excitation_hz or physical, not both"),
    ({"physical": example()}, r"physical gives lam = 0.49348, j = 8 but the trajectory was run with lam = 3.3"),
])
def test_bad_arguments_raise_clear_errors(periodic, kwargs, pattern):
    """Bad sample rates, frequencies, durations and mismatched units raise a named ValueError."""
    with pytest.raises(ValueError, match=pattern):
        synthesize(periodic, **kwargs)


def test_render_validation():
    """render rejects mismatched lengths, non-finite input and absurd durations."""
    with pytest.raises(ValueError, match="same length"):
        render([0.1, 0.2], [1.0], 1.0)
    with pytest.raises(ValueError, match="finite"):
        render([np.nan], [1.0], 1.0)
    with pytest.raises(ValueError, match=r"duration = 0.0 is outside the allowed range \(0, 600\]"):
        render([], [], 0.0)
    with pytest.raises(ValueError, match="one-dimensional"):
        write_wav("/tmp/never-written.wav", np.zeros((2, 2)), FS)


def test_many_impacts_match_closed_form_and_render_on_threads():
    """Many impacts, some in the same sample, ring the modes as the sum of their closed forms;
    the compiled rendering gives the same samples on four threads at once as one by one."""
    from concurrent.futures import ThreadPoolExecutor
    rng = np.random.default_rng(5)
    t_imp = np.sort(rng.uniform(0.0, 0.04, 30))
    t_imp[7] = t_imp[6] + 0.1 / FS  # two impacts between the same two samples
    a = rng.normal(size=30)
    s = render(t_imp, a, 0.05, FS)
    t = np.arange(s.size) / FS
    expected = np.zeros_like(t)
    for t0, a0 in zip(t_imp, a):
        tau = t - t0
        for m in DEFAULT_MODES:
            w = 2 * math.pi * m.freq_hz
            wd = w * math.sqrt(1 - m.damping**2)
            expected += np.where(tau >= 0, a0 * m.gain * np.exp(-m.damping * w * tau)
                                 * np.sin(wd * tau), 0.0)
    assert np.max(np.abs(s - expected)) < 1e-9 * np.max(np.abs(expected))
    jobs = [(t_imp, a * (k + 1)) for k in range(8)]
    serial = [render(ti, ai, 0.05, FS) for ti, ai in jobs]
    with ThreadPoolExecutor(4) as pool:
        threaded = list(pool.map(lambda job: render(job[0], job[1], 0.05, FS), jobs))
    for x, y in zip(serial, threaded):
        assert np.array_equal(x, y)
