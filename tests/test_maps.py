"""2-D regime maps and basins of attraction, locally and on a Dask cluster."""
import numpy as np
import pytest

from rattle_core import RattleParams, classify, simulate
from rattle_core.maps import REGIME_CODES, basin_map, regime_map

BASE = RattleParams(lam=2.0, amplitudes=(1.0, 0.25), phases_deg=(0.0, 0.0))


def test_regime_map_matches_single_runs():
    """Every map cell equals the classification of the same point simulated on its own."""
    lams = np.array([0.8, 1.2, 2.5, 3.3])
    phis = np.array([0.0, -135.0, 180.0])
    m = regime_map(BASE, "lam", lams, "phi2", phis, transient=300, record=100)
    assert m.fields["regime"].shape == (3, 4)
    codes = {v: k for k, v in REGIME_CODES.items()}
    for iy, phi in enumerate(phis):
        for ix, lam in enumerate(lams):
            p = BASE.replace(lam=float(lam), phases_deg=(0.0, float(phi)))
            c = classify(simulate(p, periods=100, transient=300, lyapunov=True))
            assert codes[int(m.fields["regime"][iy, ix])] == c.regime
            assert m.fields["intensity"][iy, ix] == pytest.approx(c.intensity, rel=1e-9, abs=1e-12)


def test_regime_map_sees_the_contact_boundary():
    """Below Λ_c (= 1 for harmonic excitation) the map shows permanent contact, above it not."""
    m = regime_map(RattleParams(lam=1.0), "lam", [0.6, 0.9, 2.5], "r", [0.5, 0.65],
                   transient=200, record=50)
    assert np.all(m.fields["regime"][:, :2] == REGIME_CODES["A"])
    assert np.all(m.fields["regime"][:, 2] != REGIME_CODES["A"])


def test_basins_separate_coexisting_attractors():
    """At Λ = 1.16 (harmonic) the one-sided period-1 orbit C coexists with other attractors."""
    p = RattleParams(lam=1.16)
    bm = basin_map(p, np.linspace(1.0, 9.0, 16), np.linspace(-3.0, 3.0, 16), transient=300)
    regimes = {a["regime"] for a in bm.attractors}
    assert "C" in regimes and len(bm.attractors) >= 2
    lab = bm.fields["attractor"]
    assert lab.min() >= 0 and lab.max() == len(bm.attractors) - 1
    # each labelled start point, rerun alone, reaches an attractor of the same regime
    ic = next(i for i, a in enumerate(bm.attractors) if a["regime"] == "C")
    iy, ix = np.argwhere(lab == ic)[0]
    tr = simulate(p, periods=64 + 2 * 32, transient=300, x0=bm.x_values[ix], v0=bm.y_values[iy],
                  lyapunov=True)
    assert classify(tr).regime == "C"


def test_map_bad_input():
    """Bad map requests raise ValueError naming the parameter."""
    with pytest.raises(ValueError, match="x_name and y_name must differ"):
        regime_map(BASE, "lam", [1.0], "lam", [2.0])
    with pytest.raises(ValueError, match="y_values is empty"):
        regime_map(BASE, "lam", [1.0], "phi2", [])
    with pytest.raises(ValueError, match="x_values must all be finite"):
        regime_map(BASE, "lam", [1.0, np.nan], "phi2", [0.0])
    with pytest.raises(ValueError, match="lam"):
        regime_map(BASE, "lam", [-1.0, 1.0], "phi2", [0.0])
    with pytest.raises(ValueError, match="allowed range"):
        regime_map(BASE, "lam", np.linspace(1, 2, 3000), "phi2", np.linspace(0, 1, 3000))
    with pytest.raises(ValueError, match="x0_values must lie in the backlash"):
        basin_map(BASE, [100.0], [0.0])


def test_cancel_and_progress():
    """Progress is reported per chunk, and cancelling stops the map early."""
    seen = []
    m = regime_map(BASE, "lam", np.linspace(1, 3, 8), "phi2", np.linspace(0, 90, 8),
                   transient=20, record=10, chunk_size=16, progress=lambda d, n: seen.append((d, n)))
    assert seen[-1] == (64, 64) and [d for d, _ in seen] == sorted(d for d, _ in seen)
    calls = []

    def cancel():
        calls.append(1)
        return len(calls) > 1
    m = regime_map(BASE, "lam", np.linspace(1, 3, 8), "phi2", np.linspace(0, 90, 8),
                   transient=20, record=10, chunk_size=16, cancel=cancel)
    assert m.cancelled
    assert np.sum(m.fields["regime"] >= 0) == 16


def test_dask_local_cluster_equals_local():
    """A map run on a 2-worker Dask LocalCluster equals the local run, value for value."""
    distributed = pytest.importorskip("dask.distributed")
    lams = np.linspace(0.8, 3.5, 6)
    phis = np.array([0.0, -135.0, 180.0])
    local = regime_map(BASE, "lam", lams, "phi2", phis, transient=200, record=60, chunk_size=5)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:
        remote = regime_map(BASE, "lam", lams, "phi2", phis, transient=200, record=60,
                            chunk_size=5, executor=client)
    for k in local.fields:
        np.testing.assert_array_equal(local.fields[k], remote.fields[k])


def test_maps_are_cached(tmp_path, monkeypatch):
    """A repeated map request is served from disk, identical, without recomputing."""
    from rattle_core import cache, maps
    kw = dict(transient=30, record=20)
    first = cache.cached_map("regime", BASE, "lam", [1.0, 2.0], "phi2", [0.0, 90.0],
                             directory=tmp_path, **kw)

    def boom(*a, **k):
        raise AssertionError("recomputed")
    monkeypatch.setattr(maps, "regime_map", boom)
    again = cache.cached_map("regime", BASE, "lam", [1.0, 2.0], "phi2", [0.0, 90.0],
                             directory=tmp_path, **kw)
    for k in first.fields:
        np.testing.assert_array_equal(first.fields[k], again.fields[k])
    with pytest.raises(AssertionError, match="recomputed"):
        cache.cached_map("regime", BASE, "lam", [1.0, 2.5], "phi2", [0.0, 90.0],
                         directory=tmp_path, **kw)


# ----- run_map: any two axes, physical ones included ----------------------------------------

def _phys(excitation="displacement"):
    from rattle_core.units import PhysicalParams
    amps = (5e-4, 1.25e-4) if excitation == "displacement" else (400.0, 100.0)
    return PhysicalParams(inertia=2e-4, radius=0.04, drag_torque=0.02, backlash=160e-6,
                          rpm=1500.0, amplitudes=amps, phases_deg=(0.0, 45.0),
                          excitation=excitation)


def test_run_map_rpm_by_drag_torque_equals_the_regime_map_it_drives():
    """With acceleration amplitudes rpm drives j and drag torque drives Λ: the same map."""
    from rattle_core.maps import run_map
    phys = _phys("acceleration")
    rpm = np.array([1200.0, 2000.0, 3000.0])
    torque = np.array([0.01, 0.02])
    m = run_map(phys.to_dimensionless(), phys, "rpm", rpm, "drag_torque", torque,
                use_cache=False, transient=60, record=30)
    assert (m.x_name, m.y_name) == ("rpm", "drag_torque")
    np.testing.assert_array_equal(m.x_values, rpm)
    np.testing.assert_array_equal(m.y_values, torque)
    assert m.settings["model_axes"] == ["j", "lam"]
    js = [phys.replace(rpm=v).to_dimensionless().j for v in rpm]
    lams = [phys.replace(drag_torque=c).to_dimensionless().lam for c in torque]
    assert np.ptp(js) > 0 and np.ptp(lams) > 0
    ref = regime_map(phys.to_dimensionless(), "j", js, "lam", lams, transient=60, record=30)
    for k in ref.fields:
        np.testing.assert_array_equal(m.fields[k], ref.fields[k])


def test_run_map_two_axes_driving_lambda_run_each_point_at_its_own_lambda():
    """With displacement amplitudes rpm and drag torque both drive Λ: each cell is its own run."""
    from rattle_core.maps import point_params, run_map
    phys = _phys()
    rpm = np.array([1500.0, 3000.0])
    torque = np.array([0.01, 0.03])
    m = run_map(phys.to_dimensionless(), phys, "rpm", rpm, "drag_torque", torque,
                use_cache=False, transient=60, record=30)
    assert m.settings["model_axes"] == "lam" and m.fields["regime"].shape == (2, 2)
    codes = {v: k for k, v in REGIME_CODES.items()}
    for iy, c in enumerate(torque):
        for ix, n in enumerate(rpm):
            p = point_params(phys.to_dimensionless(), phys, ("rpm", "drag_torque"), (n, c))
            assert p.lam == pytest.approx(phys.replace(rpm=n, drag_torque=c).lam, rel=1e-12)
            got = classify(simulate(p, periods=30, transient=60, lyapunov=True))
            assert codes[int(m.fields["regime"][iy, ix])] == got.regime
            assert m.fields["intensity"][iy, ix] == pytest.approx(got.intensity, rel=1e-9, abs=1e-12)


def test_run_map_basins_in_either_axis_order():
    """(v0, x0) gives the transposed basin map of (x0, v0), labelled with the caller's names."""
    from rattle_core.maps import run_map
    p = RattleParams(lam=1.16)
    xs, vs = np.linspace(2.0, 8.0, 4), np.linspace(-2.0, 2.0, 3)
    ref = basin_map(p, xs, vs, transient=100)
    m = run_map(p, None, "v0", vs, "x0", xs, use_cache=False, transient=100)
    assert (m.kind, m.x_name, m.y_name) == ("basin", "v0", "x0")
    np.testing.assert_array_equal(m.fields["attractor"], ref.fields["attractor"].T)


def test_run_map_is_served_from_the_cache(tmp_path, monkeypatch):
    """A repeated run_map comes from the disk cache, says so, and holds the same values."""
    from rattle_core.maps import run_map
    monkeypatch.setenv("RATTLE_CACHE_DIR", str(tmp_path))
    kw = dict(transient=30, record=20)
    first = run_map(BASE, None, "lam", [1.0, 2.0], "phi2", [0.0, 90.0], **kw)
    again = run_map(BASE, None, "lam", [1.0, 2.0], "phi2", [0.0, 90.0], **kw)
    assert not first.from_cache and again.from_cache
    for k in first.fields:
        np.testing.assert_array_equal(first.fields[k], again.fields[k])


@pytest.mark.parametrize("args, message", [
    (("rpm", [1000, 2000], "lam", [1, 2]), "x axis rpm leaves the dimensionless model unchanged"),
    (("lam", [-1, 2], "phi2", [0, 1]), "x axis lam: lam = -1.0 is outside the allowed range"),
    (("lam", [1, 2], "r", [0.5, 1.5]), "y axis r: r = 1.5 is outside the allowed range [0, 1]"),
    (("rpm", [1000, 2e6], "drag_torque", [0.01]), "x axis rpm: rpm = 2000000.0 is outside"),
    (("lam", [1, 2], "lam", [1, 2]), "x axis and y axis must differ"),
    (("x0", [1, 2], "lam", [1, 2]), "basins of attraction need x axis x0 y axis v0 together"),
    (("lam", [1, np.nan], "phi2", [0]), "x axis lam values must all be finite"),
    (("zeta", [1, 2], "phi2", [0]), "x axis: unknown parameter name 'zeta'"),
])
def test_run_map_rejects_bad_axes_naming_them(args, message):
    """Mismatched, unknown or out-of-range axes raise ValueError naming the axis."""
    from rattle_core.maps import run_map
    with pytest.raises(ValueError, match=None) as err:
        run_map(_phys().to_dimensionless(), _phys(), *args, use_cache=False, transient=5, record=5)
    assert message in str(err.value)


def test_run_map_physical_axis_needs_physical_units():
    """A physical axis without PhysicalParams is refused, naming the axis."""
    from rattle_core.maps import run_map
    with pytest.raises(ValueError, match="y axis 'drag_torque' is physical"):
        run_map(BASE, None, "lam", [1, 2], "drag_torque", [0.01, 0.02], use_cache=False)
