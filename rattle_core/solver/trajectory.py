"""``simulate`` and the :class:`Trajectory` it returns: impacts, stick phases, strobe samples.

A trajectory is piecewise analytic, so it is stored as its segments (start time, kind, initial
state) and can be sampled exactly at any time with :meth:`Trajectory.sample`: a parabola in
flight, the wall's own motion while stuck.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from . import kernel as solver
from .noise import MAX_SEED, _seed, user_seed
from ..model.excitation import TWO_PI, excitation
from ..model.params import RattleParams, check_bool, check_int, check_range

SOLVER_VERSION = "1.3.0"
#: Largest number of forcing periods (transient + recorded) one call may run.
MAX_PERIODS = 2_000_000
#: Largest |t0|.  The kernel runs on (period index, phase), but a trajectory reports absolute
#: times, and beyond this a double's spacing (1.2e-10 at 1e6) times the walls' speed would
#: move a sampled gear visibly through a tooth; later periods are reached with ``transient``.
MAX_T0 = 1.0e6


class SolverError(RuntimeError):
    """A run stopped at a limit (runaway chatter, root-search budget) instead of hanging."""


@dataclasses.dataclass(frozen=True)
class Trajectory:
    """One simulated run. Times are dimensionless (ω t); positions are in units of H₁.

    Attributes
    ----------
    impact_t, impact_phase : ndarray
        Impact times and their phases ``t mod 2π``.
    impact_impulse : ndarray
        Signed impulse ``Ĩ = ẋ⁺ − ẋ⁻`` (eq. 11): > 0 on the active flank, < 0 on the reverse.
    impact_flank : ndarray of int8
        +1 active flank (``x = y``), −1 reverse flank (``x = y + j``).
    impact_w : ndarray
        Incoming relative velocity ``w = ẋ⁻ − ẏ``; ``|Ĩ| = (1 + r)|w|``.
    strobe_t, strobe_x, strobe_v : ndarray
        Stroboscopic samples at ``t = 2π n + strobe_phase``.
    seg_t, seg_kind, seg_x, seg_v : ndarray
        Segments: start time, kind (0 flight, +1 stuck active, −1 stuck reverse), state at start.
    rounding_decided : bool
        Some capture in the recorded window ended an excursion that amplified perturbations
        beyond ``1e10`` (``solver.LOG_ROUNDING``): double precision alone does not decide which
        loop the exact model follows (docs/model.md, "Sticking erases the past"); with
        ``params.noise > 0`` the noise decides it, and the statistics depend on its level.
    loop_amplification : float
        log10 of the largest release-to-capture amplification in the recorded window (``-inf``
        when no capture follows an impact).
    noise_kicks : int
        Rebounds in the whole run whose restitution was scattered (``params.noise > 0``); 0
        means the run is the exact, unperturbed model.
    """

    params: RattleParams
    t_start: float
    t_end: float
    strobe_phase: float
    impact_t: np.ndarray
    impact_phase: np.ndarray
    impact_impulse: np.ndarray
    impact_flank: np.ndarray
    impact_w: np.ndarray
    strobe_t: np.ndarray
    strobe_x: np.ndarray
    strobe_v: np.ndarray
    seg_t: np.ndarray
    seg_kind: np.ndarray
    seg_x: np.ndarray
    seg_v: np.ndarray
    final_state: tuple
    lyapunov_sum: float
    lyapunov_time: float
    stick_time: float
    n_stick_phases: int
    settings: dict
    rounding_decided: bool = False
    loop_amplification: float = -math.inf
    noise_kicks: int = 0

    @property
    def periods(self) -> float:
        return (self.t_end - self.t_start) / TWO_PI

    @property
    def stick_intervals(self) -> np.ndarray:
        """(n, 2) array of [start, end] times of permanent contact within the window."""
        ends = np.append(self.seg_t[1:], self.t_end)
        mask = self.seg_kind != 0
        out = np.column_stack([np.maximum(self.seg_t[mask], self.t_start), ends[mask]])
        return out.reshape(-1, 2)

    @property
    def stick_flank(self) -> np.ndarray:
        """Flank (+1 active, −1 reverse) of each row of :attr:`stick_intervals`."""
        return self.seg_kind[self.seg_kind != 0].astype(np.int8)

    @property
    def lyapunov(self) -> float:
        """Largest Lyapunov exponent per unit dimensionless time (NaN if not computed).

        Measured on the excursions between stick phases that last at least
        ``solver.MIN_EXCURSION_PERIODS`` periods: a stick phase collapses every perturbation,
        so the periods that end in sticking and the short excursions are left out.  ``-inf``
        when nothing is left (the gear sticks at least every 20 periods).
        """
        if not self.settings.get("lyapunov") or self.lyapunov_time <= 0:
            return math.nan
        return self.lyapunov_sum / self.lyapunov_time

    def walls(self, t) -> tuple[np.ndarray, np.ndarray]:
        """Active and reverse wall positions ``y(t)`` and ``y(t) + j``."""
        y = excitation(t, self.params.h, self.params.phi)
        return y, y + self.params.j

    def sample(self, t) -> tuple[np.ndarray, np.ndarray]:
        """Exact position and velocity at times ``t`` (within ``[t_start, t_end]``).

        Flight: ``x = x₀ + v₀ s − s²/(2Λ)``; stuck: ``x = y`` or ``y + j``, ``ẋ = ẏ``.
        """
        t = np.asarray(t, dtype=np.float64)
        if t.size and (np.nanmin(t) < self.t_start - 1e-9 or np.nanmax(t) > self.t_end + 1e-9):
            raise ValueError(f"sample times must lie in the simulated window "
                             f"[{self.t_start:g}, {self.t_end:g}]")
        if len(self.seg_t) == 0:
            raise ValueError("this trajectory was run without segment recording")
        idx = np.clip(np.searchsorted(self.seg_t, t, side="right") - 1, 0, len(self.seg_t) - 1)
        kind = self.seg_kind[idx]
        s = t - self.seg_t[idx]
        lam = self.params.lam
        x = self.seg_x[idx] + self.seg_v[idx] * s - 0.5 * s * s / lam
        v = self.seg_v[idx] - s / lam
        stuck = kind != 0
        if np.any(stuck):
            ts = t[stuck]
            y = excitation(ts, self.params.h, self.params.phi)
            x[stuck] = y + np.where(kind[stuck] == -1, self.params.j, 0.0)
            v[stuck] = excitation(ts, self.params.h, self.params.phi, 1)
        return x, v

    def strobe_relative(self) -> tuple[np.ndarray, np.ndarray]:
        """Stroboscopic samples in relative form ``(x − y, ẋ − ẏ)``."""
        y = excitation(self.strobe_t, self.params.h, self.params.phi)
        yd = excitation(self.strobe_t, self.params.h, self.params.phi, 1)
        return self.strobe_x - y, self.strobe_v - yd


_check_int = check_int  # the name the batch layer imports


def simulate(params: RattleParams, periods: int = 500, x0: float | None = None, v0: float = 0.0,
             strobe_phase: float = 0.0, t0: float = 0.0, transient: int = 0,
             lyapunov: bool = False, record_segments: bool = True,
             max_impacts_per_period: int = solver.MAX_IMPACTS_PER_PERIOD,
             seed: int | None = None) -> Trajectory:
    """Simulate the idle gear exactly for ``transient + periods`` forcing periods.

    Parameters
    ----------
    params : RattleParams
    periods : int
        Recorded forcing periods (each 2π long), in [1, 2e6].
    x0, v0 : float
        Initial position and velocity at ``t0``; ``x0=None`` starts mid-backlash,
        ``x0 = y(t0) + j/2``.  ``x0`` must lie in ``[y(t0), y(t0) + j]``.
    strobe_phase : float
        θ of the stroboscopic section ``t = 2π n + θ`` (radians, reduced mod 2π).
    t0 : float
        Start time, in [-1e6, 1e6] (:data:`MAX_T0`; start later with ``transient``).
    transient : int
        Periods run first and not recorded.
    lyapunov : bool
        Also propagate the tangent dynamics (see :attr:`Trajectory.lyapunov`).
    record_segments : bool
        Keep the segments needed by :meth:`Trajectory.sample`.
    max_impacts_per_period : int
        Runaway limit: more impacts than this within one period raises :class:`SolverError`.
    seed : int or None
        The noise stream (``params.noise``, the restitution's relative scatter at every
        rebound), an int in [0, 2**63 − 1].  ``None`` (default) derives it from the inputs, so
        a run is reproducible; different seeds give independent runs.  Without noise
        (``params.noise == 0``) the model is strictly deterministic and
        :attr:`Trajectory.rounding_decided` says when its loop is not resolvable.
    """
    if not isinstance(params, RattleParams):
        raise ValueError(f"params must be a RattleParams, got {type(params).__name__}")
    periods = _check_int("periods", periods, 1, MAX_PERIODS)
    transient = _check_int("transient", transient, 0, MAX_PERIODS)
    if periods + transient > MAX_PERIODS:
        raise ValueError(f"periods + transient = {periods + transient} is outside the allowed range "
                         f"[1, {MAX_PERIODS}]")
    max_impacts_per_period = _check_int("max_impacts_per_period", max_impacts_per_period, 1, 10**7)
    if seed is not None:
        if isinstance(seed, (bool, np.bool_)) or not isinstance(seed, (int, np.integer)):
            raise ValueError(f"seed must be a whole number in [0, {MAX_SEED}] or None, got {seed!r}")
        if not 0 <= int(seed) <= MAX_SEED:
            raise ValueError(f"seed = {seed!r} is outside the allowed range [0, {MAX_SEED}]")
    lyapunov = check_bool("lyapunov", lyapunov)
    record_segments = check_bool("record_segments", record_segments)
    t0 = check_range("t0", t0, -MAX_T0, MAX_T0)
    theta = check_range("strobe_phase", strobe_phase, -1e6, 1e6) % TWO_PI
    n0 = math.floor(t0 / TWO_PI)
    tau0 = t0 - n0 * TWO_PI
    if tau0 >= TWO_PI:
        n0, tau0 = n0 + 1, 0.0
    y_t0 = float(excitation(tau0, params.h, params.phi))
    if x0 is None:
        x0 = y_t0 + 0.5 * params.j
    x0 = check_range("x0", x0, y_t0 - 1e-12, y_t0 + params.j + 1e-12)
    x0 = min(max(x0, y_t0), y_t0 + params.j)
    v0 = check_range("v0", v0, -1e6, 1e6)

    eps = params.noise
    stream = np.uint64(user_seed(int(seed)) if seed is not None else
                       _seed(params.lam, params.r, params.j, params.h, params.phi,
                             params.v_stick, n0, tau0, x0, v0, eps))
    cap_imp = 4 * periods + 64
    cap_seg = (6 * (periods + transient) + 64) if record_segments else 0
    h = params.h
    phi = params.phi
    while True:
        imp_t = np.empty(cap_imp)
        imp_tau = np.empty(cap_imp)
        imp_I = np.empty(cap_imp)
        imp_w = np.empty(cap_imp)
        imp_flank = np.empty(cap_imp, dtype=np.int8)
        seg_t = np.empty(cap_seg)
        seg_kind = np.empty(cap_seg, dtype=np.int8)
        seg_x = np.empty(cap_seg)
        seg_v = np.empty(cap_seg)
        str_x = np.empty(periods)
        str_v = np.empty(periods)
        out = solver._integrate(params.lam, params.r, params.j, h, phi, params.v_stick,
                                n0, tau0, x0, v0, periods + transient, transient, theta,
                                max_impacts_per_period, lyapunov, eps, stream,
                                imp_t, imp_tau, imp_I, imp_w, imp_flank,
                                seg_t, seg_kind, seg_x, seg_v, str_x, str_v)
        status = out[0]
        if status == solver.OVERFLOW_IMPACTS:
            cap_imp *= 4
            continue
        if status == solver.OVERFLOW_SEGMENTS:
            cap_seg *= 4
            continue
        break
    if status == solver.RUNAWAY:
        raise SolverError(f"runaway: more than max_impacts_per_period = {max_impacts_per_period} "
                          f"impacts within one forcing period (near t = {out[4] * TWO_PI + out[5]:.6g}); "
                          f"raise v_stick (now {params.v_stick:g}) or the limit")
    if status == solver.STALL:
        raise SolverError(f"the event search exceeded its iteration budget near "
                          f"t = {out[4] * TWO_PI + out[5]:.6g}; parameters {params}")
    (_, n_imp, n_seg, n_str, n_f, tau_f, x_f, v_f, mode_f, lsum, ltime, stime, nstick,
     rounding, loop_amp, kicks) = out
    t_start = (n0 + transient) * TWO_PI + tau0
    strobe_t = _strobe_times(n0 + transient, tau0, theta, n_str)
    return Trajectory(
        params=params, t_start=t_start, t_end=(n0 + transient + periods) * TWO_PI + tau0,
        strobe_phase=theta,
        impact_t=imp_t[:n_imp].copy(), impact_phase=imp_tau[:n_imp].copy(),
        impact_impulse=imp_I[:n_imp].copy(), impact_flank=imp_flank[:n_imp].copy(),
        impact_w=imp_w[:n_imp].copy(),
        strobe_t=strobe_t, strobe_x=str_x[:n_str].copy(), strobe_v=str_v[:n_str].copy(),
        seg_t=seg_t[:n_seg].copy(), seg_kind=seg_kind[:n_seg].copy(),
        seg_x=seg_x[:n_seg].copy(), seg_v=seg_v[:n_seg].copy(),
        final_state=(n_f * TWO_PI + tau_f, x_f, v_f, int(mode_f)),
        lyapunov_sum=float(lsum), lyapunov_time=float(ltime), stick_time=float(stime),
        n_stick_phases=int(nstick),
        settings={"periods": periods, "transient": transient, "x0": x0, "v0": v0, "t0": t0,
                  "lyapunov": bool(lyapunov), "noise": eps, "seed": seed,
                  "solver_version": SOLVER_VERSION},
        rounding_decided=bool(rounding), loop_amplification=float(loop_amp) / math.log(10.0),
        noise_kicks=int(kicks),
    )


def _strobe_times(n_rec: int, tau_rec: float, theta: float, count: int) -> np.ndarray:
    first = n_rec if theta >= tau_rec else n_rec + 1
    return (first + np.arange(count)) * TWO_PI + theta
