"""The dashboard's rattle-sound card, without a browser.

The sound the card plays and exports is checked against the library's own
:func:`rattle_core.analysis.sound.synthesize` of the dashboard's trajectory, and against the trajectory
itself: every impact is an onset in the signal, a gear stuck to its tooth is silent, and the
physical-units mode stretches the sound by the engine speed.
"""
from __future__ import annotations

import io
import math

import numpy as np
import pytest
from scipy.io import wavfile

from app.views import sound as sound_view
from rattle_core.model.excitation import TWO_PI
from rattle_core.analysis.sound import (DEFAULT_EXCITATION_HZ, DEFAULT_TAIL, PEAK, parse_modes, synthesize,
                               to_int16)

HARMONIC = {"h2": 0.0, "phi2": 0.0, "harmonics": ""}


def sound(d) -> sound_view.SoundView:
    return d.sound


def tr_of(d):
    return d.state.result.tr


def apply_values(state, values) -> dict:
    state.param.update(**values)
    return {k: v for k, v in state.messages.items() if k in values}


def test_player_holds_the_synthesized_sound_at_peak_099(dash):
    """The page opens with the sound of its trajectory: synthesize's samples, rate and peak 0.99."""
    sp = sound(dash)
    assert tr_of(dash).periods == pytest.approx(sp.settings["periods"])  # the whole run is played
    expected, rate = synthesize(tr_of(dash))
    assert sp.audio.sample_rate == rate == 44_100
    np.testing.assert_array_equal(sp.audio.object, expected)
    assert np.max(np.abs(sp.audio.object)) == pytest.approx(PEAK, rel=1e-12)
    assert sp.__panel__() is sp.card

    sp.widgets["sample_rate"].value = 22_050
    expected, rate = synthesize(tr_of(dash), sample_rate=22_050)
    assert sp.audio.sample_rate == rate == 22_050
    np.testing.assert_array_equal(sp.audio.object, expected)


def test_wav_download_decodes_to_the_int16_samples(dash):
    """The WAV export decodes to to_int16 of the sound, and renders a stale sound first."""
    sp = sound(dash)
    rate, data = wavfile.read(io.BytesIO(sp.download.callback().getvalue()))
    signal, expected_rate = synthesize(tr_of(dash))
    assert rate == expected_rate and data.dtype == np.int16
    np.testing.assert_array_equal(data, to_int16(signal))
    assert "lam3.3" in sp.download.filename and "50Hz" in sp.download.filename
    assert sp.download.filename.endswith("_44100.wav")

    sp.widgets["polarity"].value = "absolute"
    dash.state.lam = 2.9
    assert sp.stale
    rate, data = wavfile.read(io.BytesIO(sp.download.callback().getvalue()))
    np.testing.assert_array_equal(data, to_int16(synthesize(tr_of(dash), polarity="absolute")[0]))
    assert "lam2.9" in sp.download.filename and "absolute" in sp.download.filename
    assert not sp.stale


def test_every_impact_is_an_onset_in_regime_e(dash):
    """Regime E (harmonic, Λ = 3.3): the housing rings up at each impact, not between them."""
    sp = sound(dash)
    assert not apply_values(dash.state, {"lam": 3.3, **HARMONIC})
    assert dash.state.result.cls.regime == "E"
    assert sp.render()
    s, rate = sp.audio.object, sp.audio.sample_rate
    tr = tr_of(dash)
    k = np.ceil((tr.impact_t - tr.t_start) / (TWO_PI * DEFAULT_EXCITATION_HZ) * rate).astype(int)
    w = int(5e-4 * rate)

    def rise(i: int) -> float:
        before = np.mean(s[i - w:i] ** 2)
        return math.inf if before == 0.0 else math.sqrt(np.mean(s[i:i + w] ** 2) / before)

    k = k[k > w]
    assert len(k) > 300
    assert min(rise(i) for i in k) > 2.5
    assert max(rise(i) for i in (k[1:] + k[:-1]) // 2) < 2.5
    assert np.all(s[:k[0] - 1] == 0.0)  # nothing sounds before the first impact
    assert "Periodic buzz" in sp.hear.object and "100 impacts per second" in sp.hear.object


def test_sticking_gear_falls_silent_after_the_chatter(dash):
    """Λ < 1, harmonic: the gear chatters onto the tooth, sticks, and the housing rings out to silence."""
    sp = sound(dash)
    assert not apply_values(dash.state, {"lam": 0.8, "transient": 0, "periods": 50, **HARMONIC})
    sp.widgets["periods"].value = 50
    tr = tr_of(dash)
    assert tr.impact_t.size > 0 and tr.stick_intervals[-1, 1] == pytest.approx(tr.t_end)
    s, rate = sp.audio.object, sp.audio.sample_rate
    np.testing.assert_array_equal(s, synthesize(tr)[0])
    assert s.size == round((50 / DEFAULT_EXCITATION_HZ + DEFAULT_TAIL) * rate)
    last = (tr.impact_t[-1] - tr.t_start) / (TWO_PI * DEFAULT_EXCITATION_HZ)
    ringing = s[: int((last + 0.01) * rate)]
    after = s[int((last + 0.15) * rate):]
    assert np.max(np.abs(ringing)) == pytest.approx(PEAK)
    assert after.size > 0.5 * rate and np.max(np.abs(after)) < 1e-6
    assert "silence" in sp.hear.object.lower()


def test_invalid_modes_show_a_message_and_keep_the_last_good_sound(dash):
    """Malformed or above-Nyquist mode text leaves a message and the sound; good text renders."""
    sp = sound(dash)
    before = sp.audio.object
    for text, fragment in (("1250:0.02:1, abc", "mode 'abc' must read"),
                           ("30000:0.02:1", "Nyquist"),
                           ("1250:1.5:1", "mode damping = 1.5 is outside the allowed range (0, 1)"),
                           ("", "holds no mode")):
        sp.widgets["modes"].value = text
        alert = sp.alerts["modes"]
        assert alert.visible and fragment in sp.messages["modes"], text
        assert "Kept modes = 1250:0.02:1" in sp.messages["modes"]
        assert sp.audio.object is before
        assert sp.widgets["modes"].value == text  # left as typed, to be corrected
    sp.widgets["modes"].value = "1000:0.05:1, 3000:0.01:0.5"
    assert not sp.alerts["modes"].visible
    np.testing.assert_array_equal(
        sp.audio.object, synthesize(tr_of(dash), modes=parse_modes("1000:0.05:1, 3000:0.01:0.5"))[0])


@pytest.mark.parametrize("name,value,fragment,kept", [
    ("periods", 5000, "periods to play = 5000.0 is outside the allowed range [1, 2000]", 200),
    ("periods", 0, "periods to play = 0.0 is outside the allowed range [1, 2000]", 200),
    ("excitation", float("nan"), "excitation f (Hz) must be", 50.0),
    ("excitation", 0.0, "excitation f (Hz) = 0.0 is outside the allowed range (0, 10000]", 50.0),
    ("excitation", 1.0, "duration = 200.1 s", 50.0),
    ("sample_rate", 8_000, "mode freq_hz = 4300.0 is outside the allowed range (0, 4000)", 44_100),
])
def test_bad_settings_leave_a_message_and_the_last_good_value(dash, name, value, fragment, kept):
    """A setting out of range, or one the sound cannot be rendered with, changes nothing."""
    sp = sound(dash)
    before = sp.audio.object
    sp.widgets[name].value = value
    alert = sp.alerts[name]
    assert alert.visible and fragment in sp.messages[name]
    assert sp.settings[name] == kept and sp.widgets[name].value == kept
    assert sp.audio.object is before and not sp.alerts["render"].visible


def test_slider_moves_only_mark_the_sound_stale_unless_auto(dash, monkeypatch):
    """a new run never synthesises (the card says the sound is stale) until auto is on."""
    sp = sound(dash)
    calls = []
    real = sound_view.synthesize
    monkeypatch.setattr(sound_view, "synthesize", lambda *a, **k: calls.append(1) or real(*a, **k))
    before = sp.audio.object
    dash.state.lam = 3.0
    assert calls == [] and sp.stale and "Stale" in sp.status.object
    assert sp.audio.object is before
    sp.render_button.clicks += 1
    assert calls == [1] and not sp.stale and "Stale" not in sp.status.object
    np.testing.assert_array_equal(sp.audio.object, real(tr_of(dash))[0])
    assert sp.audio.paused is False
    sp.auto.value = True
    dash.state.lam = 3.1
    assert len(calls) == 2 and not sp.stale
    np.testing.assert_array_equal(sp.audio.object, real(tr_of(dash))[0])


def test_periods_to_play_cut_the_trajectory(dash):
    """Playing N periods of a longer run is the sound of its first N periods, no longer."""
    sp = sound(dash)
    sp.widgets["periods"].value = 20
    tr = tr_of(dash)
    s, rate = sp.audio.object, sp.audio.sample_rate
    assert s.size == round((20 / DEFAULT_EXCITATION_HZ + DEFAULT_TAIL) * rate)
    cut = sound_view.first_periods(tr, 20)
    assert cut.impact_t.size == np.count_nonzero(tr.impact_t < tr.t_start + 20 * TWO_PI) > 0
    np.testing.assert_array_equal(s, synthesize(cut)[0])
    # over those 20 periods it is the whole run's sound, scaled to its own peak
    n = int(20 / DEFAULT_EXCITATION_HZ * rate)
    raw = synthesize(tr, normalized=False)[0][:n]
    scale = np.dot(s[:n], raw) / np.dot(raw, raw)
    np.testing.assert_allclose(s[:n], scale * raw, rtol=0, atol=1e-12)
    assert np.max(np.abs(s)) == pytest.approx(PEAK)
    assert "20per" in sp.download.filename


def test_physical_mode_follows_the_engine_speed(dash):
    """In physical units the sound lasts periods / (order × rpm / 60) + tail, and the card says so."""
    sp = sound(dash)
    s = dash.state
    s.param.update(units=True, **HARMONIC)
    lengths = {}
    for rpm in (1200.0, 2400.0):
        s.rpm = rpm
        phys = s.result.phys
        assert phys is not None and phys.rpm == rpm
        assert sp.render()
        sig, rate = sp.audio.object, sp.audio.sample_rate
        np.testing.assert_array_equal(sig, synthesize(tr_of(dash), physical=phys)[0])
        assert sig.size == round((200 / (2 * rpm / 60) + DEFAULT_TAIL) * rate)
        assert f"{rpm:g} rpm" in sp.status.object and sp.widgets["excitation"].disabled
        assert f"{rpm:g}rpm" in sp.download.filename
        lengths[rpm] = sig.size / rate - DEFAULT_TAIL
    assert lengths[1200.0] == pytest.approx(2 * lengths[2400.0])
    s.units = False
    assert sp.render()
    assert sp.audio.object.size == round((200 / DEFAULT_EXCITATION_HZ + DEFAULT_TAIL) * 44_100)
    assert not sp.widgets["excitation"].disabled and "Dimensionless" in sp.status.object


def test_description_follows_every_run_even_before_a_render(dash):
    """The card never describes an old run: after a move to regime A it says silence at once."""
    sp = sound(dash)
    assert "Chaotic rattle" in sp.hear.object
    dash.state.param.update(lam=0.8, **HARMONIC)
    assert dash.state.result.cls.regime in ("A", "B") and sp.stale
    assert "Silence" in sp.hear.object or "silence" in sp.hear.object
    assert "Chaotic" not in sp.hear.object and "e+" not in sp.hear.object
