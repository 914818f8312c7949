"""Bifurcation curves for the dashboard: the background jobs that compute them, and their data.

Two jobs run in worker processes of the job pool, both through the disk cache (prefix
``atlas``), both returning plain arrays:

* :func:`atlas_curves`: every curve over a map's window (``rattle_core``'s ``atlas``): the
  contact boundary, and the folds, period doublings, grazings and onsets of sticking that
  continuation finds from a few seeds, each followed across the window;
* :func:`bifurcation_curve`: one bifurcation of a continued branch followed in a second
  parameter: the page's orbit is found again, continued in the diagram's parameter both ways,
  and the bifurcation of the asked kind nearest the asked value is followed.

:class:`Curves` holds the result in the page's axis units (φ₂ in the page's convention): one
polyline per curve with its kind, and the codimension-two points with their messages.
Nothing heavy is imported at import time, since every worker process imports this module.
"""
from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import Any

import numpy as np

#: Seeds and limits of a map's atlas: rows and columns of seeds, curves, points per curve.
ROWS, COLUMNS, MAX_CURVES, MAX_POINTS = 3, 3, 24, 400


class _Out(dict):
    """A job's output, ``{"arrays", "meta"}``, as the disk cache takes it."""

    @property
    def cancelled(self) -> bool:
        return bool(self["meta"].get("cancelled"))


def _request(kind: str, params: Any, phys: Any, **rest: Any) -> dict:
    from ..core import CONTINUATION_VERSION, SOLVER_VERSION
    return {"kind": kind, "params": params.canonical(),
            "physical": dataclasses.asdict(phys) if phys is not None else None, **rest,
            "solver": SOLVER_VERSION, "continuation": CONTINUATION_VERSION}


def _pack(curves: list, meta: dict) -> dict:
    """Plain arrays of curves: ``i/x``, ``i/y`` per curve, codimension-two points ``c/...``."""
    arrays: dict = {}
    cx, cy, ck, cm, ci = [], [], [], [], []
    meta["curves"] = []
    for i, c in enumerate(curves):
        arrays[f"{i}/x"] = c.points[c.param1].to_numpy(dtype=np.float64)
        arrays[f"{i}/y"] = c.points[c.param2].to_numpy(dtype=np.float64)
        meta["curves"].append({"kind": c.kind, "x": c.param1, "y": c.param2,
                               "status": c.status, "points": len(c.points)})
        for p in c.codim2:
            cx.append(p.value1)
            cy.append(p.value2)
            ck.append(p.kind)
            cm.append(p.message)
            ci.append(i)
    arrays["c/x"] = np.asarray(cx, dtype=np.float64)
    arrays["c/y"] = np.asarray(cy, dtype=np.float64)
    arrays["c/kind"] = np.asarray(ck, dtype="U32")
    arrays["c/curve"] = np.asarray(ci, dtype=np.int64)
    arrays["c/message"] = np.asarray(cm, dtype="U400")
    return _Out(arrays=arrays, meta=meta)


def _run_cached(request: dict, compute, use_cache: bool, directory: str | None) -> dict:
    from ..core import cached
    if not use_cache:
        return {**compute(), "from_cache": False}
    # a cancelled run is returned but not stored (the cache checks ``cancelled``)
    out, hit = cached("atlas", request, compute, _load, _save,
                      lambda o: o["meta"].get("kind") == request["kind"], directory)
    return {**out, "from_cache": hit}


def atlas_curves(params: Any, phys: Any, x_name: str, x_range: tuple, y_name: str,
                 y_range: tuple, use_cache: bool = True, directory: str | None = None) -> dict:
    """The curves over the window ``x_range × y_range`` (core units: φ₂ in the core's phases).

    Returns ``{"arrays", "meta", "from_cache"}``; ``meta["curves"]`` names each curve's kind.
    """
    from ..core import atlas
    from .jobs import cancelled, report
    x_range = tuple(float(v) for v in x_range)
    y_range = tuple(float(v) for v in y_range)

    def compute() -> dict:
        curves = atlas(params, x_name, x_range, y_name, y_range, physical=phys, rows=ROWS,
                       columns=COLUMNS, max_curves=MAX_CURVES, max_points=MAX_POINTS,
                       progress=report, cancel=cancelled)
        return _pack(curves, {"kind": "atlas", "cancelled": bool(cancelled())})

    req = _request("atlas", params, phys, axes=[x_name, y_name], x_range=list(x_range),
                   y_range=list(y_range), settings=[ROWS, COLUMNS, MAX_CURVES, MAX_POINTS])
    return _run_cached(req, compute, use_cache, directory)


def bifurcation_curve(params: Any, phys: Any, name: str, bounds: tuple, start: dict,
                      kind: str, value: float, param2: str, bounds2: tuple,
                      use_cache: bool = True, directory: str | None = None) -> dict:
    """The ``kind`` bifurcation nearest ``value`` of the branch of the orbit found at
    ``params`` (``start``: how it is found), followed in ``param2`` within ``bounds2``."""
    from ..core import ContinuationError, continue_bifurcation, continue_orbit, find_orbit
    from .jobs import cancelled, report
    phys1 = phys if name in ("rpm", "drag_torque") else None

    def compute() -> dict:
        orbit = find_orbit(params, x0=start.get("x0"), v0=float(start.get("v0", 0.0)),
                           t0=float(start.get("t0", 0.0)), transient=int(start["transient"]))
        found = []
        for sign in (1, -1):
            res = continue_orbit(orbit, name, bounds=bounds, direction=sign, max_points=1000,
                                 physical=phys1, cancel=cancelled)
            found += [b for b in res.bifurcations if b.kind == kind]
        if not found:
            raise ContinuationError(f"no {kind.replace('_', ' ')} on this branch")
        b = min(found, key=lambda b: abs(b.value - value))
        curve = continue_bifurcation(b, param2, bounds=bounds2, bounds1=bounds,
                                     max_points=MAX_POINTS * 2, progress=report,
                                     cancel=cancelled,
                                     physical=phys if param2 in ("rpm", "drag_torque") else None)
        return _pack([curve], {"kind": "curve", "from": b.message, "status": curve.status,
                               "message": curve.message, "cancelled": curve.cancelled})

    req = _request("curve", params, phys, param=name, bounds=[float(v) for v in bounds],
                   start=start, bifurcation=[kind, float(value)], param2=param2,
                   bounds2=[float(v) for v in bounds2])
    return _run_cached(req, compute, use_cache, directory)


def _save(path: Path, out: dict, key: str | None = None, request: Any = None) -> None:
    from ..core import atomic_savez
    meta = {**out["meta"], "key": key, "request": request}
    atomic_savez(Path(path), {**out["arrays"], "meta": np.array(json.dumps(meta))})


def _load(path: Path) -> tuple[dict, dict]:
    with np.load(path, allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files if k not in ("meta", "digest")}
        meta = json.loads(str(z["meta"]))
    return _Out(arrays=arrays, meta=meta), meta


# ----- the curves in axis units --------------------------------------------------------------

@dataclasses.dataclass
class Curves:
    """Curves in the page's axis units: ``paths[kind]`` lists ``(n, 2)`` polylines; ``codim2``
    is a DataFrame (``x``, ``y``, ``kind``, ``label``, ``message``)."""

    paths: dict
    codim2: Any
    meta: dict
    from_cache: bool

    @property
    def count(self) -> int:
        return sum(len(v) for v in self.paths.values())

    def summary(self) -> str:
        """Plain words: how many curves of each kind, where they came from."""
        from ..core import CURVE_STYLES
        parts = [f"{len(v)} {CURVE_STYLES[k].label.split(' (')[0]}" for k, v in self.paths.items()
                 if v]
        src = "disk cache" if self.from_cache else "computed"
        return (f"{self.count} curves" + (f": {', '.join(parts)}" if parts else "")
                + f"; {len(self.codim2)} codimension-two points · {src}")


def to_axis(name: str, phases: str, values: np.ndarray) -> np.ndarray:
    """Core values of axis ``name`` in the page's units (φ₂ in its phase convention)."""
    from ..core import core_phi2_to_paper
    v = np.asarray(values, dtype=np.float64)
    if name == "phi2" and phases == "paper":
        return np.asarray(core_phi2_to_paper(v), dtype=np.float64)
    return v


def to_core(name: str, phases: str, lo: float, hi: float) -> tuple[float, float]:
    """A window of axis ``name`` from the page's units to the core's (sorted)."""
    from ..core import paper_phi2_to_core
    if name == "phi2" and phases == "paper":
        a, b = paper_phi2_to_core(np.array([lo, hi]))
        return float(min(a, b)), float(max(a, b))
    return float(lo), float(hi)


def from_job(out: dict, phases: str, x_name: str, y_name: str) -> Curves:
    """:class:`Curves` from a job's output, drawn with ``x_name`` across."""
    import pandas as pd
    from ..core import CODIM2_MARKERS
    arrays, meta = out["arrays"], out["meta"]
    paths: dict = {}
    for i, c in enumerate(meta.get("curves", [])):
        cols = {c["x"]: arrays[f"{i}/x"], c["y"]: arrays[f"{i}/y"]}
        if x_name not in cols or y_name not in cols:
            continue
        xy = np.column_stack([to_axis(x_name, phases, cols[x_name]),
                              to_axis(y_name, phases, cols[y_name])])
        paths.setdefault(c["kind"], []).append(xy)
    cx, cy = arrays["c/x"], arrays["c/y"]
    swap = np.array([meta["curves"][int(i)]["x"] == y_name for i in arrays["c/curve"]],
                    dtype=bool)
    x, y = np.where(swap, cy, cx), np.where(swap, cx, cy)
    kinds = [str(k) for k in arrays["c/kind"]]
    codim2 = pd.DataFrame({"x": to_axis(x_name, phases, x), "y": to_axis(y_name, phases, y),
                           "kind": kinds, "label": [CODIM2_MARKERS[k][1] for k in kinds],
                           "message": [str(m) for m in arrays["c/message"]]})
    return Curves(paths=paths, codim2=codim2, meta=meta, from_cache=bool(out.get("from_cache")))
