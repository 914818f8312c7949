"""RattleParams: the one canonical, validated parameter set of the rattle model.

Every layer (solver, sweeps, cache keys, CLI, dashboard, tests) builds this object, so the
dimensionless numbers are derived in exactly one place.  Bad input raises ``ValueError``
naming the parameter, the offending value and the allowed range.

Model (dimensionless, paper eq. 10):
``Λ ẍ = −1`` in flight, ``y ≤ x ≤ y + j``, ``y(t) = Σ_k h_k cos(k t − φ_k)`` with ``h_1 = 1``.
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
import numbers
import re
from collections.abc import Iterator, Mapping, Set
from typing import Any, Callable, Iterable, Sequence

import numpy as np

from ..checks import check_range  # noqa: F401  (re-exported: the model's range check)
from .phases import paper_to_core_phases

#: Allowed ranges, shared by validation messages, the CLI and the dashboard's widgets.
LAM_RANGE = (1.0e-6, 1.0e4)  # open below: 1/Λ, the flight's deceleration, must stay finite
R_RANGE = (0.0, 1.0)
J_RANGE = (0.0, 1.0e4)  # open at 0
AMPLITUDE_RANGE = (0.0, 100.0)
PHASE_RANGE_DEG = (-1.0e6, 1.0e6)
V_STICK_RANGE = (0.0, 10.0)
NOISE_RANGE = (0.0, 0.5)
#: Default relative scatter of the restitution coefficient (docs/model.md, "Noise"): small
#: enough that robust periodic orbits stay exact to 1e-10, large enough that no loop chosen
#: by rounding survives it.
NOISE_DEFAULT = 1e-12
MAX_HARMONICS = 32


def check_int(name: str, value: Any, lo: int, hi: int) -> int:
    """Return ``value`` as an int in ``[lo, hi]``, or raise ``ValueError`` naming it.

    A float is taken only when it is whole (``2.0``); ``2.5`` is refused rather than
    truncated, and so are bools and text.
    """
    v = check_range(name, value, lo, hi)
    if v != int(v):
        raise ValueError(f"{name} = {value!r} must be a whole number in [{lo}, {hi}]")
    return int(v)


def check_reals(label: str, values: Any) -> np.ndarray:
    """``values`` as a flat float64 array, or ``ValueError`` naming ``label``.

    Text, bools and containers are refused even where numpy would convert them
    (``np.asarray(["1", "2"], float)`` parses the strings); NaN and infinities too.
    """
    if isinstance(values, (str, bytes, Mapping, Set)):
        raise ValueError(f"{label} must be a sequence of numbers, got {values!r:.60}")
    arr = np.asarray(values) if isinstance(values, np.ndarray) else None
    if arr is None:
        try:
            items = list(values) if not np.isscalar(values) else [values]
        except TypeError:
            raise ValueError(f"{label} must be a sequence of numbers, got {values!r:.60}") from None
        arr = np.asarray(items, dtype=object).ravel() if items else np.empty(0)
    if arr.dtype.kind not in "fiu":
        for v in arr.ravel():
            if (isinstance(v, (bool, np.bool_)) or not isinstance(v, (numbers.Real, np.floating,
                                                                      np.integer))):
                raise ValueError(f"{label} must be numbers, got {v!r:.60} in it")
    vals = arr.astype(np.float64).ravel()
    if not np.all(np.isfinite(vals)):
        raise ValueError(f"{label} must all be finite, got {float(vals[~np.isfinite(vals)][0])!r}")
    return vals


class ArgumentTypeError(TypeError, ValueError):
    """An argument of the wrong kind: a ``TypeError`` that callers catching ``ValueError``, as
    every bad input was, still catch."""


def check_progress(value: Any, name: str = "progress") -> Callable[..., Any] | None:
    """``value`` if it is None or callable (``progress(done, total)``); else
    :class:`ArgumentTypeError` naming ``name``, raised before any work rather than at the
    first report."""
    if value is None or callable(value):
        return value
    raise ArgumentTypeError(f"{name} = {value!r:.60} must be a callable progress(done, total) "
                            "or None")


def check_cancel(value: Any, name: str = "cancel") -> Callable[[], bool] | None:
    """A ``cancel`` argument as a callable polled for True, or None.

    Taken: None, an object with ``is_set()`` (a ``threading.Event``; its ``is_set`` is
    returned), or a callable returning a bool.  Anything else raises
    :class:`ArgumentTypeError` naming ``name``.
    """
    if value is None:
        return None
    is_set = getattr(value, "is_set", None)
    if callable(is_set):
        return is_set
    if callable(value):
        return value
    raise ArgumentTypeError(f"{name} = {value!r:.60} must be a threading.Event (anything with "
                            "is_set()), a callable returning True to stop, or None")


def check_bool(name: str, value: Any) -> bool:
    """Return ``value`` if it is a bool (numpy's included), or raise ``ValueError`` naming it."""
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    raise ValueError(f"{name} = {value!r} must be True or False")


@dataclasses.dataclass(frozen=True)
class RattleParams:
    """Dimensionless parameters of the idle-gear rattle model.

    Parameters
    ----------
    lam : float
        Λ = m H₁ ω² / F, inertia over drag (paper eq. 9). Range (0, 1e4].
    r : float
        Coefficient of restitution, ``ẋ⁺ − ẏ = −r (ẋ⁻ − ẏ)``. Range [0, 1].
    j : float
        Backlash divided by H₁. Range (0, 1e4].
    amplitudes : tuple of float
        ``h_k = H_k / H₁`` for k = 1..K; the first must be exactly 1. Each in [0, 100].
    phases_deg : tuple of float
        ``φ_k`` in degrees, same length as ``amplitudes``.
    v_stick : float
        Limit impact velocity: an impact with ``|ẋ − ẏ| < v_stick`` ends the rebounds
        (permanent contact while the reaction keeps its sign). Range [0, 10].
    noise : float
        ε, the relative scatter of the restitution coefficient: every rebound uses
        ``r (1 + ε ξ)`` (capped at 1), ``ξ`` uniform in (−1, 1] from a seeded stream.
        ``0`` is the strict deterministic model. Range [0, 0.5]; default ``NOISE_DEFAULT``
        (docs/model.md, "Noise").
    """

    lam: float
    r: float = 0.65
    j: float = 8.0
    amplitudes: tuple[float, ...] = (1.0,)
    phases_deg: tuple[float, ...] = (0.0,)
    v_stick: float = 1e-6
    noise: float = NOISE_DEFAULT

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        set_(self, "lam", check_range("lam", self.lam, *LAM_RANGE, lo_open=True))
        set_(self, "r", check_range("r", self.r, *R_RANGE))
        set_(self, "j", check_range("j", self.j, *J_RANGE, lo_open=True))
        set_(self, "v_stick", check_range("v_stick", self.v_stick, *V_STICK_RANGE))
        set_(self, "noise", check_range("noise", self.noise, *NOISE_RANGE))
        amps = _as_tuple("amplitudes", self.amplitudes)
        phases = _as_tuple("phases_deg", self.phases_deg)
        if len(amps) == 0:
            raise ValueError("amplitudes must hold at least one harmonic (h_1 = 1), got an empty list")
        if len(amps) > MAX_HARMONICS:
            raise ValueError(f"amplitudes has {len(amps)} harmonics; the allowed range is 1 to {MAX_HARMONICS}")
        if len(phases) != len(amps):
            raise ValueError(f"phases_deg has {len(phases)} entries but amplitudes has {len(amps)}; "
                             "they must have the same length")
        amps = tuple(check_range(f"amplitudes[{i}] (h_{i + 1})", a, *AMPLITUDE_RANGE)
                     for i, a in enumerate(amps))
        phases = tuple(check_range(f"phases_deg[{i}] (phi_{i + 1})", p, *PHASE_RANGE_DEG)
                       for i, p in enumerate(phases))
        if amps[0] != 1.0:
            raise ValueError(f"amplitudes[0] (h_1) = {amps[0]!r} must be exactly 1: "
                             "positions are scaled by the first harmonic's amplitude H1")
        set_(self, "amplitudes", amps)
        set_(self, "phases_deg", phases)

    # ----- derived arrays -------------------------------------------------------------
    @property
    def n_harmonics(self) -> int:
        return len(self.amplitudes)

    @property
    def h(self) -> np.ndarray:
        """Amplitudes ``h_k`` as a float64 array."""
        return np.asarray(self.amplitudes, dtype=np.float64)

    @property
    def phi(self) -> np.ndarray:
        """Phases ``φ_k`` in radians as a float64 array."""
        return np.deg2rad(np.asarray(self.phases_deg, dtype=np.float64))

    # ----- editing by name --------------------------------------------------------------
    def get(self, name: str) -> float:
        """Value of a sweepable parameter: ``lam``, ``r``, ``j``, ``v_stick``, ``noise``, ``hK``, ``phiK``."""
        kind, k = parse_name(name)
        if kind == "h":
            return self.amplitudes[k - 1] if k <= self.n_harmonics else 0.0
        if kind == "phi":
            return self.phases_deg[k - 1] if k <= self.n_harmonics else 0.0
        return getattr(self, kind)

    def with_value(self, name: str, value: float) -> "RattleParams":
        """A copy with one parameter changed; ``hK``/``phiK`` add harmonics up to K as needed."""
        kind, k = parse_name(name)
        if kind in ("h", "phi"):
            amps = list(self.amplitudes) + [0.0] * max(0, k - self.n_harmonics)
            phases = list(self.phases_deg) + [0.0] * max(0, k - self.n_harmonics)
            (amps if kind == "h" else phases)[k - 1] = value
            return dataclasses.replace(self, amplitudes=tuple(amps), phases_deg=tuple(phases))
        return dataclasses.replace(self, **{kind: value})

    def replace(self, **changes: Any) -> "RattleParams":
        return dataclasses.replace(self, **changes)

    @classmethod
    def paper(cls, lam: float, r: float = 0.65, j: float = 8.0,
              amplitudes: Sequence[float] = (1.0,), phases_deg: Sequence[float] = (0.0,),
              v_stick: float = 1e-6, noise: float = NOISE_DEFAULT, *, h2: float | None = None,
              phi2: float = 0.0) -> "RattleParams":
        """Parameters given in the paper's phase convention (:mod:`rattle_core.model.phases`).

        ``h2`` and ``phi2`` give the second harmonic as the CLI's ``--h2``/``--phi2`` do (the
        paper's Figures 4–8: ``RattleParams.paper(lam=3.3, h2=0.25, phi2=45)``); they replace
        ``amplitudes`` and ``phases_deg``, which must then be left at their defaults.
        """
        amplitudes = _as_tuple("amplitudes", amplitudes)
        phases_deg = _as_tuple("phases_deg", phases_deg)
        if h2 is not None:
            if tuple(amplitudes) != (1.0,) or tuple(phases_deg) != (0.0,):
                raise ValueError("h2/phi2 give the harmonics: leave amplitudes and phases_deg out")
            amplitudes, phases_deg = (1.0, h2), (0.0, phi2)
        return cls(lam=lam, r=r, j=j, amplitudes=tuple(amplitudes),
                   phases_deg=paper_to_core_phases(phases_deg), v_stick=v_stick, noise=noise)

    # ----- canonical form ---------------------------------------------------------------
    def canonical(self) -> dict:
        """Canonical dict: trailing zero harmonics dropped, floats exact (``float.hex``)."""
        amps, phases = list(self.amplitudes), list(self.phases_deg)
        while len(amps) > 1 and amps[-1] == 0.0:
            amps.pop()
            phases.pop()
        return {
            "lam": float(self.lam).hex(), "r": float(self.r).hex(), "j": float(self.j).hex(),
            "amplitudes": [float(a).hex() for a in amps],
            "phases_deg": [float(p).hex() for p in phases],
            "v_stick": float(self.v_stick).hex(), "noise": float(self.noise).hex(),
        }

    def to_dict(self) -> dict:
        """Plain JSON-friendly dict (decimal floats), inverse of :meth:`from_dict`."""
        return {"lam": self.lam, "r": self.r, "j": self.j, "amplitudes": list(self.amplitudes),
                "phases_deg": list(self.phases_deg), "v_stick": self.v_stick,
                "noise": self.noise}

    @classmethod
    def from_dict(cls, d: dict) -> "RattleParams":
        """Parameters from :meth:`to_dict` (or :meth:`canonical`); ``ValueError`` naming what is
        missing or unknown."""
        if not isinstance(d, Mapping):
            raise ValueError(f"parameters must be a dict, got {type(d).__name__}")
        known = [f.name for f in dataclasses.fields(cls)]
        unknown = sorted(str(k) for k in d if k not in known)
        if unknown:
            raise ValueError(f"unknown parameter {unknown[0]!r}; allowed: {', '.join(known)}")
        if "lam" not in d:
            raise ValueError("lam is missing; the parameters must give at least lam")

        def num(v: Any) -> Any:
            if isinstance(v, str) and re.match(r"^[-+]?0x", v.strip()):
                return float.fromhex(v)
            return v

        def nums(v: Any) -> Any:  # anything but a list is left for the constructor to refuse
            return tuple(num(a) for a in v) if isinstance(v, (list, tuple)) else v
        return cls(lam=num(d["lam"]), r=num(d.get("r", 0.65)), j=num(d.get("j", 8.0)),
                   amplitudes=nums(d.get("amplitudes", (1.0,))),
                   phases_deg=nums(d.get("phases_deg", (0.0,))),
                   v_stick=num(d.get("v_stick", 1e-6)), noise=num(d.get("noise", NOISE_DEFAULT)))

    def key(self, **settings: Any) -> str:
        """SHA-256 of the canonical parameters plus any settings (used as a cache key)."""
        return canonical_hash({"params": self.canonical(), **settings})


def _as_tuple(name: str, seq: Any) -> tuple:
    # a dict's keys or a set's order would silently stand in for the harmonics' values
    if isinstance(seq, (str, bytes, Mapping, Set)):
        raise ValueError(f"{name} must be a sequence of numbers, got {seq!r}")
    if isinstance(seq, Iterator):
        # a generator is used up by its first reading: a second would see no harmonics
        raise ArgumentTypeError(f"{name} must be a sequence or array of numbers (a list, a tuple, "
                                f"a numpy array), got a {type(seq).__name__}")
    if np.isscalar(seq):
        return (seq,)
    try:
        return tuple(seq)
    except TypeError:
        raise ValueError(f"{name} must be a sequence of numbers, got {seq!r}") from None


_NAME_RE = re.compile(r"^(lam|r|j|v_stick|noise|h(\d+)|phi(\d+))$")


def parse_name(name: str) -> tuple[str, int]:
    """Split a parameter name into (kind, harmonic order); raises ``ValueError`` if unknown."""
    m = _NAME_RE.match(str(name))
    if not m:
        raise ValueError(f"unknown parameter name {name!r}; allowed: lam, r, j, v_stick, noise, "
                         f"h2..h{MAX_HARMONICS} (amplitude ratio), phi1..phi{MAX_HARMONICS} (phase, degrees)")
    if m.group(2) is not None:
        k = int(m.group(2))
        if not 2 <= k <= MAX_HARMONICS:
            raise ValueError(f"parameter {name!r}: harmonic order {k} is outside the allowed range "
                             f"[2, {MAX_HARMONICS}] (h1 is fixed at 1)")
        return "h", k
    if m.group(3) is not None:
        k = int(m.group(3))
        if not 1 <= k <= MAX_HARMONICS:
            raise ValueError(f"parameter {name!r}: harmonic order {k} is outside the allowed range "
                             f"[1, {MAX_HARMONICS}]")
        return "phi", k
    return m.group(1), 0


def _canon(obj: Any) -> Any:
    if isinstance(obj, float):
        return obj.hex()
    if isinstance(obj, (np.floating,)):
        return float(obj).hex()
    if isinstance(obj, (np.integer,)):
        return int(obj)
    if isinstance(obj, np.ndarray):
        return [_canon(v) for v in obj.tolist()]
    if isinstance(obj, dict):
        return {str(k): _canon(v) for k, v in sorted(obj.items())}
    if isinstance(obj, (list, tuple)):
        return [_canon(v) for v in obj]
    return obj


def canonical_hash(obj: Any) -> str:
    """SHA-256 hex digest of canonical JSON (sorted keys, floats as ``float.hex()``)."""
    text = json.dumps(_canon(obj), sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()


def iter_names(params: RattleParams) -> Iterable[str]:
    """All sweepable names for this parameter set."""
    yield from ("lam", "r", "j", "v_stick", "noise")
    for k in range(2, params.n_harmonics + 1):
        yield f"h{k}"
    for k in range(1, params.n_harmonics + 1):
        yield f"phi{k}"
