"""Work run in the job pool's worker processes: bifurcation diagrams and 2-D maps.

Each function takes plain values (a ``RattleParams``, arrays, numbers) and returns plain
data, since both cross a process boundary. Progress and cancellation reach the running sweep
through :func:`app.work.jobs.report` and :func:`app.work.jobs.cancelled`. Sweeps and maps go through
the core's disk cache, so a diagram or map asked for twice is computed once.
"""
from __future__ import annotations

import contextlib
from typing import Any

import numpy as np

from rattle_core import RattleParams

from .jobs import cancelled, report

#: Dask clients of this worker process, by scheduler address (the server's command line).
_clients: dict[str, Any] = {}


def warm_up() -> None:
    """Load the compiled kernels before the first job (each worker runs this once)."""
    from rattle_core import simulate
    simulate(RattleParams(lam=3.3, amplitudes=(1.0, 0.25), phases_deg=(0.0, 45.0)), periods=5,
             transient=2)
    diagram(RattleParams(lam=2.0), "lam", np.array([2.0, 2.5]), 2, 2, use_cache=False)
    # a small upload's reading, order analysis and Campbell data: compiled here, not against
    # the first measurement's time limit
    from .gearbox import measurement
    t = np.arange(0.0, 2.0, 1.0 / 4000.0)
    rpm = 1500.0 + 50.0 * np.sin(2.0 * np.pi * t)
    text = "time_s,speed_rpm\n" + "\n".join(f"{a:.6f},{b:.4f}" for a, b in zip(t, rpm))
    measurement(text.encode(), (2.0,), 100.0, "warm-up")


def diagram(params: RattleParams, name: str, values: np.ndarray, transient: int, record: int,
            use_cache: bool = True) -> dict[str, np.ndarray | bool]:
    """Impacts against ``name`` swept over ``values``, and each value's regime.

    Returns ``value``, ``impulse``, ``flank`` (one entry per recorded impact) and
    ``swept``, ``regime``, ``chaotic`` (one per value run), ``cancelled`` and ``from_cache``
    (served by the disk cache, not computed now).
    """
    if use_cache:
        from ..core import cached_sweep as run
    else:
        from rattle_core import sweep as run
    res = run(params, name, np.asarray(values, dtype=np.float64), transient=transient,
              record=record, mode="fresh", progress=report, cancel=cancelled)
    t, s = res.table, res.summary
    return {"value": np.asarray(t["value"], dtype=np.float64),
            "impulse": np.asarray(t["impulse"], dtype=np.float64),
            "flank": np.asarray(t["flank"], dtype=np.int8),
            "swept": np.asarray(s["value"], dtype=np.float64),
            "regime": np.asarray(s["regime"], dtype="U5"),
            "chaotic": np.asarray(s["chaotic"], dtype=bool),
            "cancelled": bool(res.cancelled), "from_cache": bool(getattr(res, "from_cache", False))}


def _client(address: str) -> Any:
    """A Dask client for ``address`` (one per worker process, kept for the next map)."""
    client = _clients.get(address)
    if client is None or client.status != "running":
        from dask.distributed import Client
        try:
            client = Client(address, timeout="5s", set_as_default=False)
        except Exception as exc:
            raise ConnectionError(f"the server's Dask scheduler cannot be reached: "
                                  f"{' '.join(str(exc).split())[:200]}") from None
        _clients[address] = client
    return client


def regime_map(params: RattleParams, phys: Any, x_name: str, x_values: np.ndarray, y_name: str,
               y_values: np.ndarray, transient: int, record: int, scheduler: str = "",
               cached_only: bool = False) -> Any:
    """A regime map or basins over two axes (``rattle_core.store.requests.run_map``), on Dask if given.

    ``scheduler`` comes from the server's command line only, never from a page. With
    ``cached_only``, the map is read from the disk cache or not made at all (None).
    """
    from ..core import NotCached, read_only, run_map
    executor = _client(scheduler) if scheduler and not cached_only else None
    kwargs = {"executor": executor} if executor is not None else {}
    try:
        with (read_only() if cached_only else contextlib.nullcontext()), \
                (executor.as_current() if executor is not None else contextlib.nullcontext()):
            return run_map(params, phys, x_name, x_values, y_name, y_values, use_cache=True,
                           progress=report, cancel=cancelled, transient=transient, record=record,
                           **kwargs)
    except NotCached:
        return None


def noise_check(params: RattleParams, runs: int, periods: int, transient: int) -> dict:
    """The noise sensitivity of ``params`` (``rattle_core.noise_sensitivity`` at the default
    levels and the run's own), as plain data: the verdict, its reasons, one row per level, and
    each attractor reached with its runs, estimates and own verdict at every level."""
    from ..core import NOISE_LEVELS as DEFAULT_LEVELS
    from ..core import attractor_verdicts, noise_sensitivity
    levels = sorted(set(DEFAULT_LEVELS) | {params.noise} - {0.0})
    rep = noise_sensitivity(params, levels, runs=runs, periods=periods, transient=transient,
                            progress=report, cancel=cancelled)
    return {"sensitive": rep.sensitive, "describe": rep.describe(), "reasons": list(rep.reasons),
            "table": rep.table.to_dict("list"), "levels": list(rep.levels), "runs": runs,
            "attractors": attractor_verdicts(rep.levels, [r.attractors for r in rep.results])}
