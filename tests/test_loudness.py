"""ISO 532-1 loudness and DIN 45692 sharpness, compiled end to end, against MOSQITO itself: a
1 kHz tone, pink noise, a burst train and rattle sounds of simulated trajectories."""
from __future__ import annotations

import math
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

from rattle_core import RattleParams, simulate
from rattle_core.analysis.loudness import (SKIP_S, loudness, loudness_zwtv, sharpness_din,
                                           sharpness_din_tv)
from rattle_core.analysis.sound import synthesize
from gearboxes import SAMPLE_TWO_GEARS

FS = 48_000
RTOL = 1e-9


def tone(freq: float, level_db: float, seconds: float) -> np.ndarray:
    t = np.arange(int(seconds * FS)) / FS
    return 2e-5 * 10 ** (level_db / 20) * math.sqrt(2) * np.sin(2 * math.pi * freq * t)


def pink(level_db: float, seconds: float) -> np.ndarray:
    """Noise with power falling as 1/f, at the given level (dB SPL, broadband)."""
    n = int(seconds * FS)
    spectrum = np.fft.rfft(np.random.default_rng(7).standard_normal(n))
    f = np.arange(spectrum.size, dtype=np.float64)
    f[0] = 1.0
    x = np.fft.irfft(spectrum / np.sqrt(f), n)
    return x * (2e-5 * 10 ** (level_db / 20) / np.std(x))


def bursts(seconds: float) -> np.ndarray:
    """A 3 kHz tone switched on for 20 ms every 100 ms, at 80 dB while on."""
    t = np.arange(int(seconds * FS)) / FS
    return np.where(t % 0.1 < 0.02, 1.0, 0.0) * tone(3000.0, 80.0, seconds)


def rattle(params: RattleParams, periods: int, peak_pa: float) -> np.ndarray:
    """The rattle of a simulated trajectory, scaled to a peak sound pressure."""
    tr = simulate(params, periods=periods, transient=200)
    s, _ = synthesize(tr, sample_rate=FS, excitation_hz=50.0, normalized=False, tail=0.05)
    return s * (peak_pa / np.max(np.abs(s)))


SIGNALS = {
    "1 kHz tone, 60 dB": lambda: tone(1000.0, 60.0, 0.5),
    "pink noise, 70 dB": lambda: pink(70.0, 0.5),
    "burst train": lambda: bursts(0.5),
    "rattle, periodic (E)": lambda: rattle(RattleParams(lam=3.3), 22, 2.0),
    "rattle, chaotic (Figure 7)": lambda: rattle(
        RattleParams.paper(3.3, amplitudes=(1.0, 0.25), phases_deg=(0.0, 45.0)), 22, 5.0),
}


@pytest.fixture(scope="module", params=list(SIGNALS), ids=list(SIGNALS))
def case(request):
    """A signal, with MOSQITO's time-varying loudness and sharpness of it (the reference)."""
    from mosqito.sq_metrics import loudness_zwtv as ref_loudness
    from mosqito.sq_metrics import sharpness_din_from_loudness
    x = SIGNALS[request.param]()
    N, spec, bark, t = ref_loudness(x, FS)
    with np.errstate(invalid="ignore", divide="ignore"):  # MOSQITO divides 0 by 0 in silence
        S = sharpness_din_from_loudness(N, spec, "din")
    return x, (N, spec, bark, t, np.asarray(S))


def test_time_varying_loudness_equals_mosqito(case):
    """N(t), N'(z, t) and both axes equal MOSQITO's loudness_zwtv to 1e-9 relative."""
    x, (N_ref, spec_ref, bark_ref, t_ref, _) = case
    N, spec, bark, t = loudness_zwtv(x, FS)
    assert N.shape == N_ref.shape and spec.shape == spec_ref.shape == (240, N.size)
    assert np.max(N_ref) > 0.5  # every signal is well above the threshold of hearing
    np.testing.assert_allclose(N, N_ref, rtol=RTOL, atol=0)
    np.testing.assert_allclose(spec, spec_ref, rtol=RTOL, atol=RTOL * np.max(spec_ref))
    np.testing.assert_array_equal(bark, bark_ref)
    np.testing.assert_array_equal(t, t_ref)


def test_n5_and_sharpness_equal_mosqito(case):
    """N5, the sharpness per frame (sharpness_din_from_loudness, sharpness_din_tv's skip) and the
    single numbers of loudness() equal MOSQITO's to 1e-9 relative."""
    from mosqito.sq_metrics import sharpness_din_tv as ref_sharpness_tv
    x, (N_ref, _, _, t_ref, S_ref) = case
    N, spec, _, t = loudness_zwtv(x, FS)
    assert np.percentile(N, 95) == pytest.approx(np.percentile(N_ref, 95), rel=RTOL)
    np.testing.assert_allclose(sharpness_din(N, spec), S_ref, rtol=RTOL, atol=0)
    S_tv, t_tv = sharpness_din_tv(x, FS, skip=0.1)
    with np.errstate(invalid="ignore", divide="ignore"):
        S_tv_ref, t_tv_ref = ref_sharpness_tv(x, FS, skip=0.1)
    np.testing.assert_allclose(S_tv, S_tv_ref, rtol=RTOL, atol=0)
    np.testing.assert_array_equal(t_tv, t_tv_ref)
    heard = loudness(x)
    keep = t_ref >= SKIP_S
    assert heard.loudness_sone == pytest.approx(np.percentile(N_ref[keep], 95), rel=RTOL)
    framed = keep & (N_ref > 0)
    assert heard.sharpness_acum == pytest.approx(np.mean(S_ref[framed]), rel=RTOL)


def test_tone_loudness_is_zwickers_four_sone():
    """A 1 kHz tone at 60 dB is 4 sone (ISO 532-1's anchor: 40 phon is 1 sone, +10 dB doubles)
    once the temporal filters settle."""
    N, _, _, t = loudness_zwtv(tone(1000.0, 60.0, 1.0), FS)
    assert np.median(N[t > 0.5]) == pytest.approx(4.0, abs=0.1)


def test_sounds_in_threads_equal_sounds_one_by_one():
    """The kernels release the GIL: eight sounds measured on four threads at once give the
    numbers of the same sounds measured one after the other, exactly."""
    sounds = [pink(50.0 + 4 * k, 0.3) for k in range(8)]
    serial = [loudness_zwtv(s, FS) for s in sounds]
    with ThreadPoolExecutor(4) as pool:
        threaded = list(pool.map(lambda s: loudness_zwtv(s, FS), sounds))
    for a, b in zip(serial, threaded):
        np.testing.assert_array_equal(a[0], b[0])
        np.testing.assert_array_equal(a[1], b[1])


def test_silence_and_bad_input():
    """Silence is 0 sone and 0 acum; a sample rate other than 48 kHz, a non-finite or
    two-dimensional signal and a level over ISO 532-1's 120 dB below 315 Hz are refused."""
    N, spec, _, _ = loudness_zwtv(np.zeros(FS // 2), FS)
    assert not np.any(N) and not np.any(spec) and not np.any(sharpness_din(N, spec))
    with pytest.raises(ValueError, match="fs = 44100"):
        loudness_zwtv(np.zeros(1000), 44_100)
    with pytest.raises(ValueError, match="finite"):
        loudness_zwtv(np.array([0.0, np.nan]), FS)
    with pytest.raises(ValueError, match="one-dimensional"):
        loudness_zwtv(np.zeros((2, 1000)), FS)
    with pytest.raises(ValueError, match="120 dB"):
        loudness_zwtv(tone(100.0, 130.0, 0.2), FS)
    with pytest.raises(ValueError, match="N_specific must have shape"):
        sharpness_din(np.zeros(5), np.zeros((240, 4)))


def test_verdict_on_threads_equals_the_serial_verdict():
    """The gearbox verdict with its sounds on four threads equals the verdict computed one sound
    after the other, row for row and digit for digit, rattling and silent points alike."""
    import pandas as pd

    from rattle_core.batch.gearbox import GEARBOX, verdict
    from rattle_core.model.gearbox import Gearbox
    box = Gearbox.from_text(SAMPLE_TWO_GEARS)
    rpm = np.linspace(1200.0, 3000.0, 7)
    kw = dict(transient=120, record=40, chunk_speeds=3, ensemble_runs=2)
    serial = verdict(box, rpm, threads=1, **kw).table
    threaded = verdict(box, rpm, threads=4, **kw).table
    pd.testing.assert_frame_equal(threaded, serial, check_exact=True)
    gears = serial[serial["gear"] != GEARBOX]
    assert (gears["loudness_sone"] > 0).any() and (gears["loudness_sone"] == 0).any()
    assert (serial[serial["gear"] == GEARBOX]["loudness_sone"] > 0).any()
    with pytest.raises(ValueError, match="threads"):
        verdict(box, rpm, threads=0, **kw)


def test_every_kernel_is_compiled_nogil_without_fastmath():
    """Every numba kernel of the loudness and the sound releases the GIL (so threads run them at
    once) and keeps IEEE arithmetic (no fastmath)."""
    from numba.core.registry import CPUDispatcher

    from rattle_core.analysis import loudness as L
    from rattle_core.analysis import sound
    kernels = [f for mod in (L, sound) for f in vars(mod).values()
               if isinstance(f, CPUDispatcher)]
    names = {k.py_func.__name__ for k in kernels}
    assert {"_band_levels", "_core_loudness", "_nonlinear_decay", "_slopes",
            "_temporal_weighting", "_sharpness", "_zwtv", "_ring"} <= names
    for k in kernels:
        opts = k.targetoptions
        assert opts.get("nogil") and not opts.get("fastmath"), k
