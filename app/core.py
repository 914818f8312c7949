"""What the dashboard takes from ``rattle_core`` beyond its top-level names, in one place.

The app imports ``RattleParams``, ``simulate``, ``classify``, ``sweep`` and the other public
names from ``rattle_core`` itself. Everything else it needs (ranges, the physical-units
module, maps, the paper's cases, the disk cache) is re-exported here, so a reorganisation of
the core's modules changes this file only.
"""
from __future__ import annotations

from rattle_core import units
from rattle_core.cache import cached_sweep, list_assets, load_asset
from rattle_core.classify import REGIMES, contact_boundary
from rattle_core.excitation import TWO_PI, excitation
from rattle_core.maps import REGIME_CODES, REGIME_COLOURS, plan_map, run_map
from rattle_core.paper import PRESETS as PAPER_CASES
from rattle_core.paper import core_phi2_to_paper, paper_phi2_to_core
from rattle_core.params import (AMPLITUDE_RANGE, J_RANGE, LAM_RANGE, MAX_HARMONICS,
                                PHASE_RANGE_DEG, R_RANGE, V_STICK_RANGE, check_range,
                                core_to_paper_phases, paper_to_core_phases)
from rattle_core.sound import (DEFAULT_EXCITATION_HZ, DEFAULT_MODES, DEFAULT_SAMPLE_RATE,
                               DEFAULT_TAIL, EXCITATION_HZ_RANGE, HousingMode, parse_modes,
                               synthesize, write_wav)
from rattle_core.units import PhysicalParams

__all__ = [
    "cached_sweep", "list_assets", "load_asset", "contact_boundary", "excitation",
    "units", "PhysicalParams", "REGIMES", "TWO_PI", "REGIME_CODES",
    "REGIME_COLOURS", "plan_map", "run_map", "PAPER_CASES",
    "core_phi2_to_paper", "paper_phi2_to_core", "AMPLITUDE_RANGE", "J_RANGE", "LAM_RANGE",
    "MAX_HARMONICS", "PHASE_RANGE_DEG", "R_RANGE", "V_STICK_RANGE", "check_range",
    "core_to_paper_phases", "paper_to_core_phases", "DEFAULT_EXCITATION_HZ", "DEFAULT_MODES",
    "DEFAULT_SAMPLE_RATE", "DEFAULT_TAIL", "EXCITATION_HZ_RANGE", "HousingMode", "parse_modes",
    "synthesize", "write_wav",
]
