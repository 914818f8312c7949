"""Rattle statistics with their uncertainty, and whether they depend on the noise level.

A chaotic attractor's statistics come from a finite window of one noisy run, so they scatter
from run to run; where the gear sticks often they also move with the noise level
(docs/model.md, "Noise" and "What the statistics mean").  This module turns independent runs
into honest numbers:

* :class:`Estimate`: a value with the half-width of its 95 % interval, ``t₀.₉₇₅,ₙ₋₁ s / √n``
  over ``n`` independent runs (Student's t, the runs' means being near-normal).  A periodic
  attractor's statistics are exact, and their half-width is 0.
* :func:`group_runs`: runs are grouped by the attractor they ended on (a periodic orbit, told
  apart by its stroboscopic points, or a non-periodic regime), so coexisting attractors are
  reported side by side and never averaged together.  Noise blurs a periodic orbit's points
  by about 20–80 ε (measured on the C and E orbits), so an ensemble recognises orbits with the
  tolerance :func:`period_tolerance`; an orbit is exact (half-width 0) only when it repeats
  within the classification's own tolerance.
* :func:`sensitivity_verdict`: whether the statistics differ between noise levels by more than
  their intervals allow (Cochran's homogeneity test, see its docstring).
* :func:`attractor_verdicts`: the same verdict for each coexisting attractor on its own, with
  its runs and estimates at every level, as plain data.

The runs themselves are made by :mod:`rattle_core.batch.ensemble`.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from .classify import PERIOD_TOL, REGIME_LETTERS

#: The statistics every ensemble estimates, and the words users read for them.
STATISTICS = {
    "impacts_per_period": "impacts per period",
    "mean_active_impulse": "mean active impulse",
    "mean_reverse_impulse": "mean reverse impulse",
    "intensity": "rattle intensity",
}
#: Largest relative tolerance :func:`period_tolerance` grants a noisy orbit: beyond it the
#: noise blurs an orbit into a cloud, which is reported as non-periodic.
MAX_NOISY_PERIOD_TOL = 1e-2
#: Family-wise false-alarm rate of the noise-sensitivity test (over all statistics at once).
SENSITIVITY_ALPHA = 0.01


@dataclasses.dataclass(frozen=True)
class Estimate:
    """A statistic's value and the half-width of its 95 % interval (0 when it is exact)."""

    value: float
    ci95: float
    n: int = 1

    @property
    def low(self) -> float:
        return self.value - self.ci95

    @property
    def high(self) -> float:
        return self.value + self.ci95

    def __str__(self) -> str:
        if self.ci95 == 0.0:
            return f"{self.value:.6g} (exact)"
        if not math.isfinite(self.ci95):
            return f"{self.value:.4g} ± ?"
        digits = max(1, 1 - int(math.floor(math.log10(self.ci95)))) if self.ci95 > 0 else 4
        return f"{self.value:.{digits}f} ± {self.ci95:.{digits}f}"


def period_tolerance(noise: float) -> float:
    """Relative tolerance of the period test at a noise level: ``PERIOD_TOL``, or 200 ε (the
    blur of the C and E orbits is 20–80 ε), at most :data:`MAX_NOISY_PERIOD_TOL`."""
    return max(PERIOD_TOL, min(200.0 * noise, MAX_NOISY_PERIOD_TOL))


def t_quantile(n: int) -> float:
    """Student's t quantile t₀.₉₇₅ with ``n − 1`` degrees of freedom (``inf`` for n < 2)."""
    if n < 2:
        return math.inf
    # scipy.special, not scipy.stats: the dashboard calls this on its first run, and
    # scipy.stats costs most of a second to import
    from scipy.special import stdtrit
    return float(stdtrit(n - 1, 0.975))


def estimate(values, exact: bool = False) -> Estimate:
    """The mean of independent per-run values with its 95 % half-width.

    ``exact``: the runs sit on one periodic orbit, whose statistics do not scatter; the
    half-width is then 0 (the runs agree to rounding and the noise's own size).
    """
    v = np.asarray(values, dtype=np.float64)
    v = v[np.isfinite(v)]
    n = int(v.size)
    if n == 0:
        return Estimate(math.nan, math.nan, 0)
    mean = float(np.mean(v))
    if exact:
        return Estimate(mean, 0.0, n)
    if n < 2:
        return Estimate(mean, math.inf, n)
    return Estimate(mean, t_quantile(n) * float(np.std(v, ddof=1)) / math.sqrt(n), n)


def per_run_values(summary: dict) -> dict[str, np.ndarray]:
    """The four statistics of each run, from a classification dict (``classify_batch``)."""
    return {
        "impacts_per_period": summary["active_per_period"] + summary["reverse_per_period"],
        "mean_active_impulse": summary["mean_impulse_active"],
        "mean_reverse_impulse": summary["mean_impulse_reverse"],
        "intensity": summary["intensity"],
    }


@dataclasses.dataclass(frozen=True)
class Attractor:
    """The runs of an ensemble that ended on one attractor, and its statistics."""

    label: str
    regime: str
    period: int
    runs: tuple[int, ...]
    estimates: dict

    @property
    def periodic(self) -> bool:
        return self.period > 0


def _orbit_points(x: np.ndarray, v: np.ndarray, period: int) -> np.ndarray:
    """The last ``period`` stroboscopic points, in a canonical order (start-phase free)."""
    pts = np.column_stack([x[-period:], v[-period:]])
    return pts[np.lexsort((pts[:, 1], pts[:, 0]))]


def group_runs(summary: dict, strobe_x: np.ndarray, strobe_v: np.ndarray, j: float,
               exact: np.ndarray | None = None, period_tol: float = PERIOD_TOL) -> list[Attractor]:
    """Group runs by the attractor they ended on; each group gets its own estimates.

    ``summary`` classifies the runs with the relative tolerance ``period_tol``.  Periodic runs
    share an attractor when their periods and stroboscopic points agree within
    ``10 period_tol (1 + j)``; non-periodic runs are grouped by regime letter.  A periodic
    group's estimates are exact (half-width 0) when every run in it is ``exact`` (periodic
    within the classification's own tolerance); otherwise they carry the runs' scatter.
    Groups come largest first.
    """
    values = per_run_values(summary)
    n = len(summary["regime"])
    exact = np.zeros(n, np.bool_) if exact is None else np.asarray(exact, np.bool_)
    tol = 10 * period_tol * (1.0 + j)
    groups: list[tuple[str, int, np.ndarray | None, list[int]]] = []
    for i in range(n):
        letter = REGIME_LETTERS[int(summary["regime"][i])]
        period = int(summary["period"][i])
        pts = _orbit_points(strobe_x[i], strobe_v[i], period) if period > 0 else None
        for g in groups:
            if g[0] == letter and g[1] == period and (
                    pts is None or np.max(np.abs(g[2] - pts)) <= tol):
                g[3].append(i)
                break
        else:
            groups.append((letter, period, pts, [i]))
    out = []
    for letter, period, _, runs in sorted(groups, key=lambda g: -len(g[3])):
        idx = np.asarray(runs)
        is_exact = period > 0 and bool(np.all(exact[idx]))
        est = {k: estimate(values[k][idx], exact=is_exact) for k in STATISTICS}
        kind = f"period {period}" if period > 0 else (
            "chaotic" if letter == "D" else "non-periodic")
        out.append(Attractor(label=f"{letter} ({kind})", regime=letter, period=period,
                             runs=tuple(int(r) for r in runs), estimates=est))
    return out


def sensitivity_verdict(rows: list[dict]) -> tuple[bool, list[str]]:
    """Whether statistics differ between noise levels by more than their intervals allow.

    ``rows``: one dict per level, with ``noise``, ``attractor`` (the main attractor's label)
    and an :class:`Estimate` per statistic.  The answer is yes when

    * the main attractor differs between levels (periodic at one, chaotic at another, or
      another period), or
    * for some statistic, Cochran's homogeneity statistic ``Q = Σ wᵢ (vᵢ − v̄)²`` with
      ``wᵢ = 1/seᵢ²`` (``seᵢ`` the standard error behind each interval, ``v̄`` the weighted mean)
      exceeds the χ² quantile with ``levels − 1`` degrees of freedom at
      ``SENSITIVITY_ALPHA / 4``: a Bonferroni split of a 1 % family-wise false alarm over the
      four statistics.  An exact (periodic) value at noise ε is known to ``1e-9 + 100 ε``
      relative, the orbit's own shift under that noise, which stands in for its standard error
      (even from one run).  A noisy value from one run has no interval: it weighs nothing and
      its level is not counted, and a statistic with fewer than two weighed levels is not
      tested.

    Returns ``(sensitive, reasons)``, each reason a sentence naming the statistic.
    """
    from scipy.special import chdtri
    reasons: list[str] = []
    if len({r["attractor"] for r in rows}) > 1:
        reasons.append("the attractor changes with the noise level: " + ", ".join(
            f"{r['attractor']} at {r['noise']:g}" for r in rows))
    else:
        level = SENSITIVITY_ALPHA / len(STATISTICS)
        for key, words in STATISTICS.items():
            est = [r[key] for r in rows if math.isfinite(r[key].value)]
            if len(est) < 2:
                continue
            noise = np.array([r["noise"] for r in rows if math.isfinite(r[key].value)])
            v = np.array([e.value for e in est])
            # an exact value (one run or many) is known to the floor below; one noisy run alone
            # has no interval, so it weighs nothing
            se = np.array([0.0 if e.ci95 == 0.0 else e.ci95 / t_quantile(e.n) if e.n >= 2
                           else math.inf for e in est])
            se = np.maximum(se, (1e-9 + 100.0 * noise) * np.maximum(1.0, np.abs(v)))
            w = 1.0 / se ** 2
            if np.count_nonzero(w) < 2:
                continue
            mean = float(np.sum(w * v) / np.sum(w))
            q = float(np.sum(w * (v - mean) ** 2))
            differ = q > chdtri(np.count_nonzero(w) - 1, level)
            if differ:
                reasons.append(f"{words} {np.min(v):.3g}–{np.max(v):.3g} over noise "
                               f"{rows[0]['noise']:g}…{rows[-1]['noise']:g}")
    return bool(reasons), reasons


def attractor_verdicts(levels, per_level) -> list[dict]:
    """Each attractor of a noise-sensitivity check, followed across the levels, with its verdict.

    ``levels``: the noise levels; ``per_level``: for each level, the :class:`Attractor` s its
    runs reached (largest first, as :func:`group_runs` returns them).  An attractor is the same
    at two levels when its label is (the ``k``-th group of one label at a level is matched with
    the ``k``-th at another, their order being by runs).  Each attractor's statistics are
    compared across the levels that reach it by :func:`sensitivity_verdict`; one that some
    levels do not reach is noise-sensitive too, since whether a run ends on it then depends on
    the noise.

    Returns one dict per attractor, in order of first appearance (the first level's largest
    first): ``label``, ``regime``, ``period``, ``runs`` (runs on it at each level, 0 where not
    reached), ``estimates`` (per statistic, ``[value, ci95]`` at each level, NaN where not
    reached), ``sensitive`` and ``reasons``.  Plain data, so it crosses process boundaries.
    """
    levels = [float(v) for v in levels]
    if len(per_level) != len(levels):
        raise ValueError(f"per_level has {len(per_level)} entries; levels has {len(levels)}")
    found: dict[tuple[str, int], dict] = {}
    for li, groups in enumerate(per_level):
        seen: dict[str, int] = {}
        for a in groups:
            k = seen.get(a.label, 0)
            seen[a.label] = k + 1
            entry = found.setdefault((a.label, k), {
                "label": a.label, "regime": a.regime, "period": a.period,
                "runs": [0] * len(levels), "found": [None] * len(levels)})
            entry["runs"][li] = len(a.runs)
            entry["found"][li] = a
    out = []
    for entry in found.values():
        present = [(lv, a) for lv, a in zip(levels, entry.pop("found")) if a is not None]
        rows = [{"noise": lv, "attractor": a.label, **a.estimates} for lv, a in present]
        sensitive, reasons = sensitivity_verdict(rows)
        missing = [lv for lv, n in zip(levels, entry["runs"]) if n == 0]
        if missing:
            sensitive = True
            reasons.insert(0, "reached at noise " + ", ".join(f"{lv:g}" for lv, _ in present)
                           + " but not at " + ", ".join(f"{lv:g}" for lv in missing))
        nan = [math.nan, math.nan]
        entry["estimates"] = {
            k: [[a.estimates[k].value, a.estimates[k].ci95] if a is not None else nan
                for a in (dict(present).get(lv) for lv in levels)] for k in STATISTICS}
        entry.update(sensitive=bool(sensitive), reasons=list(reasons))
        out.append(entry)
    return out


def batch_means(tr, classification=None, blocks: int = 10) -> dict[str, Estimate]:
    """The four statistics of one run, each with a 95 % interval from its batch means.

    The recorded window is cut into ``blocks`` equal spans of whole periods; the statistics of
    each span are near-independent for a chaotic run (its correlations die out within a few
    periods), so ``t₀.₉₇₅,ₙ₋₁ s/√n`` over the spans is the run's own uncertainty.  A periodic
    run's statistics are exact (half-width 0).  Sweeps, maps and the dashboard's metrics use
    this single-run interval; :func:`~rattle_core.batch.ensemble.statistics` measures the
    scatter between independent runs instead.
    """
    from .classify import classify
    cls = classification if classification is not None else classify(tr)
    whole = {
        "impacts_per_period": cls.impacts_per_period,
        "mean_active_impulse": cls.mean_impulse_active,
        "mean_reverse_impulse": cls.mean_impulse_reverse,
        "intensity": cls.intensity,
    }
    n_periods = int(round(tr.periods))
    blocks = min(int(blocks), n_periods)
    if cls.period > 0 or blocks < 2:
        return {k: Estimate(float(v), 0.0 if cls.period > 0 else math.inf, 1)
                for k, v in whole.items()}
    edges = tr.t_start + (tr.t_end - tr.t_start) * np.arange(blocks + 1) / blocks
    which = np.clip(np.searchsorted(edges, tr.impact_t, side="right") - 1, 0, blocks - 1)
    per = n_periods / blocks
    vals: dict[str, list[float]] = {k: [] for k in STATISTICS}
    imp, fl = np.abs(tr.impact_impulse), tr.impact_flank
    for b in range(blocks):
        sel = which == b
        act, rev = imp[sel & (fl == 1)], imp[sel & (fl == -1)]
        vals["impacts_per_period"].append(np.count_nonzero(sel) / per)
        vals["mean_active_impulse"].append(act.mean() if act.size else math.nan)
        vals["mean_reverse_impulse"].append(rev.mean() if rev.size else math.nan)
        vals["intensity"].append(float(np.sum(tr.impact_impulse[sel] ** 2)) / per)
    out = {}
    for k, v in vals.items():
        e = estimate(v)
        out[k] = Estimate(float(whole[k]), e.ci95, e.n)
    return out
