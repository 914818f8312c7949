"""Order analysis of a measured shaft speed: each engine order's amplitude and phase per rpm bin.

Input
    The instantaneous speed of the measured shaft, ``speed_rpm`` against ``time_s``, steady or
    during a run-up or run-down; a file is read by :mod:`rattle_core.measure.measurement`
    (layout sniffed, columns recognised, pulses, a time window).  Irregular steps are resampled
    to a uniform grid (:mod:`rattle_core.measure.sampling`).  An order is reported in the rpm
    bins where the median step gives at least :data:`MIN_SAMPLES_PER_CYCLE` samples per cycle
    of it at the bin's top speed, and is NaN in the others (:attr:`OrderMap.notices` says where);
    :meth:`OrderMap.at` and :meth:`OrderMap.check_covers` refuse a speed where it is NaN.
Phase convention
    The shaft angle is ``ψ(t) + θ(t)``: ``ψ`` is the mean shaft angle [rad], zero at the file's
    first sample, and the fluctuation is

        ``θ(t) = Σ_k θ_k cos(k ψ − φ_k)``,

    with ``k`` the engine order (cycles per shaft revolution).  Its angular acceleration is
    ``α_k cos(k ψ − φ_k + 180°)`` with ``α_k = θ_k (k Ω)²``, ``Ω = 2π rpm / 60``.  This is the
    convention of :mod:`rattle_core.model.units` once ``ψ = Ω t``: the model's harmonic ``n``
    of a fundamental at engine order ``k₁`` is engine order ``n k₁``, and its phase is ``φ_{n k₁}``
    (:meth:`OrderMap.harmonics`).
Method (order tracking)
    1. The speed is integrated to the angle ``A(t)`` (Simpson's rule, ``A = 0`` at the start).
    2. The speed is resampled uniformly in angle (cubic spline, as densely as the file is
       sampled on average).
    3. Each sample is put in the rpm bin of its speed averaged over one revolution; bins are
       ``rpm_step`` wide and centred on multiples of it.
    4. In each bin, the speed against angle is fitted by least squares: a smooth trend ``T(A)``
       (a quadratic per contiguous stretch: a visit of the bin, gaps and pieces of under one
       revolution included) and, for every half order up to twice the highest
       analysed order and every order asked for, ``T(A)(c_k cos kA + s_k sin kA)``; the
       speed's order ``k`` is ``dθ/dt = −θ_k k Ω sin(kψ − φ_k)``, so
       ``θ_k = hypot(c_k, s_k) / k`` and ``φ_k = atan2(s_k, c_k) + 90°``.  Fitting every half
       order keeps the cycle-to-cycle variation of a four-stroke engine (energy at half
       orders) out of the orders asked for.
    5. ``A`` differs from ``ψ`` by ``θ(t) − θ(0)``; the constant ``θ(0)`` shifts every phase by
       ``k θ(0)`` and is taken out (twice, since it depends on the phases).  The relative phase
       ``φ₄ − 2φ₂`` does not depend on it.
    The bin's ``rpm`` is the mean speed of its samples, and ``α_k`` is computed at that speed.
Cost
    Time and memory are linear in the samples: the file is parsed by pandas' C reader, every
    pass goes :data:`BLOCK_ROWS` samples at a time through compiled kernels, and each bin's
    least squares sums its normal equations block by block, so no design matrix exists whole.
    A million samples take under 2 CPU-seconds and about 350 MB beside the interpreter
    (``benchmarks/bench_orders.py``).  An analysis reports progress and can be cancelled
    (``progress``, ``cancel`` of :meth:`OrderMap.from_csv`).
Refusals
    A file is read whole and checked before anything is computed; a bad one raises
    ``ValueError`` naming the line at fault: missing columns, text or NaN where a number
    belongs, time not increasing, a gap (a step over :data:`GAP_FACTOR` times the median step),
    too few samples per cycle of every order asked for, fewer than :data:`MIN_REVOLUTIONS`
    revolutions in a bin between others, more than :data:`MAX_ROWS` rows or
    :data:`MAX_BYTES` bytes.  Bins at either end of the speed range with fewer revolutions are
    left out (a run-up starts and ends part-way through a bin).
"""
from __future__ import annotations

import dataclasses
import math
import os
from pathlib import Path
from typing import Any, Callable

import numpy as np
from numba import njit

from ..checks import RPM_RANGE, check_range
from .measurement import read_measurement
from .pulses import PULSES_PER_CYCLE, averaging_gain
from .read import MAX_BYTES, MAX_ROWS, _check_size, _header, read_speed_csv
from .sampling import regularise

#: Samples required per cycle of the highest order analysed.
MIN_SAMPLES_PER_CYCLE = 20
#: Samples per cycle below which an order is left out of a bin's fit altogether.
NUISANCE_PER_CYCLE = 4
#: Revolutions required in an rpm bin.
MIN_REVOLUTIONS = 4
#: Rows of a design matrix (or of any pass over the samples) handled at once.
BLOCK_ROWS = 4096
#: ``progress(done, total)`` of an analysis counts to this.
PROGRESS_STEPS = 1000
ORDER_RANGE = (0.0, 50.0)             # open at 0
RPM_STEP_RANGE = (1.0, 10_000.0)
MAX_ORDERS = 32
DEFAULT_ORDERS = (2.0, 4.0, 6.0)
TABLE_COLUMNS = ("rpm", "order", "amplitude_rad", "accel_rad_s2", "phase_deg")
#: The shipped sample: a synthetic four-cylinder run-up, 1000 → 3000 rpm, orders 2, 4, 6
#: (made by ``scripts/make_sample_runup.py``; package data).
SAMPLE_RUNUP = Path(__file__).resolve().parents[1] / "assets" / "measurements" / \
    "runup_4cyl_synthetic.csv.gz"


def _wrap(deg: np.ndarray) -> np.ndarray:
    """Angles wrapped to (−180°, 180°]."""
    w = np.mod(np.asarray(deg, dtype=np.float64) + 180.0, 360.0) - 180.0
    return np.where(w == -180.0, 180.0, w)


def check_orders(orders: Any) -> tuple[float, ...]:
    """Engine orders to analyse: 1 to 32 distinct numbers in (0, 50], sorted."""
    if isinstance(orders, str):
        try:
            orders = [float(x) for x in orders.split(",") if x.strip()]
        except ValueError:
            raise ValueError(f"orders = {orders!r} must be numbers separated by commas, "
                             "e.g. 2,4,6") from None
    try:
        vals = [check_range("order", o, *ORDER_RANGE, lo_open=True) for o in orders]
    except TypeError:
        raise ValueError(f"orders = {orders!r} must be a list of numbers") from None
    if not 1 <= len(vals) <= MAX_ORDERS:
        raise ValueError(f"orders has {len(vals)} entries; the allowed range is 1 to {MAX_ORDERS}")
    if len(set(vals)) != len(vals):
        raise ValueError(f"orders = {vals} repeats an order")
    return tuple(sorted(vals))


@dataclasses.dataclass(frozen=True, eq=False)
class OrderMap:
    """Engine orders of a shaft's angular fluctuation, per rpm bin (module docstring: convention).

    Attributes
    ----------
    rpm : ndarray, shape (n_bins,)
        Mean shaft speed of each bin [rev/min], increasing.
    orders : ndarray, shape (n_orders,)
        Engine orders (cycles per shaft revolution).
    amplitude_rad : ndarray, shape (n_bins, n_orders)
        Angular displacement amplitude ``θ_k`` [rad].
    accel_rad_s2 : ndarray, shape (n_bins, n_orders)
        Angular acceleration amplitude ``α_k = θ_k (k Ω)²`` [rad/s²]; its phase is
        ``phase_deg + 180°``.
    phase_deg : ndarray, shape (n_bins, n_orders)
        Phase ``φ_k`` [deg] of ``θ_k cos(k ψ − φ_k)``, wrapped to (−180, 180].
    rpm_step : float
        Bin width [rev/min]; the map answers for speeds within half a step of its bins.
    source : str
        Where the map came from (a file name, "arrays", "table").
    detected : Detected or None
        How a file was read: delimiter, decimal mark, columns, unit, rows, duration, sample
        rate, resampling, warnings.
    notices : tuple of str
        What the analysis left out: an order not resolved at every speed is NaN where it is
        not, and a notice gives the speeds where it is.
    """

    rpm: np.ndarray
    orders: np.ndarray
    amplitude_rad: np.ndarray
    accel_rad_s2: np.ndarray
    phase_deg: np.ndarray
    rpm_step: float
    source: str = ""
    #: how the file was read (:class:`rattle_core.measure.read.Detected`), for a map from a file
    detected: Any = None
    #: what the analysis left out or changed, one sentence each
    notices: tuple[str, ...] = ()

    # ----- building ------------------------------------------------------------------
    @classmethod
    def from_arrays(cls, time_s: Any, speed_rpm: Any, orders: Any = DEFAULT_ORDERS,
                    rpm_step: float = 100.0, *, source: str = "arrays",
                    lines: np.ndarray | None = None,
                    progress: Callable[[int, int], Any] | None = None,
                    cancel: Callable[[], bool] | None = None) -> "OrderMap":
        """Order analysis of a sampled speed (module docstring: method and refusals).

        Time and memory are linear in the samples (about 150 bytes per sample at most).

        Parameters
        ----------
        time_s : array_like
            Sample times [s], strictly increasing, without gaps; irregular steps are resampled.
        speed_rpm : array_like
            Instantaneous shaft speed [rev/min], each in (0, 1e5].
        orders : sequence of float or str
            Engine orders to estimate (default 2, 4, 6).
        rpm_step : float
            Width of the rpm bins [rev/min], in [1, 1e4].
        source : str
            Label kept with the map.
        lines : ndarray, optional
            File line of each sample, for messages (default: the sample's index).
        progress : callable(done, total), optional
            Called as the analysis goes, ``total`` being :data:`PROGRESS_STEPS`.
        cancel : callable() -> bool, optional
            Polled as often; when it returns True the analysis raises :class:`AnalysisCancelled`.
        """
        return cls._from_arrays(time_s, speed_rpm, orders, rpm_step, source, lines,
                                _Steps(progress, cancel))

    @classmethod
    def _from_arrays(cls, time_s: Any, speed_rpm: Any, orders: Any, rpm_step: float, source: str,
                     lines: np.ndarray | None, step: "_Steps", max_order: float | None = None
                     ) -> "OrderMap":
        orders_t = check_orders(orders)
        rpm_step = check_range("rpm_step", rpm_step, *RPM_STEP_RANGE)
        if max_order is not None and max(orders_t) > max_order:
            raise ValueError(f"order {max(orders_t):g} is above the highest order the pulses "
                             f"resolve, {max_order:g} (pulses_per_rev / {PULSES_PER_CYCLE}); "
                             "analyse lower orders, or measure more pulses per revolution")
        t = _as_column("time_s", time_s)
        w = _as_column("speed_rpm", speed_rpm)
        if t.size != w.size:
            raise ValueError(f"time_s has {t.size} samples but speed_rpm has {w.size}")
        where = (lambda i: f"line {int(lines[i])}") if lines is not None else (lambda i: f"sample {i}")
        _check_samples(t, w, where)
        t, w, lines, note = regularise(t, w, where, lines)
        if lines is not None:
            where = (lambda i: f"line {int(lines[i])}")
        omap = _analyse(t, w, orders_t, rpm_step, source, where, step)
        return dataclasses.replace(omap, notices=((note,) if note else ()) + omap.notices)

    @classmethod
    def from_csv(cls, path: str | os.PathLike, orders: Any = DEFAULT_ORDERS,
                 rpm_step: float = 100.0, label: str | None = None, *,
                 progress: Callable[[int, int], Any] | None = None,
                 cancel: Callable[[], bool] | None = None,
                 max_rows: int | None = None, time_column: str | None = None,
                 speed_column: str | None = None, speed_unit: str | None = None,
                 pulse_column: str | None = None, pulses_per_rev: int | None = None,
                 from_s: float | None = None, to_s: float | None = None) -> "OrderMap":
        """Order analysis of a measurement file, its layout and columns sniffed
        (:mod:`rattle_core.measure.read`); ``label`` names the file in messages and in
        :attr:`source` (default: its name).  ``progress`` and ``cancel`` as in
        :meth:`from_arrays` (reading is the first tenth); ``max_rows`` as in
        :func:`read_speed_csv`.

        ``time_column``, ``speed_column`` (header names) and ``speed_unit`` (``rpm``, ``rad/s``,
        ``Hz``) override what is recognised; ``pulse_column`` and ``pulses_per_rev`` take the
        speed from tachometer pulses (:mod:`rattle_core.measure.pulses`); ``from_s`` and
        ``to_s`` [s, the file's time] analyse part of the file.  What was read is
        :attr:`detected`."""
        label = Path(path).name if label is None else label
        step = _Steps(progress, cancel)
        try:
            check_orders(orders)
            check_range("rpm_step", rpm_step, *RPM_STEP_RANGE)
        except ValueError as exc:
            raise ValueError(f"{label}, {exc}") from None
        step(0.0)
        meas = read_measurement(path, label, max_rows, time_column=time_column,
                                speed_column=speed_column, speed_unit=speed_unit,
                                pulse_column=pulse_column, pulses_per_rev=pulses_per_rev,
                                from_s=from_s, to_s=to_s)
        step(0.1)
        return cls._from_measurement(meas, orders, rpm_step, step.within(0.1, 1.0))

    @classmethod
    def from_measurement(cls, meas: Any, orders: Any = DEFAULT_ORDERS, rpm_step: float = 100.0,
                         *, progress: Callable[[int, int], Any] | None = None,
                         cancel: Callable[[], bool] | None = None) -> "OrderMap":
        """Order analysis of a :class:`rattle_core.measure.measurement.Measurement` (a file
        read by :func:`~rattle_core.measure.measurement.read_measurement`)."""
        return cls._from_measurement(meas, orders, rpm_step, _Steps(progress, cancel))

    @classmethod
    def _from_measurement(cls, meas: Any, orders: Any, rpm_step: float, step: "_Steps"
                          ) -> "OrderMap":
        label = meas.detected.source
        try:
            omap = cls._from_arrays(meas.time_s, meas.speed_rpm, orders, rpm_step, label,
                                    meas.lines, step, meas.max_order)
        except ValueError as exc:
            raise ValueError(f"{label}, {exc}") from None
        det = meas.detected
        notices = omap.notices
        if notices and notices[0].startswith("resampled"):
            det = dataclasses.replace(det, resampling=notices[0])
            notices = notices[1:]
        if meas.pulses_per_rev:  # the speed is a pulse-long average: its orders are divided out
            gain = averaging_gain(omap.orders, meas.pulses_per_rev)[None, :]
            omap = dataclasses.replace(omap, amplitude_rad=omap.amplitude_rad / gain,
                                       accel_rad_s2=omap.accel_rad_s2 / gain)
        return dataclasses.replace(omap, detected=det, notices=notices)

    @classmethod
    def from_table(cls, table: Any, source: str = "table") -> "OrderMap":
        """A map from its own table (a DataFrame or dict with :data:`TABLE_COLUMNS`, one row per
        rpm bin and order), as :meth:`to_frame` writes it."""
        cols = {}
        for c in TABLE_COLUMNS:
            if c not in table:
                raise ValueError(f"an order table needs the columns {', '.join(TABLE_COLUMNS)}; "
                                 f"{c!r} is missing")
            cols[c] = np.asarray(table[c], dtype=np.float64).ravel()
            # an order the sampling did not resolve at some speeds is NaN there
            values = cols[c] if c in ("rpm", "order") else cols[c][~np.isnan(cols[c])]
            if not np.all(np.isfinite(values)):
                raise ValueError(f"order table column {c!r} holds a value that is not a finite number")
        rpm = np.unique(cols["rpm"])
        orders = np.asarray(check_orders(np.unique(cols["order"])))
        n = rpm.size * orders.size
        if cols["rpm"].size != n:
            raise ValueError(f"an order table needs one row per rpm and order ({rpm.size} × "
                             f"{orders.size} = {n}), got {cols['rpm'].size} rows")
        idx = np.lexsort((cols["order"], cols["rpm"]))
        shape = (rpm.size, orders.size)
        if np.any(cols["rpm"][idx].reshape(shape) != rpm[:, None]) or \
                np.any(cols["order"][idx].reshape(shape) != orders[None, :]):
            raise ValueError("an order table needs every order at every rpm")
        step = float(np.median(np.diff(rpm))) if rpm.size > 1 else 100.0
        for c in ("amplitude_rad", "accel_rad_s2"):
            if np.any(cols[c] < 0):
                raise ValueError(f"order table column {c!r} holds a negative amplitude")
        if np.any(rpm <= RPM_RANGE[0]) or np.any(rpm > RPM_RANGE[1]):
            raise ValueError(f"order table rpm values must lie in ({RPM_RANGE[0]:g}, {RPM_RANGE[1]:g}]")
        return cls(rpm=rpm, orders=orders, amplitude_rad=cols["amplitude_rad"][idx].reshape(shape),
                   accel_rad_s2=cols["accel_rad_s2"][idx].reshape(shape),
                   phase_deg=_wrap(cols["phase_deg"][idx].reshape(shape)),
                   rpm_step=check_range("rpm_step", step, *RPM_STEP_RANGE), source=source)

    @classmethod
    def read(cls, path: str | os.PathLike, orders: Any = DEFAULT_ORDERS,
             rpm_step: float = 100.0, **options: Any) -> "OrderMap":
        """A map from a file: a measurement (analysed with ``orders``, ``rpm_step`` and the
        reading ``options`` of :meth:`from_csv`) or an order table written by ``rattle orders``
        (read as it is)."""
        header = _header(path)
        if set(TABLE_COLUMNS) <= set(header):
            import pandas as pd
            _check_size(path)
            return cls.from_table(pd.read_csv(path, comment="#"), source=Path(path).name)
        return cls.from_csv(path, orders, rpm_step, **options)

    # ----- reading --------------------------------------------------------------------
    @property
    def rpm_range(self) -> tuple[float, float]:
        """Speeds the map answers for: its bins, extended by half a step at either end."""
        return float(self.rpm[0] - self.rpm_step / 2), float(self.rpm[-1] + self.rpm_step / 2)

    def at(self, rpm: Any, orders: Any = None) -> tuple[np.ndarray, np.ndarray]:
        """``(θ_k [rad], φ_k [deg])`` at each speed, interpolated linearly between bins (phases
        unwrapped across bins first); the end bins' values hold to the ends of :attr:`rpm_range`.

        Returns arrays of shape ``(len(rpm), len(orders))``.  Raises ``ValueError`` for a speed
        outside :attr:`rpm_range` or an order the map does not hold.
        """
        cols = self._columns(orders)
        r = np.atleast_1d(np.asarray(rpm, dtype=np.float64))
        lo, hi = self.rpm_range
        bad = ~np.isfinite(r) | (r < lo - 1e-9) | (r > hi + 1e-9)
        if np.any(bad):
            raise ValueError(f"rpm = {float(r[bad][0])!r} is outside the measured range "
                             f"[{lo:g}, {hi:g}] of the order map ({self.source})")
        self.check_covers([self.orders[c] for c in cols], r)
        amp = np.empty((r.size, len(cols)))
        ph = np.empty((r.size, len(cols)))
        for j, c in enumerate(cols):
            ok = np.isfinite(self.amplitude_rad[:, c])
            amp[:, j] = np.interp(r, self.rpm[ok], self.amplitude_rad[ok, c])
            unwrapped = np.rad2deg(np.unwrap(np.deg2rad(self.phase_deg[ok, c])))
            ph[:, j] = _wrap(np.interp(r, self.rpm[ok], unwrapped))
        return amp, ph

    def covered(self, order: float) -> tuple[float, float] | None:
        """The speeds [rpm] at which ``order`` was analysed (its bins, extended by half a
        step), or None where the sampling resolved it nowhere."""
        c = self._columns([order])[0]
        ok = np.flatnonzero(np.isfinite(self.amplitude_rad[:, c]))
        if ok.size == 0:
            return None
        # between an analysed bin and one that is not, nothing can be interpolated
        half = self.rpm_step / 2
        return (float(self.rpm[ok[0]] - (half if ok[0] == 0 else 0.0)),
                float(self.rpm[ok[-1]] + (half if ok[-1] == self.rpm.size - 1 else 0.0)))

    def check_covers(self, orders: Any, rpm: Any) -> None:
        """Raise ``ValueError`` naming the order and its analysed speed range when any of
        ``orders`` was not analysed at one of the speeds ``rpm`` (the sampling did not resolve
        it there); a verdict calls this before it uses the orders."""
        r = np.atleast_1d(np.asarray(rpm, dtype=np.float64))
        for o in np.atleast_1d(np.asarray(orders, dtype=np.float64)):
            c = self._columns([o])[0]
            if np.all(np.isfinite(self.amplitude_rad[:, c])):
                continue
            span = self.covered(o)
            bad = np.ones(r.size, bool) if span is None else \
                (r < span[0] - 1e-9) | (r > span[1] + 1e-9)
            if np.any(bad):
                avail = ("no speed" if span is None
                         else f"{span[0]:.0f} to {span[1]:.0f} rpm only")
                raise ValueError(f"order {o:g} is needed at {float(r[bad][0]):.0f} rpm, but the "
                                 f"measurement ({self.source}) resolves it at {avail}: its sampling "
                                 "is too slow for it above; choose speeds in that range, or "
                                 "measure faster")

    def harmonics(self, rpm: Any, engine_order: float, n: int, scale: float = 1.0
                  ) -> tuple[np.ndarray, np.ndarray]:
        """The model's harmonics ``1..n`` of a fundamental at ``engine_order``: ``θ`` [rad] of
        engine orders ``engine_order × (1..n)`` times ``scale`` (a speed ratio), and their phases."""
        engine_order = check_range("engine_order", engine_order, *ORDER_RANGE, lo_open=True)
        n = int(check_range("harmonics", n, 1, MAX_ORDERS))
        amp, ph = self.at(rpm, [engine_order * k for k in range(1, n + 1)])
        return amp * scale, ph

    def _columns(self, orders: Any) -> list[int]:
        if orders is None:
            return list(range(self.orders.size))
        out = []
        for o in np.atleast_1d(np.asarray(orders, dtype=np.float64)):
            hit = np.nonzero(np.isclose(self.orders, o, rtol=0, atol=1e-9))[0]
            if hit.size == 0:
                raise ValueError(f"order {o:g} is not in the order map ({self.source}), which "
                                 f"holds orders {', '.join(f'{k:g}' for k in self.orders)}")
            out.append(int(hit[0]))
        return out

    def to_frame(self):
        """One row per rpm bin and order: :data:`TABLE_COLUMNS` (a DataFrame)."""
        import pandas as pd
        nb, no = self.amplitude_rad.shape
        return pd.DataFrame({"rpm": np.repeat(self.rpm, no), "order": np.tile(self.orders, nb),
                             "amplitude_rad": self.amplitude_rad.ravel(),
                             "accel_rad_s2": self.accel_rad_s2.ravel(),
                             "phase_deg": self.phase_deg.ravel()})

    def canonical(self) -> dict:
        """What the map is, for cache keys: its arrays and step."""
        return {"rpm": self.rpm, "orders": self.orders, "amplitude_rad": self.amplitude_rad,
                "phase_deg": self.phase_deg, "rpm_step": self.rpm_step}


# ----- checks and analysis ----------------------------------------------------------------

def _as_column(name: str, values: Any) -> np.ndarray:
    try:
        arr = np.asarray(values, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be an array of numbers") from None
    if arr.ndim != 1:
        raise ValueError(f"{name} must be one-dimensional, got shape {arr.shape}")
    if arr.size > MAX_ROWS:
        raise ValueError(f"{name} has {arr.size} samples; the allowed size is up to {MAX_ROWS}")
    return arr


def _check_samples(t: np.ndarray, w: np.ndarray, where) -> None:
    if t.size < 2 * MIN_SAMPLES_PER_CYCLE:
        raise ValueError(f"the measurement has {t.size} samples; at least "
                         f"{2 * MIN_SAMPLES_PER_CYCLE} are needed")
    for name, arr in (("time_s", t), ("speed_rpm", w)):
        bad = np.nonzero(~np.isfinite(arr))[0]
        if bad.size:
            raise ValueError(f"{where(bad[0])}: {name} = {float(arr[bad[0]])!r} is not a finite number")
    bad = np.nonzero((w <= RPM_RANGE[0]) | (w > RPM_RANGE[1]))[0]
    if bad.size:
        raise ValueError(f"{where(bad[0])}: speed_rpm = {float(w[bad[0]])!r} is outside the allowed "
                         f"range ({RPM_RANGE[0]:g}, {RPM_RANGE[1]:g}]")
    dt = np.diff(t)
    bad = np.nonzero(dt <= 0)[0]
    if bad.size:
        i = bad[0] + 1
        raise ValueError(f"{where(i)}: time_s = {float(t[i])!r} does not increase (the sample before "
                         f"is at {float(t[i - 1])!r}); time must increase strictly")


def resolved_rpm(order: float, time_step: float, per_cycle: float = MIN_SAMPLES_PER_CYCLE) -> float:
    """The highest speed [rpm] at which samples ``time_step`` apart give ``per_cycle`` samples
    per cycle of ``order``."""
    return 60.0 / (order * per_cycle * time_step)


class AnalysisCancelled(Exception):
    """An order analysis stopped because its ``cancel`` callback asked it to."""


class _Steps:
    """Progress of one analysis, ``progress(done, PROGRESS_STEPS)``, and its cancel check;
    :meth:`within` maps a part of the work onto a share of the bar."""

    def __init__(self, progress: Callable[[int, int], Any] | None,
                 cancel: Callable[[], bool] | None, lo: float = 0.0, hi: float = 1.0) -> None:
        self.progress, self.cancel, self.lo, self.hi = progress, cancel, lo, hi
        self.last = [-1]

    def within(self, lo: float, hi: float) -> "_Steps":
        part = _Steps(self.progress, self.cancel, self.lo + (self.hi - self.lo) * lo,
                      self.lo + (self.hi - self.lo) * hi)
        part.last = self.last
        return part

    def __call__(self, fraction: float) -> None:
        if self.cancel is not None and self.cancel():
            raise AnalysisCancelled("the order analysis was cancelled")
        f = self.lo + (self.hi - self.lo) * min(max(fraction, 0.0), 1.0)
        done = int(PROGRESS_STEPS * f)
        if self.progress is not None and done != self.last[0]:
            self.last[0] = done
            self.progress(done, PROGRESS_STEPS)


def _moving_mean(x: np.ndarray, win: int) -> np.ndarray:
    """Mean of ``x`` over ``win`` samples centred as ``np.convolve(..., mode="same")`` centres
    them; near either end, of the samples the window holds."""
    n = x.size
    ref = float(x[0]) if n else 0.0  # partial sums of the deviation keep their digits
    total = np.empty(n + 1)
    total[0] = 0.0
    np.cumsum(x - ref, out=total[1:])
    i = np.arange(n)
    lo = np.maximum(i - win // 2, 0)
    hi = np.minimum(i + (win - 1) // 2, n - 1) + 1
    return (total[hi] - total[lo]) / (hi - lo) + ref


def _groups(keys: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(values, bounds, order)``: ``order[bounds[g]:bounds[g + 1]]`` are the increasing
    indices where ``keys == values[g]`` (one linear-time sort of integers)."""
    order = np.argsort(keys, kind="stable")
    sk = keys[order]
    cut = np.flatnonzero(sk[1:] != sk[:-1]) + 1
    bounds = np.concatenate([[0], cut, [keys.size]]).astype(np.int64)
    return sk[bounds[:-1]], bounds, order


class _Harmonics:
    """The fitted orders as the compiled kernels take them: each half order ``m/2`` by the
    power ``m`` of ``exp(iA/2)`` (one sine and cosine per sample, then products), any other
    order directly."""

    def __init__(self, fit_orders: list[float]) -> None:
        k = np.asarray(fit_orders, dtype=np.float64)
        twice = 2.0 * k
        half = np.nonzero(twice == np.round(twice))[0]
        power = np.round(twice[half]).astype(np.int64)
        top = int(power.max()) if power.size else 0
        #: column (order index) of each power of exp(iA/2), or -1
        self.power_col = np.full(top + 1, -1, np.int64)
        self.power_col[power] = half
        self.other_col = np.nonzero(twice != np.round(twice))[0].astype(np.int64)
        self.other_k = k[self.other_col]


@njit(cache=True, nogil=True)
def _design_rows(a, psi, y, weight, use_weight, r0, s_lo, s_hi, s_mean, s_width, power_col,
                 other_col, other_k, out):
    """Rows ``r0 …`` of a bin's design matrix into ``out``: per stretch ``s`` the trend
    ``1, u, u²`` (``u = (a − mean_s)/width_s``, zero outside the stretch), then ``cos kψ`` and
    ``sin kψ`` of every fitted order, times ``weight`` if ``use_weight``; last, ``y``."""
    nt = 3 * s_lo.size
    s = 0
    for r in range(out.shape[0]):
        g = r0 + r
        for c in range(nt):
            out[r, c] = 0.0
        while s < s_lo.size - 1 and g >= s_hi[s]:
            s += 1
        if s_lo[s] <= g < s_hi[s]:
            u = (a[g] - s_mean[s]) / s_width[s]
            out[r, 3 * s] = 1.0
            out[r, 3 * s + 1] = u
            out[r, 3 * s + 2] = u * u
        w = weight[g] if use_weight else 1.0
        c1 = math.cos(0.5 * psi[g])
        s1 = math.sin(0.5 * psi[g])
        cm, sm = c1, s1
        for m in range(1, power_col.size):
            col = power_col[m]
            if col >= 0:
                out[r, nt + 2 * col] = cm * w
                out[r, nt + 2 * col + 1] = sm * w
            cm, sm = cm * c1 - sm * s1, sm * c1 + cm * s1
        for j in range(other_col.size):
            ka = psi[g] * other_k[j]
            out[r, nt + 2 * other_col[j]] = math.cos(ka) * w
            out[r, nt + 2 * other_col[j] + 1] = math.sin(ka) * w
        out[r, out.shape[1] - 1] = y[g]


@njit(cache=True, nogil=True)
def _fluctuation(a, owner, amp_cos, amp_sin, amp, phase_rad, power_col, other_col, other_k, out):
    """``θ(a) = Σ_k θ_k cos(k a − φ_k)`` per sample, with the orders of its bin ``owner``:
    ``amp_cos = θ_k cos φ_k``, ``amp_sin = θ_k sin φ_k`` per bin and order."""
    for r in range(a.size):
        q = owner[r]
        c1 = math.cos(0.5 * a[r])
        s1 = math.sin(0.5 * a[r])
        cm, sm = c1, s1
        acc = 0.0
        for m in range(1, power_col.size):
            col = power_col[m]
            if col >= 0:
                acc += amp_cos[q, col] * cm + amp_sin[q, col] * sm
            cm, sm = cm * c1 - sm * s1, sm * c1 + cm * s1
        for j in range(other_col.size):
            c = other_col[j]
            acc += amp[q, c] * math.cos(a[r] * other_k[j] - phase_rad[q, c])
        out[r] = acc


def _analyse(t: np.ndarray, w: np.ndarray, orders: tuple[float, ...], rpm_step: float,
             source: str, where, step: _Steps | None = None) -> OrderMap:
    """The method of the module docstring, in time and memory linear in the samples: every
    pass over the samples goes :data:`BLOCK_ROWS` at a time."""
    from scipy.integrate import cumulative_simpson
    from scipy.interpolate import CubicSpline

    step = step or _Steps(None, None)
    time_step = float(np.median(np.diff(t)))
    omega = w * (2.0 * math.pi / 60.0)
    angle = cumulative_simpson(omega, x=t, initial=0.0)
    bad = np.flatnonzero(np.diff(angle) <= 0)
    if bad.size:
        raise ValueError(f"{where(int(bad[0]) + 1)}: the speed varies too fast between samples to "
                         "integrate")
    # uniform in angle, as densely as the file is sampled on average
    n = max(int(round(t.size)), 2)
    grid = np.linspace(0.0, angle[-1], n)
    speed = CubicSpline(angle, omega)(grid)
    del omega
    step(0.2)

    def sample_of(i: int) -> int:
        return min(int(np.searchsorted(angle, grid[i])), t.size - 1)
    per_rev = n / (angle[-1] / (2 * math.pi))
    win = max(1, int(round(per_rev)))
    rpm_smooth = _moving_mean(speed, win) * (60.0 / (2 * math.pi))
    bins = np.round(rpm_smooth / rpm_step).astype(np.int64)
    present, bounds, by_bin = _groups(bins)
    fit_orders = sorted(set(orders) | {0.5 * m for m in range(1, int(4 * max(orders)) + 1)})
    kept, members, top_rpm = [], [], []
    for g, b in enumerate(present):
        sel = by_bin[bounds[g]:bounds[g + 1]]
        revs = sel.size / per_rev
        if revs < MIN_REVOLUTIONS:
            if g in (0, present.size - 1):
                continue  # a partly covered end bin
            lines = (where(sample_of(sel[0])), where(sample_of(sel[-1])))
            raise ValueError(f"{lines[0]} to {lines[1]}: the {b * rpm_step:g} rpm bin holds "
                             f"{revs:.2f} revolutions; at least {MIN_REVOLUTIONS} are needed (the "
                             "speed changes too fast for rpm_step; choose a wider rpm_step)")
        kept.append(int(b))
        members.append(sel)
        top_rpm.append(float(rpm_smooth[sel].max()))
    del rpm_smooth
    if not kept:
        raise ValueError(f"the measurement covers fewer than {MIN_REVOLUTIONS} revolutions in "
                         f"every {rpm_step:g} rpm bin; measure longer or choose a wider rpm_step")
    kept_arr = np.array(kept)
    # each sample's nearest analysed bin, the lower one of two as near (samples of a dropped
    # end bin borrow its neighbour's)
    upper = np.minimum(np.searchsorted(kept_arr, bins), kept_arr.size - 1)
    lower = np.maximum(upper - 1, 0)
    owner = np.where(np.abs(kept_arr[lower] - bins) <= np.abs(kept_arr[upper] - bins), lower, upper)
    del bins, upper, lower
    # per bin: the orders fitted (any the sampling resolves, asked for or not) and those
    # reported (at least MIN_SAMPLES_PER_CYCLE samples per cycle at the bin's top speed)
    fit_sets = [[o for o in fit_orders if top <= resolved_rpm(o, time_step, NUISANCE_PER_CYCLE)]
                for top in top_rpm]
    fit_sets = [fs if fs else fit_orders[:1] for fs in fit_sets]
    bin_harmonics = [_Harmonics(fs) for fs in fit_sets]
    harmonics = _Harmonics(fit_orders)
    fitted = sum(sel.size for sel in members)
    work = 2 * (2 * fitted + n)
    done = [0]

    def advance(rows: int) -> None:
        done[0] += rows
        step(0.2 + 0.8 * done[0] / work)
    psi = grid
    for _ in range(2):
        fits = []
        for sel, fs, bh in zip(members, fit_sets, bin_harmonics):
            r, a_fs, p_fs = _fit_bin(grid[sel], psi[sel], speed[sel], fs, bh, advance)
            a_all, p_all = np.zeros(len(fit_orders)), np.zeros(len(fit_orders))
            cols = [fit_orders.index(o) for o in fs]
            a_all[cols], p_all[cols] = a_fs, p_fs
            fits.append((r, a_all, p_all))
        # the fluctuation θ(A) the fits describe; ψ = A − θ(A) + θ(0) is the mean angle
        amp = np.array([f[1] for f in fits])
        ph = np.deg2rad(np.array([f[2] for f in fits]))
        theta = np.empty(n)
        amp_cos, amp_sin = amp * np.cos(ph), amp * np.sin(ph)
        for r0 in range(0, n, BLOCK_ROWS):
            r1 = min(r0 + BLOCK_ROWS, n)
            _fluctuation(grid[r0:r1], owner[r0:r1], amp_cos, amp_sin, amp, ph, harmonics.power_col,
                         harmonics.other_col, harmonics.other_k, theta[r0:r1])
            advance(r1 - r0)
        psi = grid - theta + theta[0]
        del theta
    idx = [fit_orders.index(o) for o in orders]
    rpm = np.array([f[0] for f in fits])
    amp = np.array([f[1][idx] for f in fits])
    phase = _wrap(np.array([f[2][idx] for f in fits]))
    k = np.asarray(orders)
    top = np.asarray(top_rpm)
    notices = []
    for j, o in enumerate(orders):
        limit = resolved_rpm(o, time_step)
        out = top > limit
        if not np.any(out):
            continue
        amp[out, j] = np.nan
        phase[out, j] = np.nan
        if np.all(out):
            notices.append(f"order {o:g} is not analysed at any speed: the sampling "
                           f"({1 / time_step:.6g} Hz) gives fewer than {MIN_SAMPLES_PER_CYCLE} "
                           f"samples per cycle of it above {limit:.0f} rpm (NaN)")
        else:
            notices.append(f"order {o:g} is analysed from {rpm[~out][0]:.0f} to "
                           f"{rpm[~out][-1]:.0f} rpm only: the sampling ({1 / time_step:.6g} Hz) "
                           f"gives fewer than {MIN_SAMPLES_PER_CYCLE} samples per cycle of it above "
                           f"{limit:.0f} rpm; left out (NaN) from {rpm[out][0]:.0f} to "
                           f"{rpm[out][-1]:.0f} rpm")
    if notices and np.all(np.isnan(amp)):
        raise ValueError(f"the sampling ({1 / time_step:.6g} Hz) gives fewer than "
                         f"{MIN_SAMPLES_PER_CYCLE} samples per cycle of every order asked for, at "
                         "every speed; sample faster, or analyse lower orders")
    accel = amp * (k[None, :] * rpm[:, None] * 2 * math.pi / 60.0) ** 2
    return OrderMap(rpm=rpm, orders=k.astype(np.float64), amplitude_rad=amp, accel_rad_s2=accel,
                    phase_deg=phase, rpm_step=rpm_step, source=source, notices=tuple(notices))


def _stretches(a: np.ndarray) -> np.ndarray:
    """Edges of the contiguous stretches of a bin's angles ``a`` (increasing): a run-up and a
    run-down visit a bin twice, and each visit gets its own trend.  A gap of under one
    revolution is the same visit (the speed's noise took a few samples across the bin's edge),
    and so is a piece of under one revolution, which joins the stretch before it (the first,
    the one after it): a trend needs samples to be fitted."""
    if a.size < 2:
        return np.array([0, a.size], np.int64)
    da = np.diff(a)
    step = float(np.median(da))
    breaks = np.flatnonzero(da > max(2 * step, 2 * math.pi)) + 1
    edges = np.concatenate([[0], breaks, [a.size]]).astype(np.int64)
    per_rev = 2 * math.pi / step if step > 0 else 1.0
    while edges.size > 2:
        size = np.diff(edges)
        short = np.flatnonzero(size < per_rev)
        if short.size == 0:
            break
        i = int(short[0])
        edges = np.delete(edges, i if i > 0 else 1)
    return edges


def _fit_bin(a: np.ndarray, psi: np.ndarray, speed: np.ndarray, fit_orders: list[float],
             harmonics: _Harmonics, advance: Callable[[int], None]
             ) -> tuple[float, np.ndarray, np.ndarray]:
    """Least-squares orders of one bin: ``(mean rpm, θ_k, φ_k [deg])`` for every fitted order,
    the speed ``speed`` sampled at angles ``a``, the orders referred to the mean angle ``psi``
    (module docstring, step 4).

    The normal equations are summed a block of rows at a time, so the design matrix (trend and
    two columns per fitted order) never exists whole: memory stays :data:`BLOCK_ROWS` times its
    width whatever the bin holds.  They are well conditioned (columns of order one, nearly
    orthogonal over the bin's revolutions), and a factorisation of the tall matrix would cost
    ten to a hundred times more."""
    edges = _stretches(a)
    stretches = [(int(p0), int(p1), float(a[p0:p1].mean()), max(float(np.ptp(a[p0:p1])), 1e-9))
                 for p0, p1 in zip(edges[:-1], edges[1:])]
    nt = 3 * len(stretches)
    ncol = nt + 2 * len(fit_orders)
    s_lo, s_hi = (np.array([st[i] for st in stretches], np.int64) for i in (0, 1))
    s_mean, s_width = (np.array([st[i] for st in stretches]) for i in (2, 3))
    h = harmonics

    def solve(weight: np.ndarray | None) -> np.ndarray:
        # the speed rides as the last column: one product gives XᵀX and Xᵀy
        gram = np.zeros((ncol + 1, ncol + 1))
        x = np.empty((min(BLOCK_ROWS, a.size), ncol + 1))
        for r0 in range(0, a.size, BLOCK_ROWS):
            r1 = min(r0 + BLOCK_ROWS, a.size)
            xb = x[:r1 - r0]
            _design_rows(a, psi, speed, a if weight is None else weight, weight is not None, r0,
                         s_lo, s_hi, s_mean, s_width, h.power_col, h.other_col, h.other_k, xb)
            gram += xb.T @ xb
            advance(r1 - r0)
        return np.linalg.solve(gram[:ncol, :ncol], gram[:ncol, ncol])

    def trend(coef: np.ndarray) -> np.ndarray:
        """The fitted trend T(A) at every sample of the bin."""
        out = np.zeros(a.size)
        for (p0, p1, mean, width), c in zip(stretches, coef[:nt].reshape(-1, 3)):
            u = (a[p0:p1] - mean) / width
            out[p0:p1] = c[0] + c[1] * u + c[2] * (u * u)
        return out
    smooth = trend(solve(None))
    # second pass: each order's speed is θ_k k Ω(t) sin(...), proportional to the trend
    scale = float(smooth.mean())
    coef = solve(smooth / scale)
    smooth = trend(coef)
    c, s = coef[nt::2], coef[nt + 1::2]
    amp = np.hypot(c, s) / np.asarray(fit_orders) / scale
    phase = np.rad2deg(np.arctan2(s, c)) + 90.0
    return float(smooth.mean() * 60.0 / (2 * math.pi)), amp, phase


__all__ = ["OrderMap", "AnalysisCancelled", "PROGRESS_STEPS", "read_speed_csv", "check_orders", "DEFAULT_ORDERS", "TABLE_COLUMNS",
           "SAMPLE_RUNUP",
           "MIN_SAMPLES_PER_CYCLE", "MIN_REVOLUTIONS", "MAX_ROWS", "MAX_BYTES"]
