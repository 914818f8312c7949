"""The words and colours for what the analysis finds: regimes and flanks, spelled once.

Every place that names or colours a regime or a flank (the dashboard, the CLI's PNGs, the
paper's figures, CSV and Parquet exports, map arrays) reads it from here, so a regime has one
letter, one integer code, one meaning and one colour everywhere.

Regimes (``docs/model.md``, "Regimes")
    ``A`` … ``E`` are the paper's; ``P`` and ``Q`` name the other responses; ``error`` marks a
    run that stopped at a solver limit.  :data:`REGIME_CODES` are the integers stored in map
    arrays and returned by :func:`~rattle_core.analysis.classify.classify_batch` (``error``
    last; −1 marks a point not run).
Flanks
    ``+1`` is the active flank (``x = y``, impulse ``Ĩ > 0``), ``−1`` the reverse flank
    (``x = y + j``, ``Ĩ < 0``), as in :attr:`Trajectory.impact_flank`.  Exported tables write
    them as :data:`FLANK_VALUES` (``active``, ``reverse``), so a file reads without this key.
Physical units
    :func:`physical_table` lays a :class:`~rattle_core.model.units.PhysicalParams` beside the
    dimensionless numbers it becomes, for ``rattle units`` and the dashboard.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from ..model.phases import paper_to_core
from ..model.units import PhysicalParams


@dataclasses.dataclass(frozen=True)
class Regime:
    """One regime: its letter, integer code, meaning, colour, and the rule that gives it
    (``docs/model.md``'s table, word for word; a test compares them)."""

    letter: str
    code: int
    meaning: str
    colour: str
    rule: str = ""


REGIMES: tuple[Regime, ...] = (
    Regime("A", 0, "permanent contact", "#9e9e9e",
           "no impact, stuck more than 99 % of the window"),
    Regime("B", 1, "impacts followed by permanent contact", "#ff9800",
           "some sticking"),
    Regime("C", 2, "one active-flank impact per period", "#2e7d32",
           "period 1, one active impact per period (±2 %), none on the reverse flank"),
    Regime("D", 3, "chaotic", "#d32f2f",
           "no period, a Lyapunov exponent above 1e-3; it may stick now and then"),
    Regime("E", 4, "two impacts per period, one on each flank", "#1565c0",
           "period 1, one impact per period on each flank (±2 %)"),
    Regime("P", 5, "periodic", "#7b1fa2",
           "any other periodic response"),
    Regime("Q", 6, "non-repeating, no positive exponent", "#795548",
           "quasi-periodic, or a long transient"),
    Regime("error", 7, "stopped at a solver limit", "#000000"),
)
#: Letters in code order, ``error`` last.
LETTERS: tuple[str, ...] = tuple(g.letter for g in REGIMES)
#: The letters a classification can give (every one but ``error``).
CLASS_LETTERS: tuple[str, ...] = LETTERS[:-1]
REGIME_CODES: dict[str, int] = {g.letter: g.code for g in REGIMES}
REGIME_MEANING: dict[str, str] = {g.letter: g.meaning for g in REGIMES}
REGIME_COLOURS: dict[str, str] = {g.letter: g.colour for g in REGIMES}
#: Regime letter → the rule that gives it, for the letters a classification can give.
REGIME_RULES: dict[str, str] = {g.letter: g.rule for g in REGIMES if g.rule}
#: Kinds of motion through sticking (``Classification.sticking``), in the order of their codes:
#: none, a loop resolvable in double precision, a loop decided by rounding (``docs/model.md``).
STICKING_KINDS: tuple[str, ...] = ("", "stick-locked", "chaos-through-sticking")
#: Colour of an unknown or missing regime.
UNKNOWN_COLOUR = "#555555"

ACTIVE = 1
REVERSE = -1
FLANK_COLOURS: dict[int, str] = {ACTIVE: "#c0392b", REVERSE: "#1f5fa8"}
FLANK_LABELS: dict[int, str] = {ACTIVE: "active flank", REVERSE: "reverse flank"}
#: How exported tables (CSV, Parquet) spell a flank, and the contact state of a sample.
FLANK_VALUES: dict[int, str] = {ACTIVE: "active", REVERSE: "reverse"}
CONTACT_VALUES: dict[int, str] = {0: "none", **FLANK_VALUES}
#: Permanent contact (stick phases) in time histories.
STICK_COLOUR = "#f39c12"


@dataclasses.dataclass(frozen=True)
class CurveStyle:
    """How a bifurcation curve of the atlas is drawn: legend label, colour, dash pattern
    (a Bokeh ``line_dash`` name, which matplotlib's :data:`MPL_DASH` translates)."""

    label: str
    colour: str
    dash: str


#: One line style per kind of bifurcation curve, in the dashboard and in PNGs alike.
CURVE_STYLES: dict[str, CurveStyle] = {
    "contact": CurveStyle("contact boundary Λ_c (rattle starts)", "#000000", "solid"),
    "fold": CurveStyle("fold (multiplier +1)", "#8e44ad", "dashed"),
    "period_doubling": CurveStyle("period doubling (multiplier −1)", "#c0392b", "solid"),
    "grazing": CurveStyle("grazing (an impact appears)", "#16a085", "dotdash"),
    "stick_onset": CurveStyle("onset of sticking", "#d35400", "dotted"),
    "stick_end": CurveStyle("end of sticking", "#7f8c8d", "dotted"),
}
#: matplotlib's spelling of the Bokeh dash names used above.
MPL_DASH = {"solid": "-", "dashed": "--", "dotdash": "-.", "dotted": ":"}
#: Codimension-two points: marker and short label.
CODIM2_MARKERS = {"grazing_period_doubling": ("o", "graze+PD"), "fold_period_doubling":
                  ("s", "fold+PD"), "grazing_fold": ("D", "graze+fold"),
                  "grazing_sticking": ("v", "graze+stick"), "turn": ("^", "turn")}


def regime_letters(codes) -> np.ndarray:
    """Letters of regime codes (an array of str; ``""`` for −1, a point not run)."""
    table = np.array(LETTERS + ("",), dtype=object)
    c = np.asarray(codes, dtype=np.int64)
    return table[np.where((c >= 0) & (c < len(LETTERS)), c, len(LETTERS))]


def flank_values(flank) -> np.ndarray:
    """Flanks (+1, −1) as exported tables spell them (:data:`FLANK_VALUES`)."""
    return np.where(np.asarray(flank) > 0, FLANK_VALUES[ACTIVE], FLANK_VALUES[REVERSE]).astype(object)


def contact_values(kind) -> np.ndarray:
    """Contact states (0 flight, +1 stuck active, −1 stuck reverse) as exported tables spell them."""
    k = np.asarray(kind)
    return np.where(k > 0, CONTACT_VALUES[ACTIVE],
                    np.where(k < 0, CONTACT_VALUES[REVERSE], CONTACT_VALUES[0])).astype(object)


def flank_colours(flank) -> np.ndarray:
    """The colour of each flank (+1, −1), as an array of str."""
    return np.where(np.asarray(flank) > 0, FLANK_COLOURS[ACTIVE], FLANK_COLOURS[REVERSE]).astype(object)


def physical_table(phys: PhysicalParams, noise: float | None = None,
                   phases: str = "core") -> list[tuple[str, str, str]]:
    """Rows ``(quantity, physical value, dimensionless value)`` of a physical parameter set, for
    showing both systems side by side (``rattle units``, the dashboard's units panel); with
    ``noise``, a row says what the model's noise level means for this gear.

    Harmonic ``k`` of the fundamental is named by its engine order, ``k`` × ``phys.order``.
    Phases are given in one convention, ``phases``: ``"core"`` (``cos(k t − φ_k)``) or
    ``"paper"`` (``sin(k t + φ_k)``).
    """
    if phases not in ("core", "paper"):
        raise ValueError(f"phases = {phases!r}; allowed: core, paper")
    p = phys.to_dimensionless()
    shown = ((lambda v, k: v) if phases == "core"
             else (lambda v, k: float(paper_to_core(v, k))))  # the map is its own inverse
    unit = "rad" if phys.excitation == "displacement" else "rad/s²"
    sym = "θ" if phys.excitation == "displacement" else "α"
    rows = [
        ("inertia J, radius R_b", f"{phys.inertia:.6g} kg·m², {phys.radius:.6g} m",
         f"m = J/R_b² = {phys.mass:.6g} kg"),
        ("drag torque C", f"{phys.drag_torque:.6g} N·m", f"F = C/R_b = {phys.force:.6g} N"),
        ("engine speed, order", f"{phys.rpm:.6g} rpm, order {phys.order:g}",
         f"ω = {phys.omega:.6g} rad/s ({phys.frequency_hz:.6g} Hz)"),
        (f"{sym}₁ (engine order {phys.order:g})", f"{phys.amplitudes[0]:.6g} {unit}",
         f"H₁ = {phys.H1 * 1e6:.6g} µm"),
        ("Λ = m H₁ ω² / F", "", f"{p.lam:.6g}"),
        ("backlash b", f"{phys.backlash_um:.6g} µm ({phys.backlash_deg:.6g}°)", f"j = {p.j:.6g}"),
    ]
    for k in range(2, p.n_harmonics + 1):
        rows.append((f"engine order {k * phys.order:g} ({sym}_{k}, phase {phases})",
                     f"{phys.amplitudes[k - 1]:.6g} {unit}, {shown(phys.phases_deg[k - 1], k):.6g}°",
                     f"h_{k} = {p.amplitudes[k - 1]:.6g}, φ_{k} = {shown(p.phases_deg[k - 1], k):.6g}°"))
    rows.append(("restitution r", f"{phys.r:.6g}", f"{p.r:.6g}"))
    if noise is not None:
        rows.append(("restitution scatter per impact", f"r = {phys.r:.4g} ± {phys.r * noise:.3g}",
                     f"noise ε = {noise:g}"))
    rows.append(("limit impact velocity", f"{phys.v_stick_mps:.6g} m/s", f"v_stick = {p.v_stick:.6g}"))
    rows.append(("impulse scale m ω H₁", f"{phys.impulse_scale:.6g} N·s", "Ĩ = 1"))
    rows.append(("time scale 1/ω", f"{1.0 / phys.omega:.6g} s", "t = 1"))
    return rows
