"""Ensembles of independent runs: rattle statistics with intervals, and noise sensitivity.

:func:`statistics` runs one parameter set ``runs`` times, each with its own noise seed and its
own start inside the backlash, and reports each statistic with its 95 % interval per attractor
reached (:mod:`rattle_core.analysis.statistics`).  :func:`noise_sensitivity` does that at
several noise levels and says whether the answer depends on the level.  All runs of a request
go through the chunk runner in one batch (parallel over cores, or on Dask).
"""
from __future__ import annotations

import dataclasses
from typing import Any, Callable, Sequence

import numpy as np

from ..analysis.statistics import (STATISTICS, Attractor, Estimate, group_runs,
                                   period_tolerance, sensitivity_verdict)
from ..model.excitation import excitation
from ..model.params import NOISE_RANGE, RattleParams, check_cancel, check_progress, check_range
from ..solver import kernel as solver
from ..solver.noise import MAX_SEED
from ..solver.trajectory import SOLVER_VERSION, _check_int
from .chunks import run_chunk, summary_arrays
from .executor import run_chunks
from .sweep import check_budget

#: Levels :func:`noise_sensitivity` compares unless told otherwise.
DEFAULT_LEVELS = (1e-12, 1e-10, 1e-8, 1e-6, 1e-4)
MAX_RUNS = 1000
MAX_LEVELS = 20


@dataclasses.dataclass(frozen=True)
class Statistics:
    """Rattle statistics of one parameter set over independent runs.

    ``impacts_per_period``, ``mean_active_impulse``, ``mean_reverse_impulse`` and
    ``intensity`` are :class:`~rattle_core.analysis.statistics.Estimate` s (``.value``,
    ``.ci95``) of the attractor most runs ended on; ``attractors`` lists every attractor
    reached, with its runs and its own estimates, so coexisting attractors are never averaged.
    """

    params: RattleParams
    attractors: tuple[Attractor, ...]
    settings: dict

    @property
    def main(self) -> Attractor:
        return self.attractors[0]

    @property
    def coexisting(self) -> bool:
        return len(self.attractors) > 1

    @property
    def periodic(self) -> bool:
        return self.main.periodic

    @property
    def impacts_per_period(self) -> Estimate:
        return self.main.estimates["impacts_per_period"]

    @property
    def mean_active_impulse(self) -> Estimate:
        return self.main.estimates["mean_active_impulse"]

    @property
    def mean_reverse_impulse(self) -> Estimate:
        return self.main.estimates["mean_reverse_impulse"]

    @property
    def intensity(self) -> Estimate:
        return self.main.estimates["intensity"]

    def table(self):
        """One row per attractor: its label, runs, and each statistic's value and ci95."""
        import pandas as pd
        rows = []
        for a in self.attractors:
            row = {"noise": self.params.noise, "attractor": a.label, "runs": len(a.runs),
                   "run_ids": " ".join(map(str, a.runs))}
            for k in STATISTICS:
                row[k] = a.estimates[k].value
                row[k + "_ci95"] = a.estimates[k].ci95
            rows.append(row)
        return pd.DataFrame(rows)

    def __str__(self) -> str:
        n = self.settings["runs"]
        lines = []
        for a in self.attractors:
            lines.append(f"{a.label}: {len(a.runs)} of {n} runs")
            lines += [f"  {words}: {a.estimates[k]}" for k, words in STATISTICS.items()]
        return "\n".join(lines)


@dataclasses.dataclass(frozen=True)
class NoiseSensitivity:
    """Statistics at several noise levels, and whether they depend on the level.

    ``table`` has one row per level: the noise, the main attractor, how many runs reached it,
    and each statistic with its ``_ci95``.  ``sensitive`` and ``reasons`` come from
    :func:`~rattle_core.analysis.statistics.sensitivity_verdict`.
    """

    params: RattleParams
    levels: tuple[float, ...]
    results: tuple[Statistics, ...]
    sensitive: bool
    reasons: tuple[str, ...]

    @property
    def table(self):
        import pandas as pd
        rows = []
        for level, res in zip(self.levels, self.results):
            row = {"noise": level, "attractor": res.main.label, "runs_on_it": len(res.main.runs),
                   "attractors": len(res.attractors)}
            for k in STATISTICS:
                row[k] = res.main.estimates[k].value
                row[k + "_ci95"] = res.main.estimates[k].ci95
            rows.append(row)
        return pd.DataFrame(rows)

    def describe(self) -> str:
        """One line for a badge: what depends on the noise, or that nothing does."""
        span = f"{self.levels[0]:g}…{self.levels[-1]:g}"
        if not self.sensitive:
            return f"not noise-sensitive over noise {span}"
        return "noise-sensitive: " + "; ".join(self.reasons)


def _check_runs(runs, periods, transient) -> tuple[int, int, int]:
    runs = _check_int("runs", runs, 2, MAX_RUNS)
    periods = _check_int("periods", periods, 1, 1_000_000)
    transient = _check_int("transient", transient, 0, 1_000_000)
    return runs, periods, transient


def _ensemble(params: RattleParams, levels: Sequence[float], runs: int, periods: int,
              transient: int, seed: int, executor: Any, progress, cancel) -> list[Statistics]:
    """Every level × run in one batch; the runs of a level are told apart by seed and start."""
    if not isinstance(params, RattleParams):
        raise ValueError(f"params must be a RattleParams, got {type(params).__name__}")
    nl = len(levels)
    check_budget(nl * runs * (periods + transient), "levels × runs × (periods + transient)")
    y0 = float(excitation(0.0, params.h, params.phi))
    # starts spread evenly over the backlash, at the driving tooth's speed
    frac = (np.arange(runs) + 0.5) / runs
    x0 = np.tile(y0 + frac * params.j, nl)
    v0 = np.full(nl * runs, float(excitation(0.0, params.h, params.phi, 1)))
    noise = np.repeat(np.asarray(levels, dtype=np.float64), runs)
    seeds = seed + np.arange(nl * runs, dtype=np.int64)
    rows = np.arange(nl * runs, dtype=np.float64)
    per_task = max(1, min(nl * runs, 16))
    tasks, sizes = [], []
    for s in range(0, nl * runs, per_task):
        sl = slice(s, s + per_task)
        tasks.append((params, {"noise": noise[sl]}, rows[sl], transient, periods, x0[sl], v0[sl],
                      solver.MAX_IMPACTS_PER_PERIOD, seeds[sl]))
        sizes.append(len(rows[sl]))
    chunks, cancelled = run_chunks(run_chunk, tasks, sizes, executor=executor,
                                   progress=progress, cancel=cancel)
    if cancelled:
        raise InterruptedError("the ensemble was cancelled")
    settings = {"runs": runs, "periods": periods, "transient": transient, "seed": seed,
                "solver_version": SOLVER_VERSION}
    out = []
    for li, level in enumerate(levels):
        parts = _rows(chunks, per_task, li * runs, (li + 1) * runs)
        tol = period_tolerance(float(level))
        summary = summary_arrays(parts, periods, period_tol=tol)
        exact = summary_arrays(parts, periods)["period"] > 0
        if np.any(summary["status"] != 0):
            raise RuntimeError(f"a run at noise {level:g} stopped at a solver limit "
                               f"(status {int(summary['status'].max())}); raise v_stick")
        groups = group_runs(summary, parts["str_x"], parts["str_v"], params.j, exact, tol)
        out.append(Statistics(params=params.replace(noise=float(level)),
                              attractors=tuple(groups), settings=dict(settings)))
    return out


def _rows(chunks: list[dict], per_task: int, start: int, stop: int) -> dict:
    """Rows ``start:stop`` of the batch, gathered across chunks, in the chunk runner's form."""
    keys = ("counts", "status", "lyap", "stick", "str_x", "str_v", "rounding", "loop_amp",
            "kicks", "j")
    sel = {k: [] for k in keys}
    imp = {"impulse": [], "flank": []}
    for ci, c in enumerate(chunks):
        lo, hi = max(start - ci * per_task, 0), min(stop - ci * per_task, len(c["counts"]))
        if lo >= hi:
            continue
        offsets = np.concatenate([[0], np.cumsum(c["counts"])])
        for k in keys:
            sel[k].append(np.asarray(c[k])[lo:hi])
        imp["impulse"].append(c["impulse"][offsets[lo]:offsets[hi]])
        imp["flank"].append(c["flank"][offsets[lo]:offsets[hi]])
    out = {k: np.concatenate(v) for k, v in sel.items()}
    out.update({k: np.concatenate(v) for k, v in imp.items()})
    return out


def statistics(params: RattleParams, *, runs: int = 8, periods: int = 4000,
               transient: int = 500, seed: int = 0, executor: Any = None,
               progress: Callable[[int, int], Any] | None = None,
               cancel: Callable[[], bool] | None = None) -> Statistics:
    """Rattle statistics with 95 % intervals, from ``runs`` independent runs.

    Run ``i`` starts at ``x₀ = y(0) + j (i + ½)/runs`` with the tooth's speed and noise seed
    ``seed + i``; each records ``periods`` forcing periods after ``transient``.  Each
    statistic's value is the mean over the runs on the main attractor, and ``ci95`` the
    half-width ``t₀.₉₇₅,ₙ₋₁ s/√n`` of its 95 % interval (0 on a periodic orbit, whose
    statistics are exact).  The cost is ``runs × (periods + transient)`` forcing periods,
    within the sweeps' period budget.

    Parameters
    ----------
    params : RattleParams
        Its ``noise`` is the level the runs use.
    runs : int
        Independent runs, in [2, 1000].
    periods, transient : int
        Recorded and unrecorded forcing periods per run.
    seed : int
        First noise seed; runs use ``seed, seed + 1, …``.
    executor, progress, cancel
        As for :func:`~rattle_core.batch.sweep.sweep`; a cancelled ensemble raises
        ``InterruptedError``.
    """
    runs, periods, transient = _check_runs(runs, periods, transient)
    seed = _check_int("seed", seed, 0, MAX_SEED - 100_000)
    progress, cancel = check_progress(progress), check_cancel(cancel)
    return _ensemble(params, [params.noise], runs, periods, transient, seed, executor,
                     progress, cancel)[0]


def noise_sensitivity(params: RattleParams, levels: Sequence[float] = DEFAULT_LEVELS, *,
                      runs: int = 8, periods: int = 4000, transient: int = 500, seed: int = 0,
                      executor: Any = None, progress: Callable[[int, int], Any] | None = None,
                      cancel: Callable[[], bool] | None = None) -> NoiseSensitivity:
    """Statistics at each noise level in ``levels``, and whether they depend on it.

    Every level runs the same ``runs`` starts and seeds, so only the noise level differs.
    ``.sensitive`` is decided by
    :func:`~rattle_core.analysis.statistics.sensitivity_verdict`: a change of attractor, or a
    statistic whose values differ by more than their intervals allow (a homogeneity test at a
    1 % family-wise false-alarm rate).  Cost: ``len(levels)`` times that of
    :func:`statistics`.
    """
    progress, cancel = check_progress(progress), check_cancel(cancel)
    if isinstance(levels, (str, bytes)) or np.isscalar(levels):
        raise ValueError(f"levels must be a sequence of noise levels in [0, 0.5], got {levels!r}")
    levels = [check_range(f"levels[{i}]", v, *NOISE_RANGE) for i, v in enumerate(levels)]
    if not 2 <= len(levels) <= MAX_LEVELS:
        raise ValueError(f"levels has {len(levels)} entries; the allowed range is 2 to {MAX_LEVELS}")
    levels = sorted(levels)
    runs, periods, transient = _check_runs(runs, periods, transient)
    seed = _check_int("seed", seed, 0, MAX_SEED - 100_000)
    results = _ensemble(params, levels, runs, periods, transient, seed, executor, progress,
                        cancel)
    rows = [{"noise": lv, "attractor": res.main.label, **res.main.estimates}
            for lv, res in zip(levels, results)]
    sensitive, reasons = sensitivity_verdict(rows)
    return NoiseSensitivity(params=params, levels=tuple(levels), results=tuple(results),
                            sensitive=sensitive, reasons=tuple(reasons))
