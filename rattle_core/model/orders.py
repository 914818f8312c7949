"""Order analysis of a measured shaft speed: each engine order's amplitude and phase per rpm bin.

Input
    The instantaneous speed of the measured shaft, ``speed_rpm`` against ``time_s``, steady or
    during a run-up or run-down, sampled at least :data:`MIN_SAMPLES_PER_CYCLE` times per cycle
    of the highest order analysed.  A CSV file has a header with the columns ``time_s`` and
    ``speed_rpm`` (others are ignored, lines starting with ``#`` are comments); ``.csv.gz`` is
    read too.
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
       (a quadratic per contiguous stretch) and, for every half order up to twice the highest
       analysed order and every order asked for, ``T(A)(c_k cos kA + s_k sin kA)``; the
       speed's order ``k`` is ``dθ/dt = −θ_k k Ω sin(kψ − φ_k)``, so
       ``θ_k = hypot(c_k, s_k) / k`` and ``φ_k = atan2(s_k, c_k) + 90°``.  Fitting every half
       order keeps the cycle-to-cycle variation of a four-stroke engine (energy at half
       orders) out of the orders asked for.
    5. ``A`` differs from ``ψ`` by ``θ(t) − θ(0)``; the constant ``θ(0)`` shifts every phase by
       ``k θ(0)`` and is taken out (twice, since it depends on the phases).  The relative phase
       ``φ₄ − 2φ₂`` does not depend on it.
    The bin's ``rpm`` is the mean speed of its samples, and ``α_k`` is computed at that speed.
Refusals
    A file is read whole and checked before anything is computed; a bad one raises
    ``ValueError`` naming the line at fault: missing columns, text or NaN where a number
    belongs, time not increasing, a gap (a step over :data:`GAP_FACTOR` times the median step),
    too few samples per cycle of the highest order, fewer than :data:`MIN_REVOLUTIONS`
    revolutions in a bin between others, more than :data:`MAX_ROWS` rows or
    :data:`MAX_BYTES` bytes.  Bins at either end of the speed range with fewer revolutions are
    left out (a run-up starts and ends part-way through a bin).
"""
from __future__ import annotations

import csv
import dataclasses
import gzip
import io
import math
import os
from pathlib import Path
from typing import Any

import numpy as np

from .engine import RPM_RANGE
from .params import check_range

#: Samples required per cycle of the highest order analysed.
MIN_SAMPLES_PER_CYCLE = 20
#: Revolutions required in an rpm bin.
MIN_REVOLUTIONS = 4
#: A time step over this many times the median step is a gap.
GAP_FACTOR = 1.5
MAX_ROWS = 5_000_000
MAX_BYTES = 256_000_000
ORDER_RANGE = (0.0, 50.0)             # open at 0
RPM_STEP_RANGE = (1.0, 10_000.0)
MAX_ORDERS = 32
DEFAULT_ORDERS = (2.0, 4.0, 6.0)
COLUMNS = ("time_s", "speed_rpm")
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
    """

    rpm: np.ndarray
    orders: np.ndarray
    amplitude_rad: np.ndarray
    accel_rad_s2: np.ndarray
    phase_deg: np.ndarray
    rpm_step: float
    source: str = ""

    # ----- building ------------------------------------------------------------------
    @classmethod
    def from_arrays(cls, time_s: Any, speed_rpm: Any, orders: Any = DEFAULT_ORDERS,
                    rpm_step: float = 100.0, *, source: str = "arrays",
                    lines: np.ndarray | None = None) -> "OrderMap":
        """Order analysis of a sampled speed (module docstring: method and refusals).

        Parameters
        ----------
        time_s : array_like
            Sample times [s], strictly increasing, without gaps.
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
        """
        orders_t = check_orders(orders)
        rpm_step = check_range("rpm_step", rpm_step, *RPM_STEP_RANGE)
        t = _as_column("time_s", time_s)
        w = _as_column("speed_rpm", speed_rpm)
        if t.size != w.size:
            raise ValueError(f"time_s has {t.size} samples but speed_rpm has {w.size}")
        where = (lambda i: f"line {int(lines[i])}") if lines is not None else (lambda i: f"sample {i}")
        _check_samples(t, w, max(orders_t), where)
        return _analyse(t, w, orders_t, rpm_step, source, where)

    @classmethod
    def from_csv(cls, path: str | os.PathLike, orders: Any = DEFAULT_ORDERS,
                 rpm_step: float = 100.0, label: str | None = None) -> "OrderMap":
        """Order analysis of a CSV file with columns ``time_s`` and ``speed_rpm``; ``label``
        names the file in messages and in :attr:`source` (default: its name)."""
        label = Path(path).name if label is None else label
        t, w, lines = read_speed_csv(path, label)
        try:
            return cls.from_arrays(t, w, orders, rpm_step, source=label, lines=lines)
        except ValueError as exc:
            raise ValueError(f"{label}, {exc}") from None

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
            if not np.all(np.isfinite(cols[c])):
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
             rpm_step: float = 100.0) -> "OrderMap":
        """A map from a file: a measurement (``time_s``, ``speed_rpm``: analysed with ``orders``
        and ``rpm_step``) or an order table written by ``rattle orders`` (read as it is)."""
        header = _header(path)
        if set(TABLE_COLUMNS) <= set(header):
            import pandas as pd
            _check_size(path)
            return cls.from_table(pd.read_csv(path, comment="#"), source=Path(path).name)
        return cls.from_csv(path, orders, rpm_step)

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
        amp = np.empty((r.size, len(cols)))
        ph = np.empty((r.size, len(cols)))
        for j, c in enumerate(cols):
            amp[:, j] = np.interp(r, self.rpm, self.amplitude_rad[:, c])
            unwrapped = np.rad2deg(np.unwrap(np.deg2rad(self.phase_deg[:, c])))
            ph[:, j] = _wrap(np.interp(r, self.rpm, unwrapped))
        return amp, ph

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


# ----- reading files ----------------------------------------------------------------------

def _open_text(path: str | os.PathLike):
    p = Path(path)
    if str(p).lower().endswith(".gz"):
        return io.TextIOWrapper(gzip.open(p, "rb"), encoding="utf-8", newline="")
    return open(p, encoding="utf-8", newline="")


def _check_size(path: str | os.PathLike) -> None:
    p = Path(path)
    if not p.is_file():
        raise ValueError(f"measurement file {str(p)!r} does not exist or is not a file")
    size = p.stat().st_size
    if size > MAX_BYTES:
        raise ValueError(f"measurement file {p.name!r} has {size} bytes; the allowed size is up "
                         f"to {MAX_BYTES} bytes")


def _header(path: str | os.PathLike) -> list[str]:
    _check_size(path)
    with _open_text(path) as f:
        for line in f:
            if line.strip() and not line.lstrip().startswith("#"):
                return [c.strip() for c in line.strip().split(",")]
    return []


def read_speed_csv(path: str | os.PathLike, label: str | None = None
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(time_s, speed_rpm, line numbers)`` of a measurement CSV, read whole and checked.

    Raises ``ValueError`` naming the file (or ``label``) and the line at fault (module
    docstring, "Refusals")."""
    _check_size(path)
    name = Path(path).name if label is None else label
    times: list[float] = []
    speeds: list[float] = []
    lines: list[int] = []
    try:
        with _open_text(path) as f:
            reader = csv.reader(f)
            header = None
            for row in reader:
                line = reader.line_num
                if not row or not "".join(row).strip() or row[0].lstrip().startswith("#"):
                    continue
                if header is None:
                    header = [c.strip() for c in row]
                    missing = [c for c in COLUMNS if c not in header]
                    if missing:
                        raise ValueError(f"{name}, line {line}: the header lacks the column(s) "
                                         f"{', '.join(missing)}; it needs time_s and speed_rpm, "
                                         f"found {', '.join(header)[:200]}")
                    it, iw = header.index("time_s"), header.index("speed_rpm")
                    continue
                if len(times) >= MAX_ROWS:
                    raise ValueError(f"{name}, line {line}: more than {MAX_ROWS} samples; the "
                                     f"allowed size is up to {MAX_ROWS} rows")
                try:
                    tv, wv = float(row[it]), float(row[iw])
                except (ValueError, IndexError):
                    raise ValueError(f"{name}, line {line}: time_s and speed_rpm must be numbers, "
                                     f"got {','.join(row)[:80]!r}") from None
                times.append(tv)
                speeds.append(wv)
                lines.append(line)
    except UnicodeDecodeError:
        raise ValueError(f"{name} is not a UTF-8 text file") from None
    except (OSError, EOFError, gzip.BadGzipFile) as exc:
        raise ValueError(f"{name} cannot be read: {exc}") from None
    except csv.Error as exc:
        raise ValueError(f"{name}: not a CSV file ({exc})") from None
    if header is None:
        raise ValueError(f"{name} holds no header line; it needs the columns time_s and speed_rpm")
    return np.array(times), np.array(speeds), np.array(lines, dtype=np.int64)


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


def _check_samples(t: np.ndarray, w: np.ndarray, max_order: float, where) -> None:
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
    step = float(np.median(dt))
    bad = np.nonzero(dt > GAP_FACTOR * step)[0]
    if bad.size:
        i = bad[0] + 1
        raise ValueError(f"{where(i)}: a gap of {dt[bad[0]]:.6g} s after time_s = {float(t[i - 1])!r} "
                         f"(the sampling step is {step:.6g} s; steps over {GAP_FACTOR:g} times it "
                         "are gaps)")
    # samples per cycle of the highest order, at each sample's speed
    per_cycle = 60.0 / (w * max_order) / np.concatenate([dt, dt[-1:]])
    bad = np.nonzero(per_cycle < MIN_SAMPLES_PER_CYCLE)[0]
    if bad.size:
        i = bad[0]
        raise ValueError(f"{where(i)}: at {w[i]:.6g} rpm the sampling gives {per_cycle[i]:.3g} "
                         f"samples per cycle of order {max_order:g}; at least "
                         f"{MIN_SAMPLES_PER_CYCLE} are needed (sample faster, or analyse lower "
                         "orders)")


def _analyse(t: np.ndarray, w: np.ndarray, orders: tuple[float, ...], rpm_step: float,
             source: str, where) -> OrderMap:
    from scipy.integrate import cumulative_simpson
    from scipy.interpolate import CubicSpline

    omega = w * (2.0 * math.pi / 60.0)
    angle = cumulative_simpson(omega, x=t, initial=0.0)
    if np.any(np.diff(angle) <= 0):
        i = int(np.nonzero(np.diff(angle) <= 0)[0][0]) + 1
        raise ValueError(f"{where(i)}: the speed varies too fast between samples to integrate")
    # uniform in angle, as densely as the file is sampled on average
    n = max(int(round(t.size)), 2)
    grid = np.linspace(0.0, angle[-1], n)
    speed = CubicSpline(angle, omega)(grid)
    sample_of = np.minimum(np.searchsorted(angle, grid), t.size - 1)
    per_rev = n / (angle[-1] / (2 * math.pi))
    win = max(1, int(round(per_rev)))
    smooth = np.convolve(speed, np.ones(win) / win, mode="same")
    # the half-window at either end averages fewer samples
    edge = np.convolve(np.ones_like(speed), np.ones(win) / win, mode="same")
    smooth = smooth / edge
    rpm_smooth = smooth * 60.0 / (2 * math.pi)
    bins = np.round(rpm_smooth / rpm_step).astype(np.int64)
    present = np.unique(bins)
    fit_orders = sorted(set(orders) | {0.5 * m for m in range(1, int(4 * max(orders)) + 1)})
    kept = []
    for b in present:
        sel = np.nonzero(bins == b)[0]
        revs = sel.size / per_rev
        if revs < MIN_REVOLUTIONS:
            if b in (present[0], present[-1]):
                continue  # a partly covered end bin
            lines = (where(sample_of[sel[0]]), where(sample_of[sel[-1]]))
            raise ValueError(f"{lines[0]} to {lines[1]}: the {b * rpm_step:g} rpm bin holds "
                             f"{revs:.2f} revolutions; at least {MIN_REVOLUTIONS} are needed (the "
                             "speed changes too fast for rpm_step; choose a wider rpm_step)")
        kept.append(b)
    if not kept:
        raise ValueError(f"the measurement covers fewer than {MIN_REVOLUTIONS} revolutions in "
                         f"every {rpm_step:g} rpm bin; measure longer or choose a wider rpm_step")
    kept_arr = np.array(kept)
    # each sample's nearest analysed bin (samples of a dropped end bin borrow its neighbour's)
    owner = kept_arr[np.argmin(np.abs(bins[:, None] - kept_arr[None, :]), axis=1)]
    psi = grid
    for _ in range(2):
        fits = {b: _fit_bin(grid[bins == b], psi[bins == b], speed[bins == b], fit_orders)
                for b in kept}
        # the fluctuation θ(A) the fits describe; ψ = A − θ(A) + θ(0) is the mean angle
        theta = np.zeros(grid.size)
        for b, (_, th, ph) in fits.items():
            sel = owner == b
            theta[sel] = np.sum(th[None, :] * np.cos(np.outer(grid[sel], fit_orders)
                                                    - np.deg2rad(ph)[None, :]), axis=1)
        psi = grid - theta + theta[0]
    idx = [fit_orders.index(o) for o in orders]
    rpm = np.array([fits[b][0] for b in kept])
    amp = np.array([fits[b][1][idx] for b in kept])
    phase = _wrap(np.array([fits[b][2][idx] for b in kept]))
    k = np.asarray(orders)
    accel = amp * (k[None, :] * rpm[:, None] * 2 * math.pi / 60.0) ** 2
    return OrderMap(rpm=rpm, orders=k.astype(np.float64), amplitude_rad=amp, accel_rad_s2=accel,
                    phase_deg=phase, rpm_step=rpm_step, source=source)


def _lstsq(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Least squares by the normal equations: the columns are of order one and nearly
    orthogonal over the revolutions of a bin, and a factorisation of the tall matrix costs ten to
    a hundred times more (OpenBLAS threads on a busy machine)."""
    return np.linalg.solve(x.T @ x, x.T @ y)


def _fit_bin(a: np.ndarray, psi: np.ndarray, speed: np.ndarray, fit_orders: list[float]
             ) -> tuple[float, np.ndarray, np.ndarray]:
    """Least-squares orders of one bin: ``(mean rpm, θ_k, φ_k [deg])`` for every fitted order,
    the speed ``speed`` sampled at angles ``a``, the orders referred to the mean angle ``psi``
    (module docstring, step 4)."""
    # contiguous stretches of the bin (a run-up and a run-down visit it twice) get own trends
    breaks = np.nonzero(np.diff(a) > 2 * np.median(np.diff(a)))[0] + 1 if a.size > 1 else []
    trend_cols = []
    for p in np.split(np.arange(a.size), breaks):
        u = (a - a[p].mean()) / max(float(np.ptp(a[p])), 1e-9)
        inside = np.zeros(a.size)
        inside[p] = 1.0
        trend_cols += [inside, inside * u, inside * u * u]
    trend = np.array(trend_cols).T
    kpsi = np.outer(psi, fit_orders)
    harm = np.empty((a.size, 2 * len(fit_orders)))
    harm[:, 0::2] = np.cos(kpsi)
    harm[:, 1::2] = np.sin(kpsi)
    nt = trend.shape[1]
    coef = _lstsq(np.hstack([trend, harm]), speed)
    smooth = trend @ coef[:nt]
    # second pass: each order's speed is θ_k k Ω(t) sin(...), proportional to the trend
    scale = float(smooth.mean())
    coef = _lstsq(np.hstack([trend, harm * (smooth / scale)[:, None]]), speed)
    smooth = trend @ coef[:nt]
    c, s = coef[nt::2], coef[nt + 1::2]
    amp = np.hypot(c, s) / np.asarray(fit_orders) / scale
    phase = np.rad2deg(np.arctan2(s, c)) + 90.0
    return float(smooth.mean() * 60.0 / (2 * math.pi)), amp, phase


__all__ = ["OrderMap", "read_speed_csv", "check_orders", "DEFAULT_ORDERS", "TABLE_COLUMNS",
           "SAMPLE_RUNUP",
           "MIN_SAMPLES_PER_CYCLE", "MIN_REVOLUTIONS", "MAX_ROWS", "MAX_BYTES"]
