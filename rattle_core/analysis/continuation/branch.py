"""One impact sequence under one continued parameter: tangent, corrector, solve at fixed ``q``."""
from __future__ import annotations

import numpy as np

from .defining import _null_vector
from .orbits import PeriodicOrbit, _impact_orbit
from .parameter import _Param
from .shooting import NEWTON_TOL, _newton, _set_params, _system


class _Branch:
    """One impact sequence ``(flanks, period)`` under one continued parameter."""

    def __init__(self, spec: _Param, fl: np.ndarray, n: int):
        self.spec = spec
        self.fl = np.ascontiguousarray(fl, dtype=np.int8)
        self.n = int(n)
        self.lam, self.r, self.j, self.h, self.phi = spec.arrays()
        self.m2 = 2 * len(self.fl)

    def system(self, z, q):
        lam, r, j, h, phi = self._at(q)
        F = np.empty(self.m2)
        J = np.empty((self.m2, self.m2))
        Fp = np.empty(self.m2)
        _system(z, self.fl, self.n, lam, r, j, h, phi, self.spec.kind, self.spec.kidx, F, J, Fp)
        return F, J, Fp

    def _at(self, q):
        return _set_params(float(q), self.spec.kind, self.spec.kidx, self.lam, self.r, self.j,
                           self.h, self.phi)

    def tangent(self, z, q, prev: np.ndarray | None):
        """Unit null vector of ``[∂F/∂z | ∂F/∂q]``, oriented along ``prev``."""
        F, J, Fp = self.system(z, q)
        return _null_vector(np.hstack([J, Fp[:, None]]), prev)

    def correct(self, X_pred, tau, maxit=12):
        z = X_pred[:-1].copy()
        lam, r, j, h, phi = self.lam, self.r, self.j, self.h, self.phi
        st, q, it, res = _newton(z, float(X_pred[-1]), self.fl, self.n, lam, r, j, h, phi,
                                 self.spec.kind, self.spec.kidx, tau, X_pred, True, NEWTON_TOL,
                                 maxit)
        if st != 0:
            return None, it
        return np.append(z, q), it

    def solve_at(self, z, q, maxit=30):
        z = z.copy()
        st, _, it, res = _newton(z, float(q), self.fl, self.n, self.lam, self.r, self.j, self.h,
                                 self.phi, self.spec.kind, self.spec.kidx, np.zeros(1),
                                 np.zeros(1), False, NEWTON_TOL, maxit)
        return (z if st == 0 else None), it

    def orbit(self, X) -> PeriodicOrbit:
        return _impact_orbit(self.spec.params(X[-1]), X[:-1].copy(), self.fl, self.n)
