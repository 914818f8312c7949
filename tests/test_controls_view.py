"""The sidebar's presets, without a browser: a preset says what it shows under the buttons once loaded.

A hover tooltip on a preset button stayed over the plots after the click; the buttons carry none,
and the line under them names the preset just loaded with its description from ``app.presets``.
A preset that clears an optional value (x₀) leaves its box empty in the page, not "NaN".
"""
from __future__ import annotations

import math

import pytest

from app.presets import PRESETS
from app.state import ExplorerState
from app.views.controls import Controls


@pytest.mark.parametrize("label", ["Fig 2", "Fig 7"])
def test_a_loaded_preset_is_described_under_the_buttons_and_no_button_has_a_tooltip(label):
    """After a preset is loaded the note names it and gives its description; no button has a tooltip."""
    assert label in PRESETS
    view = Controls(state=ExplorerState())
    assert all(not b.description for b in view.presets)
    assert label not in view.preset_note.object
    view.apply_preset(label)
    desc = PRESETS[label][0]
    assert f"{label}: " in view.preset_note.object
    assert desc.split()[0] in view.preset_note.object


def test_a_preset_that_clears_x0_sends_the_page_an_empty_box():
    """x₀ = 1, then the Fig 7 preset (x₀ cleared): the box's Bokeh model, which the page shows,
    holds null, not NaN (which the page's box would read as "NaN"); a value comes back as is."""
    state = ExplorerState(x0=1.0)
    view = Controls(state=state)
    box = view.fields["x0"].box
    model = box.get_root()
    assert model.value == 1.0
    view.apply_preset("Fig 7")
    assert state.x0 is None and box.value is None
    assert model.value is None, model.value
    state.x0 = 0.5
    assert model.value == 0.5 and not math.isnan(model.value)


def test_the_slider_follows_a_typed_value_before_the_views_redraw():
    """Λ typed into its box: the slider stands at it already when the state's first watcher
    (the session's redraw, registered before any control) runs, not after every view has
    redrawn; a value the state refuses puts the slider back."""
    state = ExplorerState()
    seen: list[float] = []
    state.param.watch(lambda e: seen.append(view.fields["lam"].slider.value), "lam")
    view = Controls(state=state)
    field = view.fields["lam"]
    new = state.lam + 0.125
    field.box.value = new
    assert seen == [pytest.approx(new)] and field.slider.value == pytest.approx(new)
    field.box.value = -5.0  # Λ must be positive
    assert state.lam == pytest.approx(new) and field.slider.value == pytest.approx(new)
    assert field.slider.start <= new <= field.slider.end and field.slider.start >= 0
