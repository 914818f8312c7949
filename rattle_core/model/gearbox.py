"""A gearbox of loose gears driven by one measured shaft: what a ``GEARBOX.toml`` describes.

File format (TOML, read with :mod:`tomllib`)::

    [excitation]
    measurement = "runup.csv"   # relative to this file, or "sample"; or instead:
    # orders = [{order = 2, accel_rad_s2 = 400, phase_deg = 0}, {order = 4, ...}]
    engine_order = 2            # engine order of the model's fundamental
    harmonics = 3               # harmonics of the fundamental kept (orders 2, 4, 6)
    rpm_step = 100              # bins of the measurement's order analysis (default 100)

    [sound]                     # optional
    transfer_pa_per_ns = 5      # sound pressure [Pa] per N·s of tooth impulse (default 5)
    duration_s = 0.5            # sound analysed per gear and speed

    [oil]                       # optional; needed by a drag that depends on temperature
    iso_vg = 68                 # ISO 3448 grade (ν at 40 °C, cSt)
    nu100_cSt = 9               # ν at 100 °C from the data sheet
    temp_C = 40                 # the oil temperature a verdict runs at (default 40)

    [target]                    # optional: limit curves over rpm (rattle_core.model.target)
    rpm = [800, 3000]
    sone = [10, 20]             # and/or dba = [...]

    [[gear]]
    name = "5th idler"
    inertia_kgm2 = 4e-4
    base_radius_m = 0.035
    drag_torque_Nm = 0.05       # a constant drag, or instead one of (rattle_core.model.drag):
    # drag = {rpm = [800, 4000], torque_Nm = [0.04, 0.08]}
    # drag = {bush_Nm = 0.02, churn_Nm = 0.03, at_rpm = 2000, at_temp_C = 40}
    backlash_um = 80
    restitution = 0.65          # default 0.65
    speed_ratio = 1.0           # driving gear speed / measured shaft speed (default 1)
    driver_radius_m = 0.035     # default: base_radius_m

A gear gives exactly one of ``drag_torque_Nm`` (a constant) and ``drag`` (a constant, a table
over rpm and optionally oil temperature, or the oil model); a drag that depends on the oil's
temperature needs the ``[oil]`` table.  The drag at each point is taken at the point's speed
and the gearbox's oil temperature (:meth:`Gearbox.drag_Nm`), so Λ and the closed-form contact
boundary follow both; :meth:`Gearbox.replace` with ``oil_temp_C`` gives the same box at
another temperature.

The measured shaft's angular fluctuation is ``θ(t) = Σ_k θ_k cos(k ψ − φ_k)``
(:mod:`rattle_core.measure.orders`); a driving gear turning ``speed_ratio`` times as fast
fluctuates ``speed_ratio`` times as much, at the same engine orders.  The model's harmonic
``n = 1..harmonics`` is engine order ``n × engine_order``, with ``ω = engine_order × 2π rpm / 60``
(``rpm`` the measured shaft's speed).  Constant ``orders`` give ``accel_rad_s2`` (held over
the speed range: ``θ_k = α_k / (k Ω)²``) or ``amplitude_rad``, and ``phase_deg``, the phase
``φ_k`` of the displacement; orders not listed are zero.

Every value is checked; a bad one raises ``ValueError`` naming the gear, the key, the value and
the allowed range.  Unknown keys are refused (a misspelt key would otherwise be ignored).

A file is untrusted input.  Before it is parsed its brackets and braces may nest at most
:data:`MAX_TOML_DEPTH` deep (the parser recurses once per level); once parsed, tables nest at
most that deep, an array holds at most :data:`MAX_TOML_ARRAY` items and a string or key at
most :data:`MAX_TOML_STRING` characters.  A name (a gear's, a measurement file's) may not
hold control characters, line breaks or bidirectional formatting characters, which would let
it break a one-line message or display as another text.  Every error is one line naming the
file and the place in it: the line, the key path, or the gear's number and name.
"""
from __future__ import annotations

import dataclasses
import math
import tomllib
from pathlib import Path
from typing import Any

import numpy as np

from .drag import TEMP_RANGE, Drag, Oil
from .engine import RPM_RANGE
from ..measure.measurement import OPTIONS as MEASUREMENT_OPTIONS, measurement_options
from ..measure.orders import MAX_ORDERS, ORDER_RANGE, SAMPLE_RUNUP, OrderMap
from .params import R_RANGE, check_range
from .target import Target
from .toml_checks import (MAX_TOML_ARRAY, MAX_TOML_DEPTH, MAX_TOML_STRING,
                          _at, _check_keys, _FileError, _one_line, _subtable, _table,
                          check_name, check_nesting, check_sizes)
from .units import (ALPHA_RANGE, DRAG_TORQUE_RANGE, INERTIA_RANGE, RADIUS_RANGE, THETA_RANGE,
                    PhysicalParams)

MAX_GEARS = 32
MAX_TOML_BYTES = 1_000_000
RATIO_RANGE = (0.0, 100.0)            # open at 0
BACKLASH_UM_RANGE = (0.0, 1.0e5)      # open at 0
DURATION_RANGE = (0.2, 10.0)          # s
DEFAULT_DURATION_S = 0.5
DEFAULT_TRANSFER_PA_PER_NS = 5.0
TRANSFER_RANGE = (0.0, 1.0e6)         # open at 0
_GEAR_KEYS = {"name", "inertia_kgm2", "base_radius_m", "drag_torque_Nm", "drag", "backlash_um",
              "restitution", "speed_ratio", "driver_radius_m"}
_EXC_KEYS = {"measurement", "orders", "engine_order", "harmonics", "rpm_step", *MEASUREMENT_OPTIONS}
_SOUND_KEYS = {"transfer_pa_per_ns", "duration_s"}


@dataclasses.dataclass(frozen=True)
class Gear:
    """One loose gear (module docstring: keys and units).

    Its drag is ``drag`` (:class:`~rattle_core.model.drag.Drag`); a constant one may be given
    as ``drag_torque_Nm`` instead, which then holds that constant (None for a drag that
    varies).  Give one of the two, or both when ``drag`` is that same constant.
    """

    name: str
    inertia_kgm2: float
    base_radius_m: float
    drag_torque_Nm: float | None
    backlash_um: float
    restitution: float = 0.65
    speed_ratio: float = 1.0
    driver_radius_m: float | None = None
    drag: Drag | None = None

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        self._set_drag()
        if not isinstance(self.name, str) or not self.name.strip() or len(self.name) > 80:
            raise ValueError(f"gear name = {self.name!r:.100} must be text of 1 to 80 characters")
        check_name("gear name", self.name)
        set_(self, "name", self.name.strip())
        where = f"gear {self.name!r}: "
        for key, rng, open_lo in (("inertia_kgm2", INERTIA_RANGE, True),
                                  ("base_radius_m", RADIUS_RANGE, True),
                                  ("backlash_um", BACKLASH_UM_RANGE, True),
                                  ("restitution", R_RANGE, False),
                                  ("speed_ratio", RATIO_RANGE, True)):
            try:
                set_(self, key, check_range(key, getattr(self, key), *rng, lo_open=open_lo))
            except ValueError as exc:
                raise ValueError(where + str(exc)) from None
        if self.driver_radius_m is not None:
            try:
                set_(self, "driver_radius_m", check_range("driver_radius_m", self.driver_radius_m,
                                                          *RADIUS_RANGE, lo_open=True))
            except ValueError as exc:
                raise ValueError(where + str(exc)) from None

    def _set_drag(self) -> None:
        where = f"gear {self.name!r}: "
        value, drag = self.drag_torque_Nm, self.drag
        if drag is not None and not isinstance(drag, Drag):
            raise TypeError(f"{where}drag must be a Drag, got {type(drag).__name__}")
        if value is not None:
            try:
                value = check_range("drag_torque_Nm", value, *DRAG_TORQUE_RANGE, lo_open=True)
            except ValueError as exc:
                raise ValueError(where + str(exc)) from None
        if drag is None and value is None:
            raise ValueError(f"{where}give drag_torque_Nm or drag")
        if drag is None:
            drag = Drag.constant(value)
        elif value is None:
            value = drag.value_Nm if drag.kind == "constant" else None
        elif not (drag.kind == "constant" and drag.value_Nm == value):
            raise ValueError(f"{where}give drag_torque_Nm or drag, not both")
        object.__setattr__(self, "drag_torque_Nm", value)
        object.__setattr__(self, "drag", drag)

    @property
    def drive_radius_m(self) -> float:
        """The driving gear's base radius ``R_d`` [m]."""
        return self.base_radius_m if self.driver_radius_m is None else self.driver_radius_m

    def replace(self, **changes: Any) -> "Gear":
        """A checked copy with some fields changed; a new ``drag_torque_Nm`` replaces the
        drag, and a new ``drag`` the constant."""
        if "drag_torque_Nm" in changes and "drag" not in changes:
            changes["drag"] = None
        elif "drag" in changes and "drag_torque_Nm" not in changes:
            changes["drag_torque_Nm"] = None
        return dataclasses.replace(self, **changes)

    def canonical(self) -> dict:
        """What the gear is, for cache keys."""
        out = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        out["drag"] = self.drag.canonical()
        return out


@dataclasses.dataclass(frozen=True, eq=False)
class Excitation:
    """The measured shaft's orders: from an :class:`OrderMap` or constant (module docstring)."""

    engine_order: float = 2.0
    harmonics: int = 3
    order_map: OrderMap | None = None
    constant: tuple[tuple[float, float, float, str], ...] = ()

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        set_(self, "engine_order", check_range("engine_order", self.engine_order, *ORDER_RANGE,
                                               lo_open=True))
        h = check_range("harmonics", self.harmonics, 1, MAX_ORDERS)
        if h != int(h):
            raise ValueError(f"harmonics = {self.harmonics!r} must be a whole number in [1, {MAX_ORDERS}]")
        set_(self, "harmonics", int(h))
        if self.order_map is None and not self.constant:
            raise ValueError("[excitation] needs a measurement or a list of orders")
        if self.order_map is not None:
            self.order_map.harmonics(self.order_map.rpm[:1], self.engine_order, self.harmonics)
        else:
            found = [o for o, *_ in self.constant]
            if not any(math.isclose(o, self.engine_order) for o in found):
                raise ValueError(f"[excitation] orders must include the fundamental, engine order "
                                 f"{self.engine_order:g}")

    @property
    def engine_orders(self) -> np.ndarray:
        """Engine orders of the model's harmonics ``1..harmonics``."""
        return self.engine_order * np.arange(1, self.harmonics + 1)

    @property
    def rpm_range(self) -> tuple[float, float]:
        """Speeds the excitation answers for [rpm]."""
        if self.order_map is not None:
            return self.order_map.rpm_range
        return (0.0, RPM_RANGE[1])

    def shaft(self, rpm: Any) -> tuple[np.ndarray, np.ndarray]:
        """``(θ_k [rad], φ_k [deg])`` of the measured shaft at each speed, shape (n, harmonics)."""
        r = np.atleast_1d(np.asarray(rpm, dtype=np.float64))
        if self.order_map is not None:
            return self.order_map.harmonics(r, self.engine_order, self.harmonics)
        theta = np.zeros((r.size, self.harmonics))
        phase = np.zeros((r.size, self.harmonics))
        omega = r * 2 * math.pi / 60
        for n, k in enumerate(self.engine_orders):
            for order, value, ph, kind in self.constant:
                if math.isclose(order, k):
                    theta[:, n] = value / (k * omega) ** 2 if kind == "accel" else value
                    phase[:, n] = ph
        return theta, phase

    def follow(self, phys: PhysicalParams, rpm: float, speed_ratio: float = 1.0) -> PhysicalParams:
        """``phys`` at engine speed ``rpm`` with its harmonics taken from this excitation: the
        driving gear's displacement amplitudes are ``speed_ratio`` times the shaft's at engine
        orders ``engine_order × (1..harmonics)``, with their phases, and the fundamental's
        order is ``engine_order``; every other input of ``phys`` is kept."""
        theta, phase = self.shaft([rpm])
        return phys.replace(rpm=float(rpm), amplitudes=tuple(theta[0] * speed_ratio),
                            phases_deg=tuple(phase[0]), order=self.engine_order,
                            excitation="displacement")

    def columns(self, phys: PhysicalParams, rpm: Any, speed_ratio: float = 1.0) -> dict:
        """The model's numbers at each speed when the harmonics follow engine speed: a dict
        ``lam, j, phi1, h2, phi2, ...`` → one value per speed, for
        :func:`~rattle_core.batch.sweep.sweep` (``columns=``)."""
        return model_columns([self.follow(phys, r, speed_ratio).to_dimensionless()
                              for r in np.atleast_1d(np.asarray(rpm, dtype=np.float64))])

    def canonical(self) -> dict:
        """What the excitation is, for cache keys."""
        return {"engine_order": self.engine_order, "harmonics": self.harmonics,
                "order_map": None if self.order_map is None else self.order_map.canonical(),
                "constant": [list(c) for c in self.constant]}


@dataclasses.dataclass(frozen=True, eq=False)
class Gearbox:
    """Loose gears driven by one measured shaft, and how their rattle is heard.

    ``oil`` is the gearbox's oil (needed by a drag that depends on temperature) and
    ``oil_temp_C`` the temperature the drags are taken at (None: ``oil.temp_C``); ``target``
    is the limit curve a verdict compares with (:class:`~rattle_core.model.target.Target`).
    """

    excitation: Excitation
    gears: tuple[Gear, ...]
    transfer_pa_per_ns: float = DEFAULT_TRANSFER_PA_PER_NS
    duration_s: float = DEFAULT_DURATION_S
    oil: Oil | None = None
    oil_temp_C: float | None = None
    target: Target | None = None

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        gears = tuple(self.gears)
        if not 1 <= len(gears) <= MAX_GEARS:
            raise ValueError(f"a gearbox has {len(gears)} gears; the allowed range is 1 to {MAX_GEARS}")
        names = [g.name for g in gears]
        dup = {n for n in names if names.count(n) > 1}
        if dup:
            raise ValueError(f"gear names must differ; {sorted(dup)[0]!r} appears twice")
        set_(self, "gears", gears)
        set_(self, "transfer_pa_per_ns", check_range("transfer_pa_per_ns", self.transfer_pa_per_ns,
                                                     *TRANSFER_RANGE, lo_open=True))
        set_(self, "duration_s", check_range("duration_s", self.duration_s, *DURATION_RANGE))
        if self.oil is not None and not isinstance(self.oil, Oil):
            raise TypeError(f"oil must be an Oil, got {type(self.oil).__name__}")
        if self.target is not None and not isinstance(self.target, Target):
            raise TypeError(f"target must be a Target, got {type(self.target).__name__}")
        temp = self.oil_temp_C
        if temp is None and self.oil is not None:
            temp = self.oil.temp_C
        if temp is not None:
            temp = check_range("oil_temp_C", temp, *TEMP_RANGE)
        set_(self, "oil_temp_C", temp)
        for g in gears:
            if g.drag.needs_oil and self.oil is None:
                raise ValueError(f"gear {g.name!r}: its drag depends on the oil temperature; give "
                                 "the gearbox an [oil] table (iso_vg, nu100_cSt, temp_C)")

    def drag_Nm(self, gear: int, rpm: Any) -> np.ndarray:
        """Gear ``gear``'s drag torque ``C`` [N·m] at each engine speed ``rpm``, at the box's oil
        temperature."""
        g = self.gears[gear]
        try:
            return g.drag.torque(rpm, self.oil_temp_C, self.oil)
        except ValueError as exc:
            raise ValueError(f"gear {g.name!r}: drag: {exc}") from None

    def physical(self, gear: int, rpm: float) -> PhysicalParams:
        """Gear ``gear`` at engine speed ``rpm``, in physical units (displacement amplitudes of
        its driving gear, at this speed's orders, and its drag at this speed and temperature)."""
        g = self.gears[gear]
        theta, phase = self.excitation.shaft([rpm])
        drag = float(self.drag_Nm(gear, [rpm])[0])
        try:
            return PhysicalParams(inertia=g.inertia_kgm2, radius=g.base_radius_m,
                                  drag_torque=drag, backlash=g.backlash_um * 1e-6,
                                  rpm=float(rpm), amplitudes=tuple(theta[0] * g.speed_ratio),
                                  phases_deg=tuple(phase[0]), order=self.excitation.engine_order,
                                  excitation="displacement", r=g.restitution,
                                  driver_radius=g.driver_radius_m)
        except ValueError as exc:
            raise ValueError(f"gear {g.name!r} at {rpm:g} rpm: {exc}") from None

    def inertia_torque_Nm(self, gear: int, rpm: Any, grid: int = 2048) -> np.ndarray:
        """``J R_d max(−θ̈_drive) / R_b`` [N·m] at each speed: the drag that just keeps the gear
        on its driving tooth (the largest inertia torque, evaluated on a grid of the period)."""
        g = self.gears[gear]
        r = np.atleast_1d(np.asarray(rpm, dtype=np.float64))
        theta, phase = self.excitation.shaft(r)
        omega = self.excitation.engine_order * r * 2 * math.pi / 60
        t = np.linspace(0.0, 2 * math.pi, grid, endpoint=False)
        n = np.arange(1, self.excitation.harmonics + 1)
        acc = -np.einsum("rn,rnt->rt", g.speed_ratio * theta * (n[None, :] * omega[:, None]) ** 2,
                         np.cos(n[None, :, None] * t[None, None, :]
                                - np.deg2rad(phase)[:, :, None]))
        return g.inertia_kgm2 * g.drive_radius_m * np.max(-acc, axis=1) / g.base_radius_m

    def contact_ratio(self, gear: int, rpm: Any, grid: int = 2048) -> np.ndarray:
        """``J R_d max(−θ̈_drive) / (R_b C)`` at each speed, ``C`` the drag at that speed and the
        box's temperature: the gear leaves permanent contact where it exceeds 1 (the
        closed-form contact boundary)."""
        return self.inertia_torque_Nm(gear, rpm, grid) / self.drag_Nm(gear, rpm)

    def replace(self, **changes: Any) -> "Gearbox":
        """A checked copy with some fields changed (``oil_temp_C``: the box at another oil
        temperature)."""
        return dataclasses.replace(self, **changes)

    def canonical(self) -> dict:
        """What the gearbox is, for cache keys."""
        return {"excitation": self.excitation.canonical(),
                "gears": [g.canonical() for g in self.gears],
                "transfer_pa_per_ns": self.transfer_pa_per_ns, "duration_s": self.duration_s,
                "oil": None if self.oil is None else self.oil.canonical(),
                "oil_temp_C": self.oil_temp_C,
                "target": None if self.target is None else self.target.canonical()}

    # ----- files -----------------------------------------------------------------------
    @classmethod
    def from_toml(cls, path: str | Path) -> "Gearbox":
        """Read a ``GEARBOX.toml``; a measurement path is relative to the file's folder."""
        p = Path(path)
        label = f"gearbox file {p.name!r}"
        if not p.is_file():
            raise ValueError(f"gearbox file {str(p)!r} does not exist or is not a file")
        if p.stat().st_size > MAX_TOML_BYTES:
            raise ValueError(f"{label} has {p.stat().st_size} bytes; the allowed size is up to "
                             f"{MAX_TOML_BYTES}")
        try:
            text = p.read_text(encoding="utf-8")
        except UnicodeDecodeError as exc:
            raise ValueError(f"{label}, byte {exc.start}: the file is not UTF-8 text") from None
        return cls.from_text(text, base_dir=p.parent, source=label)

    @classmethod
    def from_text(cls, text: str, base_dir: str | Path | None = None,
                  measurement: OrderMap | None = None, source: str = "gearbox text") -> "Gearbox":
        """A gearbox from TOML text.

        ``base_dir`` is where a ``measurement`` file is looked for; with ``base_dir=None``
        (text from an upload) no file is opened: ``measurement`` must be ``"sample"`` or the
        map passed as ``measurement``, which then replaces whatever file the text names.
        ``source`` names the text in error messages (``"gearbox file 'box.toml'"``): every
        error is a one-line ``ValueError``, ``SOURCE, PLACE: what is wrong``.
        """
        try:
            return cls._from_text(text, base_dir, measurement)
        except _FileError as exc:
            raise ValueError(_one_line(f"{source}, {exc.place}: {exc.message}")) from None
        except ValueError as exc:
            raise ValueError(_one_line(f"{source}: {exc}")) from None

    @classmethod
    def _from_text(cls, text: str, base_dir: str | Path | None,
                   measurement: OrderMap | None) -> "Gearbox":
        if not isinstance(text, str):
            raise ValueError(f"the gearbox text must be a str, got {type(text).__name__}")
        if len(text.encode("utf-8", "replace")) > MAX_TOML_BYTES:
            raise ValueError(f"the text is over the allowed size of {MAX_TOML_BYTES} bytes")
        check_nesting(text)
        try:
            data = tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            raise ValueError(f"TOML syntax: {exc}") from None
        except RecursionError:  # check_nesting stops this first; a second guard
            raise ValueError(f"the TOML nests deeper than the parser can follow; the allowed "
                             f"depth is {MAX_TOML_DEPTH}") from None
        check_sizes(data)
        unknown = set(data) - {"excitation", "gear", "sound", "oil", "target"}
        if unknown:
            raise _FileError(f"[{sorted(unknown)[0]}]", "unknown table; allowed: excitation, "
                             "sound, oil, target, gear")
        oil = target = None
        if "oil" in data:
            oil = _subtable(Oil.from_table, data["oil"], "[oil]")
        if "target" in data:
            target = _subtable(Target.from_table, data["target"], "[target]")
        exc_t = _table(data, "excitation", _EXC_KEYS)
        sound_t = _table(data, "sound", _SOUND_KEYS)
        gear_list = data.get("gear", [])
        if not isinstance(gear_list, list) or not gear_list:
            raise _FileError("[[gear]]", "give at least one [[gear]] table")
        if len(gear_list) > MAX_GEARS:
            raise _FileError("[[gear]]", f"{len(gear_list)} gears; the allowed range is 1 to "
                             f"{MAX_GEARS}")
        gears = []
        for i, g in enumerate(gear_list):
            place = f"[[gear]] number {i + 1}"
            if not isinstance(g, dict):
                raise _FileError(place, "is not a table")
            name = g.get("name")
            if isinstance(name, str):
                with _at(place):
                    check_name("name", name)
                place += f" ({name.strip()!r:.100})"
            with _at(place):
                _check_keys(g, _GEAR_KEYS, "")
                missing = {"name", "inertia_kgm2", "base_radius_m", "backlash_um"} - set(g)
                if missing:
                    raise ValueError(f"missing key {sorted(missing)[0]!r}")
                if ("drag_torque_Nm" in g) == ("drag" in g):
                    raise ValueError("give exactly one of drag_torque_Nm (a constant [N·m]) "
                                     "and drag (a constant, a table or the oil model)")
                g = dict(g)
                if "drag" in g:
                    g["drag"] = Drag.from_value(g["drag"], "drag")
                g.setdefault("drag_torque_Nm", None)
            try:
                gears.append(Gear(**g))
            except ValueError as exc:
                # the place already names the gear
                text = str(exc)
                own = f"gear {name.strip()!r}: " if isinstance(name, str) else ""
                raise _FileError(place, text[len(own):] if own and text.startswith(own)
                                 else text) from None
        with _at("[excitation]"):
            excitation = excitation_from_table(exc_t, base_dir, measurement)
        with _at("[[gear]]"):
            box = cls(excitation=excitation, gears=tuple(gears), oil=oil, target=target)
        with _at("[sound]"):
            return box.replace(
                transfer_pa_per_ns=sound_t.get("transfer_pa_per_ns", DEFAULT_TRANSFER_PA_PER_NS),
                duration_s=sound_t.get("duration_s", DEFAULT_DURATION_S))


def model_columns(points: list) -> dict:
    """Columns of ``points``' dimensionless numbers (RattleParams of the same number of
    harmonics): name → one value per point; Λ, j and every harmonic always, the others where
    they differ."""
    from .params import iter_names
    out = {}
    for name in iter_names(points[0]):
        v = np.array([p.get(name) for p in points])
        if name not in ("r", "v_stick", "noise") or np.ptp(v) > 0:
            out[name] = v
    return out


def excitation_from_table(t: dict, base_dir: str | Path | None,
                          measurement: OrderMap | None = None) -> Excitation:
    """The ``[excitation]`` table of a gearbox file, checked (module docstring); an error names
    its key (``ValueError``, ``[excitation] KEY: ...``)."""
    engine_order = t.get("engine_order", 2.0)
    harmonics = t.get("harmonics", 3)
    with _at("[excitation] engine_order"):
        check_range("engine_order", engine_order, *ORDER_RANGE, lo_open=True)
    with _at("[excitation] harmonics"):
        h = check_range("harmonics", harmonics, 1, MAX_ORDERS)
        if h != int(h):
            raise ValueError(f"harmonics = {harmonics!r} must be a whole number in "
                             f"[1, {MAX_ORDERS}]")
    if "measurement" in t and "orders" in t:
        raise _FileError("[excitation]", "give measurement or orders, not both")
    if "orders" in t:
        constant = []
        if not isinstance(t["orders"], list) or not t["orders"]:
            raise _FileError("[excitation] orders", "must be a list of tables, e.g. "
                             "[{order = 2, accel_rad_s2 = 400, phase_deg = 0}]")
        for i, item in enumerate(t["orders"]):
            place = f"[excitation] orders[{i}]"
            if not isinstance(item, dict) or "order" not in item or \
                    ("accel_rad_s2" in item) == ("amplitude_rad" in item) or \
                    set(item) - {"order", "accel_rad_s2", "amplitude_rad", "phase_deg"}:
                raise _FileError(place, f"{item!r:.100} must hold order, one of accel_rad_s2 or "
                                 "amplitude_rad, and optionally phase_deg")
            with _at(place):
                order = check_range("order", item["order"], *ORDER_RANGE, lo_open=True)
                if "accel_rad_s2" in item:
                    value = check_range("accel_rad_s2", item["accel_rad_s2"], *ALPHA_RANGE)
                    kind = "accel"
                else:
                    value = check_range("amplitude_rad", item["amplitude_rad"], *THETA_RANGE)
                    kind = "disp"
                phase = check_range("phase_deg", item.get("phase_deg", 0.0), -360.0, 360.0)
            constant.append((order, value, phase, kind))
        with _at("[excitation] orders"):
            return Excitation(engine_order=engine_order, harmonics=harmonics,
                              constant=tuple(constant))
    if measurement is not None:
        with _at("[excitation]"):
            return Excitation(engine_order=engine_order, harmonics=harmonics,
                              order_map=measurement)
    name = t.get("measurement")
    if not isinstance(name, str) or not name.strip():
        raise _FileError("[excitation] measurement",
                         "give measurement = \"FILE.csv\" (or \"sample\"), or orders")
    with _at("[excitation] measurement"):
        check_name("the file name", name)
    orders = [engine_order * n for n in range(1, int(h) + 1)]
    step = t.get("rpm_step", 100.0)
    if name == "sample":
        path = SAMPLE_RUNUP
    elif base_dir is None:
        raise _FileError("[excitation] measurement", f"{name!r}: a gearbox given as text names "
                         "no file; upload the measurement beside it, or use \"sample\"")
    else:
        path = Path(base_dir) / name
    with _at(f"[excitation] measurement = {name!r:.200}"):
        order_map = OrderMap.read(path, orders, step, **measurement_options(t))
    with _at("[excitation]"):
        return Excitation(engine_order=engine_order, harmonics=harmonics, order_map=order_map)


__all__ = ["Gear", "Gearbox", "Excitation", "excitation_from_table", "model_columns", "check_name",
           "check_nesting", "check_sizes", "MAX_GEARS", "MAX_TOML_DEPTH", "MAX_TOML_ARRAY",
           "MAX_TOML_STRING", "DEFAULT_TRANSFER_PA_PER_NS", "DEFAULT_DURATION_S"]
