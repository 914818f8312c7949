"""Hover help for the words the page uses, quoted from ``docs/model.md``: one place for them.

Each entry of :data:`HELP` is a short title and the sentences that explain it, copied from
the specification word for word (its backticks and bold marks left out). A test finds every
sentence in ``docs/model.md``, so the page and the specification cannot drift apart: a
change of wording there fails the test until the help here follows.

:func:`tooltip` is the ``?`` icon that shows one entry when hovered.
"""
from __future__ import annotations

from typing import Any

import panel as pn

#: key → (title, sentences of docs/model.md, word for word).
HELP: dict[str, tuple[str, tuple[str, ...]]] = {
    "lam": ("Λ", (
        "Λ = m H₁ ω² / F > 0 (inertia over drag)",
        "A gear resting on the active flank stays there while R̃ > 0, so below "
        "Λ_c = 1 / max_t(−ÿ(t)) it never leaves (regime A).",
    )),
    "r": ("r", (
        "restitution r ∈ [0, 1]",
        "Impact on a flank with incoming relative velocity w = ẋ⁻ − ẏ (w < 0 on the active "
        "flank, w > 0 on the reverse one): ẋ⁺ = ẏ − r w, so Ĩ = −(1 + r) w and "
        "|Ĩ| = (1 + r)|w|.",
    )),
    "j": ("j", (
        "backlash j > 0",
        "The driving tooth (the active flank) is at y(t), the opposite tooth (the reverse "
        "flank) at y(t) + j. The gear lives in y ≤ x ≤ y + j.",
    )),
    "multipliers": ("Floquet multipliers", (
        "Floquet multipliers are the eigenvalues of the impact map's Jacobian at a periodic "
        "orbit: how much a small perturbation grows or shrinks in one turn of the orbit.",
        "The orbit is stable while every multiplier lies inside the unit circle.",
    )),
    "pd": ("period doubling (PD)", (
        "A period doubling (PD) is where a multiplier crosses −1: the orbit loses stability and "
        "an orbit of twice the period takes over.",
        "A cascade of them is a road to chaos.",
    )),
    "grazing": ("grazing", (
        "Grazing is a flight that touches a wall with zero relative velocity: an impact appears "
        "or disappears, and the impact pattern changes.",
    )),
    "sticking": ("sticking", (
        "After a plastic impact the gear sticks (moves with the wall, x = y or y + j, ẋ = ẏ) "
        "while σ R̃ > 0.",
        "It is released at the first sign change of σ R̃",
    )),
}


def help_text(key: str) -> str:
    """The help of ``key`` as one paragraph (plain text)."""
    title, sentences = HELP[key]
    body = " ".join(s if s.endswith(".") else s + "." for s in sentences)
    return f"{title}: {body}"


def tooltip(key: str, **kw: Any) -> pn.widgets.TooltipIcon:
    """A ``?`` icon showing the help of ``key`` on hover (CSS class ``help-<key>``)."""
    return pn.widgets.TooltipIcon(value=help_text(key), css_classes=[f"help-{key}"],
                                  margin=(0, 4), **kw)
