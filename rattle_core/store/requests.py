"""Maps as the CLI and the dashboard ask for them: any two axes, served from the cache.

:func:`run_map` takes two axes of any kind (dimensionless, physical or the start state; see
:func:`~rattle_core.batch.plan.plan_map`), runs the regime map, basin map or reshaped sweep
they amount to, through the disk cache unless told not to, and labels the result with the
caller's axes.
"""
from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from ..analysis.vocabulary import REGIME_CODES
from ..batch.maps import _FLOAT_FIELDS, MapResult, _fields, _grid_args, basin_map, regime_map
from ..batch.plan import BASIN_AXES, PHYSICAL_AXES, plan_map
from ..batch.sweep import sweep
from ..model.params import RattleParams, check_bool, check_cancel, check_progress
from .cache import cached_map, cached_sweep

__all__ = ["run_map", "PHYSICAL_AXES"]


def _flat_map(params: RattleParams, name: str, flat: np.ndarray, shape: tuple[int, int],
              use_cache: bool, common: dict, columns: dict | None = None) -> MapResult:
    """A map whose two axes drive one parameter, or (``columns``) every point's own numbers:
    a 1-D sweep over every grid point, reshaped."""
    res = (cached_sweep if use_cache else sweep)(params, name, flat, columns=columns, **common)
    summ = res.summary
    fields = _fields([], flat.size)
    m = len(summ)
    fields["regime"][:m] = summ["regime"].map(REGIME_CODES).to_numpy(dtype=np.int8)
    for k in _FLOAT_FIELDS:
        fields[k][:m] = summ[k].to_numpy(dtype=np.float64)
    return MapResult(kind="regime", x_name=name, y_name=name, x_values=flat, y_values=flat,
                     params=params, settings=dict(res.settings),
                     fields={k: v.reshape(shape) for k, v in fields.items()},
                     cancelled=res.cancelled, from_cache=res.from_cache)


def run_map(params: RattleParams, phys: Any, x_name: str, x_values, y_name: str, y_values, *,
            use_cache: bool = True, labels: tuple[str, str] = ("x axis", "y axis"),
            follow: Any = None, **common: Any) -> MapResult:
    """A regime/intensity map or basins of attraction over any two axes, labelled as asked.

    Parameters
    ----------
    params : RattleParams
        Parameters held fixed (for physical axes, those of ``phys`` at its own values).
    phys : PhysicalParams or None
        The same model in physical units; needed for physical axes.
    x_name, y_name : str
        Dimensionless names (``lam``, ``r``, ``j``, ``v_stick``, ``hK``, ``phiK``), physical
        ones (:data:`~rattle_core.batch.plan.PHYSICAL_AXES`: ``rpm``, ``drag_torque`` [N·m],
        ``inertia`` [kg·m²], ``backlash_um`` [µm]), or ``x0`` and ``v0`` for basins.
    x_values, y_values : sequence of float
    use_cache : bool
        Serve a map that ran before from the disk cache (:mod:`rattle_core.store.cache`), and
        store this one; ``result.from_cache`` tells which happened.
    labels : (str, str)
        How error messages name the two axes.
    follow : Excitation, optional
        Harmonics that follow engine speed (:class:`~rattle_core.model.gearbox.Excitation`,
        from a measurement): every point takes them at its own speed.
    **common
        ``transient``, ``record``, ``x0``, ``v0`` (regime maps), ``progress``, ``cancel``,
        ``executor``, ``chunk_size``, as for :func:`~rattle_core.batch.maps.regime_map` and
        :func:`~rattle_core.batch.maps.basin_map`.

    Returns
    -------
    MapResult
        ``x_name``, ``y_name``, ``x_values``, ``y_values`` are the caller's; ``settings``
        adds ``model_axes`` (the dimensionless parameters the axes drive) and, in physical
        units, ``physical``.
    """
    use_cache = check_bool("use_cache", use_cache)
    for key, check in (("progress", check_progress), ("cancel", check_cancel)):
        if key in common:
            common[key] = check(common[key])
    plan = plan_map(params, phys, x_name, x_values, y_name, y_values, labels, follow)
    xv = _grid_args(x_name, x_values, "x_values")
    yv = _grid_args(y_name, y_values, "y_values")
    if plan[0] == "basin":
        if "x0" in common or "v0" in common:
            raise ValueError("x0 and v0 are the axes of a basin map; do not give them as settings")
        xs, vs = (xv, yv) if x_name == "x0" else (yv, xv)
        result = (cached_map("basin", params, "x0", xs, "v0", vs, **common) if use_cache
                  else basin_map(params, xs, vs, **common))
        if x_name != "x0":
            result = dataclasses.replace(result, fields={k: v.T for k, v in result.fields.items()})
        axes: Any = list(BASIN_AXES)
    elif plan[0] == "map":
        _, a, av, b, bv = plan
        result = (cached_map("regime", params, a, av, b, bv, **common) if use_cache
                  else regime_map(params, a, av, b, bv, **common))
        axes = [a, b]
    elif plan[0] == "rows":
        cols = plan[1]
        result = _flat_map(params, "point", np.arange(xv.size * yv.size, dtype=np.float64),
                           (yv.size, xv.size), use_cache, common, cols)
        axes = sorted(cols)
    else:
        _, name, flat = plan
        result = _flat_map(params, name, flat, (yv.size, xv.size), use_cache, common)
        axes = name
    settings = dict(result.settings, model_axes=axes)
    if phys is not None:
        settings["physical"] = dataclasses.asdict(phys)
    return dataclasses.replace(result, x_name=x_name, y_name=y_name, x_values=xv, y_values=yv,
                               settings=settings)
