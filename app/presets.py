"""The paper's figures as one-click presets: the state values that reproduce each one.

:data:`PRESETS` maps a button's label to its description and the values it sets; the values
come from ``rattle_core.paper``'s cases, in the paper's phase convention, and
:func:`preset_values` converts them when the page shows the core's.
"""
from __future__ import annotations

from typing import Any

from .core import PAPER_CASES
from .state import ExplorerState, convert_phase

def _case(key: str, **kw: Any) -> dict[str, Any]:
    """State values of one of the paper's cases (``rattle_core.paper``), in its phases."""
    c = PAPER_CASES[key]
    p = c.params
    values = {"r": p.r, "j": p.j, "h2": 0.0, "phi2": 0.0, "harmonics": "", "phases": "paper",
              "x0": None, "v0": 0.0, "t0": 0.0, "lam": p.lam}
    if c.paper_phi2 is not None or c.name == "phi2":
        values.update(h2=p.amplitudes[1], phi2=c.paper_phi2 if c.paper_phi2 is not None else 0.0)
    if c.name:
        values["bif"] = c.name
    return {**values, **kw}


#: One-click reproductions of the paper's figures: label → (description, state values).
PRESETS: dict[str, tuple[str, dict[str, Any]]] = {
    "Fig 2": ("Impulse vs Λ, harmonic excitation", _case("fig2", lam=2.5, shown=12)),
    "Fig 3B": ("Time history, regime B: impacts then permanent contact",
               _case("fig3", lam=1.1, bif="lam", shown=6)),
    "Fig 3C": ("Time history, regime C: one active-flank impact per period",
               _case("fig3", lam=1.2, bif="lam", shown=6)),
    "Fig 3D": ("Time history, regime D: chaotic", _case("fig3", lam=1.16, bif="lam", shown=12)),
    "Fig 3E": ("Time history, regime E: one impact on each flank per period",
               _case("fig3", lam=3.3, bif="lam", shown=6)),
    "Fig 4": ("Impulse vs Λ, H₂/H₁ = 0.25, φ₂ = 45° (paper)", _case("fig4", lam=3.3)),
    "Fig 5": ("Impulse vs Λ, H₂/H₁ = 0.25, φ₂ = 90° (paper)", _case("fig5", lam=3.3)),
    "Fig 6": ("Impulse vs φ₂ at Λ = 1.95", _case("fig6", phi2=45.0)),
    "Fig 7": ("Strange attractor: Λ = 3.3, φ₂ = 45° (paper)",
              _case("fig7", bif="lam", periods=5000, section="absolute")),
    "Fig 8": ("Periodic, one impact per flank: Λ = 3.3, φ₂ = 90° (paper)",
              _case("fig8", bif="lam", periods=200, shown=6, section="absolute")),
}


def preset_values(state: ExplorerState, label: str) -> dict[str, Any]:
    """A preset's values for ``state``: phases converted when the page shows the core's."""
    values = dict(PRESETS[label][1])
    if state.phases == "core":
        values["phases"] = "core"
        values["phi2"] = convert_phase(values["phi2"], 2)
    return values

