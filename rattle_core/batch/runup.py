"""A gearbox's run-up, replayed, heard and measured; and set against the quasi-steady verdict.

:func:`gearbox_runup` replays every gear of a gearbox through the same linear run-up (or
run-down) of the measured shaft (:func:`rattle_core.solver.runup.replay`, each gear's drag at
each instant's speed), one gear per thread (the kernels release the GIL), and measures it:

Impacts
    Every impact of every gear: ``t_s, rpm, gear, flank, impulse_Ns``.
Rattle intervals
    A gear rattles from an impact until a gap: two consecutive impacts further apart than
    :data:`GAP_PERIODS` periods of the forcing's fundamental, taken at the mean speed between
    them (``60 / (engine_order · rpm)`` s), end an interval; the next impact starts the next.
    Each interval is given by its first and last impact, in s and rpm, with its impact count.
Sound
    Each gear's impulses ring the housing (:func:`rattle_core.analysis.sound.render`) and reach
    the listener through the gearbox's transfer [Pa per N·s]: its sound pressure [Pa] at
    48 kHz.  The gearbox's sound is the sum of the gears' pressures (what one hears).
Loudness and level over the run
    The gears are incoherent sources, so their energies add, not their pressures, as in the
    verdict: ``N(t)`` is ISO 532-1 on the sum of the gears' third-octave band intensities
    (:func:`~rattle_core.analysis.loudness.loudness_incoherent`), and ``L_AF(t)`` [dB(A)] the
    fast-weighted level (125 ms) of the sum of their A-weighted energies
    (:func:`~rattle_core.analysis.levels.fast_level_series`), both every 2 ms and against the
    run's rpm at that time.  Each gear's own ``N(t)`` is kept too.

:func:`compare` sets a run-up (and optionally the run-down over the same speeds, for hysteresis)
against the quasi-steady verdict on a round grid of the same range (:func:`verdict_grid`):

* per gear, the onset on the run, the lowest speed at which it hits a tooth (the first impact of
  a run-up, the last of a run-down), against the verdict's onset, its first rattling grid
  speed.  The quasi-steady answer holds when they differ by at most one grid step;
* the loudness against rpm: the run's ``N5`` over the stretch of the run whose speed lies within
  half a grid step of each grid speed, against the verdict's ``N5`` there.  It holds where they
  differ by at most :data:`LOUDNESS_TOL_REL` of the larger, or :data:`LOUDNESS_TOL_SONE`,
  whichever is more;
* a short text saying, per gear and for the gearbox, where it holds and where it does not.
"""
from __future__ import annotations

import dataclasses
import math
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import numpy as np

from ..analysis.levels import fast_level_series
from ..analysis.loudness import (SAMPLE_RATE, SKIP_S, band_levels, loudness_of_levels,
                                 sum_levels)
from ..analysis.sound import render
from ..model.gearbox import Gearbox
from ..model.target import fail_ranges
from ..solver.angle_wall import FilteredAngle, filter_angle
from ..solver.runup import check_run, measured_window, replay, replay_angle
from .executor import default_threads
from .gearbox import GEARBOX, Verdict

#: A gap longer than this many forcing periods (at the gap's mean speed) ends a rattle interval.
GAP_PERIODS = 5.0
#: Grid step [rpm] of the verdict a run is compared with.
GRID_STEP_RPM = 50.0
#: Loudness tolerance of the comparison: relative to the larger of the two ...
LOUDNESS_TOL_REL = 0.25
#: ... or this many sone, whichever is more.
LOUDNESS_TOL_SONE = 1.0
#: Time step of N(t) and L_AF(t) [s].
SERIES_STEP_S = 0.002

INTERVAL_COLUMNS = ["gear", "start_s", "end_s", "start_rpm", "end_rpm", "impacts"]


@dataclasses.dataclass(frozen=True, eq=False)
class GearboxRunup:
    """Every gear of a gearbox over one run (module docstring: what each part is).

    Attributes
    ----------
    gearbox : Gearbox
    rpm_from, rpm_to, duration_s : float
    replays : dict
        Gear name → :class:`~rattle_core.solver.runup.RunupReplay`.
    pressure_pa : ndarray or None
        The gearbox's sound pressure [Pa] at :data:`SAMPLE_RATE` (None: run without sound).
    time_s, rpm_t : ndarray
        Times [s] of ``N(t)`` and ``L_AF(t)`` and the run's speed then [rpm].
    loudness_t, level_dba_t : ndarray
        The gearbox's ``N(t)`` [sone] and ``L_AF(t)`` [dB(A)].
    gear_loudness_t : dict
        Gear name → its own ``N(t)`` [sone] (zeros for a silent gear).
    """

    gearbox: Gearbox
    rpm_from: float
    rpm_to: float
    duration_s: float
    replays: dict
    pressure_pa: np.ndarray | None = None
    time_s: np.ndarray | None = None
    rpm_t: np.ndarray | None = None
    loudness_t: np.ndarray | None = None
    level_dba_t: np.ndarray | None = None
    gear_loudness_t: dict | None = None
    #: the driving tooth's motion: "orders" (the order reconstruction) or "angle" (the measured
    #: angle, low-pass filtered at ``cutoff_hz``)
    wall: str = "orders"
    cutoff_hz: float | None = None
    #: mean shaft speed [rpm] of time from the start, for a run driven by the measured angle
    mean_rpm: Any = None

    @property
    def sample_rate(self) -> int:
        return SAMPLE_RATE

    @property
    def run_down(self) -> bool:
        return self.rpm_to < self.rpm_from

    def rpm_at(self, t_s) -> np.ndarray:
        """The run's mean shaft speed [rpm] at times ``t_s`` [s]."""
        t = np.asarray(t_s, dtype=np.float64)
        if self.wall == "angle":
            # the measurement's own speed: its function, or the stored series read back
            if self.mean_rpm is not None:
                return np.asarray(self.mean_rpm(t), dtype=np.float64)
            return np.interp(t, self.time_s, self.rpm_t)
        return self.rpm_from + (self.rpm_to - self.rpm_from) * t / self.duration_s

    @property
    def impacts(self):
        """One row per impact of every gear, by time: ``t_s, rpm, gear, flank, impulse_Ns``."""
        import pandas as pd
        table = pd.concat([r.to_frame() for r in self.replays.values()], ignore_index=True)
        return table.sort_values("t_s", kind="stable").reset_index(drop=True)

    @property
    def intervals(self):
        """Each gear's rattle intervals (module docstring: the rule): ``gear, start_s, end_s,
        start_rpm, end_rpm, impacts``, by gear then time."""
        import pandas as pd
        rows = []
        eo = self.gearbox.excitation.engine_order
        for name, r in self.replays.items():
            for a, b, n in rattle_intervals(r.impact_t, r.impact_rpm, eo):
                rows.append((name, r.impact_t[a], r.impact_t[b], r.impact_rpm[a],
                             r.impact_rpm[b], n))
        return pd.DataFrame(rows, columns=INTERVAL_COLUMNS)

    @property
    def onsets(self) -> dict[str, float]:
        """Gear → the lowest speed [rpm] at which it hits a tooth on the run (NaN: never)."""
        return {n: float(r.impact_rpm.min()) if r.impact_rpm.size else math.nan
                for n, r in self.replays.items()}

    @property
    def calibration_pa(self) -> float:
        """Pa per full scale of the normalised sound (``max |p| / 0.99``; 0 for silence)."""
        from ..analysis.sound import PEAK
        if self.pressure_pa is None:
            return 0.0
        return float(np.max(np.abs(self.pressure_pa))) / PEAK if self.pressure_pa.size else 0.0


def rattle_intervals(t_s: np.ndarray, rpm: np.ndarray, engine_order: float,
                     gap_periods: float = GAP_PERIODS) -> list[tuple[int, int, int]]:
    """Rattle intervals of one gear's impacts: ``(first, last, count)`` index triples.

    Two consecutive impacts further apart than ``gap_periods · 60 / (engine_order · rpm)`` s,
    ``rpm`` the mean of their speeds, belong to different intervals.
    """
    t = np.asarray(t_s, dtype=np.float64)
    if t.size == 0:
        return []
    r = np.asarray(rpm, dtype=np.float64)
    limit = gap_periods * 60.0 / (engine_order * 0.5 * (r[:-1] + r[1:]))
    breaks = np.nonzero(np.diff(t) > limit)[0]
    first = np.concatenate([[0], breaks + 1])
    last = np.concatenate([breaks, [t.size - 1]])
    return [(int(a), int(b), int(b - a + 1)) for a, b in zip(first, last)]


def _gear_task(gearbox: Gearbox, gi: int, rpm_from: float, rpm_to: float, duration_s: float,
               sound: bool, angle: FilteredAngle | None = None,
               window: tuple[float, float] | None = None):
    """One gear: its replay; with ``sound``, its pressure [Pa], band levels and own N(t)."""
    if angle is None:
        rr = replay(gearbox, gi, rpm_from, rpm_to, duration_s)
    else:
        rr = replay_angle(gearbox, gi, angle, *window)
    if not sound:
        return rr, None, None, None
    p = gearbox.transfer_pa_per_ns * render(rr.impact_t, rr.impact_impulse, duration_s,
                                            SAMPLE_RATE)
    if not np.any(p):
        return rr, p, None, None
    lv = band_levels(p)
    return rr, p, lv, loudness_of_levels(lv, p.size).loudness_t


def gearbox_runup(gearbox: Gearbox, rpm_from: float, rpm_to: float, duration_s: float | None,
                  *, sound: bool = True, threads: int | None = None,
                  angle: FilteredAngle | None = None) -> GearboxRunup:
    """Every gear of ``gearbox`` over a linear run from ``rpm_from`` to ``rpm_to`` in
    ``duration_s`` seconds, with its sound, ``N(t)`` and ``L_AF(t)`` (module docstring).

    Parameters
    ----------
    gearbox : Gearbox
    rpm_from, rpm_to : float
        Speeds at the start and end [rpm], inside the measurement; ``rpm_to < rpm_from`` is a
        run-down.
    duration_s : float
        Length of the run [s]; with ``sound``, at least 0.1 s (ISO 532-1's shortest signal).
    sound : bool
        Render and measure the sound (False: impacts and intervals only).
    threads : int, optional
        Gears replayed at once (default: the cores, at most one per gear).
    angle : FilteredAngle, optional
        Drive the gears by the measured angle itself, filtered
        (:func:`measured_angle`), instead of the order reconstruction: the run is then the
        measurement's own stretch from ``rpm_from`` to ``rpm_to``
        (:func:`~rattle_core.solver.runup.measured_window`), its duration and its speed over
        time the measurement's, and ``duration_s`` must be None.

    Raises
    ------
    ValueError
        A speed outside the measurement, a run over the period budget (before anything runs).
    """
    if not isinstance(gearbox, Gearbox):
        raise TypeError(f"gearbox must be a Gearbox, got {type(gearbox).__name__}")
    window = None
    if angle is not None:
        if duration_s is not None:
            raise ValueError(f"duration_s = {duration_s!r}: a run driven by the measured angle "
                             "lasts as long as the measurement takes between the two speeds; "
                             "give duration_s=None")
        window = measured_window(angle, rpm_from, rpm_to)
        duration_s = window[1] - window[0]
    else:
        check_run(gearbox, rpm_from, rpm_to, duration_s)
    rpm_from, rpm_to, duration_s = float(rpm_from), float(rpm_to), float(duration_s)
    if sound and duration_s < 0.1:
        raise ValueError(f"duration_s = {duration_s!r} must be at least 0.1 s for the sound's "
                         f"loudness (ISO 532-1)")
    ng = len(gearbox.gears)
    threads = min(ng, default_threads()) if threads is None else int(threads)
    if threads < 1:
        raise ValueError(f"threads = {threads!r} must be at least 1")
    args = [(gearbox, gi, rpm_from, rpm_to, duration_s, sound, angle, window)
            for gi in range(ng)]
    if threads > 1:
        with ThreadPoolExecutor(threads) as pool:
            parts = list(pool.map(lambda a: _gear_task(*a), args))
    else:
        parts = [_gear_task(*a) for a in args]
    names = [g.name for g in gearbox.gears]
    replays = {n: p[0] for n, p in zip(names, parts)}
    wall = {} if angle is None else {"wall": "angle", "cutoff_hz": angle.cutoff_hz,
                                     "mean_rpm": replays[names[0]].runup.mean_rpm}
    if not sound:
        return GearboxRunup(gearbox, rpm_from, rpm_to, duration_s, replays, **wall)
    pressures = [p[1] for p in parts]
    total = np.sum(pressures, axis=0)
    n = total.size
    heard = [p[2] for p in parts if p[2] is not None]
    t_lv, level_t = fast_level_series(np.stack(pressures), SAMPLE_RATE, step_s=SERIES_STEP_S)
    del pressures
    if heard:
        box = loudness_of_levels(sum_levels(heard), n)
        t_n, n_t = box.time_s, box.loudness_t
    else:
        t_n = np.arange(n // 96) * SERIES_STEP_S
        n_t = np.zeros(t_n.size)
    gear_n = {name: (p[3] if p[3] is not None else np.zeros(t_n.size)) for name, p in
              zip(names, parts)}
    # the level is sampled from the first sample, the loudness on ISO 532-1's own grid: both
    # every 2 ms; the level is read on the loudness's times
    level_on_n = np.interp(t_n, t_lv, level_t)
    rpm_t = (rpm_from + (rpm_to - rpm_from) * t_n / duration_s if angle is None
             else wall["mean_rpm"](t_n))
    return GearboxRunup(gearbox, rpm_from, rpm_to, duration_s, replays, pressure_pa=total,
                        time_s=t_n, rpm_t=rpm_t, loudness_t=n_t, level_dba_t=level_on_n,
                        gear_loudness_t=gear_n, **wall)


def measured_angle(path, cutoff_hz: float, engine_order: float = 2.0, **options: Any
                   ) -> FilteredAngle:
    """The shaft angle of a measurement file (:func:`~rattle_core.measure.measurement.
    read_measurement` with its reading ``options``), by :func:`angle_of_samples`."""
    from ..measure.measurement import read_measurement
    meas = read_measurement(path, **options)
    return angle_of_samples(meas.time_s, meas.speed_rpm, cutoff_hz, engine_order,
                            meas.detected.source)


def angle_of_samples(time_s, speed_rpm, cutoff_hz: float, engine_order: float = 2.0,
                     source: str = "the measurement") -> FilteredAngle:
    """A measured shaft speed [rpm] at ``time_s`` [s], put on a uniform grid as the order
    analysis puts it, split into its mean rotation and its fluctuation low-pass filtered at
    ``cutoff_hz`` (:func:`~rattle_core.solver.angle_wall.filter_angle`); messages name
    ``source`` and its sampling rate."""
    from ..measure.sampling import regularise
    t, w, _, _ = regularise(np.asarray(time_s, dtype=np.float64),
                            np.asarray(speed_rpm, dtype=np.float64), lambda i: f"sample {i}", None)
    if t.size < 2:
        raise ValueError(f"{source}: too few samples for a measured angle")
    rate = 1.0 / float(np.median(np.diff(t)))
    try:
        return filter_angle(t, cutoff_hz=cutoff_hz, speed_rpm=w, engine_order=engine_order)
    except ValueError as exc:
        raise ValueError(f"{source} (sampled at {rate:.6g} Hz): {exc}") from None


def verdict_grid(rpm_from: float, rpm_to: float, step: float = GRID_STEP_RPM) -> np.ndarray:
    """The round grid of speeds [rpm] (multiples of ``step``) inside the run's range."""
    lo, hi = min(rpm_from, rpm_to), max(rpm_from, rpm_to)
    if not (math.isfinite(step) and step > 0):
        raise ValueError(f"step = {step!r} must be a positive number of rpm")
    grid = np.arange(math.ceil(lo / step - 1e-9), math.floor(hi / step + 1e-9) + 1) * step
    if grid.size < 2:
        raise ValueError(f"the run's range [{lo:g}, {hi:g}] rpm holds fewer than 2 multiples of "
                         f"the grid step {step:g} rpm; widen it")
    return grid


def _window_n5(run: GearboxRunup, n_t: np.ndarray, grid: np.ndarray, step: float) -> np.ndarray:
    """The run's N5 [sone] over the stretch within half a step of each grid speed."""
    out = np.full(grid.size, np.nan)
    keep = run.time_s >= SKIP_S
    for i, v in enumerate(grid):
        sel = keep & (np.abs(run.rpm_t - v) <= 0.5 * step)
        if np.any(sel):
            out[i] = float(np.percentile(n_t[sel], 95))
    return out


@dataclasses.dataclass(frozen=True, eq=False)
class Comparison:
    """A run against the quasi-steady verdict (module docstring: the rules).

    Attributes
    ----------
    onsets : DataFrame
        Per gear: ``onset_run_rpm``, ``onset_rundown_rpm`` (NaN without a run-down),
        ``onset_verdict_rpm``, ``onset_holds`` (the run's within one grid step of the verdict's).
    loudness : DataFrame
        Per gear and for the gearbox (``gear = "gearbox"``), per grid speed: ``rpm``,
        ``run_sone``, ``verdict_sone``, ``holds``.
    text : str
        Where the quasi-steady answer holds and where it does not.
    step : float
        The grid step [rpm].
    """

    onsets: Any
    loudness: Any
    text: str
    step: float


def compare(run: GearboxRunup, verdict: Verdict, rundown: GearboxRunup | None = None, *,
            tol_rel: float = LOUDNESS_TOL_REL, tol_sone: float = LOUDNESS_TOL_SONE) -> Comparison:
    """The run (with its sound) against ``verdict`` on a round grid of the same speeds, and the
    run-down's onset beside the run-up's (module docstring)."""
    import pandas as pd
    if run.time_s is None:
        raise ValueError("run must be measured with its sound (gearbox_runup(..., sound=True))")
    names = [g.name for g in run.gearbox.gears]
    if [g.name for g in verdict.gearbox.gears] != names:
        raise ValueError(f"verdict is of the gears {[g.name for g in verdict.gearbox.gears]}, "
                         f"the run of {names}; compare the same gearbox")
    if rundown is not None and list(rundown.replays) != names:
        raise ValueError(f"rundown is of the gears {list(rundown.replays)}, the run of {names}")
    grid = np.asarray(verdict.rpm, dtype=np.float64)
    step = float(np.median(np.diff(grid))) if grid.size > 1 else GRID_STEP_RPM
    v_onsets = verdict.onsets
    r_onsets = run.onsets
    d_onsets = rundown.onsets if rundown is not None else {}
    rows, lrows, lines = [], [], []
    for name in names + [GEARBOX]:
        rows_v = verdict.gear(name)
        v_n = np.interp(grid, rows_v["rpm"].to_numpy(), rows_v["loudness_sone"].to_numpy())
        n_t = run.loudness_t if name == GEARBOX else run.gear_loudness_t[name]
        r_n = _window_n5(run, n_t, grid, step)
        tol = np.maximum(tol_rel * np.fmax(r_n, v_n), tol_sone)
        holds = ~(np.abs(r_n - v_n) > tol)
        lrows.append(pd.DataFrame({"gear": name, "rpm": grid, "run_sone": r_n,
                                   "verdict_sone": v_n, "holds": holds}))
        bad = fail_ranges(grid, holds)
        loud = ("loudness within tolerance at every grid speed" if not bad else
                "loudness differs beyond tolerance at " +
                ", ".join(f"{a:g}–{b:g} rpm" if b > a else f"{a:g} rpm" for a, b in bad))
        if name == GEARBOX:
            lines.append(f"gearbox: {loud}.")
            continue
        o_r, o_v = r_onsets[name], v_onsets[name]
        o_d = d_onsets.get(name, math.nan)
        both_nan = math.isnan(o_r) and math.isnan(o_v)
        ok = both_nan or (abs(o_r - o_v) <= step + 1e-9)
        rows.append((name, o_r, o_d, o_v, ok))
        fmt = lambda x: "never" if math.isnan(x) else f"{x:.0f} rpm"  # noqa: E731
        onset = f"onset {fmt(o_r)} on the run"
        if rundown is not None:
            onset += f", {fmt(o_d)} on the run-down"
        onset += f", {fmt(o_v)} in the verdict"
        verdict_word = ("holds" if ok else
                        f"does not hold (more than one {step:g}-rpm step apart)")
        hyst = ""
        if rundown is not None and not (math.isnan(o_r) or math.isnan(o_d)):
            diff = o_r - o_d
            hyst = (f"; hysteresis: the onset moves by {diff:+.0f} rpm between up and down"
                    if abs(diff) > step else "; no hysteresis beyond one grid step")
        lines.append(f"{name}: {onset}: the quasi-steady onset {verdict_word}{hyst}; {loud}.")
    onsets = pd.DataFrame(rows, columns=["gear", "onset_run_rpm", "onset_rundown_rpm",
                                         "onset_verdict_rpm", "onset_holds"])
    return Comparison(onsets=onsets, loudness=pd.concat(lrows, ignore_index=True),
                      text="\n".join(lines), step=step)


__all__ = ["GearboxRunup", "gearbox_runup", "measured_angle", "angle_of_samples",
           "rattle_intervals", "verdict_grid", "compare",
           "Comparison", "GAP_PERIODS", "GRID_STEP_RPM", "LOUDNESS_TOL_REL",
           "LOUDNESS_TOL_SONE", "INTERVAL_COLUMNS"]
