"""The continued parameter: the user's units and the internal value the equations use.

The shooting equations take Λ, r, j, a harmonic amplitude h_K or a phase φ_K (in radians) as
their parameter ``q``.  Engine speed and drag torque are reparametrisations of Λ (or of j, for
engine speed with the acceleration amplitudes held), so a branch in rpm or N·m is the same
computation, reported in other units.
"""
from __future__ import annotations

import dataclasses
import math
from typing import Any

from ...model.params import RattleParams, parse_name

PARAMETERS = ("lam", "r", "j", "hK", "phiK", "rpm", "drag_torque")

_KIND_LAM, _KIND_R, _KIND_J, _KIND_H, _KIND_PHI = 0, 1, 2, 3, 4


@dataclasses.dataclass(frozen=True)
class _Param:
    """The continued parameter: user units ↔ the internal value ``q`` the equations use.

    ``q`` is Λ, r, j, h_K, or φ_K in radians.  Engine speed and drag torque are
    reparametrisations of Λ (or of j, for engine speed with acceleration amplitudes held).
    """

    name: str
    kind: int
    kidx: int
    base: RattleParams
    physical: Any = None

    @classmethod
    def make(cls, name: str, base: RattleParams, physical=None) -> "_Param":
        if not isinstance(name, str):
            raise ValueError(f"param must be a parameter name, got {name!r}; allowed: "
                             f"{', '.join(PARAMETERS)} (K = 1..32)")
        if name in ("rpm", "drag_torque"):
            from ...model.units import PhysicalParams
            if not isinstance(physical, PhysicalParams):
                raise ValueError(f"param = {name!r} needs physical= a PhysicalParams "
                                 f"(got {type(physical).__name__})")
            base = physical.to_dimensionless()
            if name == "rpm" and physical.excitation == "acceleration":
                return cls(name, _KIND_J, 0, base, physical)
            return cls(name, _KIND_LAM, 0, base, physical)
        if name == "v_stick":
            raise ValueError("param = 'v_stick' cannot be continued: it sets only where chatter "
                             f"ends; allowed: {', '.join(PARAMETERS)} (K = 1..32)")
        try:
            kind, k = parse_name(name)
        except ValueError:
            raise ValueError(f"param = {name!r} is not a continuation parameter; allowed: "
                             f"{', '.join(PARAMETERS)} (K = 1..32)") from None
        if kind in ("h", "phi"):
            base = base.with_value(name, base.get(name))
            if kind == "phi" and base.amplitudes[k - 1] == 0.0:
                raise ValueError(f"param = {name!r} has no effect while h{k} = 0 (harmonic {k} "
                                 f"is absent); give h{k} > 0 first")
            return cls(name, _KIND_H if kind == "h" else _KIND_PHI, k - 1, base, None)
        return cls(name, {"lam": _KIND_LAM, "r": _KIND_R, "j": _KIND_J}[kind], 0, base, None)

    # internal value and user value
    def q_of(self, value: float) -> float:
        value = float(value)
        if self.name == "rpm":
            ph = self.physical
            ref = self.base.lam if self.kind == _KIND_LAM else self.base.j
            return ref * (value / ph.rpm) ** 2
        if self.name == "drag_torque":
            return self.base.lam * self.physical.drag_torque / value
        if self.kind == _KIND_PHI:
            return math.radians(value)
        return value

    def value_of(self, q: float) -> float:
        q = float(q)
        if self.name == "rpm":
            ref = self.base.lam if self.kind == _KIND_LAM else self.base.j
            return self.physical.rpm * math.sqrt(q / ref)
        if self.name == "drag_torque":
            return self.physical.drag_torque * self.base.lam / q
        if self.kind == _KIND_PHI:
            return math.degrees(q)
        return q

    @property
    def q0(self) -> float:
        b = self.base
        if self.kind == _KIND_LAM:
            return b.lam
        if self.kind == _KIND_R:
            return b.r
        if self.kind == _KIND_J:
            return b.j
        return float(b.h[self.kidx] if self.kind == _KIND_H else b.phi[self.kidx])

    def arrays(self):
        b = self.base
        return b.lam, b.r, b.j, b.h, b.phi

    def params(self, q: float) -> RattleParams:
        """The :class:`RattleParams` at internal value ``q`` (validated)."""
        b = self.base
        if self.kind == _KIND_LAM:
            return b.replace(lam=float(q))
        if self.kind == _KIND_R:
            return b.replace(r=float(q))
        if self.kind == _KIND_J:
            return b.replace(j=float(q))
        k = self.kidx + 1
        if self.kind == _KIND_H:
            return b.with_value(f"h{k}", float(q))
        return b.with_value(f"phi{k}", math.degrees(q))

    def q_range(self) -> tuple[float, float]:
        """Allowed internal values (the model's own ranges)."""
        from ...model.params import AMPLITUDE_RANGE, J_RANGE, LAM_RANGE, PHASE_RANGE_DEG, R_RANGE
        if self.kind == _KIND_LAM:
            return LAM_RANGE
        if self.kind == _KIND_R:
            return R_RANGE
        if self.kind == _KIND_J:
            return J_RANGE
        if self.kind == _KIND_H:
            return AMPLITUDE_RANGE
        return tuple(math.radians(v) for v in PHASE_RANGE_DEG)
