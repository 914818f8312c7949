"""What a map request may ask for: its axes and their ranges, its limits, and where it runs.

The Maps tab (:mod:`app.views.maps`) builds its requests from these. Maps run on the server's
cores, or on the Dask scheduler given on the server's command line (:func:`set_scheduler`);
no page can choose where the server connects.
"""
from __future__ import annotations

from typing import Any

AXES = {"lam": "Λ", "r": "r", "j": "j", "h2": "H₂/H₁", "phi2": "φ₂ [°]",
        "rpm": "engine speed [rpm]", "drag_torque": "drag torque C [N·m]"}
PHYSICAL = ("rpm", "drag_torque")
RANGES = {"lam": (0.5, 4.0), "r": (0.3, 0.95), "j": (2.0, 16.0), "h2": (0.0, 1.0),
          "phi2": (0.0, 360.0), "rpm": (800.0, 6000.0), "v0": (-3.0, 3.0)}
FIELDS = {"regime": "regime", "intensity": "rattle intensity Σ Ĩ² per period",
          "period": "period (forcing periods)", "lyapunov": "Lyapunov exponent",
          "stick_fraction": "stick fraction"}
MAX_POINTS = 100_000
MAX_WORK = 2e7  # points × (transient + record): about a minute on two cores
_scheduler = ""


def grid_refusal(nx: int, ny: int, periods: int) -> str | None:
    """Why a map of ``nx`` × ``ny`` points of ``periods`` periods each is refused, or None."""
    points = nx * ny
    if points > MAX_POINTS:
        return (f"the grid has {nx} × {ny} = {points} points; the allowed range is up to "
                f"{MAX_POINTS:,} points.")
    if points * periods > MAX_WORK:
        return (f"points × (transient + recorded periods) = {points * periods:.3g}; the allowed "
                f"range is up to {MAX_WORK:.0e} (fewer points or periods).")
    return None


def set_scheduler(address: str | None) -> None:
    """Where every session's maps run: ``""`` (the server's cores) or a Dask scheduler address."""
    global _scheduler
    _scheduler = address or ""


def scheduler() -> str:
    """Where maps run now (see :func:`set_scheduler`)."""
    return _scheduler


def axis_label(name: str) -> str:
    """An axis's name as the page shows it."""
    return {"x0": "x₀ at t = 0", "v0": "ẋ₀ at t = 0"}.get(name, AXES.get(name, name))


def request_key(params: Any, plan: tuple) -> str:
    """What a map depends on besides its axes; a map is stale when this changes."""
    if plan[0] == "map":
        params = params.with_value(plan[1], 1.0).with_value(plan[3], 1.0)
    elif plan[0] == "flat":
        params = params.with_value(plan[1], 1.0)
    return repr(params.canonical())
