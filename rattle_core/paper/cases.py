"""The paper's cases: its figures as computations, and the explorer's presets made from them.

The paper ("Influence of Multiharmonics Excitation on Rattle Noise in Automotive Gearboxes")
shows eight figures, of which only the captions survive.  This module turns each into a
:class:`PaperCase` (:data:`CASES`), serves the bifurcation diagrams (:func:`paper_sweep`, from
the shipped assets when they still match the solver), and derives from the cases the one-click
presets of the dashboard (:func:`explorer_presets`).  :mod:`rattle_core.paper.figures` draws the
figures and :mod:`rattle_core.paper.evidence` settles the phase convention.

Phase convention.  The core writes ``y = Σ h_k cos(k t − φ_k)``.  The paper's figures are
reproduced when its phases are read as ``y = Σ h_k sin(k t + φ_k)``, that is core phase
``φ'_2 = −φ_2 − 90°`` (:mod:`rattle_core.model.phases`): the paper's ``φ_2 = 45°`` is core
``−135°`` and its ``90°`` is core ``180°``.  Every case stores core parameters; axes and
titles show the paper's degrees.

Sticking erases the past (``docs/model.md``): a chaotic response that sticks leaves the wall
in the same state every time, so the Poincaré map of Figure 7 gathers points from many starts,
each up to its first stick phase (:func:`poincare_cloud`).
"""
from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any, Callable

import numpy as np

from ..analysis.vocabulary import REGIME_MEANING
from ..batch.sweep import SweepResult
from ..model.excitation import TWO_PI, excitation
from ..model.params import RattleParams
from ..model.phases import core_to_paper, paper_to_core
from ..solver.trajectory import simulate
from ..store.assets import read_asset
from ..store.cache import cached_sweep, sweep_key

#: The paper's fixed parameters: restitution, backlash (in units of H₁), H₂/H₁.
PAPER_R = 0.65
PAPER_J = 8.0
PAPER_H2 = 0.25
#: Λ range of the bifurcation diagrams (Figures 2, 4, 5).
PAPER_LAM_RANGE = (0.5, 4.0)

Progress = Callable[[int, int], Any]



def paper_params(lam: float, phi2_paper: float | None = None, h2: float = PAPER_H2,
                 r: float = PAPER_R, j: float = PAPER_J) -> RattleParams:
    """Core parameters of a paper case.

    Parameters
    ----------
    lam : float
        Λ.
    phi2_paper : float or None
        The paper's φ₂ in degrees; ``None`` for the purely harmonic excitation.
    h2, r, j : float
        H₂/H₁, restitution and backlash (the paper's values by default).
    """
    if phi2_paper is None:
        return RattleParams(lam=lam, r=r, j=j)
    return RattleParams.paper(lam, r=r, j=j, amplitudes=(1.0, h2), phases_deg=(0.0, phi2_paper))


@dataclasses.dataclass(frozen=True)
class PaperCase:
    """One figure of the paper as a computation.

    Attributes
    ----------
    key : str
        ``fig2`` … ``fig8``.
    caption : str
        The paper's caption (paper conventions).
    kind : str
        ``"sweep"`` (bifurcation diagram), ``"time"`` (time histories), ``"poincare"``, or
        ``"time+poincare"``.
    params : RattleParams
        Core parameters; for a sweep the swept parameter is overridden value by value.
    paper_phi2 : float or None
        The paper's φ₂ in degrees (None: harmonic, or φ₂ is the swept parameter).
    name : str or None
        Swept parameter (core name: ``lam`` or ``phi2``).
    values : ndarray or None
        Swept values in core units (``phi2``: core degrees).
    transient, record : int
        Unrecorded and recorded periods per value (sweeps) or per run.
    lams : tuple of float
        Λ of each panel of a time-history figure.
    x_label : str
        Axis label of the swept parameter, in the paper's terms.
    """

    key: str
    caption: str
    kind: str
    params: RattleParams
    paper_phi2: float | None = None
    name: str | None = None
    values: np.ndarray | None = dataclasses.field(default=None, compare=False, repr=False)
    transient: int = 500
    record: int = 100
    lams: tuple[float, ...] = ()
    x_label: str = "Λ"

    def axis(self, values) -> np.ndarray:
        """Swept values as the paper's axis shows them (the paper's φ₂ degrees for ``phi2``)."""
        if self.name == "phi2":
            return core_to_paper(values, 2, wrap=False)
        return np.asarray(values, dtype=np.float64)

    def sweep_settings(self) -> dict:
        """The settings a sweep of this case runs with (and is cached under)."""
        return {"transient": self.transient, "record": self.record, "mode": "fresh",
                "x0": None, "v0": 0.0}

    def cache_key(self) -> str:
        """Content key of this case's sweep (the one stored in its shipped asset)."""
        if self.kind != "sweep":
            raise ValueError(f"case {self.key!r} is a {self.kind!r} figure, not a sweep")
        return sweep_key(self.params, self.name, self.values, self.sweep_settings())


def _lam_values(n: int = 600) -> np.ndarray:
    return np.linspace(*PAPER_LAM_RANGE, n)


#: The paper's cases, by figure.  All with r = 0.65, j = 8 and (multiharmonic) H₂/H₁ = 0.25.
CASES: dict[str, PaperCase] = {
    "fig2": PaperCase(
        "fig2", "Impulses versus Λ for an excitation purely harmonic, r = 0.65 and j = 8.",
        "sweep", paper_params(1.0), None, "lam", _lam_values()),
    "fig3": PaperCase(
        "fig3", "Time response histories of the idle gear for r = 0.65 and j = 8 "
        "(regimes B, C, D and E).", "time", paper_params(1.0), None,
        lams=(1.05, 1.13, 1.16, 3.3), record=8),
    "fig4": PaperCase(
        "fig4", "Impulses versus Λ for a multiharmonics excitation φ2 = 45°, r = 0.65, j = 8.",
        "sweep", paper_params(1.0, 45.0), 45.0, "lam", _lam_values()),
    "fig5": PaperCase(
        "fig5", "Impulses versus Λ for a multiharmonics excitation φ2 = 90°, r = 0.65, j = 8.",
        "sweep", paper_params(1.0, 90.0), 90.0, "lam", _lam_values()),
    "fig6": PaperCase(
        "fig6", "Impulses versus φ2 for Λ = 1.95, r = 0.65 and j = 8.", "sweep",
        paper_params(1.95, 0.0), None, "phi2",
        paper_to_core(np.linspace(0.0, 360.0, 600), 2, wrap=False), x_label="φ2 (paper, degrees)"),
    "fig7": PaperCase(
        "fig7", "Poincaré map for a multiharmonics excitation φ2 = 45° for Λ = 3.3, "
        "r = 0.65 and j = 8.", "poincare", paper_params(3.3, 45.0), 45.0, record=4000),
    "fig8": PaperCase(
        "fig8", "Time response history (a) and Poincaré map (b) for a multiharmonics excitation "
        "φ2 = 90° for Λ = 3.3, r = 0.65 and j = 8.", "time+poincare",
        paper_params(3.3, 90.0), 90.0, record=2000, lams=(3.3,)),
}

SWEEP_CASES = tuple(k for k, c in CASES.items() if c.kind == "sweep")


def paper_sweep(key: str, use_assets: bool = True, progress: Progress | None = None,
                cancel: Callable[[], bool] | None = None,
                directory: Path | str | None = None) -> SweepResult:
    """The bifurcation diagram of a sweep case (``fig2``, ``fig4``, ``fig5``, ``fig6``).

    Served from the shipped asset when ``use_assets`` and the asset's content key equals the
    case's (same parameters, values, settings, schema and solver version); otherwise from
    the disk cache (:func:`~rattle_core.store.cache.cached_sweep`, in ``directory`` if given), which
    computes it on a miss.
    """
    try:
        case = CASES[key]
    except KeyError:
        raise ValueError(f"unknown paper case {key!r}; allowed: {', '.join(CASES)}") from None
    if case.kind != "sweep":
        raise ValueError(f"paper case {key!r} is a {case.kind!r} figure, not a sweep; "
                         f"sweeps: {', '.join(SWEEP_CASES)}")
    found = read_asset(key) if use_assets else None
    if found is not None:
        res, meta = found
        # the key says the request is the same; the arrays must say so too
        if (meta.get("key") == case.cache_key() and np.array_equal(res.values, case.values)
                and res.params.canonical() == case.params.canonical()):
            if progress is not None:
                progress(len(res.values), len(res.values))
            return res
    return cached_sweep(case.params, case.name, case.values, progress=progress, cancel=cancel,
                        directory=directory, **case.sweep_settings())


def poincare_cloud(params: RattleParams, n_points: int = 4000, skip: int = 50,
                   periods: int = 1500, max_runs: int = 200, seed: int = 0
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Stroboscopic points ``(x, ẋ)`` at ``t = 2πn`` and impact-map points of an attractor.

    Runs start from random states inside the backlash (reproducible with ``seed``).  Each run
    contributes its points after ``skip`` periods and before its first stick phase: after a
    stick the release state is always the same, so later points would only retrace one
    excursion.  Runs are added until ``n_points`` section points are gathered.

    Returns
    -------
    x, v : ndarray
        Stroboscopic section points.
    phase, impulse : ndarray
        Impact-map points ``(t mod 2π, Ĩ)`` of the same stretches.
    """
    rng = np.random.default_rng(seed)
    y0 = float(excitation(0.0, params.h, params.phi))
    xs, vs, ps, imps = [], [], [], []
    total = 0
    for _ in range(max_runs):
        tr = simulate(params, periods=periods, x0=y0 + params.j * rng.uniform(0.02, 0.98),
                      v0=rng.uniform(-2.0, 2.0))
        stop = tr.stick_intervals[0, 0] if len(tr.stick_intervals) else np.inf
        t_skip = tr.t_start + skip * TWO_PI
        keep = (tr.strobe_t >= t_skip) & (tr.strobe_t < stop)
        ikeep = (tr.impact_t >= t_skip) & (tr.impact_t < stop)
        xs.append(tr.strobe_x[keep])
        vs.append(tr.strobe_v[keep])
        ps.append(tr.impact_phase[ikeep])
        imps.append(tr.impact_impulse[ikeep])
        total += int(keep.sum())
        if total >= n_points:
            break
    return (np.concatenate(xs)[:n_points], np.concatenate(vs)[:n_points], np.concatenate(ps),
            np.concatenate(imps))


@dataclasses.dataclass(frozen=True)
class ExplorerPreset:
    """A one-click view of a paper case in the dashboard: its parameters and how to show them.

    ``view`` holds the dashboard settings that go with it: ``bif`` (the diagram's parameter,
    ``lam`` or ``phi2``), and where it matters ``shown`` (periods drawn), ``periods`` (periods
    recorded) and ``section``.
    """

    label: str
    description: str
    params: RattleParams
    view: dict


def explorer_presets() -> tuple[ExplorerPreset, ...]:
    """The dashboard's presets, one per figure and one per regime of Figure 3, from :data:`CASES`.

    A bifurcation figure is shown at a Λ inside its diagram (2.5 harmonic, 3.3 with two
    harmonics) or, for Figure 6, at its own Λ = 1.95 with the diagram swept over φ₂.
    """
    c = CASES
    out = [ExplorerPreset("Fig 2", "Impulse vs Λ, harmonic excitation",
                          c["fig2"].params.replace(lam=2.5), {"bif": "lam", "shown": 12})]
    for lam, regime in zip(c["fig3"].lams, "BCDE"):
        out.append(ExplorerPreset(f"Fig 3{regime}", f"Time history, regime {regime}: "
                                  f"{REGIME_MEANING[regime]}", c["fig3"].params.replace(lam=lam),
                                  {"bif": "lam", "shown": 12 if regime == "D" else 6}))
    for key in ("fig4", "fig5"):
        out.append(ExplorerPreset(f"Fig {key[3:]}", f"Impulse vs Λ, H₂/H₁ = {PAPER_H2:g}, "
                                  f"φ₂ = {c[key].paper_phi2:g}° (paper)",
                                  c[key].params.replace(lam=3.3), {"bif": "lam"}))
    out.append(ExplorerPreset("Fig 6", "Impulse vs φ₂ at Λ = 1.95", c["fig6"].params,
                              {"bif": "phi2"}))
    out.append(ExplorerPreset("Fig 7", "Strange attractor: Λ = 3.3, φ₂ = 45° (paper)",
                              c["fig7"].params, {"bif": "lam", "periods": 5000,
                                                 "section": "absolute"}))
    out.append(ExplorerPreset("Fig 8", "Periodic, one impact per flank: Λ = 3.3, φ₂ = 90° (paper)",
                              c["fig8"].params, {"bif": "lam", "periods": 200, "shown": 6,
                                                 "section": "absolute"}))
    return tuple(out)
