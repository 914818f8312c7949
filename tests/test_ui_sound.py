"""Browser test of the rattle-sound card: the page's ``<audio>`` element carries the sound,
and a parameter change marks it stale until Render / play replaces it.

The WAV the browser holds is read back from the element's ``src`` (a base64 data URL) and
decoded, so a check passes only if the sound travelled server → websocket → page. The checks
share one page (a page load is the costly part of a browser test): the sound the page loaded
with is read first, then Λ is changed.
"""
from __future__ import annotations

import base64
import io

import numpy as np
import pytest
from playwright.sync_api import expect
from scipy.io import wavfile

from rattle_core.analysis.sound import DEFAULT_EXCITATION_HZ, DEFAULT_TAIL, PEAK
from test_ui import box, open_dashboard, painted, wait_box

pytestmark = [pytest.mark.ui, pytest.mark.timeout(300)]

AUDIO = ".sound-audio audio"
#: A cheap fingerprint of the audio element's data URL, computed in the page.
SRC_HASH = """(el) => { const s = el.src; let h = s.length;
  for (let i = 0; i < s.length; i += 97) h = (h * 31 + s.charCodeAt(i)) % 1000000007;
  return h; }"""


def audio_wav(page) -> tuple[int, np.ndarray]:
    """Sample rate and int16 samples of the WAV held by the page's audio element."""
    src = page.locator(AUDIO).first.evaluate("el => el.src")
    head, _, data = src.partition(",")
    assert head == "data:audio/wav;base64" and data, src[:80]
    return wavfile.read(io.BytesIO(base64.b64decode(data)))


def wait_sound(page, timeout: float = 30_000) -> None:
    """Wait until the audio element holds a WAV: the first sound follows the first run, which
    the page draws after it has loaded."""
    page.wait_for_function("(el) => el.src.length > 100",
                           arg=page.locator(AUDIO).first.element_handle(), timeout=timeout)


def wait_text(page, selector: str, stale: bool, timeout: float = 20_000) -> None:
    """Wait until the text of ``selector`` does (or does not) say the sound is stale."""
    saying = expect(page.locator(selector).filter(has_text="Stale"))
    if stale:
        saying.not_to_have_count(0, timeout=timeout)
    else:
        saying.to_have_count(0, timeout=timeout)


@pytest.mark.timeout(600)
def test_the_page_holds_the_rattle_sound_and_render_replaces_it(page, dashboard_server):
    """?lam=3.3&h2=0&periods=50: the audio element holds the run's WAV; a Λ change marks it
    stale and Render / play loads a new one."""
    errors = open_dashboard(page, dashboard_server, "?lam=3.3&h2=0&periods=50")
    _step_page_holds_the_rattle_sound(page, errors)
    _step_render_after_a_parameter_change_replaces_the_sound(page, dashboard_server, errors)


def _step_page_holds_the_rattle_sound(page, errors) -> None:
    """The card's audio element holds a WAV of the trajectory's length at a peak of 0.99."""
    wait_box(page, "h2", 0.0)
    wait_sound(page)
    rate, data = audio_wav(page)
    assert rate == 44_100 and data.dtype == np.int16
    assert data.size == round((50 / DEFAULT_EXCITATION_HZ + DEFAULT_TAIL) * rate)
    # Panel writes floats as int16(x × 32768): the peak of 0.99 is 32440
    assert int(np.max(np.abs(data))) == int(PEAK * 32768)
    expect(page.locator(".sound-hear p").first).to_contain_text("Periodic buzz", timeout=30_000)
    assert errors == []


def _step_render_after_a_parameter_change_replaces_the_sound(page, dashboard_server,
                                                             errors) -> None:
    """Moving Λ marks the sound stale; Render / play loads a new one into the audio element."""
    wait_box(page, "h2", 0.0)
    audio = page.locator(AUDIO).first
    wait_sound(page)
    before = audio.evaluate(SRC_HASH)
    b = box(page, "lam")
    b.fill("2.6")
    b.press("Enter")
    wait_box(page, "lam", 2.6)
    wait_text(page, ".sound-status p", stale=True)
    assert audio.evaluate(SRC_HASH) == before
    page.locator(".sound-render button").first.click()
    page.wait_for_function(f"(el) => ({SRC_HASH})(el) !== {before}", arg=audio.element_handle(),
                           timeout=20_000)
    rate, data = audio_wav(page)
    assert rate == 44_100 and data.size == round((50 / DEFAULT_EXCITATION_HZ + DEFAULT_TAIL) * rate)
    wait_text(page, ".sound-status p", stale=False)
    painted(page)
    assert errors == []
    assert dashboard_server["log"].tracebacks() == []
