"""A continued branch for the dashboard: the background job that computes it, and its data.

:func:`continue_both_ways` runs in a worker process of the job pool. It finds the periodic
orbit the page's run settles on (``find_orbit`` from the run's initial state), follows it with
``continue_orbit`` in the diagram's parameter over the diagram's range, towards larger and
towards smaller values (both are cheap: under a second each for the paper's branches), and
returns plain arrays: each result's :meth:`ContinuationResult.arrays` under ``up/`` and
``down/``, the impulses of each bifurcation's orbit (where its mark goes on the diagram) and a
JSON record of statuses, messages, provenances and cache keys.  Then it switches branches at
the period doublings it found, as ``rattle continue --branches`` does, breadth first: the
doubled orbit's branch (``pd1/``), the branches at that one's doublings (``pd2/``, ...), up to
:data:`MAX_SWITCHED` of them: the period-doubling cascade.  The same arrays are the disk
cache's entry (``rattle_core.store.cache.cached``, prefix ``cont``), written as ``.npz`` and
read back without pickle.  The request that keys it holds what the results' provenance
holds: the parameters, the continued parameter, the bounds, the start (here the simulation
that finds the first orbit, so a cache hit needs no simulation) and the settings, with the
solver's and the continuation's versions.

:class:`Branch` holds those results in the diagram's axis units (Λ; φ₂ in the page's phase
convention; engine speed in rpm with impulses in N·s): the segments drawn stable and
unstable, the bifurcation marks, and each point's Floquet multipliers.  This module imports
nothing heavy at import time, since every worker process imports it.
"""
from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path
from typing import Any

import numpy as np

#: Most points per direction; ``ds`` and ``ds_max`` of ``continue_orbit``.
MAX_POINTS, DS, DS_MAX = 1000, 0.01, 0.1
#: Periods simulated before the first orbit is taken (at least the page's transient).
FIND_TRANSIENT = 2000
DIRECTIONS = {"up": 1, "down": -1}
#: Branches followed from period doublings, beyond the continued orbit's own (the cascade).
MAX_SWITCHED = 4
#: Short labels of bifurcation kinds on the diagram.
SHORT = {"fold": "fold", "period_doubling": "PD", "neimark_sacker": "NS", "grazing": "graze",
         "stick_onset": "stick", "stick_end": "stick end", "sequence_change": "sequence",
         "permanent_contact": "contact"}
#: Why a direction of a continuation stopped, in words (the core's status names → text).
STOPPED = {"bound": "at the end of the range", "closed": "where the branch closed on itself",
           "done": "at the end of the range", "grazing": "at a grazing impact",
           "stick_end": "where sticking ends", "stick_onset": "where sticking begins",
           "permanent_contact": "where the gear comes to rest on a tooth",
           "step_too_small": "where the step became too small to go on",
           "inadmissible": "where the orbit stops being an orbit of the model",
           "max_points": "at the limit of points", "cancelled": "when cancelled"}
TOWARDS = {"up": "upwards", "down": "downwards"}


@dataclasses.dataclass
class Branches:
    """Both directions' arrays (``up/points/value``, ...) and their JSON record ``meta``."""

    arrays: dict
    meta: dict

    @property
    def cancelled(self) -> bool:
        return any(self.meta.get(d, {}).get("status") == "cancelled" for d in DIRECTIONS)


def request(params: Any, phys: Any, name: str, bounds: tuple[float, float],
            start: dict) -> dict:
    """What the branches depend on; its canonical hash is the cache key."""
    from ..core import CONTINUATION_VERSION, SOLVER_VERSION
    return {"kind": "continuation", "params": params.canonical(),
            "physical": dataclasses.asdict(phys) if phys is not None else None,
            "param": name, "bounds": [float(bounds[0]), float(bounds[1])],
            "start": {"x0": start.get("x0"), "v0": float(start.get("v0", 0.0)),
                      "t0": float(start.get("t0", 0.0)), "transient": int(start["transient"])},
            "settings": {"directions": list(DIRECTIONS), "ds": DS, "ds_max": DS_MAX,
                         "max_points": MAX_POINTS, "switch": "period_doubling",
                         "max_switched": MAX_SWITCHED},
            "solver": SOLVER_VERSION, "continuation": CONTINUATION_VERSION}


def continue_both_ways(params: Any, phys: Any, name: str, bounds: tuple[float, float],
                       start: dict, use_cache: bool = True,
                       directory: str | None = None) -> dict:
    """The orbit of the run at ``params``, continued in ``name`` within ``bounds`` both ways.

    Returns ``{"arrays": ..., "meta": ..., "from_cache": bool}`` (see the module docstring).
    ``start`` holds ``x0``, ``v0``, ``t0`` and ``transient`` of the simulation that finds the
    first orbit.  Raises ``ContinuationError`` when the response there is not periodic.
    """
    from ..core import cached
    from .jobs import cancelled, report

    def compute() -> Branches:
        from ..core import ContinuationError, continue_orbit, find_orbit
        orbit = find_orbit(params, x0=start.get("x0"), v0=float(start.get("v0", 0.0)),
                           t0=float(start.get("t0", 0.0)), transient=int(start["transient"]))
        arrays, meta = {}, {"start": orbit.summary(), "switched": []}
        runs = 2 + MAX_SWITCHED
        todo: list = []

        def follow(k: int, key: str, first: Any, **kw: Any) -> Any:
            res = continue_orbit(first, name, bounds=bounds, ds=DS, ds_max=DS_MAX,
                                 max_points=MAX_POINTS,
                                 physical=phys if name in ("rpm", "drag_torque") else None,
                                 progress=lambda n, m: report(k * m + n, runs * m),
                                 cancel=cancelled, **kw)
            arrays.update({f"{key}/{a}": v for a, v in res.arrays().items()})
            which = np.concatenate([[i] * b.orbit.n_impacts for i, b in enumerate(res.bifurcations)]
                                   or [np.zeros(0)]).astype(np.int64)
            imp = np.concatenate([b.orbit.impulse for b in res.bifurcations] or [np.zeros(0)])
            arrays[f"{key}/marks/bifurcation"] = which
            arrays[f"{key}/marks/impulse"] = np.asarray(imp, dtype=np.float64)
            meta[key] = {"status": res.status, "message": res.message, "key": res.cache_key(),
                         "provenance": res.provenance, "seconds": res.seconds}
            todo.extend(b for b in res.bifurcations
                        if b.kind == "period_doubling" and b.can_restart)
            return res
        for k, (d, sign) in enumerate(DIRECTIONS.items()):
            if follow(k, d, orbit, direction=sign).cancelled:
                return Branches(arrays, meta)
        k = 0
        while todo and k < MAX_SWITCHED and not cancelled():
            pd = todo.pop(0)
            key = f"pd{k + 1}"
            try:
                res = follow(2 + k, key, pd)
            except ContinuationError as exc:  # the doubled branch could not be started: go on
                meta.setdefault("skipped", []).append(f"{pd.value:.10g}: {exc}")
                continue
            meta["switched"].append(key)
            meta[key]["from"] = {"value": float(pd.value), "period": int(pd.orbit.period)}
            k += 1
            if res.cancelled:
                break
        return Branches(arrays, meta)

    def holds(b: Branches) -> bool:
        return all(b.meta.get(d, {}).get("provenance", {}).get("param") == name
                   for d in DIRECTIONS)

    req = request(params, phys, name, bounds, start)
    if use_cache:
        out, hit = cached("cont", req, compute, _load, _save, holds, directory)
    else:
        out, hit = compute(), False
    return {"arrays": out.arrays, "meta": out.meta, "from_cache": hit}


def _save(path: Path, result: Branches, key: str | None = None, request: Any = None) -> None:
    from ..core import atomic_savez
    meta = {**result.meta, "key": key, "request": request}
    atomic_savez(Path(path), {**result.arrays, "meta": np.array(json.dumps(meta))})


def _load(path: Path) -> tuple[Branches, dict]:
    with np.load(path, allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files if k not in ("meta", "digest")}
        meta = json.loads(str(z["meta"]))
    return Branches(arrays, meta), meta


# ----- the branch in axis units -------------------------------------------------------------

@dataclasses.dataclass
class Branch:
    """Continued branches in the diagram's axis units (see the module docstring).

    ``points`` and ``impacts`` are DataFrames (both directions, column ``direction``);
    ``marks`` has one row per impulse of each bifurcation's orbit (``x``, ``y``, ``kind``,
    ``label``, ``message``); ``key`` is the diagram key and start the branch belongs to.
    """

    name: str
    key: tuple
    start: float
    points: Any
    impacts: Any
    marks: Any
    meta: dict
    from_cache: bool

    @property
    def numbers(self) -> list[int]:
        """The branches held: 0 is the continued orbit's, 1, 2, ... start at period doublings."""
        return sorted(int(b) for b in self.points["branch"].unique()) if len(self.points) else []

    def legend(self, number: int) -> str:
        """The legend of branch ``number``: its period, and where it comes from."""
        period = int(self.points.loc[self.points["branch"] == number, "period"].iloc[0])
        if number == 0:
            return f"period {period}, from {self.start:.5g}"
        key = self.meta.get("switched", [])[number - 1]
        return f"period {period}, PD at {self.meta[key]['from']['value']:.5g}"

    def segments(self, stable: bool, number: int | None = None) -> list[np.ndarray]:
        """``(x, impulse)`` polylines of one impact each, where the branch is (un)stable.

        A segment runs over consecutive points of one direction; it ends where stability
        changes, and holds the first point of the other kind so that the two styles meet.
        ``number`` keeps one branch (see :attr:`numbers`); None keeps them all.
        """
        out = []
        imp = self.impacts if number is None else self.impacts[self.impacts["branch"] == number]
        for (_, k), g in imp.groupby(["direction", "impact"], sort=False):
            g = g.sort_values("point")
            x, y = g["x"].to_numpy(), g["y"].to_numpy()
            st, pt = g["stable"].to_numpy(dtype=bool), g["point"].to_numpy()
            i = 0
            while i < len(g):
                j = i
                while j + 1 < len(g) and st[j + 1] == st[i] and pt[j + 1] == pt[j] + 1:
                    j += 1
                if st[i] == stable:
                    stop = j + 1 if j + 1 < len(g) and pt[j + 1] == pt[j] + 1 else j
                    if stop > i:
                        out.append(np.column_stack([x[i:stop + 1], y[i:stop + 1]]))
                i = j + 1
        return out

    def nearest(self, value: float) -> dict | None:
        """The continued orbit's branch point nearest ``value`` of the parameter: its value,
        multipliers and stability (None if the branch has no point)."""
        p = self.points
        if len(p):
            p = p[p["branch"] == 0]
        if not len(p):
            return None
        i = int(np.argmin(np.abs(p["x"].to_numpy() - value)))
        row = p.iloc[i]
        mu = np.array([complex(row["mu1_re"], row["mu1_im"]), complex(row["mu2_re"], row["mu2_im"])])
        return {"x": float(row["x"]), "multipliers": mu, "stable": bool(row["stable"]),
                "period": int(row["period"]), "n_impacts": int(row["n_impacts"])}

    def summary(self) -> str:
        """Plain words: points, stable share, bifurcations, why each direction stopped."""
        n = len(self.points)
        stable = int(self.points["stable"].sum()) if n else 0
        bifs = self.marks.drop_duplicates(["kind", "x"])
        found = ", ".join(f"{SHORT.get(k, k)} at {x:.6g}" for k, x in zip(bifs["kind"], bifs["x"]))
        ends = "; ".join(
            f"{TOWARDS[d]} {STOPPED.get(self.meta[d]['status'], self.meta[d]['status'].replace('_', ' '))}"
            for d in DIRECTIONS if d in self.meta)
        src = "read from the disk cache" if self.from_cache else "computed"
        more = len(self.meta.get("switched", []))
        switched = f" · {more} more branch{'es' if more > 1 else ''} from period doublings" if more else ""
        return (f"Continued branch: {n} points ({stable} stable, {n - stable} unstable)"
                f"{' · ' + found if found else ''} · stopped {ends}{switched} · {src}")


def to_axis(name: str, phases: str, phys: Any, values: np.ndarray,
            impulse: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray | None]:
    """Continuation values (Λ, core φ₂ in degrees, rpm) and impulses in the diagram's units."""
    from ..core import core_phi2_to_paper, units
    from .diagram_data import wrap180
    v = np.asarray(values, dtype=np.float64)
    if name == "phi2":
        v = np.mod(core_phi2_to_paper(v), 360.0) if phases == "paper" else wrap180(v)
    elif name == "rpm" and impulse is not None and phys is not None:
        impulse = np.asarray(impulse) * units.impulse_scale_from_rpm(phys, v)
    return np.asarray(v, dtype=np.float64), impulse


def from_job(name: str, phases: str, phys: Any, key: tuple, start: float, out: dict) -> Branch:
    """A :class:`Branch` from :func:`continue_both_ways`'s output."""
    import pandas as pd
    from ..core import ContinuationResult
    arrays, meta = out["arrays"], out["meta"]
    points, impacts, marks = [], [], []
    parts = [(d, 0) for d in DIRECTIONS] + [(k, i + 1) for i, k in enumerate(meta.get("switched", []))]
    for d, number in parts:
        if not any(k.startswith(d + "/") for k in arrays):
            continue
        t = ContinuationResult.tables({k[len(d) + 1:]: v for k, v in arrays.items()
                                       if k.startswith(d + "/") and not k.startswith(f"{d}/marks/")})
        p, imp, bif = t["points"], t["impacts"], t["bifurcations"]
        p["x"], _ = to_axis(name, phases, phys, p["value"].to_numpy())
        imp["x"], imp["y"] = to_axis(name, phases, phys, imp["value"].to_numpy(),
                                     imp["impulse"].to_numpy())
        which = arrays[f"{d}/marks/bifurcation"]
        if len(which):
            vals = bif["value"].to_numpy()[which]
            x, y = to_axis(name, phases, phys, vals, arrays[f"{d}/marks/impulse"])
            kinds = bif["kind"].to_numpy()[which]
            marks.append(pd.DataFrame({"x": x, "y": y, "kind": kinds,
                                       "label": [SHORT.get(k, k) for k in kinds],
                                       "message": bif["message"].to_numpy()[which],
                                       "branch": number}))
        points.append(p.assign(direction=d, branch=number))
        impacts.append(imp.assign(direction=d, branch=number))
    cols = ["x", "y", "kind", "label", "message", "branch"]
    return Branch(name=name, key=key, start=start,
                  points=pd.concat(points, ignore_index=True) if points else pd.DataFrame(),
                  impacts=pd.concat(impacts, ignore_index=True) if impacts else pd.DataFrame(),
                  marks=pd.concat(marks, ignore_index=True) if marks else pd.DataFrame(columns=cols),
                  meta=meta, from_cache=bool(out.get("from_cache")))


def is_periodic(cls: Any) -> bool:
    """Whether a classification is a periodic regime a continuation can start from."""
    return cls is not None and int(getattr(cls, "period", 0) or 0) > 0 and not cls.chaotic \
        and math.isfinite(float(getattr(cls, "period", math.nan)))
