"""A slow, obvious order analysis: the reference for :mod:`rattle_core.model.orders`.

:func:`read_speed_csv` reads a measurement row by row with the ``csv`` module. :func:`analyse`
runs the method of :mod:`rattle_core.model.orders` (its docstring) in the plainest form: each
rpm bin's whole design matrix built in memory and solved by the normal equations, each sample's
nearest analysed bin found through an (n × bins) table, the moving average by ``np.convolve``.
It is quadratic in time and memory where the library streams, so it serves small files in the
tests and the baseline of ``benchmarks/bench_orders.py``.
"""
from __future__ import annotations

import csv
import gzip
import io
import math
import os
from pathlib import Path

import numpy as np

from rattle_core.model.engine import RPM_RANGE
from rattle_core.model.orders import MIN_REVOLUTIONS, OrderMap

COLUMNS = ("time_s", "speed_rpm")
MAX_ROWS = 5_000_000


def _wrap(deg):
    w = np.mod(np.asarray(deg, dtype=np.float64) + 180.0, 360.0) - 180.0
    return np.where(w == -180.0, 180.0, w)


def _check_size(path) -> None:
    if not Path(path).is_file():
        raise ValueError(f"measurement file {str(path)!r} does not exist or is not a file")


def _open_text(path):
    if str(path).lower().endswith(".gz"):
        return io.TextIOWrapper(gzip.open(path, "rb"), encoding="utf-8", newline="")
    return open(path, encoding="utf-8", newline="")


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


def analyse(t: np.ndarray, w: np.ndarray, orders: tuple[float, ...], rpm_step: float,
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
        fits = {b: fit_bin(grid[bins == b], psi[bins == b], speed[bins == b], fit_orders)
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


def lstsq(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Least squares by the normal equations: the columns are of order one and nearly
    orthogonal over the revolutions of a bin, and a factorisation of the tall matrix costs ten to
    a hundred times more (OpenBLAS threads on a busy machine)."""
    return np.linalg.solve(x.T @ x, x.T @ y)


def fit_bin(a: np.ndarray, psi: np.ndarray, speed: np.ndarray, fit_orders: list[float]
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
    coef = lstsq(np.hstack([trend, harm]), speed)
    smooth = trend @ coef[:nt]
    # second pass: each order's speed is θ_k k Ω(t) sin(...), proportional to the trend
    scale = float(smooth.mean())
    coef = lstsq(np.hstack([trend, harm * (smooth / scale)[:, None]]), speed)
    smooth = trend @ coef[:nt]
    c, s = coef[nt::2], coef[nt + 1::2]
    amp = np.hypot(c, s) / np.asarray(fit_orders) / scale
    phase = np.rad2deg(np.arctan2(s, c)) + 90.0
    return float(smooth.mean() * 60.0 / (2 * math.pi)), amp, phase
