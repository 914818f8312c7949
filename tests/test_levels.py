"""A-weighted sound levels (rattle_core.analysis.levels) against IEC 61672-1 and closed forms."""
from __future__ import annotations

import math

import numpy as np
import pytest

from rattle_core.analysis.levels import P_REF, a_weighting_db, energy_sum_db, level

FS = 48_000
# IEC 61672-1:2013 Table 3: A-weighting at the nominal frequencies, to 0.1 dB
TABLE = {10: -70.4, 12.5: -63.4, 16: -56.7, 20: -50.5, 25: -44.7, 31.5: -39.4, 40: -34.6,
         50: -30.2, 63: -26.2, 80: -22.5, 100: -19.1, 125: -16.1, 160: -13.4, 200: -10.9,
         250: -8.6, 315: -6.6, 400: -4.8, 500: -3.2, 630: -1.9, 800: -0.8, 1000: 0.0,
         1250: 0.6, 1600: 1.0, 2000: 1.2, 2500: 1.3, 3150: 1.2, 4000: 1.0, 5000: 0.5,
         6300: -0.1, 8000: -1.1, 10000: -2.5, 12500: -4.3, 16000: -6.6, 20000: -9.3}


def _tone(f, db, seconds=1.0):
    t = np.arange(int(seconds * FS)) / FS
    return math.sqrt(2) * P_REF * 10 ** (db / 20) * np.sin(2 * np.pi * f * t)


def test_the_weighting_is_the_standards_table():
    """A(f) at the exact base-ten frequencies of each nominal one rounds to the table's value."""
    nominal = sorted(TABLE)
    exact = 1000 * 10 ** (np.round(10 * np.log10(np.array(nominal) / 1000)) / 10)
    got = a_weighting_db(exact)
    want = np.array([TABLE[f] for f in nominal])
    assert np.max(np.abs(got - want)) <= 0.05 + 1e-9


def test_a_1khz_tone_at_94_db_is_94_dba():
    """A 1 kHz tone of 94 dB is 94.0 dB(A), both as L_Aeq and as its steady fast-weighted maximum."""
    lv = level(_tone(1000, 94.0), FS)
    assert lv.spl_dba == pytest.approx(94.0, abs=1e-6)
    assert lv.spl_dba_max == pytest.approx(94.0, abs=0.02)


def test_a_100hz_tone_at_94_db_is_weighted_by_minus_19_1():
    """A 100 Hz tone of 94 dB reads 94 − 19.1 dB(A)."""
    assert level(_tone(100, 94.0), FS).spl_dba == pytest.approx(94.0 - 19.1, abs=0.05)


def test_two_tones_add_as_energy():
    """Tones at different frequencies are incoherent over whole cycles: their levels add as energy."""
    a, b = _tone(500, 80.0), _tone(2000, 75.0)
    both = level(a + b, FS).spl_dba
    assert both == pytest.approx(energy_sum_db([level(a, FS).spl_dba, level(b, FS).spl_dba]),
                                 abs=1e-6)


def test_a_burst_of_one_time_constant_peaks_1_minus_1_over_e_below_the_tone():
    """A 1 kHz burst lasting τ = 0.125 s reaches L_eq(tone) + 10 log₁₀(1 − 1/e) on fast weighting."""
    burst = np.zeros(FS)
    tone = _tone(1000, 90.0, 0.125)
    burst[FS // 2: FS // 2 + tone.size] = tone
    want = 90.0 + 10 * math.log10(1 - math.exp(-1))
    assert level(burst, FS).spl_dba_max == pytest.approx(want, abs=0.05)


def test_silence_is_minus_infinity_and_bad_input_is_refused():
    """Silence has no level; NaN, an empty signal and a bad rate are refused by name."""
    assert level(np.zeros(FS), FS).spl_dba == -math.inf
    for bad, word in [(np.array([np.nan] * 10), "finite"), (np.array([]), "pressure_pa")]:
        with pytest.raises(ValueError, match=word):
            level(bad, FS)
    with pytest.raises(ValueError, match="fs"):
        level(np.ones(10), 0)
