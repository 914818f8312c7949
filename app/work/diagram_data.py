"""The bifurcation diagram's data: what to sweep, where it comes from, and what to mark on it.

A :class:`Request` says which parameter is swept over which values, in the axis units the
page shows (Λ; φ₂ in the page's phase convention; engine speed in rpm) and in the core's
terms the sweep runs in. A :class:`Diagram` holds the impacts and the per-value regimes of a
sweep in axis units. The range asked for is always the whole default range, stretched to
hold the current value, so the current-value marker, the rattle-free range and the onset of
rattle are on the plot even where no impact happens.
"""
from __future__ import annotations

import dataclasses
import functools
import hashlib
import math
from typing import Any

import numpy as np

from rattle_core import RattleParams

from ..core import (TWO_PI, contact_boundary, core_phi2_to_paper, list_assets, load_asset,
                   paper_phi2_to_core, units)

#: Default ranges (axis units) and values per diagram; zoomed regions get ZOOM_VALUES.
RANGES = {"lam": (0.5, 4.0), "phi2-paper": (0.0, 360.0), "phi2-core": (-180.0, 180.0),
          "rpm": (500.0, 6000.0)}
VALUES = {"lam": 400, "phi2": 361, "rpm": 400}
ZOOM_VALUES = 300
TRANSIENT, RECORD = 300, 100


def wrap180(v: Any) -> np.ndarray:
    """Degrees wrapped to (−180, 180]."""
    w = np.mod(np.asarray(v, dtype=np.float64) + 180.0, 360.0) - 180.0
    return np.where(w == -180.0, 180.0, w)


@dataclasses.dataclass(frozen=True)
class Request:
    """A diagram to compute: ``name`` (lam, phi2, rpm) over ``axis`` values (axis units)."""

    name: str
    phases: str
    base: RattleParams
    phys: Any
    axis: tuple[float, ...]

    @property
    def key(self) -> tuple:
        """What the diagram depends on besides the swept value (it is stale when this changes)."""
        return diagram_key(self.name, self.phases, self.base, self.phys)

    def sweep_args(self) -> tuple[RattleParams, str, np.ndarray]:
        """``(base, core name, core values)`` for :func:`app.work.diagram`."""
        x = np.asarray(self.axis, dtype=np.float64)
        if self.name == "rpm":
            name, values = units.rpm_sweep(self.phys, x)
            return self.phys.to_dimensionless(), name, np.asarray(values, dtype=np.float64)
        if self.name == "phi2":
            values = paper_phi2_to_core(x) if self.phases == "paper" else x
            return self.base, "phi2", np.asarray(values, dtype=np.float64)
        return self.base, "lam", x


def diagram_key(name: str, phases: str, params: RattleParams, phys: Any) -> tuple:
    if name == "rpm":
        return (name, repr(phys.with_rpm(1.0)), repr(params.with_value("lam", 1.0).with_value("j", 1.0)))
    return (name, phases if name == "phi2" else "", repr(params.with_value(name, 1.0).canonical()))


def current_value(name: str, state: Any) -> float:
    """The current value of the swept parameter, in axis units."""
    if name == "rpm":
        return float(state.rpm)
    if name == "phi2":
        v = float(state.phi2)
        return float(np.mod(v, 360.0)) if state.phases == "paper" else float(wrap180(v))
    return float(state.lam)


def run_value(name: str, run: Any, phases: str) -> float | None:
    """Where ``run`` stands on the diagram of ``name`` (axis units, the page's convention
    ``phases``); None for engine speed when the run has no physical side."""
    if name == "rpm":
        return None if run.phys is None else float(run.phys.rpm)
    if name == "phi2":
        core = float(run.params.phases_deg[1]) if run.params.n_harmonics > 1 else 0.0
        return float(core_phi2_to_paper(core) % 360.0) if phases == "paper" else float(wrap180(core))
    return float(run.params.lam)


def full_range(name: str, phases: str, value: float) -> tuple[float, float]:
    """The default range of a diagram, stretched to hold ``value`` with a margin."""
    if name == "phi2":
        return RANGES[f"phi2-{phases}"]
    lo, hi = RANGES[name]
    return (0.8 * value if value < lo else lo), (1.25 * value if value > hi else hi)


def request(name: str, state: Any, run: Any, lo: float | None = None, hi: float | None = None,
            n: int | None = None) -> Request:
    """The diagram of ``name`` around the current run (the whole range unless ``lo``/``hi``)."""
    value = current_value(name, state)
    if lo is None or hi is None:
        lo, hi = full_range(name, state.phases, value)
    n = n or VALUES[name]
    return Request(name, state.phases, run.params, run.phys, tuple(np.linspace(lo, hi, n)))


@dataclasses.dataclass
class Diagram:
    """Impacts (``x``, ``impulse``, ``flank``) and per-value regimes (``swept``, ``regime``)."""

    name: str
    span: tuple[float, float]
    x: np.ndarray
    impulse: np.ndarray
    flank: np.ndarray
    swept: np.ndarray
    regime: np.ndarray
    source: str
    refined: list = dataclasses.field(default_factory=list)

    @functools.cached_property
    def digest(self) -> str:
        """A BLAKE2 digest of the impacts (``x``, ``impulse``, ``flank``): equal for equal data."""
        h = hashlib.blake2b(digest_size=16)
        for a in (self.x, self.impulse, self.flank):
            h.update(np.ascontiguousarray(a).data)
        return h.hexdigest()

    def merge(self, other: "Diagram") -> "Diagram":
        """This diagram with the region ``other`` covers replaced by ``other``'s finer values."""
        lo, hi = other.span
        keep = (self.x < lo) | (self.x > hi)
        keep_v = (self.swept < lo) | (self.swept > hi)
        order = np.argsort(np.concatenate([self.swept[keep_v], other.swept]), kind="stable")
        return Diagram(self.name, self.span, np.concatenate([self.x[keep], other.x]),
                       np.concatenate([self.impulse[keep], other.impulse]),
                       np.concatenate([self.flank[keep], other.flank]),
                       np.concatenate([self.swept[keep_v], other.swept])[order],
                       np.concatenate([self.regime[keep_v], other.regime])[order],
                       self.source, [*self.refined, (lo, hi)])

    def counts(self) -> str:
        """Plain words for how many values were swept and what happened at them."""
        n = len(self.swept)
        rattle = int(np.count_nonzero(np.isin(self.swept, np.unique(self.x)))) if n else 0
        quiet = n - rattle
        what = {"lam": "Λ", "phi2": "φ₂", "rpm": "engine speeds"}[self.name]
        text = (f"{n} values of {what} swept: {rattle} rattle, {quiet} without impacts "
                f"(permanent contact) · {len(self.x):,} impacts")
        if self.refined:
            text += f" · {len(self.refined)} region{'s' if len(self.refined) > 1 else ''} refined"
        return f"{text} · {self.source}"


def from_work(req: Request, out: dict[str, Any], source: str) -> Diagram:
    """A :class:`Diagram` in axis units from :func:`app.work.diagram`'s output."""
    x_core, swept_core = out["value"], out["swept"]
    if req.name == "rpm":
        _, name, _ = req.sweep_args()
        x = units.rpm_from_sweep(req.phys, name, x_core) if x_core.size else x_core
        swept = units.rpm_from_sweep(req.phys, name, swept_core) if swept_core.size else swept_core
        impulse = out["impulse"] * units.impulse_scale_from_rpm(req.phys, x) if x.size else out["impulse"]
    elif req.name == "phi2":
        conv = core_phi2_to_paper if req.phases == "paper" else wrap180
        x, swept = np.asarray(conv(x_core)), np.asarray(conv(swept_core))
        impulse = out["impulse"]
        if req.phases == "paper":
            x, swept = np.mod(x, 360.0), np.mod(swept, 360.0)
    else:
        x, swept, impulse = x_core, swept_core, out["impulse"]
    order = np.argsort(swept, kind="stable")
    span = (float(min(req.axis)), float(max(req.axis)))
    return Diagram(req.name, span, np.asarray(x, dtype=np.float64), np.asarray(impulse, dtype=np.float64),
                   np.asarray(out["flank"], dtype=np.int8), np.asarray(swept)[order],
                   np.asarray(out["regime"])[order], source)


@functools.lru_cache(maxsize=1)
def _assets() -> tuple:
    """Every shipped diagram, loaded once per process."""
    out = []
    for name in list_assets():
        res = load_asset(name)
        if res is not None:
            out.append((name, res))
    return tuple(out)


def shipped(req: Request) -> Diagram | None:
    """A shipped diagram (``assets/paper``) of exactly this request's range and parameters."""
    if req.name == "rpm" or len(req.axis) < 2:
        return None
    base, name, values = req.sweep_args()
    for asset, res in _assets():
        if res.name != name or len(res.values) < len(values):
            continue
        lo, hi = float(np.min(values)), float(np.max(values))
        if not (np.isclose(np.min(res.values), lo) and np.isclose(np.max(res.values), hi)):
            continue
        try:
            same = res.params.with_value(name, base.get(name)).canonical() == base.canonical()
        except ValueError:
            same = False
        if same:
            t, s = res.table, res.summary
            out = {"value": np.asarray(t["value"], dtype=np.float64),
                   "impulse": np.asarray(t["impulse"], dtype=np.float64),
                   "flank": np.asarray(t["flank"], dtype=np.int8),
                   "swept": np.asarray(s["value"], dtype=np.float64),
                   "regime": np.asarray(s["regime"], dtype="U5")}
            return from_work(dataclasses.replace(req, axis=tuple(res.values if name != "phi2" else
                                                                 req.axis)), out,
                             f"shipped diagram {asset} ({len(res.values)} values)")
    return None


def marks(name: str, run: Any, diagram: Diagram | None) -> dict[str, Any]:
    """Where rattle starts (Λ_c) and where chaos first appears, in axis units (None if not)."""
    onset = None
    if name in ("lam", "rpm"):
        lam_c = contact_boundary(run.params)
        if lam_c is not None and math.isfinite(lam_c) and lam_c > 0:
            if name == "lam":
                onset = float(lam_c)
            elif run.phys is not None and run.phys.excitation == "displacement":
                onset = float(units.rpm_from_lam(run.phys, lam_c))
    chaos = None
    if diagram is not None and diagram.swept.size:
        hits = diagram.swept[diagram.regime == "D"]
        chaos = float(hits.min()) if hits.size else None
    return {"onset": onset, "chaos": chaos}


def one_sided(name: str, run: Any, lo: float, hi: float, orders: int = 4) -> list[np.ndarray]:
    """The one-sided period-n impulses 2πn/Λ as (x, y) curves across the axis."""
    out = []
    if name == "lam":
        x = np.linspace(max(lo, 1e-3), max(hi, 2e-3), 200)
        lam = x
    elif name == "rpm" and run.phys is not None:
        x = np.linspace(max(lo, 1e-3), max(hi, 2e-3), 200)
        lam = units.lam_from_rpm(run.phys, x)
    else:
        x = np.array([lo, hi])
        lam = np.full(2, run.params.lam)
    scale = units.impulse_scale_from_rpm(run.phys, x) if name == "rpm" and run.phys is not None else 1.0
    for n in range(1, orders + 1):
        out.append(np.column_stack([x, TWO_PI * n / lam * scale]))
    return out
