"""2-D regime maps and basins of attraction, locally and on a Dask cluster."""
import pickle

import numpy as np
import pytest

from rattle_core import RattleParams, classify, simulate
from rattle_core.analysis.vocabulary import REGIME_CODES
from rattle_core.batch.maps import basin_map, regime_map

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


@pytest.fixture(scope="module")
def dask_client():
    """A 2-worker Dask LocalCluster (one thread per worker, separate processes)."""
    distributed = pytest.importorskip("dask.distributed")
    from rattle_core.batch.executor import local_cluster
    with local_cluster(2) as cluster, distributed.Client(cluster) as client:
        yield client


def test_local_cluster_workers_retry_a_failed_message(dask_client):
    """The workers of the local cluster (the server's ``--dask local`` too) retry a message
    to the scheduler, so a connection closed on a loaded machine is not a logged failure."""
    from rattle_core.batch.executor import COMM_RETRIES

    def retries():
        import dask
        return dask.config.get("distributed.comm.retry.count")
    seen = dask_client.run(retries)
    assert len(seen) == 2 and set(seen.values()) == {COMM_RETRIES} and COMM_RETRIES > 0, seen


def test_dask_local_cluster_equals_local(dask_client):
    """A map run on a 2-worker Dask LocalCluster equals the local run, value for value."""
    lams = np.linspace(0.8, 3.5, 6)
    phis = np.array([0.0, -135.0, 180.0])
    local = regime_map(BASE, "lam", lams, "phi2", phis, transient=200, record=60, chunk_size=5)
    remote = regime_map(BASE, "lam", lams, "phi2", phis, transient=200, record=60,
                        chunk_size=5, executor=dask_client)
    for k in local.fields:
        np.testing.assert_array_equal(local.fields[k], remote.fields[k])


def _full_results(params, columns, x0, v0, transient, record, decimals=4):
    """Per-point fields and attractor fingerprints from one full chunk result (every impact
    and stroboscopic sample), classified afterwards: how maps were built from whole results."""
    from rattle_core.analysis.classify import detect_period
    from rattle_core.batch.maps import _FLOAT_FIELDS, _fingerprint
    from rattle_core.batch.chunks import run_chunk
    from rattle_core.batch.sweep import _summarise
    n = len(next(iter(columns.values())))
    chunk = run_chunk(params, columns, np.arange(n, dtype=np.float64), transient, record, x0, v0)
    summ = _summarise(chunk, record)
    fields = {k: summ[k].to_numpy(dtype=np.float64) for k in _FLOAT_FIELDS}
    fields["regime"] = summ["regime"].map(REGIME_CODES).to_numpy(dtype=np.int8)
    fps = []
    for sx, sv, reg in zip(chunk["str_x"], chunk["str_v"], summ["regime"]):
        fps.append(_fingerprint(sx, sv, detect_period(sx, sv, params.j), reg, decimals))
    return fields, fps


@pytest.mark.parametrize("where", ["local", "dask"])
def test_summarised_chunks_equal_full_results(where, request):
    """Maps built from per-point summaries equal maps built from every impact, locally and on
    Dask: the regime fields value for value, and the basins' attractors fingerprint for
    fingerprint (one attractor per distinct fingerprint, each point on its own)."""
    executor = request.getfixturevalue("dask_client") if where == "dask" else None
    lams = np.array([0.8, 1.16, 2.0, 3.3, 3.6])
    phis = np.array([0.0, 45.0, -135.0, 180.0])
    m = regime_map(BASE, "lam", lams, "phi2", phis, transient=200, record=60, chunk_size=7,
                   executor=executor)
    gx, gy = np.meshgrid(lams, phis)
    ref, _ = _full_results(BASE, {"lam": gx.ravel(), "phi2": gy.ravel()}, None, 0.0, 200, 60)
    assert set(m.fields) == set(ref)
    for k in ref:
        np.testing.assert_array_equal(m.fields[k].ravel(), ref[k])

    p = RattleParams(lam=1.16)
    xs, vs = np.linspace(1.0, 9.0, 8), np.linspace(-3.0, 3.0, 6)
    bm = basin_map(p, xs, vs, transient=300, chunk_size=7, executor=executor)
    bx, bv = np.meshgrid(xs, vs)
    ref, fps = _full_results(p, {"lam": np.full(bx.size, p.lam)}, bx.ravel(), bv.ravel(), 300,
                             bm.settings["record"])
    for k in ref:
        np.testing.assert_array_equal(bm.fields[k].ravel(), ref[k])
    labels = bm.fields["attractor"].ravel()
    assert len(bm.attractors) == len(set(fps)) >= 2
    for fp, lab in zip(fps, labels):
        a = bm.attractors[lab]
        assert (a["regime"], a["period"], a["section_point"]) == (fp[0], *(fp[1:2] or (0,)),
                                                                 fp[2:])
    counts = np.bincount(labels, minlength=len(bm.attractors))
    assert [a["share"] for a in bm.attractors] == list(counts / labels.size)


def test_map_tasks_return_per_point_summaries_only():
    """A map task sends back a few numbers per point, not the impacts and strobe samples."""
    from rattle_core.batch.maps import _map_chunk
    from rattle_core.batch.chunks import run_chunk
    n = 48
    cols = {"lam": np.linspace(1.5, 3.5, n), "phi2": np.linspace(0.0, 180.0, n)}
    rows = np.arange(n, dtype=np.float64)
    part = _map_chunk(BASE, cols, rows, 100, 200, None, 0.0)
    full = run_chunk(BASE, cols, rows, 100, 200, None, 0.0)
    # row index, regime code and six float fields per point, plus pickling overhead
    assert len(pickle.dumps(part)) < n * (8 + 1 + 6 * 8) + 2000
    assert len(pickle.dumps(full)) > 10 * len(pickle.dumps(part))
    bpart = _map_chunk(RattleParams(lam=1.16), {"lam": np.full(n, 1.16)}, rows, 100, 200,
                       np.linspace(1.0, 9.0, n), 0.0, decimals=4)
    assert len(bpart["fingerprint"]) == n and all(isinstance(f, tuple) for f in bpart["fingerprint"])


def test_dask_progress_and_cancel_between_chunks(dask_client):
    """On Dask too, progress comes chunk by chunk, and cancelling keeps the chunks done."""
    kw = dict(transient=20, record=10, chunk_size=16)
    lams, phis = np.linspace(1, 3, 8), np.linspace(0, 90, 8)
    seen = []
    full = regime_map(BASE, "lam", lams, "phi2", phis, executor=dask_client,
                      progress=lambda d, n: seen.append((d, n)), **kw)
    assert [d for d, _ in seen] == [16, 32, 48, 64] and {n for _, n in seen} == {64}
    m = regime_map(BASE, "lam", lams, "phi2", phis, executor=dask_client, cancel=lambda: True,
                   **kw)
    assert m.cancelled
    done = m.fields["regime"] >= 0
    assert done.sum() == 16
    for k in full.fields:
        np.testing.assert_array_equal(m.fields[k][done], full.fields[k][done])
        if k != "regime":
            assert np.all(np.isnan(m.fields[k][~done]))


def test_maps_are_cached(tmp_path, monkeypatch):
    """A repeated map request is served from disk, identical, without recomputing."""
    from rattle_core.store import cache
    kw = dict(transient=30, record=20)
    first = cache.cached_map("regime", BASE, "lam", [1.0, 2.0], "phi2", [0.0, 90.0],
                             directory=tmp_path, **kw)

    def boom(*a, **k):
        raise AssertionError("recomputed")
    monkeypatch.setattr(cache, "regime_map", boom)
    again = cache.cached_map("regime", BASE, "lam", [1.0, 2.0], "phi2", [0.0, 90.0],
                             directory=tmp_path, **kw)
    assert again.from_cache and not first.from_cache
    for k in first.fields:
        np.testing.assert_array_equal(first.fields[k], again.fields[k])
    with pytest.raises(AssertionError, match="recomputed"):
        cache.cached_map("regime", BASE, "lam", [1.0, 2.5], "phi2", [0.0, 90.0],
                         directory=tmp_path, **kw)


# ----- run_map: any two axes, physical ones included ----------------------------------------

def _phys(excitation="displacement"):
    from rattle_core.model.units import PhysicalParams
    amps = (5e-4, 1.25e-4) if excitation == "displacement" else (400.0, 100.0)
    return PhysicalParams(inertia=2e-4, radius=0.04, drag_torque=0.02, backlash=160e-6,
                          rpm=1500.0, amplitudes=amps, phases_deg=(0.0, 45.0),
                          excitation=excitation)


def test_run_map_rpm_by_drag_torque_equals_the_regime_map_it_drives():
    """With acceleration amplitudes rpm drives j and drag torque drives Λ: the same map."""
    from rattle_core.store.requests import run_map
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
    from rattle_core.batch.plan import point_params
    from rattle_core.store.requests import run_map
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
    from rattle_core.store.requests import run_map
    p = RattleParams(lam=1.16)
    xs, vs = np.linspace(2.0, 8.0, 4), np.linspace(-2.0, 2.0, 3)
    ref = basin_map(p, xs, vs, transient=100)
    m = run_map(p, None, "v0", vs, "x0", xs, use_cache=False, transient=100)
    assert (m.kind, m.x_name, m.y_name) == ("basin", "v0", "x0")
    np.testing.assert_array_equal(m.fields["attractor"], ref.fields["attractor"].T)


def test_run_map_is_served_from_the_cache(tmp_path, monkeypatch):
    """A repeated run_map comes from the disk cache, says so, and holds the same values."""
    from rattle_core.store.requests import run_map
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
    from rattle_core.store.requests import run_map
    with pytest.raises(ValueError, match=None) as err:
        run_map(_phys().to_dimensionless(), _phys(), *args, use_cache=False, transient=5, record=5)
    assert message in str(err.value)


def test_run_map_physical_axis_needs_physical_units():
    """A physical axis without PhysicalParams is refused, naming the axis."""
    from rattle_core.store.requests import run_map
    with pytest.raises(ValueError, match="y axis 'drag_torque' is physical"):
        run_map(BASE, None, "lam", [1, 2], "drag_torque", [0.01, 0.02], use_cache=False)
