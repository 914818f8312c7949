"""Grazing and sticking points, exactly there and at the neighbouring floats.

At a grazing impact the relative velocity ``w`` is zero and the local maps, which carry a
factor ``1/w``, do not exist.  Continuation locates such points by regula falsi, which may land
on ``w = 0.0`` exactly.  These tests take located points of several branches (a flight that
touches a wall, an impact that slows to zero, an onset of sticking, the events of a branch that
sticks), build the point where ``w`` is exactly zero, and walk the floats around them: every
kernel and test function gives a finite value or a flagged NaN there, and none raises.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, note, settings
from hypothesis import strategies as st

from rattle_core import RattleParams
from rattle_core.analysis.continuation import c_orbit, continue_orbit, find_orbit
from rattle_core.analysis.continuation.branch import _Branch
from rattle_core.analysis.continuation.events import (_admissible_sign, _event, _light, _locate,
                                                      _tests_of)
from rattle_core.analysis.continuation.results import _Run
from rattle_core.analysis.continuation.stability import (_flip_vectors, _local_maps, _maps,
                                                         _velocities)
from rattle_core.analysis.continuation.sticking import (_handle, _signature, _stick_at,
                                                        _stick_margin, _w_min)
from rattle_core.model.excitation import excitation

SETTINGS = settings(max_examples=120, deadline=None, derandomize=True,
                    suppress_health_check=[HealthCheck.too_slow,
                                           HealthCheck.function_scoped_fixture])


def _step(x: float, n: int) -> float:
    """``x`` moved by ``n`` floats."""
    toward = math.inf if n > 0 else -math.inf
    for _ in range(abs(n)):
        x = math.nextafter(x, toward)
    return x


def _w(br: _Branch, X) -> np.ndarray:
    lam, r, j, h, phi = br._at(X[-1])
    w = np.empty(len(br.fl))
    _velocities(X[:-1], br.fl, br.n, lam, h, phi, w)
    return w


def _exact_zero(br: _Branch, X, k: int):
    """``X`` with impact ``k``'s relative velocity exactly 0.0, or None if none is found.

    ``w = (u − s/Λ) − ẏ(t_k)`` of the flight that ends at impact ``k``: its velocity ``u`` is
    moved by ``−w`` (``∂w/∂u = 1``) and then by a few floats, with ``t_k`` moved by up to 400
    floats, until the rounded ``w`` is zero.
    """
    i = k - 1 if k > 0 else len(br.fl) - 1
    for dt in sorted(range(-400, 401), key=abs):
        Y = X.copy()
        Y[2 * k] = X[2 * k] + dt * np.spacing(X[2 * k])
        u0 = Y[2 * i + 1] - _w(br, Y)[k]
        for du in sorted(range(-8, 9), key=abs):
            Y[2 * i + 1] = u0 + du * np.spacing(u0)
            if _w(br, Y)[k] == 0.0:
                return Y
    return None


def _inserted(br: _Branch, X, orb):
    """The branch and point with an impact inserted where a flight touches its wall (its
    incoming relative velocity is the touching flight's: zero to rounding)."""
    k, tg, wall = orb.gap_where
    p = orb.params
    z = X[:-1]
    z_new = np.concatenate([z[:2 * k + 2], [tg, float(excitation(tg, p.h, p.phi, 1))],
                            z[2 * k + 2:]])
    fl_new = np.concatenate([br.fl[:k + 1], [wall], br.fl[k + 1:]]).astype(np.int8)
    return _Branch(br.spec, fl_new, br.n), np.append(z_new, X[-1]), k + 1


@pytest.fixture(scope="module")
def located():
    """Located points of several branches: impact orbits as ``(name, branch, X, impact,
    v_stick)`` (``impact``: the slow one, −1 for none) and orbits that stick as ``(name,
    bifurcation)``; each grazing impact also at its exact zero."""
    un = c_orbit(RattleParams(lam=1.5), which="unstable")
    touch = continue_orbit(un, "lam", bounds=(1.5, 6.0)).bifurcations[-1]
    assert touch.kind == "grazing" and touch.detail["type"] == "flight"
    gained = continue_orbit(touch, bounds=(1.0, 6.0), max_points=5)
    travel = 1 if touch.value > gained.points["value"].iloc[-1] else -1
    lost = continue_orbit(gained.orbit(len(gained.points) - 1), "lam", bounds=(1.0, 6.0),
                          direction=travel).bifurcations[-1]
    assert lost.kind == "grazing" and lost.detail["type"] == "impact"
    p = RattleParams(lam=1.05, r=0.3, v_stick=1e-3)
    up = continue_orbit(find_orbit(p), "lam", bounds=(1.0, 3.0))
    onset = continue_orbit(up.bifurcations[-1], bounds=(1.0, 3.0)).bifurcations[-1]
    assert onset.kind == "stick_onset"
    stuck = continue_orbit(onset, bounds=(1.0, 3.0))
    br_t, X_t = touch._restart[1], touch._restart[2]
    br_i, X_i, k_i = _inserted(br_t, X_t, touch.orbit)
    impact = [
        ("a flight touches the active flank", br_t, X_t, -1, 0.0),
        ("the touching impact inserted", br_i, X_i, k_i, 0.0),
        ("an impact slows to zero", lost._restart[1], lost._restart[2], lost.detail["impact"],
         0.0),
        ("an impact slows to v_stick on a pushing flank", onset._restart[1], onset._restart[2],
         onset.detail["impact"], 1e-3),
    ]
    for name, br, X, k, vs in list(impact):
        if k >= 0 and vs == 0.0:
            Z = _exact_zero(br, X, k)
            assert Z is not None, name
            impact.append((name + ", w exactly 0", br, Z, k, vs))
    sticking = [(f"{b.kind} of an orbit that sticks", b)
                for b in up.bifurcations + stuck.bifurcations if b.orbit.kind == "stick"]
    assert len(sticking) >= 2
    return {"impact": impact, "stick": sticking, "lost": lost}


def test_an_impact_at_exactly_zero_velocity_is_flagged_and_is_the_limit_of_its_neighbours(
        located):
    """At ``w = 0.0`` exactly the kernels return the count of grazing impacts and NaN
    matrices, instead of raising; on either side ``S`` grows like ``1/w`` and keeps
    ``det S = r^(2m)`` (each saltation has determinant r², each flight shear 1)."""
    name, br, Z, k, vs = next(e for e in located["impact"]
                              if e[0] == "an impact slows to zero, w exactly 0")
    lam, r, j, h, phi = br._at(Z[-1])
    m = len(br.fl)
    w, M, S = np.empty(m), np.empty((2, 2)), np.empty((2, 2))
    assert _maps(Z[:-1], br.fl, br.n, lam, r, j, h, phi, w, M, S) == 1
    assert w[k] == 0.0 and np.all(np.isnan(M)) and np.all(np.isnan(S))
    D = np.empty((m, 2, 2))
    assert _local_maps(Z[:-1], br.fl, br.n, lam, r, h, phi, D) == 1
    i = k - 1 if k > 0 else m - 1
    assert np.all(np.isnan(D[i])) and np.all(np.isfinite(np.delete(D, i, axis=0)))
    assert np.all(np.isnan(_flip_vectors(Z[:-1], br.fl, br.n, lam, r, h, phi)))
    # the test functions that locate the grazing exist there; the multiplier tests do not
    fine = _light(br, Z, vs, monodromy=False)
    assert fine["w"] == 0.0 and np.isfinite(fine["gap"])
    full = _light(br, Z, vs)
    assert full["w"] == 0.0 and math.isnan(full["pd"]) and math.isnan(full["tr"])
    orb = br.orbit(Z)
    assert np.all(np.isnan(orb.multipliers.real)) and not orb.stable
    # beside it, S is finite, of size ~ 1/|w|, with the closed-form determinant
    u = Z[2 * i + 1]
    sizes = []
    for du in (1e-4, -1e-4, 1e-5, -1e-5):
        Y = Z.copy()
        Y[2 * i + 1] = u + du
        assert _maps(Y[:-1], br.fl, br.n, lam, r, j, h, phi, w, M, S) == 0
        assert np.all(np.isfinite(S))
        det = S[0, 0] * S[1, 1] - S[0, 1] * S[1, 0]
        # (the products cancel: rounding leaves about eps·|S|² of the determinant)
        assert abs(det - r ** (2 * m)) < 1e-9 + 1e-15 * np.max(np.abs(S)) ** 2
        sizes.append(np.max(np.abs(S)) * abs(w[k]))
    assert max(sizes) / min(sizes) < 1.01


def test_the_grazing_is_located_on_w_and_recorded_at_its_exact_zero(located):
    """Regula falsi on the slowing impact's speed, from a point before the grazing to one
    past it, finds the grazing to 1e-9 (the test function exists at every trial point);
    recording the event at ``w = 0.0`` exactly reports it with NaN multipliers instead of
    raising."""
    lost = located["lost"]
    name, br, Z, k, vs = next(e for e in located["impact"]
                              if e[0] == "an impact slows to zero, w exactly 0")
    tau = lost._restart[3]
    X0 = Z.copy()
    X0[-1] = Z[-1] - 1e-4 * math.copysign(1.0, tau[-1])
    X0, _ = br.correct(X0, tau)
    h_hi = 2.0 * float(tau @ (Z - X0))
    X1, _ = br.correct(X0 + h_hi * tau, tau)
    f0, f1 = (_light(br, Y, vs, monodromy=False)["w"] for Y in (X0, X1))
    assert f0 > 0.0 > f1
    Xe, fe = _locate(br, X0, tau, h_hi, f0, f1,
                     lambda Y: _light(br, Y, vs, monodromy=False)["w"], 1e-11)
    assert Xe is not None and abs(fe) < 1e-12
    assert Xe[-1] == pytest.approx(Z[-1], abs=1e-9)
    run = _Run(lost._spec, 0.0, 10.0, 100, None, None, vs)
    assert _event(run, br, "w", Z, tau)
    (b,) = run.bifs
    assert b.kind == "grazing" and b.detail["w"] == 0.0
    assert all(math.isnan(m.real) for m in b.orbit.multipliers)


@SETTINGS
@given(data=st.data())
def test_no_exception_escapes_at_or_beside_a_grazing_or_sticking_impact(located, data):
    """At a located point, its exact-zero twin, and floats around them (in the parameter
    and in the velocity of the slow impact's flight), every kernel and test function
    returns: ``w`` and the gaps finite, the matrices finite or flagged NaN, as many flags as
    impacts at ``w = 0``, and ``det S = r^(2m)`` wherever ``S`` is finite."""
    name, br, X, k, vs = data.draw(st.sampled_from(located["impact"]), label="point")
    Y = X.copy()
    Y[-1] = _step(float(X[-1]), data.draw(st.integers(-64, 64), label="parameter floats"))
    if k >= 0:
        i = k - 1 if k > 0 else len(br.fl) - 1
        Y[2 * i + 1] = _step(float(X[2 * i + 1]),
                             data.draw(st.integers(-64, 64), label="velocity floats"))
    note(name)
    lam, r, j, h, phi = br._at(Y[-1])
    m = len(br.fl)
    w = _w(br, Y)
    assert np.all(np.isfinite(w))
    w2, M, S = np.empty(m), np.empty((2, 2)), np.empty((2, 2))
    flags = _maps(Y[:-1], br.fl, br.n, lam, r, j, h, phi, w2, M, S)
    assert np.array_equal(w, w2) and flags == int(np.sum(w == 0.0))
    if flags:
        assert np.all(np.isnan(M)) and np.all(np.isnan(S))
    else:
        assert not np.any(np.isnan(S))
        if np.all(np.isfinite(S)):
            det = S[0, 0] * S[1, 1] - S[0, 1] * S[1, 0]
            assert abs(det - r ** (2 * m)) <= 1e-9 * (1.0 + np.max(np.abs(S)) ** 2)
    D = np.empty((m, 2, 2))
    assert _local_maps(Y[:-1], br.fl, br.n, lam, r, h, phi, D) == flags
    delta = _flip_vectors(Y[:-1], br.fl, br.n, lam, r, h, phi)
    assert np.all(np.isnan(delta)) if flags else not np.any(np.isnan(delta))
    fine = _light(br, Y, vs, monodromy=False)
    assert all(np.all(np.isfinite(fine[key])) for key in ("w", "speed", "react"))
    assert not math.isnan(fine["gap"])
    full = _light(br, Y, vs)
    assert np.array_equal(full["speed"], fine["speed"])
    assert math.isnan(full["pd"]) == bool(flags)
    assert flags or abs(full["pd"]) <= 1.0 + 1e-12
    _admissible_sign(br, Y, vs)
    orb = br.orbit(Y)
    tests = _tests_of(orb, vs)
    assert tests["w"] == fine["w"] and math.isnan(tests["pd"]) == bool(flags)


@settings(max_examples=24, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_orbits_that_stick_are_solved_or_refused_around_their_events(located, data):
    """Around an event of a branch that sticks (an end of sticking, a grazing), the stick
    orbit through the same release is solved or refused (None), never raises, and what it
    reports is finite: its stick phase, its slowest impact, its signature."""
    name, b = data.draw(st.sampled_from(located["stick"]), label="event")
    q = _step(float(b.q), data.draw(st.integers(-64, 64), label="parameter floats"))
    note(f"{name} at q = {q!r}")
    orb = _stick_at(b._spec, q, _handle(b.orbit))
    if orb is None:
        return
    assert orb.kind == "stick" and len(orb.stick)
    assert np.isfinite(_stick_margin(orb)) and _stick_margin(orb) >= 0.0
    assert not math.isnan(_w_min(orb))
    assert _signature(orb)[0] == "stick"
