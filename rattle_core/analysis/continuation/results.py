"""What a continuation returns: bifurcations, the branch's tables, and the run that fills them."""
from __future__ import annotations

import dataclasses
import math
import threading
from typing import TYPE_CHECKING, Any

import numpy as np

from .orbits import PeriodicOrbit, solve_orbit
from .sticking import _handle, _stick_at, _w_min

if TYPE_CHECKING:
    import pandas as pd


BIFURCATION_KINDS = {
    "fold": "fold: a multiplier crosses +1 and the branch turns back",
    "period_doubling": "period doubling: a multiplier crosses −1",
    "neimark_sacker": "Neimark–Sacker: a complex pair crosses the unit circle",
    "grazing": "grazing: a flight touches a wall, the orbit gains or loses an impact",
    "stick_onset": "onset of sticking: an impact on a pushing wall becomes slower than v_stick",
    "stick_end": "end of sticking: the stick phase shrinks to nothing",
    "sequence_change": "the impact sequence of an orbit that sticks changes",
    "permanent_contact": "the reaction never changes sign: the gear stays on the tooth (A)",
}
#: Bifurcations after which the branch cannot go on with the same impact sequence.
TERMINAL = ("grazing", "stick_onset", "stick_end", "sequence_change", "permanent_contact")


@dataclasses.dataclass(frozen=True, eq=False)
class Bifurcation:
    """A bifurcation located on a branch.

    Attributes
    ----------
    kind : str
        One of :data:`BIFURCATION_KINDS`.
    param : str
        The continued parameter.
    value : float
        Where, in the parameter's units (degrees for phases, rpm, N·m).
    point : int
        Index of the last branch point before it.
    orbit : PeriodicOrbit
        The orbit at the bifurcation.
    detail : dict
        Kind-specific facts: the flight and wall of a grazing, the critical multiplier, ...
    message : str
        One line for people.
    """

    kind: str
    param: str
    value: float
    point: int
    orbit: PeriodicOrbit
    detail: dict
    message: str
    q: float = math.nan
    _restart: Any = None
    _spec: Any = None

    @property
    def multipliers(self) -> np.ndarray:
        return self.orbit.multipliers

    @property
    def can_restart(self) -> bool:
        """Whether :func:`continue_orbit` can start a new branch here (``start=bifurcation``)."""
        return self._restart is not None

    def as_dict(self) -> dict:
        mu = self.orbit.multipliers
        d = {"kind": self.kind, "param": self.param, "value": self.value, "point": self.point,
             "period": self.orbit.period, "n_impacts": self.orbit.n_impacts,
             "mu1_re": float(mu[0].real), "mu1_im": float(mu[0].imag),
             "mu2_re": float(mu[1].real) if len(mu) > 1 else math.nan,
             "mu2_im": float(mu[1].imag) if len(mu) > 1 else math.nan,
             "message": self.message}
        for k, v in self.detail.items():
            if isinstance(v, (int, float, str, bool, np.integer, np.floating)):
                d[k] = v
        return d


@dataclasses.dataclass(eq=False)
class ContinuationResult:
    """A continued branch.

    Attributes
    ----------
    param : str
        The continued parameter.
    points : DataFrame
        One row per branch point: ``point``, ``value`` (the parameter, in its units), ``q``
        (the dimensionless value the equations use: Λ, r, j, h_K, φ_K in radians), ``kind``
        (``impact`` or ``stick``), ``period``, ``n_impacts``, ``n_active``, ``n_reverse``,
        ``stable``, the multipliers ``mu1_re, mu1_im, mu2_re, mu2_im`` and ``mu_max`` (largest
        modulus), ``impulse_max``/``impulse_min`` (signed extremes), ``stick_time``,
        ``gap_min`` (grazing test), ``w_min`` (slowest impact), ``event`` (the bifurcation at
        that point, if any).
    impacts : DataFrame
        One row per impact per point: ``point``, ``value``, ``impact``, ``t``, ``phase``,
        ``u``, ``w``, ``impulse``, ``flank``, ``stable``: the branch drawn on a bifurcation
        diagram.
    bifurcations : list of Bifurcation
    status : str
        Why it stopped: ``bound``, ``max_points``, ``grazing``, ``stick_onset``, ``stick_end``,
        ``sequence_change``, ``step_too_small``, ``cancelled``, ``closed`` (the branch came
        back to its start).
    message : str
    provenance : dict
        Parameters, start, settings, versions: everything the result depends on (JSON-ready;
        :meth:`cache_key` hashes it).
    orbits : list of PeriodicOrbit
        The orbit at each point (:meth:`orbit`, :meth:`orbit_at`).
    seconds : float
        Wall time of the run.
    """

    param: str
    points: "pd.DataFrame"
    impacts: "pd.DataFrame"
    bifurcations: list
    status: str
    message: str
    provenance: dict
    orbits: list = dataclasses.field(default_factory=list, repr=False)
    _spec: Any = dataclasses.field(default=None, repr=False)
    seconds: float = math.nan

    @property
    def bifurcation_table(self) -> "pd.DataFrame":
        import pandas as pd
        cols = ["kind", "param", "value", "point", "period", "n_impacts", "mu1_re", "mu1_im",
                "mu2_re", "mu2_im", "message"]
        rows = [b.as_dict() for b in self.bifurcations]
        df = pd.DataFrame(rows) if rows else pd.DataFrame(columns=cols)
        return df[cols + [c for c in df.columns if c not in cols]]

    @property
    def cancelled(self) -> bool:
        return self.status == "cancelled"

    def orbit(self, i: int) -> PeriodicOrbit:
        """The orbit at branch point ``i``."""
        return self.orbits[int(i)]

    def orbit_at(self, value: float) -> list:
        """The orbits of the branch at exactly ``value`` of the parameter (one per crossing:
        a branch that folds crosses a value more than once), solved there from the two branch
        points around it."""
        spec = self._spec
        value = float(value)
        q = spec.q_of(value)
        vals = self.points["value"].to_numpy()
        out = []
        for i in range(len(vals) - 1):
            a, b = self.orbits[i], self.orbits[i + 1]
            if (vals[i] - value) * (vals[i + 1] - value) > 0 or vals[i] == vals[i + 1]:
                continue
            if (vals[i + 1] == value and i + 2 < len(vals)
                    and (vals[i + 2] - value) * (vals[i] - value) < 0):
                continue  # counted with the next interval
            if a.kind != b.kind or a.period != b.period or a.n_impacts != b.n_impacts:
                continue
            if a.kind == "stick":
                o = _stick_at(spec, q, _handle(a))
                if o is not None:
                    out.append(o)
                continue
            f = (value - vals[i]) / (vals[i + 1] - vals[i])
            t = a.t + f * (b.t - a.t)
            u = a.u + f * (b.u - a.u)
            out.append(solve_orbit(spec.params(q), t, u, a.flank, a.period))
        return out

    def cache_key(self) -> str:
        """SHA-256 of the provenance: equal keys, equal results."""
        from ...model.params import canonical_hash
        return canonical_hash(self.provenance)

    def arrays(self) -> dict:
        """Plain arrays of the points, impacts and bifurcations, keyed ``table/column``: numbers
        and fixed-width strings only, so ``np.savez`` stores them and ``np.load`` reads them
        back with ``allow_pickle=False`` (see :meth:`tables`)."""
        out = {}
        for name, df in (("points", self.points), ("impacts", self.impacts),
                         ("bifurcations", self.bifurcation_table)):
            for c in df.columns:
                col = df[c].to_numpy()
                if col.dtype == object:
                    col = np.array(["" if v is None or (isinstance(v, float) and math.isnan(v))
                                    else str(v) for v in col], dtype=str)
                out[f"{name}/{c}"] = col
        return out

    @staticmethod
    def tables(arrays) -> dict:
        """The DataFrames ``points``, ``impacts`` and ``bifurcations`` back from :meth:`arrays`
        (or from an ``np.load`` of them)."""
        import pandas as pd
        out: dict = {"points": {}, "impacts": {}, "bifurcations": {}}
        for key in arrays.keys():
            name, col = key.split("/", 1)
            out[name][col] = arrays[key]
        return {name: pd.DataFrame(cols) for name, cols in out.items()}


POINT_COLUMNS = ["point", "value", "q", "kind", "period", "n_impacts", "n_active", "n_reverse",
                 "stable", "mu1_re", "mu1_im", "mu2_re", "mu2_im", "mu_max", "impulse_max",
                 "impulse_min", "stick_time", "gap_min", "w_min", "event"]
IMPACT_COLUMNS = ["point", "value", "impact", "t", "phase", "u", "w", "impulse", "flank",
                  "stable"]


def _is_cancelled(cancel) -> bool:
    if cancel is None:
        return False
    if isinstance(cancel, threading.Event) or hasattr(cancel, "is_set"):
        return bool(cancel.is_set())
    return bool(cancel())


def _limit(count: int, max_points: int, cancel) -> tuple[str, str]:
    """``(status, message)`` when a curve must stop at ``count`` points, else empty strings."""
    if count >= max_points:
        return "max_points", (f"stopped at the limit of max_points = {max_points} curve points; "
                              "raise it to go on")
    if _is_cancelled(cancel):
        return "cancelled", f"cancelled after {count} points"
    return "", ""


class _Run:
    """State of one :func:`continue_orbit` call: the points so far and what was found."""

    def __init__(self, spec, q_lo, q_hi, max_points, progress, cancel, v_stick):
        self.spec = spec
        self.q_lo, self.q_hi = q_lo, q_hi
        self.max_points = max_points
        self.progress = progress
        self.cancel = cancel
        self.v_stick = v_stick
        self.rows: list[dict] = []
        self.impact_rows: list[tuple] = []
        self.orbits: list[PeriodicOrbit] = []
        self.bifs: list[Bifurcation] = []
        self.status = ""
        self.message = ""

    def add(self, orb: PeriodicOrbit, q: float, event: str = "") -> int:
        i = len(self.rows)
        mu = orb.multipliers
        imp = orb.impulse
        value = self.spec.value_of(q)
        stable = orb.stable
        self.rows.append({
            "point": i, "value": value, "q": float(q), "kind": orb.kind, "period": orb.period,
            "n_impacts": orb.n_impacts, "n_active": int(np.sum(orb.flank == 1)),
            "n_reverse": int(np.sum(orb.flank == -1)), "stable": stable,
            "mu1_re": float(mu[0].real), "mu1_im": float(mu[0].imag),
            "mu2_re": float(mu[1].real), "mu2_im": float(mu[1].imag),
            "mu_max": float(np.max(np.abs(mu))),
            "impulse_max": float(np.max(imp)) if len(imp) else math.nan,
            "impulse_min": float(np.min(imp)) if len(imp) else math.nan,
            "stick_time": orb.stick_time, "gap_min": orb.gap_min, "w_min": _w_min(orb),
            "event": event})
        ph = orb.phase
        for k in range(orb.n_impacts):
            self.impact_rows.append((i, value, k, float(orb.t[k]), float(ph[k]), float(orb.u[k]),
                                     float(orb.w[k]), float(imp[k]), int(orb.flank[k]), stable))
        self.orbits.append(orb)
        if self.progress is not None:
            self.progress(len(self.rows), self.max_points)
        return i

    def full(self) -> bool:
        if len(self.rows) >= self.max_points:
            self.status = "max_points"
            self.message = (f"stopped at the limit of max_points = {self.max_points} branch points; "
                            "raise it to go on")
            return True
        if _is_cancelled(self.cancel):
            self.status = "cancelled"
            self.message = f"cancelled after {len(self.rows)} points"
            return True
        return False

    def bifurcation(self, kind, q, orb, detail, message, restart=None) -> Bifurcation:
        b = Bifurcation(kind=kind, param=self.spec.name, value=self.spec.value_of(q),
                        point=max(len(self.rows) - 1, 0), orbit=orb, detail=detail,
                        message=message, q=float(q), _restart=restart, _spec=self.spec)
        self.bifs.append(b)
        return b
