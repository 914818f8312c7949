"""What the dashboard takes from ``rattle_core`` beyond its top-level names, in one place.

The app imports ``RattleParams``, ``simulate``, ``classify``, ``sweep`` and the other public
names from ``rattle_core`` itself. Everything else it needs (ranges, the physical-units
module, the vocabulary of regimes, maps, the paper's cases, the disk cache) is re-exported
here from the core's layers, so a reorganisation of the core changes this file only.
"""
from __future__ import annotations

from functools import partial

from rattle_core import units
from rattle_core.analysis.continuation import (ATLAS_AXES, CONTINUATION_VERSION,
                                                ContinuationError, ContinuationResult, atlas,
                                                axes_supported, continue_bifurcation,
                                                continue_orbit, find_orbit)
from rattle_core.analysis.overlays import contact_boundary
from rattle_core.analysis.statistics import attractor_verdicts, batch_means
from rattle_core.batch.ensemble import DEFAULT_LEVELS as NOISE_LEVELS
from rattle_core.batch.ensemble import noise_sensitivity
from rattle_core.analysis.sound import (DEFAULT_EXCITATION_HZ, DEFAULT_MODES,
                                        DEFAULT_SAMPLE_RATE, DEFAULT_TAIL, EXCITATION_HZ_RANGE,
                                        HousingMode, parse_modes, synthesize, write_wav)
from rattle_core.analysis.vocabulary import (CODIM2_MARKERS, CURVE_STYLES, REGIME_CODES,
                                             REGIME_COLOURS, REGIME_MEANING, REGIME_RULES,
                                             physical_table)
from rattle_core.batch.plan import PHYSICAL_AXES as MAP_PHYSICAL_AXES
from rattle_core.batch.plan import plan_map, point_params
from rattle_core.model.excitation import TWO_PI, excitation
from rattle_core.model.params import (AMPLITUDE_RANGE, J_RANGE, LAM_RANGE, MAX_HARMONICS,
                                      NOISE_DEFAULT, NOISE_RANGE, PHASE_RANGE_DEG, R_RANGE,
                                      V_STICK_RANGE, check_range)
from rattle_core.model.phases import core_to_paper, paper_to_core, paper_to_core_phases
from rattle_core.model.units import PhysicalParams
from rattle_core.paper.cases import CASES as PAPER_CASES
from rattle_core.store.assets import find_asset, list_assets, load_asset
from rattle_core.store.cache import NotCached, cached, cached_sweep, read_only
from rattle_core.store.files import atomic_savez
from rattle_core.store.exports import impacts_frame
from rattle_core.store.requests import run_map
from rattle_core.batch.executor import local_cluster
from rattle_core.solver.trajectory import MAX_T0, SOLVER_VERSION
from rattle_core.analysis.loudness import SAMPLE_RATE as LOUDNESS_RATE
from rattle_core.analysis.loudness import loudness
from rattle_core.analysis.sound import render, normalize
from rattle_core.batch.actions import scaled_drag
from rattle_core.batch.gearbox import GEARBOX
from rattle_core.batch.gearbox import check_rpm as check_verdict_rpm
from rattle_core.model.gearbox import (DEFAULT_DURATION_S, DEFAULT_TRANSFER_PA_PER_NS,
                                       Excitation, Gear, Gearbox)
from rattle_core.measure.orders import SAMPLE_RUNUP, OrderMap
from rattle_core.measure.campbell import campbell
from rattle_core.measure.measurement import read_measurement
from rattle_core.measure.sniff import SPEED_UNITS
from rattle_core.paper.drawing import campbell_png, orders_png, verdict_png
from rattle_core.store.verdicts import cached_verdict
from rattle_core.model.target import Target
from rattle_core.paper.verdict_pictures import designs_png
from rattle_core.store import verdict_tables
from rattle_core.store.exports import csv_text
from rattle_core.analysis.vocabulary import REGIMES as REGIME_WORDS
from rattle_core.batch.runup import compare as compare_runup
from rattle_core.model.params import canonical_hash
from rattle_core.solver.runup import check_run
from rattle_core.store.runups import cached_runup
from rattle_core.batch.runup import angle_of_samples
from rattle_core.solver.runup import measured_window

#: Regime letter → meaning, for the letters a classification gives.
REGIMES = {k: v for k, v in REGIME_MEANING.items() if k != "error"}
#: φ₂ between the conventions, unwrapped so that a sweep of the paper's phase stays monotone.
paper_phi2_to_core = partial(paper_to_core, k=2, wrap=False)
core_phi2_to_paper = partial(core_to_paper, k=2, wrap=False)
#: The conversion of all phases is its own inverse.
core_to_paper_phases = paper_to_core_phases

__all__ = [
    "CONTINUATION_VERSION", "ContinuationResult", "SOLVER_VERSION", "MAX_T0", "continue_orbit",
    "find_orbit", "atomic_savez", "cached", "cached_sweep", "find_asset", "list_assets", "load_asset", "contact_boundary", "excitation",
    "units", "PhysicalParams", "REGIMES", "TWO_PI", "MAP_PHYSICAL_AXES", "REGIME_CODES",
    "REGIME_COLOURS", "REGIME_RULES", "plan_map", "point_params", "run_map", "PAPER_CASES",
    "NotCached", "read_only", "local_cluster",
    "core_phi2_to_paper", "paper_phi2_to_core", "AMPLITUDE_RANGE", "J_RANGE", "LAM_RANGE",
    "MAX_HARMONICS", "PHASE_RANGE_DEG", "R_RANGE", "V_STICK_RANGE", "check_range",
    "core_to_paper_phases", "paper_to_core_phases", "DEFAULT_EXCITATION_HZ", "DEFAULT_MODES",
    "DEFAULT_SAMPLE_RATE", "DEFAULT_TAIL", "EXCITATION_HZ_RANGE", "HousingMode", "parse_modes",
    "synthesize", "write_wav", "physical_table", "impacts_frame", "batch_means", "attractor_verdicts",
    "NOISE_DEFAULT", "NOISE_RANGE", "NOISE_LEVELS", "noise_sensitivity",
    "ATLAS_AXES", "ContinuationError", "atlas", "axes_supported", "continue_bifurcation",
    "CODIM2_MARKERS", "CURVE_STYLES",
    "LOUDNESS_RATE", "loudness", "render", "normalize", "GEARBOX", "DEFAULT_DURATION_S",
    "DEFAULT_TRANSFER_PA_PER_NS", "Excitation", "Gear", "Gearbox", "SAMPLE_RUNUP", "OrderMap",
    "orders_png", "verdict_png", "campbell", "campbell_png", "read_measurement", "SPEED_UNITS",
    "cached_verdict", "check_verdict_rpm",
    "Target", "designs_png", "verdict_tables", "csv_text", "REGIME_WORDS", "scaled_drag",
    "compare_runup", "canonical_hash", "check_run", "cached_runup", "angle_of_samples",
    "measured_window",
]
