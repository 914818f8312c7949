"""(in development)"""
from __future__ import annotations

from .panel_base import FeaturePanel


class SoundPanel(FeaturePanel):
    pass
