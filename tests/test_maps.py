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
