"""Continuation of periodic orbits: closed forms, brute-force simulation and finite differences.

Every number continuation produces is checked against something computed another way: the
closed-form regime C orbit and its period doubling and fold, ``simulate`` (the exact event
solver, run forward from the orbit or from elsewhere), sweeps, and finite differences of the
stroboscopic map.
"""
from __future__ import annotations

import math
import threading

import numpy as np
import pytest

from rattle_core import RattleParams, classify, simulate, sweep
from rattle_core.analysis import continuation as cont
from rattle_core.analysis.continuation import (Bifurcation, ContinuationError, c_orbit, continue_orbit,
                                      find_orbit, solve_orbit, stick_orbit)
from rattle_core.model.excitation import excitation

R, J = 0.65, 8.0
GAMMA1 = math.pi * (1 - R) / (1 + R)
LAM_PD = math.sqrt(GAMMA1**2 + (2 * (1 + R**2) / (1 + R) ** 2) ** 2)


def sim(params, **kw):
    """``simulate`` of the deterministic model (no noise): periodic orbits are exact there."""
    return simulate(params.replace(noise=0.0), **kw)


def one_period(orb, at=0.5):
    """Simulate one period of ``orb`` from a point of its first flight (``at`` = fraction of
    it): the impacts are then the orbit's, starting with its second (``np.roll(orb.impulse,
    -1)``)."""
    t1 = orb.t[1] if orb.n_impacts > 1 else orb.t[0] + 2 * np.pi * orb.period
    t0 = float(orb.t[0] + at * (t1 - orb.t[0]))
    x0, v0 = orb.state_at(t0)
    return sim(orb.params, periods=orb.period, t0=t0, x0=float(x0), v0=float(v0))


def strobe_fd_multipliers(orb, d=1e-6):
    """Multipliers from central differences of the n-period stroboscopic map at mid-flight."""
    p = orb.params
    th = float(orb.t[0] + 0.5 * ((orb.t[1] if orb.n_impacts > 1 else orb.t[0] + 2 * np.pi
                                 * orb.period) - orb.t[0]))
    x, v = orb.state_at(th)

    def F(x, v):
        tr = sim(p, periods=orb.period, t0=th, x0=float(x), v0=float(v), record_segments=False)
        return np.array(tr.final_state[1:3])
    Jfd = np.column_stack([(F(x + d, v) - F(x - d, v)) / (2 * d),
                           (F(x, v + d) - F(x, v - d)) / (2 * d)])
    return np.sort_complex(np.linalg.eigvals(Jfd).astype(complex)), F(x, v) - [x, v]


@pytest.fixture(scope="module")
def c_branch():
    return continue_orbit(c_orbit(RattleParams(lam=0.9)), "lam", bounds=(0.9, 1.5))


@pytest.fixture(scope="module")
def e_orbit():
    return find_orbit(RattleParams(lam=3.3))


# ----- orbits as fixed points ----------------------------------------------------------------

def test_closed_form_c_orbit_is_a_fixed_point_and_simulation_converges_to_it():
    """The closed-form C orbit solves the shooting equations; Newton from simulate finds it too."""
    p = RattleParams(lam=1.2)
    a = c_orbit(p)
    assert a.residual < 1e-13 and a.admissible
    assert a.impulse[0] == pytest.approx(2 * np.pi / p.lam, abs=1e-12)
    assert math.sin(a.t[0]) == pytest.approx(-GAMMA1 / p.lam, abs=1e-12)
    b = find_orbit(p)
    assert b.kind == "impact" and b.period == 1 and b.n_impacts == 1
    assert b.t[0] == pytest.approx(a.t[0], abs=1e-11)
    assert b.u[0] == pytest.approx(a.u[0], abs=1e-11)
    # a crude guess converges as well
    c = solve_orbit(p, [a.t[0] + 0.2], [a.u[0] * 1.1], [1], 1)
    assert c.t[0] == pytest.approx(a.t[0], abs=1e-12)


def test_e_orbit_impulses_match_simulation(e_orbit):
    """E at Λ = 3.3 (harmonic): Newton's impulses equal a long simulation's to 1e-9."""
    o = e_orbit
    assert o.period == 1 and sorted(o.flank.tolist()) == [-1, 1] and o.stable
    tr = sim(o.params, periods=4, transient=4000)
    ref = np.sort(tr.impact_impulse[-2:])
    assert np.allclose(np.sort(o.impulse), ref, atol=1e-9, rtol=0)
    assert np.allclose(np.sort(o.phase), np.sort(tr.impact_phase[-2:]), atol=1e-9, rtol=0)
    # from a rough guess: the simulated impacts moved by 1e-2
    rough = solve_orbit(o.params, o.t + 1e-2, o.u - 1e-2, o.flank, 1)
    assert np.allclose(rough.impulse, o.impulse, atol=1e-12, rtol=0)


@pytest.mark.parametrize("lam,which", [(3.3, "E"), (1.25, "P2"), (1.5, "C unstable"),
                                       (1.1, "C stable")])
def test_multipliers_agree_with_finite_differences(lam, which):
    """Floquet multipliers (saltation matrices) equal those of finite differences of the map."""
    p = RattleParams(lam=lam)
    if which == "E":
        o = find_orbit(p)
    elif which == "P2":
        o = find_orbit(p, x0=float(np.cos(5.75)), v0=np.pi / lam + 1e-3, t0=5.75, transient=4000)
        assert o.period == 2
    else:
        o = c_orbit(p, which="unstable" if "unstable" in which else "stable")
    fd, closure = strobe_fd_multipliers(o)
    assert np.max(np.abs(closure)) < 1e-10  # the orbit closes under the simulator
    mu = np.sort_complex(o.multipliers)
    assert np.allclose(mu, fd, atol=1e-6, rtol=0), (mu, fd)
    # the impact-map Jacobian has the same eigenvalues
    m = o.n_impacts
    D = np.empty((m, 2, 2))
    z = np.empty(2 * m)
    z[0::2], z[1::2] = o.t, o.u
    cont._local_maps(z, o.flank, o.period, p.lam, p.r, p.h, p.phi, D)
    M = np.eye(2)
    for i in range(m):
        M = D[i] @ M
    assert np.allclose(np.sort_complex(np.linalg.eigvals(M).astype(complex)), mu, atol=1e-9)


def test_monodromy_determinant_is_r_to_the_2m(e_orbit):
    """Flights keep area and each impact scales it by r², so det M = r^(2m): no torus
    (Neimark–Sacker) bifurcation is possible for r < 1."""
    for o in (e_orbit, c_orbit(RattleParams(lam=1.1)), c_orbit(RattleParams(lam=2.5, r=0.3))):
        assert np.linalg.det(o.monodromy) == pytest.approx(o.params.r ** (2 * o.n_impacts),
                                                          rel=1e-10)


def test_parameter_derivatives_match_finite_differences(e_orbit):
    """∂F/∂p of the shooting equations for Λ, r, j, h2, φ2 equals a central difference."""
    o = e_orbit
    base = o.params.replace(amplitudes=(1.0, 0.2), phases_deg=(0.0, 30.0))
    z = np.empty(2 * o.n_impacts)
    z[0::2], z[1::2] = o.t, o.u
    for name in ("lam", "r", "j", "h2", "phi2", "h3"):
        spec = cont._Param.make(name, base)
        br = cont._Branch(spec, o.flank, o.period)
        q = spec.q0
        _, _, Fp = br.system(z, q)
        d = 1e-6
        fd = (br.system(z, q + d)[0] - br.system(z, q - d)[0]) / (2 * d)
        assert np.allclose(Fp, fd, atol=1e-8), name
        _, Jz, _ = br.system(z, q)
        for k in range(len(z)):
            e = np.zeros(len(z))
            e[k] = d
            col = (br.system(z + e, q)[0] - br.system(z - e, q)[0]) / (2 * d)
            assert np.allclose(Jz[:, k], col, atol=1e-7), (name, k)


# ----- continuation of the C orbit: closed forms ------------------------------------------------

def test_c_orbit_keeps_impulse_two_pi_over_lam_along_branch(c_branch):
    """Along the harmonic C branch every point has Ĩ = 2π/Λ to 1e-9."""
    pts = c_branch.points
    assert len(pts) > 10 and c_branch.status == "bound"
    assert (pts["value"].min() <= 0.9 + 1e-12) and (pts["value"].max() >= 1.5 - 1e-12)
    assert np.allclose(pts["impulse_max"], 2 * np.pi / pts["q"], atol=1e-9, rtol=0)
    assert np.allclose(pts["impulse_min"], 2 * np.pi / pts["q"], atol=1e-9, rtol=0)
    imp = c_branch.impacts
    assert np.allclose(np.sin(imp["t"]), -GAMMA1 / imp["value"], atol=1e-9)


def test_period_doubling_of_c_at_closed_form(c_branch):
    """The C orbit doubles its period at Λ = √(Γ₁² + (2(1+r²)/(1+r)²)²) = 1.23940 (to 1e-8)."""
    pds = [b for b in c_branch.bifurcations if b.kind == "period_doubling"]
    assert len(pds) == 1
    assert LAM_PD == pytest.approx(1.23940, abs=5e-6)
    assert pds[0].value == pytest.approx(LAM_PD, abs=1e-8)
    mu = pds[0].multipliers
    assert np.min(np.abs(mu + 1.0)) < 1e-6
    # stable before, unstable after
    pts = c_branch.points
    assert pts.loc[pts["value"] < LAM_PD - 1e-6, "stable"].all()
    assert not pts.loc[pts["value"] > LAM_PD + 1e-6, "stable"].any()
    assert pds[0].as_dict()["kind"] == "period_doubling"
    assert "period_doubling" in c_branch.bifurcation_table["kind"].tolist()


def test_fold_of_c_at_closed_form_and_unstable_branch_beyond():
    """Going down, the C branch turns back at the fold Λ = Γ₁ (multiplier +1), onto the
    unstable C orbit, whose impulse is still 2π/Λ."""
    res = continue_orbit(c_orbit(RattleParams(lam=0.9)), "lam", bounds=(0.5, 0.9), direction=-1)
    folds = [b for b in res.bifurcations if b.kind == "fold"]
    assert len(folds) == 1
    assert folds[0].value == pytest.approx(GAMMA1, abs=1e-8)
    assert np.min(np.abs(folds[0].multipliers - 1.0)) < 1e-4
    end = res.orbits[-1]
    assert res.status == "bound" and end.params.lam == pytest.approx(0.9, abs=1e-12)
    assert not end.stable and math.cos(end.t[0]) < 0
    assert end.impulse[0] == pytest.approx(2 * np.pi / 0.9, abs=1e-9)
    un = c_orbit(RattleParams(lam=0.9), which="unstable")
    assert end.t[0] == pytest.approx(un.t[0], abs=1e-9)


def test_period_two_branch_matches_brute_force_simulation(c_branch):
    """Switched onto at the period doubling, the period-2 branch is the orbit a simulation
    started near the old C orbit settles on, at two values of Λ."""
    pd = next(b for b in c_branch.bifurcations if b.kind == "period_doubling")
    p2 = continue_orbit(pd, bounds=(1.0, 1.32))
    assert p2.points["period"].iloc[1:].eq(2).all()
    assert p2.points["n_impacts"].eq(2).all()
    for lam in (1.245, 1.3):
        (orb,) = p2.orbit_at(lam)
        assert orb.stable and orb.period == 2
        th = 5.72
        tr = sim(RattleParams(lam=lam), periods=8, transient=6000, t0=th,
                 x0=float(np.cos(th)), v0=np.pi / lam + 1e-3)
        assert np.all(tr.impact_flank == 1)
        assert np.allclose(np.sort(tr.impact_impulse[-2:]), np.sort(orb.impulse), atol=1e-9,
                           rtol=0)
        assert np.allclose(np.sort(tr.impact_phase[-2:]), np.sort(orb.phase), atol=1e-9, rtol=0)
        # and the two impulses really differ: not the doubled C orbit
        assert abs(orb.impulse[0] - orb.impulse[1]) > 1e-3


# ----- the E orbit and a brute-force sweep ---------------------------------------------------------

def test_e_orbit_loses_stability_where_sweep_stops_showing_e(e_orbit):
    """Continued down from Λ = 3.3, E loses stability by period doubling where a continuation
    sweep (following the attractor down) stops showing E, within the sweep's step."""
    res = continue_orbit(e_orbit, "lam", bounds=(1.2, 3.3), direction=-1, max_points=60)
    first = next(b for b in res.bifurcations if b.kind in ("period_doubling", "fold", "grazing",
                                                           "neimark_sacker"))
    assert first.kind == "period_doubling"
    lam_loss = first.value
    pts = res.points
    above = pts[(pts["value"] > lam_loss + 1e-9) & (pts.index < first.point)]
    assert above["stable"].all() and above["n_reverse"].eq(1).all()
    step = 0.005
    vals = np.round(np.arange(1.60, 1.50 - 1e-9, -step), 6)
    s = sweep(RattleParams(lam=3.3), "lam", vals, transient=20000, record=100,
              mode="continuation", x0=float(np.cos(0.0)) + 1.0)
    reg = s.summary["regime"].to_numpy()
    assert reg[0] == "E"
    k = int(np.argmax(reg != "E"))
    assert k > 0
    last_e, first_not = vals[k - 1], vals[k]
    assert first_not - 1e-12 <= lam_loss <= last_e + 1e-12, (first_not, lam_loss, last_e)


# ----- grazing ------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def grazing_run():
    un = c_orbit(RattleParams(lam=1.5), which="unstable")
    return continue_orbit(un, "lam", bounds=(1.5, 6.0))


def test_grazing_found_where_min_gap_crosses_zero_checked_by_simulation(grazing_run):
    """The unstable C orbit grazes the active flank; simulation on either side agrees."""
    res = grazing_run
    assert res.status == "grazing"
    g = res.bifurcations[-1]
    assert g.kind == "grazing" and g.detail["type"] == "flight" and g.detail["wall"] == 1
    assert abs(g.detail["gap"]) < 1e-9
    lam_g = g.value
    assert 2.0 < lam_g < 5.0
    # the gap function brackets the event: positive before, crossing at the located point
    pts = res.points
    assert (pts["gap_min"].iloc[:-1] > 0).all()
    d = 1e-5
    guess = g.orbit
    before = solve_orbit(RattleParams(lam=lam_g - d), guess.t, guess.u, guess.flank, 1)
    after = solve_orbit(RattleParams(lam=lam_g + d), guess.t, guess.u, guess.flank, 1)
    assert before.admissible and before.gap_min > 0
    assert not after.admissible and after.gap_min < 0
    # located to 1e-8: where the event search starts to see the extra contact
    lo, hi = lam_g - 1e-6, lam_g + 1e-6
    while hi - lo > 1e-11:
        mid = 0.5 * (lo + hi)
        ok = solve_orbit(RattleParams(lam=mid), guess.t, guess.u, guess.flank, 1).admissible
        lo, hi = (mid, hi) if ok else (lo, mid)
    assert lo == pytest.approx(lam_g, abs=1e-8)
    tr = one_period(before, at=1e-4)
    assert len(tr.impact_t) == 1  # only the orbit's own impact, at the end of the period
    assert tr.impact_t[0] == pytest.approx(before.t[0] + 2 * np.pi, abs=1e-8)
    tr = one_period(after, at=1e-4)
    assert len(tr.impact_t) >= 1 and tr.impact_flank[0] == 1
    assert tr.impact_t[0] < after.t[0] + 2 * np.pi - 1e-3  # an extra, early impact
    assert tr.impact_t[0] == pytest.approx(g.detail["time"], abs=0.05)
    assert abs(tr.impact_w[0]) < 0.05  # a near-grazing contact


def test_grazing_restart_gains_an_impact(grazing_run):
    """Restarting from the grazing gives an admissible orbit with one more impact, the new one
    near the touching point and slow."""
    g = grazing_run.bifurcations[-1]
    res = continue_orbit(g, bounds=(1.0, 6.0), max_points=30)
    first = res.orbits[0]
    assert first.admissible and first.n_impacts == 2
    k = int(np.argmin(np.abs(first.w)))
    assert abs(first.w[k]) < 0.05
    assert first.t[k] % (2 * np.pi) == pytest.approx(g.detail["time"] % (2 * np.pi), abs=0.05)
    tr = one_period(first)
    assert len(tr.impact_t) == 2
    assert np.allclose(np.sort(tr.impact_impulse), np.sort(first.impulse), atol=1e-9)


def test_gained_impact_is_lost_at_the_same_grazing(grazing_run):
    """Followed back, the branch that gained an impact loses it (its speed reaches zero) at the
    Λ where the old flight touched the wall: two test functions agree to 1e-9.  Restarting
    without it gives back the one-sided orbit, Ĩ = 2π/Λ."""
    g = grazing_run.bifurcations[-1]
    gained = continue_orbit(g, bounds=(1.0, 6.0), max_points=5)
    travel = 1 if g.value > gained.points["value"].iloc[-1] else -1
    back = continue_orbit(gained.orbit(len(gained.points) - 1), "lam", bounds=(1.0, 6.0),
                          direction=travel)
    lost = back.bifurcations[-1]
    assert lost.kind == "grazing" and lost.detail["type"] == "impact"
    assert lost.value == pytest.approx(g.value, abs=1e-9)
    assert abs(lost.detail["w"]) < 1e-9
    again = continue_orbit(lost, bounds=(1.0, 6.0), max_points=10)
    pts = again.points
    assert pts["n_impacts"].eq(1).all()
    assert np.allclose(pts["impulse_max"], 2 * np.pi / pts["value"], atol=1e-9)


# ----- a fold between two attractors --------------------------------------------------------------

def test_unstable_orbit_through_fold_separates_two_attractors():
    """At Λ = 0.68 (harmonic) the stable C orbit coexists with permanent contact (A).  The
    unstable orbit reached through the fold lies between them: its unstable manifold leads
    to C on one side and to A on the other."""
    lam = 0.68
    res = continue_orbit(c_orbit(RattleParams(lam=lam)), "lam", bounds=(0.5, lam), direction=-1)
    assert [b.kind for b in res.bifurcations] == ["fold"]
    u = res.orbits[-1]
    assert u.params.lam == pytest.approx(lam, abs=1e-12) and not u.stable
    mu, vec = np.linalg.eig(u.monodromy)
    k = int(np.argmax(np.abs(mu)))
    assert abs(mu[k]) > 1 and abs(mu[1 - k]) < 1  # a saddle
    e = np.real(vec[:, k])
    tm = u.t[0] + np.pi
    em = np.array([[1.0, np.pi], [0.0, 1.0]]) @ e  # carried from just after the impact
    em /= np.linalg.norm(em)
    x, v = u.state_at(tm)
    ends = []
    for eps in (1e-6, -1e-6):
        tr = sim(u.params, periods=50, transient=400, t0=float(tm), x0=float(x + eps * em[0]),
                 v0=float(v + eps * em[1]), lyapunov=True)
        ends.append(classify(tr))
    regimes = sorted(c.regime for c in ends)
    assert regimes == ["A", "C"]
    c_side = next(c for c in ends if c.regime == "C")
    assert c_side.mean_impulse_active == pytest.approx(2 * np.pi / lam, abs=1e-9)
    # and the stable C orbit is an attractor there
    s = c_orbit(RattleParams(lam=lam))
    assert s.stable and s.admissible


# ----- orbits that stick ----------------------------------------------------------------------------

def test_stick_orbit_is_superstable_and_matches_simulation():
    """In regime B the orbit sticks once a period: multipliers 0, impacts as simulated."""
    p = RattleParams(lam=1.1)
    o = find_orbit(p)
    assert o.kind == "stick" and o.period == 1 and o.stable
    assert np.all(o.multipliers == 0) and np.all(o.monodromy == 0)
    assert o.stick.shape == (1, 3)
    f, ts, tr_ = o.stick[0]
    assert f == 1 and 1.0 + p.lam * float(excitation(tr_, p.h, p.phi, 2)) == pytest.approx(0, abs=1e-12)
    ref = sim(p, periods=3, transient=500)
    last = ref.impact_t >= ref.t_end - 2 * np.pi
    n = int(last.sum())
    assert n == o.n_impacts
    assert np.allclose(np.sort(ref.impact_phase[last]), np.sort(o.phase), atol=1e-9)
    assert np.allclose(np.sort(ref.impact_impulse[last]), np.sort(o.impulse), atol=1e-9)
    # through a release found independently
    again = stick_orbit(p, tr_, 1)
    assert np.allclose(again.impulse, o.impulse, atol=1e-9)


def test_stick_branch_ends_at_permanent_contact_and_at_end_of_sticking():
    """Going down the B orbit meets Λ = 1 (below it R̃ > 0 for ever: regime A); going up its
    stick phase shrinks to nothing, checked by simulation on both sides."""
    o = find_orbit(RattleParams(lam=1.1))
    down = continue_orbit(o, "lam", bounds=(0.5, 1.1), direction=-1)
    assert down.status == "permanent_contact"
    assert down.bifurcations[-1].value == pytest.approx(1.0, abs=1e-8)
    assert not down.bifurcations[-1].can_restart
    up = continue_orbit(o, "lam", bounds=(1.1, 2.0), direction=1)
    assert up.status == "stick_end"
    b = up.bifurcations[-1]
    assert b.detail["stick_time"] < 1e-6
    assert (up.points["stick_time"].diff().iloc[1:] < 0).all()  # shrinking all the way
    lam_e = b.value
    rel = b.orbit.stick[-1, 2] % (2 * np.pi)
    # (1e-8: close enough that no change in the number of chatter impacts resolved above
    # v_stick comes between, each of which perturbs the orbit in a tiny window of Λ)
    for lam, sticks in ((lam_e - 1e-8, True), (lam_e + 1e-8, False)):
        p = RattleParams(lam=lam)
        roots = cont._release_roots(p, 1)
        t_r = float(roots[np.argmin(np.abs((roots - rel + np.pi) % (2 * np.pi) - np.pi))])
        tr = sim(p, periods=2, t0=t_r, x0=float(excitation(t_r, p.h, p.phi)),
                 v0=float(excitation(t_r, p.h, p.phi, 1)))
        stuck = tr.stick_intervals[tr.stick_intervals[:, 0] < t_r + 2 * np.pi + 0.5]
        assert (len(stuck) > 0) == sticks, (lam, stuck)
        if sticks:
            # captured just before the release: the stick phase is nearly gone
            assert 0 < stuck[0, 1] - stuck[0, 0] < 1e-3


def test_onset_of_sticking_on_an_impact_branch_checked_by_simulation():
    """Past the end of sticking (r = 0.3, v_stick = 1e-3) the orbit restarted by simulation
    has impacts only; followed on, its slowest impact on a pushing flank reaches v_stick and
    the gear sticks there: simulation without and with a stick phase on the two sides."""
    p = RattleParams(lam=1.05, r=0.3, v_stick=1e-3)
    o = find_orbit(p)
    assert o.kind == "stick"
    up = continue_orbit(o, "lam", bounds=(1.0, 3.0))
    assert up.status == "stick_end"
    after = continue_orbit(up.bifurcations[-1], bounds=(1.0, 3.0))
    assert after.orbits[0].kind == "impact" and after.orbits[0].admissible
    assert after.status == "stick_onset"
    b = after.bifurcations[-1]
    orb = b.orbit
    k = b.detail["impact"]
    assert abs(orb.w[k]) == pytest.approx(1e-3, rel=1e-6)
    assert orb.flank[k] * (1 + b.value * float(excitation(orb.t[k], p.h, p.phi, 2))) > 0
    travel = np.sign(b.value - after.points["value"].iloc[0])
    for d, sticks in ((-1e-7, False), (1e-7, True)):
        lam = b.value + travel * d
        near = solve_orbit(RattleParams(lam=lam, r=0.3, v_stick=1e-3), orb.t, orb.u, orb.flank,
                           orb.period)
        assert (abs(near.w[k]) < 1e-3) == sticks
        tr = one_period(near)
        assert (len(tr.stick_intervals) > 0) == sticks
        if not sticks:
            assert np.allclose(tr.impact_impulse, np.roll(near.impulse, -1), atol=1e-9)


# ----- other parameters, physical units ------------------------------------------------------------

@pytest.mark.parametrize("name,bounds", [("r", (0.55, 0.65)), ("j", (7.0, 8.0)),
                                         ("h2", (0.0, 0.1)), ("phi2", (-135.0, -100.0))])
def test_branch_points_in_other_parameters_are_orbits_of_the_simulator(e_orbit, name, bounds):
    """Continued in r, j, H2/H1 or φ2, sampled points are reproduced by one simulated period."""
    base = e_orbit.params.replace(amplitudes=(1.0, 0.05), phases_deg=(0.0, -135.0))
    start = find_orbit(base)
    start_value = base.get(name)
    lo, hi = bounds
    direction = 1 if start_value <= lo + 1e-12 else -1
    res = continue_orbit(start, name, bounds=bounds, direction=direction, max_points=40)
    assert res.status in ("bound", "max_points", "grazing")
    assert len(res.points) > 3
    for i in (1, len(res.points) // 2, len(res.points) - 1):
        orb = res.orbit(i)
        assert orb.params.get(name) == pytest.approx(res.points["value"].iloc[i], abs=1e-9)
        if not orb.admissible:
            continue
        tr = one_period(orb)
        assert len(tr.impact_t) == orb.n_impacts
        assert np.allclose(tr.impact_impulse, np.roll(orb.impulse, -1), atol=1e-9)


def test_physical_units_rpm_and_drag_torque():
    """Continuation in engine speed and drag torque: the C orbit's period doubling sits at the
    physical values that give Λ = 1.23940."""
    from rattle_core import units
    phys = units.PhysicalParams(inertia=2e-4, radius=0.04, drag_torque=0.02, backlash=160e-6,
                                rpm=2100.0, amplitudes=(5e-4,), order=2.0)
    p = phys.to_dimensionless()
    assert 0.9 < p.lam < 1.2
    o = c_orbit(p)
    res = continue_orbit(o, "rpm", physical=phys, bounds=(2000.0, 2800.0))
    pd = next(b for b in res.bifurcations if b.kind == "period_doubling")
    assert pd.value == pytest.approx(float(units.rpm_from_lam(phys, LAM_PD)), rel=1e-9)
    assert np.allclose(res.points["q"], units.lam_from_rpm(phys, res.points["value"]), rtol=1e-12)
    res = continue_orbit(o, "drag_torque", physical=phys, bounds=(0.01, 0.02), direction=-1)
    pd = next(b for b in res.bifurcations if b.kind == "period_doubling")
    assert pd.value == pytest.approx(phys.drag_torque * p.lam / LAM_PD, rel=1e-9)


# ----- API -------------------------------------------------------------------------------------------

def test_bad_input_names_the_parameter():
    """Bad input raises ValueError naming the parameter and what is allowed."""
    o = c_orbit(RattleParams(lam=1.0))
    cases = [(dict(param="zeta"), "param"), (dict(param="v_stick"), "v_stick"),
             (dict(direction=0), "direction"), (dict(ds=-1), "ds"),
             (dict(max_points=0), "max_points"), (dict(bounds=(2.0, 1.0)), "bounds"),
             (dict(bounds=(1.5, 2.0)), "bounds"), (dict(bounds=(-1.0, 2.0)), "lam"),
             (dict(param="rpm"), "physical")]
    for kw, word in cases:
        with pytest.raises(ValueError, match=word):
            continue_orbit(o, **{"param": "lam", **kw})
    with pytest.raises(ValueError, match="start"):
        continue_orbit("orbit")
    with pytest.raises(ValueError, match="flank"):
        solve_orbit(o.params, [1.0], [1.0], [2], 1)
    with pytest.raises(ContinuationError):
        find_orbit(RattleParams.paper(lam=3.3, amplitudes=(1, 0.25), phases_deg=(0, 45)),
                   transient=300)


def test_progress_cancel_and_limit():
    """Progress is reported per point; a set Event stops the run; max_points stops with a
    message; the result carries its provenance."""
    o = c_orbit(RattleParams(lam=1.0))
    seen = []
    ev = threading.Event()

    def progress(done, total):
        seen.append((done, total))
        if done == 5:
            ev.set()
    res = continue_orbit(o, "lam", bounds=(0.9, 3.0), progress=progress, cancel=ev,
                         max_points=200)
    assert res.status == "cancelled" and res.cancelled and len(res.points) == 5
    assert seen[:5] == [(i, 200) for i in range(1, 6)]
    res = continue_orbit(o, "lam", bounds=(0.9, 3.0), max_points=7, cancel=lambda: False)
    assert res.status == "max_points" and len(res.points) == 7 and "max_points" in res.message
    again = continue_orbit(o, "lam", bounds=(0.9, 3.0), max_points=7)
    assert again.cache_key() == res.cache_key()
    assert np.array_equal(again.points["value"], res.points["value"])
    prov = res.provenance
    assert prov["param"] == "lam" and prov["settings"]["max_points"] == 7
    assert prov["continuation_version"] == cont.CONTINUATION_VERSION
    assert len(res.cache_key()) == 64
    arrays = res.arrays()
    assert arrays["points/value"].shape == (7,)
    assert isinstance(res.bifurcations, list)
    assert all(isinstance(b, Bifurcation) for b in res.bifurcations)


# ----- the command ------------------------------------------------------------------------------------

def test_cli_continue_writes_branches_bifurcations_and_png(tmp_path, capsys):
    """``rattle continue`` writes the branch, its impacts and bifurcations, following the
    period-2 branch; the numbers are those of continue_orbit."""
    from PIL import Image

    from rattle_cli.main import main
    out = tmp_path / "c.csv"
    code = main(["continue", "--lam", "1.0", "--start", "c", "--bounds", "1.0,1.3", "--branches",
                 "2", "--out", str(out), "--png", str(tmp_path / "c.png"), "-q"])
    assert code == 0
    pts = __import__("pandas").read_csv(out)
    imp = __import__("pandas").read_csv(tmp_path / "c_impacts.csv")
    bif = __import__("pandas").read_csv(tmp_path / "c_bifurcations.csv")
    assert set(pts["branch"]) == {0, 1}
    assert np.allclose(pts.loc[pts.branch == 0, "impulse_max"],
                       2 * np.pi / pts.loc[pts.branch == 0, "value"], atol=1e-9)
    pd0 = bif[(bif.branch == 0) & (bif.kind == "period_doubling")]
    assert len(pd0) == 1 and pd0["value"].iloc[0] == pytest.approx(LAM_PD, abs=1e-8)
    assert set(imp.loc[imp.branch == 1, "impact"]) == {0, 1}
    assert (pts.loc[pts.branch == 1, "period"].iloc[1:] == 2).all()
    with Image.open(tmp_path / "c.png") as im:
        assert im.size[0] > 500
    assert capsys.readouterr().out == ""


def test_cli_continue_errors_are_one_line(tmp_path, capsys):
    """Bad arguments and unknown parameters exit 2 with one line; no orbit exits 1."""
    from rattle_cli.main import main
    for argv, word in ((["--param", "zeta"], "param"), (["--bounds", "1"], "--bounds"),
                       (["--param", "rpm"], "physical"), (["--branches", "0"], "--branches"),
                       (["--direction", "sideways"], "direction")):
        code = main(["continue", "--out", str(tmp_path / "x.csv"), *argv])
        err = capsys.readouterr().err
        assert code == 2 and err.count("\n") == 1 and word in err, (argv, err)
    code = main(["continue", "--lam", "0.5", "--start", "c", "--out", str(tmp_path / "x.csv")])
    err = capsys.readouterr().err
    assert code == 1 and "no one-sided" in err and err.count("\n") == 1


def test_start_from_parameters_simulates_first():
    """``continue_orbit(RattleParams)`` starts from the orbit a simulation settles on."""
    res = continue_orbit(RattleParams(lam=3.3), "lam", bounds=(3.3, 3.5), max_points=20)
    assert res.status == "bound"
    assert res.orbit(0).n_impacts == 2 and res.points["stable"].all()
    (o,) = res.orbit_at(3.4)
    assert o.params.lam == 3.4 and o.residual < 1e-12
    assert np.allclose(np.sort(o.impulse), np.sort(find_orbit(RattleParams(lam=3.4)).impulse),
                       atol=1e-10)


def test_phase_continuation_repeats_every_360_degrees():
    """φ2 is an angle: continued over two turns, the bifurcations of the first turn recur
    360° later, to 1e-8 (each located independently); φ2 without h2 is refused."""
    start = find_orbit(RattleParams(lam=3.3, amplitudes=(1.0, 0.1), phases_deg=(0.0, -180.0)))
    res = continue_orbit(start, "phi2", bounds=(-360.0, 360.0), max_points=2000)
    assert res.status == "bound"
    vals = sorted(b.value for b in res.bifurcations)
    assert len(vals) >= 2 and len(vals) % 2 == 0
    first = [v for v in vals if v < 0.0]
    second = [v for v in vals if v >= 0.0]
    assert len(first) == len(second)
    assert np.allclose(np.array(second) - np.array(first), 360.0, atol=1e-8)
    with pytest.raises(ValueError, match="h2"):
        continue_orbit(find_orbit(RattleParams(lam=3.3)), "phi2")


def test_result_arrays_survive_npz_without_pickle(tmp_path, c_branch):
    """The arrays of a result load back with allow_pickle=False into the same tables."""
    path = tmp_path / "branch.npz"
    np.savez(path, **c_branch.arrays())
    with np.load(path, allow_pickle=False) as data:
        back = cont.ContinuationResult.tables(data)
    assert np.array_equal(back["points"]["value"], c_branch.points["value"])
    assert back["points"]["kind"].tolist() == c_branch.points["kind"].tolist()
    assert np.array_equal(back["impacts"]["impulse"], c_branch.impacts["impulse"])
    assert back["bifurcations"]["kind"].tolist() == ["period_doubling"]
    assert back["bifurcations"]["value"].iloc[0] == c_branch.bifurcations[0].value


def test_continuation_refuses_an_inadmissible_start():
    """The (1,2) orbit at Λ = 1.64362 crosses the backlash (gap −4.7): continuing it raises a
    clear ValueError instead of reporting a grazing of a virtual orbit."""
    orb = c_orbit(RattleParams(lam=1.64362, r=0.65, j=8.0), 2)
    assert not orb.admissible
    with pytest.raises(ValueError, match="not an orbit of the model"):
        continue_orbit(orb, "lam", bounds=(1.34, 1.84))
