"""The rattle sound of the current run: a card in the Explorer tab.

A ``pn.viewable.Viewer`` that plays :func:`rattle_core.analysis.sound.synthesize` of ``state.result``
(its first N periods), normalised to a peak of 0.99 because ``pn.pane.Audio`` turns floats
into int16 as ``int16(x × 32768)``, without clipping. It offers the sound's own settings
(periods to play, excitation frequency, housing modes, polarity, sample rate), a 16-bit WAV
download and one line saying what the run sounds like. These settings belong to the card, not
to the model, so they are not part of the state or the URL; a refused value leaves its message
beside its control (escaped text) and the last good setting.

Time scale: in dimensionless mode the fundamental excitation frequency is the one set here; in
physical-units mode (``result.phys``) it follows the engine speed, ``f = order × rpm / 60``.

Cost: ``synthesize`` takes about 20 ms for 200 periods at 50 Hz and 44.1 kHz, and each new
sound sends about 0.5 MB of base64 WAV to the browser: too much for the slider path. A new run
only marks the sound stale (the card says so, and its description follows the new run at
once); the sound is rendered on "Render / play", at every run while "auto" is on, and at once
when one of the sound's own settings changes. The first sound is rendered once the page has
loaded, so it never delays the first plot.
"""
from __future__ import annotations

import functools
import io
import logging
import math
import time
from typing import Any

import numpy as np
import panel as pn
import param

from ..core import (DEFAULT_EXCITATION_HZ, DEFAULT_MODES, DEFAULT_SAMPLE_RATE, DEFAULT_TAIL,
                   EXCITATION_HZ_RANGE, TWO_PI, HousingMode, PhysicalParams, check_range,
                   parse_modes, synthesize, write_wav)
from ..state import ExplorerState
from ..ui.labels import message_html, what_to_hear
from ..ui.plots import first_periods

log = logging.getLogger(__name__)

#: Sample rates offered [Hz]; every one is within the library's allowed range.
SAMPLE_RATES = (8_000, 16_000, 22_050, 44_100, 48_000, 96_000)
#: Forcing periods played: at most this many, and never more than the trajectory holds.
PERIODS_RANGE = (1, 2_000)
DEFAULT_PERIODS = 200
#: Longest sound rendered [s] and most samples: beyond them the render (and the base64 WAV sent
#: to the browser, two bytes and a third per sample) would stall the session.
MAX_SECONDS = 30.0
MAX_SAMPLES = 2_000_000
POLARITIES = {"signed (flank flips polarity)": "signed", "absolute": "absolute"}
SETTINGS = ("periods", "excitation", "modes", "polarity", "sample_rate")


def format_modes(modes: tuple[HousingMode, ...]) -> str:
    """Modes as the text :func:`~rattle_core.analysis.sound.parse_modes` reads back."""
    return ", ".join(f"{m.freq_hz:g}:{m.damping:g}:{m.gain:g}" for m in modes)


def guarded(method):
    """A card callback: an exception becomes a message beside the render button."""
    @functools.wraps(method)
    def wrapper(self, *args: Any, **kwargs: Any) -> Any:
        try:
            return method(self, *args, **kwargs)
        except Exception as exc:
            log.warning("sound: %s failed: %s: %s", method.__name__, type(exc).__name__, exc)
            self.show_error("render", f"{type(exc).__name__}: {exc}")
            return None
    return wrapper


class SoundView(pn.viewable.Viewer):
    """The "Rattle sound" card: an audio player, its settings and a WAV export."""

    state = param.ClassSelector(class_=ExplorerState)

    def __init__(self, **params: Any):
        super().__init__(**params)
        #: Last accepted value of every setting; a rejected entry leaves these unchanged.
        self.settings: dict[str, Any] = {
            "periods": DEFAULT_PERIODS, "excitation": DEFAULT_EXCITATION_HZ,
            "modes": DEFAULT_MODES, "polarity": "signed", "sample_rate": DEFAULT_SAMPLE_RATE}
        self.signal: np.ndarray | None = None
        self.sample_rate = DEFAULT_SAMPLE_RATE
        self.stale = True
        self.render_ms = math.nan
        self._rendered: dict[str, Any] = {}
        self._scale_text = ""
        self._first = True  # the first sound renders once the page is up and a run exists
        self._loaded = False
        self._syncing = False
        self._build()

    # ----- construction -------------------------------------------------------------------

    def _build(self) -> None:
        s = self.settings
        # a volume of its own: left unset, every page's player would send it at once, a
        # message that can reach a session while it closes
        self.audio = pn.pane.Audio(None, sample_rate=s["sample_rate"], name="rattle sound",
                                   volume=100, css_classes=["sound-audio"],
                                   sizing_mode="stretch_width", margin=(5, 10))
        self.render_button = pn.widgets.Button(label="Render / play", color="primary",
                                               css_classes=["sound-render"], width=130)
        self.auto = pn.widgets.Checkbox(label="auto (render at every redraw)", value=False,
                                        css_classes=["sound-auto"], align="center")
        self.download = pn.widgets.FileDownload(callback=self._wav, filename="rattle.wav",
                                                label="Sound as WAV", css_classes=["sound-download"],
                                                width=150)
        self.widgets: dict[str, Any] = {
            "periods": pn.widgets.IntInput(
                label=f"periods to play ({PERIODS_RANGE[0]}–{PERIODS_RANGE[1]})",
                value=s["periods"], step=10, css_classes=["sound-periods"], width=160),
            "excitation": pn.widgets.FloatInput(
                label="excitation f (Hz)", value=s["excitation"], step=5.0,
                css_classes=["sound-excitation"], width=140),
            "sample_rate": pn.widgets.Select(
                label="sample rate (Hz)", options=list(SAMPLE_RATES), value=s["sample_rate"],
                css_classes=["sound-rate"], width=130),
            "polarity": pn.widgets.RadioButtonGroup(
                options=POLARITIES, value=s["polarity"], css_classes=["sound-polarity"],
                align="end"),
            "modes": pn.widgets.TextInput(
                label="housing modes, f (Hz) : damping ζ : gain, comma-separated",
                value=format_modes(s["modes"]), placeholder=format_modes(DEFAULT_MODES),
                css_classes=["sound-modes"], sizing_mode="stretch_width"),
        }
        self.alerts = {name: pn.pane.HTML("", visible=False, margin=(0, 10),
                                          css_classes=[f"msg-sound-{name}"], sizing_mode="stretch_width")
                       for name in (*SETTINGS, "render")}
        #: The message beside each control, as plain text ("" when none).
        self.messages = {name: "" for name in self.alerts}
        self.hear = pn.pane.Markdown("", css_classes=["sound-hear"], margin=(0, 10),
                                     sizing_mode="stretch_width")
        self.status = pn.pane.Markdown("", css_classes=["sound-status"], margin=(0, 10),
                                       sizing_mode="stretch_width",
                                       styles={"color": "#777", "font-size": "12px"})
        for name, w in self.widgets.items():
            w.param.watch(functools.partial(self._on_setting, name), "value")
        self.render_button.on_click(self._on_render)
        self.auto.param.watch(self._on_auto, "value")
        self._update_status()

        a = self.alerts
        self.card = pn.Card(
            pn.Row(self.render_button, self.auto, self.download, sizing_mode="stretch_width"),
            self.audio, self.hear, self.status, a["render"],
            pn.Row(pn.Column(self.widgets["periods"], a["periods"], margin=0),
                   pn.Column(self.widgets["excitation"], a["excitation"], margin=0),
                   pn.Column(self.widgets["sample_rate"], a["sample_rate"], margin=0),
                   self.widgets["polarity"], sizing_mode="stretch_width"),
            self.widgets["modes"], a["modes"],
            pn.pane.Markdown(f"Default modes (an illustrative cast housing, not a measured one): "
                             f"`{format_modes(DEFAULT_MODES)}`", margin=(0, 10),
                             styles={"color": "#777", "font-size": "12px"}),
            title="Rattle sound", collapsed=False, sizing_mode="stretch_width",
            css_classes=["sound-card"])
        self.state.param.watch(self._on_result, "result")
        doc = pn.state.curdoc
        if doc is not None and doc.session_context is not None:
            pn.state.onload(self._on_load)
        else:
            self._on_load()

    def __panel__(self):
        return self.card

    # ----- messages -----------------------------------------------------------------------

    def show_error(self, name: str, message: str) -> None:
        name = name if name in self.alerts else "render"
        self.messages[name] = message
        self.alerts[name].param.update(object=message_html(message), visible=True)

    def clear_error(self, name: str) -> None:
        self.messages[name] = ""
        alert = self.alerts[name]
        if alert.visible:
            alert.param.update(object="", visible=False)

    # ----- settings -----------------------------------------------------------------------

    @staticmethod
    def validate(name: str, value: Any) -> Any:
        """``value`` cleaned for setting ``name``, or ``ValueError`` naming it and its range."""
        if name == "periods":
            lo, hi = PERIODS_RANGE
            v = check_range("periods to play", value, lo, hi, text_ok=True)
            if v != int(v):
                raise ValueError(f"periods to play = {value!r} must be a whole number in [{lo}, {hi}]")
            return int(v)
        if name == "excitation":
            return check_range("excitation f (Hz)", value, *EXCITATION_HZ_RANGE, lo_open=True,
                               text_ok=True)
        if name == "modes":
            return parse_modes(value)
        if name == "polarity":
            if value not in POLARITIES.values():
                raise ValueError(f"polarity = {value!r} is not allowed; use 'signed' or 'absolute'")
            return value
        if name == "sample_rate":
            if value not in SAMPLE_RATES:
                raise ValueError(f"sample rate = {value!r} Hz is not offered; choose one of "
                                 f"{', '.join(map(str, SAMPLE_RATES))}")
            return int(value)
        raise ValueError(f"unknown sound setting {name!r}")

    @guarded
    def _on_setting(self, name: str, event) -> None:
        if not self._syncing:
            self.set(name, event.new)

    def set(self, name: str, value: Any) -> bool:
        """Accept a setting and render with it.

        A value that is invalid, or that cannot render with the other settings (a mode above
        the Nyquist frequency, too long a sound), leaves a message beside its control, the last
        good setting and the last good sound.
        """
        old = self.settings[name]
        try:
            self.settings[name] = self.validate(name, value)
        except (TypeError, ValueError) as exc:
            self.show_error(name, f"{exc}. {self._kept(name)}")
            self._revert_widget(name)
            return False
        self.clear_error(name)
        if self.render(source=name):
            return True
        self.settings[name] = old
        self._revert_widget(name)
        self.show_error(name, f"{self.messages[name]} {self._kept(name)}")
        return False

    def _kept(self, name: str) -> str:
        v = self.settings[name]
        shown = format_modes(v) if name == "modes" else f"{v:g}" if name != "polarity" else v
        return f"Kept {name.replace('_', ' ')} = {shown} and the last good sound."

    def _revert_widget(self, name: str) -> None:
        """Show the setting in use again; the modes text stays as typed, for correction."""
        if name == "modes":
            return
        self._syncing = True
        try:
            self.widgets[name].value = self.settings[name]
        finally:
            self._syncing = False

    @guarded
    def _on_auto(self, event) -> None:
        if event.new and self.stale:
            self.render()

    @guarded
    def _on_render(self, event=None) -> None:
        if self.render():
            # the click is the user's gesture the browser asks for before it plays a sound
            self.audio.param.update(autoplay=True, paused=False)

    # ----- rendering ----------------------------------------------------------------------

    def physical(self) -> PhysicalParams | None:
        run = self.state.result
        return run.phys if run is not None else None

    def excitation_hz(self) -> float:
        """The fundamental frequency the sound is played at [Hz]."""
        phys = self.physical()
        return phys.frequency_hz if phys is not None else self.settings["excitation"]

    def _update_status(self) -> None:
        phys = self.physical()
        if phys is not None:
            scale = (f"Physical units: the time scale follows the engine, {phys.rpm:g} rpm × "
                     f"order {phys.order:g} / 60 = {phys.frequency_hz:.4g} Hz fundamental.")
        else:
            scale = (f"Dimensionless mode: one forcing period lasts 1/f, f = "
                     f"{self.settings['excitation']:g} Hz.")
        cost = f" Rendered in {self.render_ms:.0f} ms." if math.isfinite(self.render_ms) else ""
        stale = (" **Stale**: the trajectory changed since this sound was rendered; press "
                 "Render / play." if self.stale and self.signal is not None else "")
        text = scale + cost + stale
        if text != self._scale_text:
            self._scale_text = text
            self.status.object = text
        self.widgets["excitation"].disabled = phys is not None

    def _check_size(self, window, freq: float, sample_rate: int) -> None:
        seconds = (window.t_end - window.t_start) / (TWO_PI * freq) + DEFAULT_TAIL
        if seconds > MAX_SECONDS:
            raise ValueError(f"duration = {seconds:.4g} s ({window.periods:.0f} periods at "
                             f"{freq:.4g} Hz) is outside the allowed range (0, {MAX_SECONDS:g}] s; "
                             "play fewer periods or raise the excitation frequency")
        if seconds * sample_rate > MAX_SAMPLES:
            raise ValueError(f"duration = {seconds:.4g} s at {sample_rate} Hz gives "
                             f"{seconds * sample_rate:,.0f} samples; the allowed maximum is "
                             f"{MAX_SAMPLES:,}: play fewer periods or lower the sample rate")

    def render(self, source: str | None = None) -> bool:
        """Synthesise the sound of the current trajectory and load it into the player.

        On failure the message goes beside the setting ``source`` (or the one it names) and
        the last good sound stays. Returns whether a new sound was loaded.
        """
        run = self.state.result
        if run is None:
            return False
        tr = run.tr
        t0 = time.perf_counter()
        s = self.settings
        phys = self.physical()
        freq = self.excitation_hz()
        window = first_periods(tr, s["periods"])
        try:
            self._check_size(window, freq, s["sample_rate"])
            signal, rate = synthesize(window, sample_rate=s["sample_rate"],
                                      excitation_hz=None if phys is not None else freq,
                                      physical=phys, modes=s["modes"], polarity=s["polarity"])
        except ValueError as exc:
            msg = str(exc)
            target = source or ("modes" if msg.startswith("mode") else
                                "periods" if msg.startswith("duration") else "render")
            self.show_error(target, f"{msg}." if source else f"{msg}. Kept the last good sound.")
            return False
        self.clear_error("render")
        if source is not None:
            self.clear_error(source)
        self.signal, self.sample_rate = signal, rate
        # sample_rate first: the pane encodes the WAV with the rate it holds when the data lands
        self.audio.param.update(sample_rate=rate, object=signal)
        self.stale = False
        self._rendered = dict(s, freq=freq, physical=phys, periods_played=window.periods)
        self.download.filename = self.filename()
        seconds = signal.size / rate
        self.hear.object = what_to_hear(run.cls, int(window.impact_t.size), seconds, freq)
        self.render_ms = 1e3 * (time.perf_counter() - t0)
        self._update_status()
        return True

    def filename(self) -> str:
        """WAV file name carrying the parameters of the sound last rendered."""
        p = self.state.result.params
        r = self._rendered
        phys = r.get("physical")
        scale = f"{phys.rpm:g}rpm-o{phys.order:g}" if phys is not None else f"{r['freq']:g}Hz"
        return (f"rattle_lam{p.lam:g}_r{p.r:g}_j{p.j:g}_{scale}_{r['periods_played']:.0f}per_"
                f"{r['polarity']}_{r['sample_rate']}.wav")

    def wav_bytes(self) -> bytes:
        """The sound last rendered as a mono 16-bit PCM WAV file."""
        if self.signal is None:
            raise ValueError("no sound has been rendered yet; press Render / play")
        buf = io.BytesIO()
        write_wav(buf, self.signal, self.sample_rate)
        return buf.getvalue()

    def _wav(self) -> io.BytesIO:
        try:
            if self.stale:
                self.render()
            return io.BytesIO(self.wav_bytes())
        except Exception as exc:
            log.warning("sound WAV export failed: %s: %s", type(exc).__name__, exc)
            self.show_error("render", f"The WAV could not be written: {exc}")
            return io.BytesIO(b"")

    # ----- following the runs ------------------------------------------------------------

    @guarded
    def _on_load(self) -> None:
        self._loaded = True
        self._first_render()

    def _first_render(self) -> None:
        # the first run may land after the page has loaded (it is drawn after load)
        if self._first and self._loaded and self.state.result is not None:
            self._first = False
            self.render()

    @guarded
    def _on_result(self, *_: Any) -> None:
        if self._first:
            self._first_render()
            return
        if self.auto.value and self.render():
            return
        self.stale = True
        run = self.state.result
        if run is not None:
            window = first_periods(run.tr, self.settings["periods"])
            freq = self.excitation_hz()
            seconds = (window.t_end - window.t_start) / (TWO_PI * freq)
            self.hear.object = (what_to_hear(run.cls, int(window.impact_t.size), seconds, freq)
                                + " *(press Render / play to hear it)*")
        self._update_status()
