"""The sidebar's presets, without a browser: a preset says what it shows under the buttons once loaded.

A hover tooltip on a preset button stayed over the plots after the click; the buttons carry none,
and the line under them names the preset just loaded with its description from ``app.presets``.
"""
from __future__ import annotations

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
