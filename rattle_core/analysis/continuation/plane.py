"""Two continued parameters at once: the plane a bifurcation curve lives in.

A bifurcation located in one parameter ``p₁`` is followed as a second one, ``p₂``, changes.
Each is held as the internal value ``q`` the equations use (:class:`~.parameter._Param`): Λ, r,
j, h_K, or φ_K in radians, with engine speed and drag torque as reparametrisations of Λ (or of
j).  The two must set different model numbers, with one exception: engine speed and drag
torque both scale Λ (``Λ = Λ₀ (n/n₀)² C₀/C``), so in that plane ``Λ = q₁ q₂ / Λ₀``.
"""
from __future__ import annotations

import math

import numpy as np

from ...model.params import RattleParams
from .parameter import _KIND_H, _KIND_J, _KIND_LAM, _KIND_PHI, _KIND_R, _Param
from .shooting import _set_params, _system

_MODEL_NAME = {_KIND_LAM: "lam", _KIND_R: "r", _KIND_J: "j"}


class _Plane:
    """The parameters ``(q₁, q₂)`` ↔ the model's numbers, with their derivatives."""

    def __init__(self, spec1: _Param, spec2: _Param, base: RattleParams):
        self.spec1, self.spec2 = spec1, spec2
        same = (spec1.kind, spec1.kidx) == (spec2.kind, spec2.kidx)
        self.product = same and {spec1.name, spec2.name} == {"rpm", "drag_torque"} and \
            spec1.kind == _KIND_LAM
        if same and not self.product:
            raise ValueError(f"param2 = {spec2.name!r} sets the same model number as "
                             f"{spec1.name!r}; choose a parameter that changes something else")
        # a base with every harmonic either parameter names (h_K, φ_K padded with zeros)
        for spec in (spec1, spec2):
            if spec.kind in (_KIND_H, _KIND_PHI):
                name = f"h{spec.kidx + 1}"
                base = base.with_value(name, base.get(name))
        self.base = base
        self.lam0 = float(spec1.base.lam if spec1.name == "rpm" else spec2.base.lam) \
            if self.product else math.nan
        self.arrays = (float(base.lam), float(base.r), float(base.j),
                       np.ascontiguousarray(base.h), np.ascontiguousarray(base.phi))

    @property
    def names(self) -> tuple[str, str]:
        return self.spec1.name, self.spec2.name

    def at(self, q1: float, q2: float):
        """``(Λ, r, j, h, φ)`` at ``(q₁, q₂)`` (phases in radians)."""
        lam, r, j, h, phi = self.arrays
        if self.product:
            return (q1 * q2 / self.lam0, r, j, h.copy(), phi.copy())
        lam, r, j, h, phi = _set_params(float(q1), self.spec1.kind, self.spec1.kidx, lam, r, j,
                                        h, phi)
        return _set_params(float(q2), self.spec2.kind, self.spec2.kidx, lam, r, j, h, phi)

    def kinds(self, q1: float, q2: float):
        """For each parameter: the model number it moves (kind, index) and ``d number / d q``."""
        if self.product:
            return ((_KIND_LAM, 0, q2 / self.lam0), (_KIND_LAM, 0, q1 / self.lam0))
        return ((self.spec1.kind, self.spec1.kidx, 1.0), (self.spec2.kind, self.spec2.kidx, 1.0))

    def params(self, q1: float, q2: float) -> RattleParams:
        """The validated :class:`RattleParams` at ``(q₁, q₂)``."""
        lam, r, j, h, phi = self.at(q1, q2)
        p = self.base.replace(lam=float(lam), r=float(r), j=float(j))
        for (kind, kidx, _) in self.kinds(q1, q2):
            if kind == _KIND_H:
                p = p.with_value(f"h{kidx + 1}", float(h[kidx]))
            elif kind == _KIND_PHI:
                p = p.with_value(f"phi{kidx + 1}", math.degrees(phi[kidx]))
        return p

    def system(self, z, fl, n, q1, q2):
        """Shooting residual ``F``, ``∂F/∂z`` and ``∂F/∂q₁``, ``∂F/∂q₂`` at ``(q₁, q₂)``."""
        lam, r, j, h, phi = self.at(q1, q2)
        m2 = len(z)
        F = np.empty(m2)
        J = np.empty((m2, m2))
        cols = []
        for kind, kidx, scale in self.kinds(q1, q2):
            Fp = np.empty(m2)
            _system(z, fl, n, lam, r, j, h, phi, kind, kidx, F, J, Fp)
            cols.append(Fp * scale)
        return F, J, cols[0], cols[1]

    def value_of(self, q1: float, q2: float) -> tuple[float, float]:
        """Both parameters in the user's units."""
        return self.spec1.value_of(q1), self.spec2.value_of(q2)


def _dy_dparam(kind: int, kidx: int, order: int, t, h, phi) -> float:
    """``∂y⁽ᵐ⁾(t)/∂p`` for the model number ``p`` = h_K or φ_K (zero for Λ, r, j)."""
    if kind not in (_KIND_H, _KIND_PHI):
        return 0.0
    k = kidx + 1.0
    arg = k * t - phi[kidx] + order * 0.5 * math.pi
    if kind == _KIND_H:
        return k ** order * math.cos(arg)
    return h[kidx] * k ** order * math.sin(arg)


def _model_name(kind: int, kidx: int) -> str:
    if kind == _KIND_H:
        return f"h{kidx + 1}"
    if kind == _KIND_PHI:
        return f"phi{kidx + 1}"
    return _MODEL_NAME[kind]
