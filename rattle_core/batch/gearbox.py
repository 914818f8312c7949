"""The verdict on a gearbox: which loose gears rattle, from which engine speed, and how loud.

:func:`verdict` runs every gear at every speed as one batch: the speeds are cut into chunks,
each chunk (all gears at a few speeds) is one task of :func:`~rattle_core.batch.executor.run_chunks`
(here, or on Dask), with progress and cancel between chunks.  A task runs its points through
the chunk runner (:func:`~rattle_core.batch.chunks.run_chunk`, one parallel kernel), classifies
them, renders each gear's rattle and measures its loudness and level, and the whole
gearbox's; it sends back one row per gear and speed.  Within a chunk the speeds' sounds run on threads (``threads``, every core by
default): rendering and loudness are compiled kernels that release the GIL, so the threads run
at once, while the chunk's own thread finds the intervals of the points that do not repeat.
Each speed's numbers come from its own sounds alone, so the verdict is the same, row for row,
on any number of threads.

The gears are incoherent sources, each heard through its own transfer path: their phases are
unrelated, so their energies add, not their pressures (adding pressures lets their ringing
cancel, and the total could be quieter than one gear).  The gearbox's ``spl_dba`` is the energy
sum of the gears' L_Aeq; its ``spl_dba_max`` the fast-weighted maximum of the summed A-weighted
energies ``Σ p_A,g²``; its loudness and sharpness come from the gears' third-octave band
intensities added before the rest of ISO 532-1
(:func:`~rattle_core.analysis.loudness.loudness_incoherent`).  Every stage after the bands
grows with the band levels, so the gearbox is never quieter than its loudest gear.

Columns of :attr:`Verdict.table` (one row per gear and speed, then one per speed with ``gear``
= :data:`GEARBOX`, the gears together):

``gear, rpm``
    The gear's name and the measured shaft's speed.
``regime``
    The regime's letter (``docs/model.md``, "Regimes"); ``A`` is permanent contact.
``impacts_per_s``
    Impacts on both flanks per second.
``intensity``
    Rattle intensity in physical units, ``Σ I² / time`` [N²·s]: the squared impulses
    ``I = Ĩ m ω H₁`` [N·s] per second.
``loudness_sone``, ``sharpness_acum``
    ISO 532-1 loudness ``N5`` and DIN 45692 sharpness of the rattle's sound over the gearbox's
    ``duration_s`` (:mod:`rattle_core.analysis.loudness`); 0 for a gear in permanent contact.
``spl_dba``, ``spl_dba_max``
    L_Aeq over that sound and L_AFmax [dB(A)] (:func:`~rattle_core.analysis.levels.level`, the
    same calibrated pressure at ``SAMPLE_RATE``).  A silent sound's level is −inf dB; the table
    holds NaN.
``onset_rpm``
    The lowest speed of the sweep at which the gear leaves permanent contact (NaN if it never
    does; the sweep's first speed if it rattles throughout).
``impacts_per_s_ci95``, ``intensity_ci95``, ``interval``
    Half-widths of 95 % intervals of the two rates, and how they were found (``interval``):
    ``exact`` for periodic motion (0); for motion that does not repeat, ``N runs``: the two
    rates and their intervals over ``ensemble_runs`` independent runs
    (:func:`~rattle_core.batch.ensemble.statistics`, each of the point's own transient and
    recorded periods), or with ``ensemble_runs=0`` ``blocks``: one run's recorded window cut
    into :data:`BLOCKS` blocks, Student's t over the block means (the single run's uncertainty,
    which understates a slow drift between attractors' regions).  The rates and intervals are
    those of the attractor the point's own run is on (:func:`own_attractor`); where the runs
    end on several, ``interval`` says ``k of N runs``.
``attractors``
    The attractors the runs ended on, with their runs (``P 4, D 4``); empty when one.
``contact_ratio``
    ``J R_d max(−θ̈_drive) / (R_b C)``: the closed-form contact boundary is where it passes 1.
``rattle_ranges``, ``share``, ``drag_Nm``, ``drag_to_quiet_Nm``, ``inertia_to_quiet_kgm2``
    Every rattle range, the share of the gearbox's sound, the drag, and the drag or inertia
    that keeps the gear quiet (:mod:`rattle_core.batch.actions`).
``target_sone``, ``margin_sone``, ``target_dba``, ``margin_dba``, ``pass``
    The target's limits, the margins and pass/fail (same module).
``lam, j``
    The dimensionless Λ and j of the point.
"""
from __future__ import annotations

import dataclasses
import math
from concurrent.futures import ThreadPoolExecutor
from typing import Any, Callable

import numpy as np

from ..analysis.levels import a_weighted, level_of_power
from ..analysis.loudness import (SAMPLE_RATE, SKIP_S, band_levels, loudness_of_levels,
                                 sum_levels)
from ..analysis.sound import render
from ..analysis.statistics import estimate
from ..analysis.vocabulary import regime_letters
from ..model.gearbox import Gearbox
from ..model.params import RattleParams, check_cancel, check_progress
from ..solver.trajectory import SOLVER_VERSION, _check_int
from .chunks import run_chunk, summary_arrays
from .ensemble import statistics
from .executor import default_threads, run_chunks
from .sweep import check_budget
from . import actions as _actions
from .actions import GEARBOX, add_columns

#: Blocks of one run's recorded window behind its 95 % intervals (``ensemble_runs=0``).
BLOCKS = 5
#: Independent runs behind the intervals of a point whose motion does not repeat.
ENSEMBLE_RUNS = 8
MAX_SPEEDS = 2000
VERDICT_VERSION = 3
COLUMNS = ["gear", "rpm", "regime", "impacts_per_s", "intensity", "loudness_sone",
           "sharpness_acum", "spl_dba", "spl_dba_max", "onset_rpm", "rattle_ranges",
           "impacts_per_s_ci95", "intensity_ci95", "interval", "attractors", "contact_ratio",
           "drag_Nm", "drag_to_quiet_Nm", "inertia_to_quiet_kgm2", "share", "target_sone",
           "margin_sone", "target_dba", "margin_dba", "pass", "lam", "j"]
#: Columns :func:`~rattle_core.batch.actions.add_columns` adds.
_ADDED = {"rattle_ranges", "drag_Nm", "drag_to_quiet_Nm", "inertia_to_quiet_kgm2", "share",
          "target_sone", "margin_sone", "target_dba", "margin_dba", "pass", "onset_rpm"}


@dataclasses.dataclass
class Verdict:
    """A gearbox's verdict over engine speed (module docstring: the columns).

    Attributes
    ----------
    gearbox : Gearbox
    rpm : ndarray
        Speeds asked for.
    table : DataFrame
        One row per gear and speed, then the gearbox rows.
    settings : dict
        transient, record, solver and verdict versions.
    cancelled, from_cache : bool
    """

    gearbox: Gearbox
    rpm: np.ndarray
    table: Any
    settings: dict
    cancelled: bool = False
    from_cache: bool = False

    def gear(self, name: str):
        """The rows of one gear (or of :data:`GEARBOX`), by speed."""
        t = self.table
        return t[t["gear"] == name].sort_values("rpm").reset_index(drop=True)

    @property
    def onsets(self) -> dict[str, float]:
        """Each gear's onset rpm (NaN: never leaves contact in the sweep)."""
        return {g.name: _onset(self.gear(g.name)) for g in self.gearbox.gears}

    @property
    def ranges(self) -> dict[str, list[tuple[float, float]]]:
        """Each gear's rattle ranges ``[(start, end), ...]`` [rpm], edges at the closed-form
        contact boundary between grid speeds."""
        return _actions.ranges(self)

    @property
    def fail_ranges(self) -> dict[str, list[tuple[float, float]]]:
        """Each gear's and the gearbox's speed ranges that fail the target (grid speeds)."""
        return _actions.failing(self)

    @property
    def ranking(self) -> list[str]:
        """Gear names, the largest contributor to the gearbox's A-weighted energy first."""
        return _actions.ranking(self)

    def drag_for_target(self, gear: str, **kw: Any) -> float:
        """The drag [N·m] to add to ``gear`` so that it meets the target at every speed, by
        bisection on verdicts of that gear (:mod:`rattle_core.batch.actions`)."""
        return _actions.drag_for_target(self, gear, verdict, **kw)

    @property
    def summaries(self) -> dict[str, str]:
        """Per gear, the drag to add or the inertia to remove that keeps it quiet."""
        return _actions.summaries(self)


def _onset(rows) -> float:
    rattles = rows["regime"].to_numpy() != "A"
    return float(rows["rpm"].to_numpy()[rattles][0]) if np.any(rattles) else math.nan


def check_rpm(rpm: Any, gearbox: Gearbox) -> np.ndarray:
    """Engine speeds of a verdict: 1 to 2000 finite, increasing values in the excitation's range."""
    try:
        r = np.asarray(rpm, dtype=np.float64).ravel()
    except (TypeError, ValueError):
        raise ValueError(f"rpm must be numbers, got {rpm!r}") from None
    if not 1 <= r.size <= MAX_SPEEDS:
        raise ValueError(f"rpm has {r.size} values; the allowed range is 1 to {MAX_SPEEDS}")
    if not np.all(np.isfinite(r)) or np.any(np.diff(r) <= 0):
        raise ValueError("rpm values must be finite and increasing")
    lo, hi = gearbox.excitation.rpm_range
    if r[0] < lo - 1e-9 or r[-1] > hi + 1e-9 or r[0] <= 0:
        raise ValueError(f"rpm from {r[0]:g} to {r[-1]:g} is outside the allowed range "
                         f"[{max(lo, 0):g}, {hi:g}] (the excitation's)")
    return r


def record_periods(gearbox: Gearbox, rpm: np.ndarray, record: int) -> int:
    """Recorded periods per point: ``record``, or more if the sound window needs them."""
    f_max = gearbox.excitation.engine_order * float(np.max(rpm)) / 60.0
    return max(int(record), int(math.ceil(gearbox.duration_s * f_max)) + 1)


def _point_rows(gearbox: Gearbox, rpm: np.ndarray) -> tuple[list, dict]:
    """Per (speed, gear) point: the physical parameters, and the chunk runner's columns."""
    phys, params = [], []
    for r in rpm:
        for g in range(len(gearbox.gears)):
            ph = gearbox.physical(g, float(r))
            try:
                params.append(ph.to_dimensionless())
            except ValueError as exc:
                raise ValueError(f"gear {gearbox.gears[g].name!r} at {r:g} rpm: {exc}") from None
            phys.append(ph)
    K = gearbox.excitation.harmonics
    cols = {"lam": np.array([p.lam for p in params]), "r": np.array([p.r for p in params]),
            "j": np.array([p.j for p in params]), "phi1": np.array([p.phases_deg[0] for p in params])}
    for k in range(2, K + 1):
        cols[f"h{k}"] = np.array([p.amplitudes[k - 1] for p in params])
        cols[f"phi{k}"] = np.array([p.phases_deg[k - 1] for p in params])
    return phys, cols


def _blocks(t: np.ndarray, values: np.ndarray, transient: int, record: int) -> np.ndarray:
    """Sums of ``values`` over :data:`BLOCKS` equal blocks of the recorded periods, per period."""
    period = np.floor(t / (2 * math.pi)).astype(np.int64) - transient
    edges = np.linspace(0, record, BLOCKS + 1)
    block = np.clip(np.searchsorted(edges, period, side="right") - 1, 0, BLOCKS - 1)
    return np.bincount(block, weights=values, minlength=BLOCKS) / np.diff(edges)


_HEARD = ("loudness_sone", "sharpness_acum", "spl_dba", "spl_dba_max")


def _spl(pa2: np.ndarray) -> Any:
    """``L_Aeq`` and ``L_AFmax`` of an A-weighted power, silence as NaN (a table's empty cell)."""
    spl = level_of_power(pa2, SAMPLE_RATE, skip_s=SKIP_S)
    return type(spl)(*(v if math.isfinite(v) else math.nan for v in (spl.spl_dba, spl.spl_dba_max)))


def own_attractor(attractors, letter: str):
    """The attractor of ``statistics`` that a point's own non-periodic run is on: the
    non-periodic one of its regime ``letter`` with most runs, else the non-periodic one with
    most runs, else the one with most runs (the attractors come largest first)."""
    for keep in (lambda a: not a.periodic and a.regime == letter, lambda a: not a.periodic,
                 lambda a: True):
        found = [a for a in attractors if keep(a)]
        if found:
            return found[0]
    raise ValueError("statistics found no attractor")


def _verdict_chunk(gearbox: Gearbox, rpm: np.ndarray, transient: int, record: int,
                   runs: int = ENSEMBLE_RUNS, threads: int | None = None,
                   points: tuple | None = None) -> dict:
    """All gears at the speeds ``rpm``: one row per point, plus the gearbox's per speed.

    The motion of all points is one parallel kernel; then the speeds' sounds (each gear's
    rattle, the gearbox's, their loudness) run on ``threads`` threads (compiled, ``nogil``
    kernels) while this thread finds the intervals of the points that do not repeat
    (``statistics`` runs its own parallel kernel).  ``points`` is :func:`_point_rows` of these
    speeds when the caller has it already."""
    phys, cols = _point_rows(gearbox, rpm) if points is None else points
    K = gearbox.excitation.harmonics
    base = RattleParams(lam=1.0, amplitudes=(1.0,) + (0.0,) * (K - 1), phases_deg=(0.0,) * K)
    n = len(phys)
    chunk = run_chunk(base, cols, np.arange(n, dtype=np.float64), transient, record, None, 0.0,
                      times=True)
    cl = summary_arrays(chunk, record)
    letters = regime_letters(cl["regime_code"])
    ends = np.cumsum(chunk["counts"])
    starts = ends - chunk["counts"]
    ng = len(gearbox.gears)
    out = {k: np.zeros(n) for k in ("impacts_per_s", "intensity", "loudness_sone",
                                     "sharpness_acum", "spl_dba", "spl_dba_max",
                                     "impacts_per_s_ci95", "intensity_ci95")}
    box = {k: np.zeros(len(rpm)) for k in out}

    def sounds(s: int) -> list[tuple[float, float, float, float]]:
        """Speed ``s``: each gear's (loudness, sharpness, L_Aeq, L_AFmax), then the gearbox's."""
        heard, levels, weighted = [], [], []
        silent = (0.0, 0.0, math.nan, math.nan)
        for i in range(s * ng, (s + 1) * ng):
            if letters[i] == "A" or ends[i] == starts[i]:
                heard.append(silent)  # permanent contact is silent
                continue
            ph = phys[i]
            sl = slice(starts[i], ends[i])
            t_s = (chunk["time"][sl] - 2 * math.pi * transient) / ph.omega
            p = gearbox.transfer_pa_per_ns * render(t_s, chunk["impulse"][sl] * ph.impulse_scale,
                                                    gearbox.duration_s, SAMPLE_RATE)
            if not np.any(p):
                heard.append(silent)
                continue
            lv = band_levels(p)
            h = loudness_of_levels(lv, p.size)
            pa2 = a_weighted(p, SAMPLE_RATE) ** 2
            spl = _spl(pa2)
            heard.append((h.loudness_sone, h.sharpness_acum, spl.spl_dba, spl.spl_dba_max))
            levels.append(lv)
            weighted.append(pa2)
        loud = [row for row in heard if not math.isnan(row[2])]
        if len(loud) > 1:
            h = loudness_of_levels(sum_levels(levels), weighted[0].size)
            spl = _spl(sum(weighted))  # incoherent gears: their A-weighted powers add
            loud = [(h.loudness_sone, h.sharpness_acum, spl.spl_dba, spl.spl_dba_max)]
        heard.append(loud[0] if loud else silent)
        return heard

    threads = default_threads() if threads is None else threads
    pool = ThreadPoolExecutor(threads) if threads > 1 else None
    try:
        pending = ([pool.submit(sounds, s) for s in range(len(rpm))] if pool is not None
                   else None)
        interval = np.full(n, "exact", dtype=object)
        seen = np.full(n, "", dtype=object)
        for i, ph in enumerate(phys):
            f = ph.frequency_hz
            scale = ph.impulse_scale
            sl = slice(starts[i], ends[i])
            t, imp = chunk["time"][sl], chunk["impulse"][sl]
            out["impacts_per_s"][i] = (cl["active_per_period"][i]
                                       + cl["reverse_per_period"][i]) * f
            out["intensity"][i] = cl["intensity"][i] * scale**2 * f
            if cl["period"][i] == 0 and t.size:
                if runs >= 2:
                    st = statistics(ph.to_dimensionless(), runs=runs, periods=record,
                                    transient=transient)
                    a = own_attractor(st.attractors, letters[i])
                    rate, energy = a.estimates["impacts_per_period"], a.estimates["intensity"]
                    if st.coexisting:
                        interval[i] = f"{len(a.runs)} of {runs} runs"
                        seen[i] = ", ".join(f"{b.regime} {len(b.runs)}" for b in st.attractors)
                    else:
                        interval[i] = f"{runs} runs"
                else:
                    rate = estimate(_blocks(t, np.ones(t.size), transient, record))
                    energy = estimate(_blocks(t, imp**2, transient, record))
                    interval[i] = "blocks"
                out["impacts_per_s"][i] = rate.value * f
                out["impacts_per_s_ci95"][i] = rate.ci95 * f
                out["intensity"][i] = energy.value * scale**2 * f
                out["intensity_ci95"][i] = energy.ci95 * scale**2 * f
        heard = ([fut.result() for fut in pending] if pool is not None
                 else [sounds(s) for s in range(len(rpm))])
    finally:
        if pool is not None:
            pool.shutdown(wait=True, cancel_futures=True)
    for s, rows in enumerate(heard):
        for g in range(ng):
            for k, key in enumerate(_HEARD):
                out[key][s * ng + g] = rows[g][k]
        box["impacts_per_s"][s] = out["impacts_per_s"][s * ng:(s + 1) * ng].sum()
        box["intensity"][s] = out["intensity"][s * ng:(s + 1) * ng].sum()
        for k, key in enumerate(_HEARD):
            box[key][s] = rows[ng][k]
    ratio = np.empty(n)
    for g in range(ng):
        ratio[g::ng] = gearbox.contact_ratio(g, rpm)
    return {"rpm": np.asarray(rpm), "regime": letters.astype(str), "ratio": ratio,
            "interval": interval, "attractors": seen,
            "lam": cols["lam"], "j": cols["j"], "status": cl["status"], **out,
            "box": box}


def verdict(gearbox: Gearbox, rpm: Any, *, transient: int = 200, record: int = 100,
            progress: Callable[[int, int], Any] | None = None,
            cancel: Callable[[], bool] | None = None, executor: Any = None,
            chunk_speeds: int | None = None, ensemble_runs: int = ENSEMBLE_RUNS,
            threads: int | None = None, target: Any = None) -> Verdict:
    """Which gears rattle, from which speed, and how loud: every gear at every speed, one batch.

    Parameters
    ----------
    gearbox : Gearbox
    rpm : sequence of float
        Engine speeds [rpm], increasing, within the excitation's range (1 to 2000 values).
    transient, record : int
        Unrecorded and recorded excitation periods per point; ``record`` grows to cover the
        sound window (``duration_s`` at the highest speed).
    progress : callable(done, total), optional
        Called after each chunk, counting points (gears × speeds).
    cancel : callable() -> bool, optional
        Polled between chunks; the speeds done are returned (``cancelled``).
    executor : dask.distributed.Client, optional
        Run the chunks on a Dask cluster.
    chunk_speeds : int, optional
        Speeds per chunk (default: about 1/10 of them, at least 2).
    ensemble_runs : int
        Independent runs behind the rates and intervals of a point whose motion does not
        repeat (0: one run, intervals from blocks of its window; module docstring).
    threads : int, optional
        Threads that render and measure a chunk's sounds, speed by speed (default
        ``NUMBA_NUM_THREADS`` or the number of cores; 1: one after the other).  The verdict is
        the same, row for row, for any number.
    target : Target, optional
        The limit curves to compare with, instead of the gearbox's own ``target``.
    """
    import pandas as pd
    if not isinstance(gearbox, Gearbox):
        raise ValueError(f"gearbox must be a Gearbox, got {type(gearbox).__name__}")
    if target is not None:
        gearbox = gearbox.replace(target=target)
    progress, cancel = check_progress(progress), check_cancel(cancel)
    r = check_rpm(rpm, gearbox)
    transient = _check_int("transient", transient, 0, 100_000)
    record = _check_int("record", record, BLOCKS, 100_000)
    record = record_periods(gearbox, r, record)
    runs = _check_int("ensemble_runs", ensemble_runs, 0, 64)
    if threads is not None:
        threads = _check_int("threads", threads, 1, 1024)
    ng = len(gearbox.gears)
    # the worst case: every point non-periodic, each run again ``runs`` times
    check_budget(r.size * ng * (transient + record) * (1 + runs),
                 "gears × speeds × (transient + record) × (1 + ensemble_runs)")
    # every point is checked before anything runs
    phys, cols = _point_rows(gearbox, r)
    if chunk_speeds is None:
        chunk_speeds = max(2, math.ceil(r.size / 10))
    chunk_speeds = _check_int("chunk_speeds", chunk_speeds, 1, MAX_SPEEDS)
    tasks = [(gearbox, r[s:s + chunk_speeds], transient, record, runs, threads,
              (phys[s * ng:(s + chunk_speeds) * ng],
               {k: v[s * ng:(s + chunk_speeds) * ng] for k, v in cols.items()}))
             for s in range(0, r.size, chunk_speeds)]
    parts, cancelled = run_chunks(_verdict_chunk, tasks, [len(t[1]) * ng for t in tasks],
                                  executor=executor, progress=progress, cancel=cancel)
    frames = []
    names = [g.name for g in gearbox.gears]
    for p in parts:
        m = p["rpm"].size
        frames.append(pd.DataFrame({
            "gear": np.tile(names, m), "rpm": np.repeat(p["rpm"], ng), "regime": p["regime"],
            **{k: p[k] for k in ("impacts_per_s", "intensity", "loudness_sone", "sharpness_acum",
                                 "spl_dba", "spl_dba_max", "impacts_per_s_ci95",
                                 "intensity_ci95")},
            "interval": p["interval"], "attractors": p["attractors"], "contact_ratio": p["ratio"],
            "lam": p["lam"], "j": p["j"]}))
        frames.append(pd.DataFrame({"gear": GEARBOX, "rpm": p["rpm"], "regime": "", **p["box"],
                                    "impacts_per_s_ci95": np.nan, "intensity_ci95": np.nan,
                                    "interval": "", "attractors": "",
                                    "contact_ratio": np.nan, "lam": np.nan, "j": np.nan}))
    table = (pd.concat(frames, ignore_index=True) if frames
             else pd.DataFrame({c: [] for c in COLUMNS if c not in _ADDED}))
    for c in ("spl_dba", "spl_dba_max"):
        # a silent sound's level is −inf; the table holds NaN, as for every missing number
        table[c] = table[c].astype(float).where(np.isfinite(table[c].astype(float)), np.nan)
    table["onset_rpm"] = np.nan
    for name in names:
        sel = table["gear"] == name
        table.loc[sel, "onset_rpm"] = _onset(table[sel].sort_values("rpm"))
    order = {n: i for i, n in enumerate(names + [GEARBOX])}
    table = table.sort_values(["gear", "rpm"], key=lambda c: c.map(order) if c.name == "gear"
                              else c).reset_index(drop=True)
    add_columns(table, gearbox)
    table = table[COLUMNS]
    settings = {"transient": transient, "record": record, "ensemble_runs": runs,
                "solver_version": SOLVER_VERSION, "verdict_version": VERDICT_VERSION}
    return Verdict(gearbox=gearbox, rpm=r, table=table, settings=settings, cancelled=cancelled)


__all__ = ["Verdict", "verdict", "GEARBOX", "COLUMNS", "check_rpm"]
