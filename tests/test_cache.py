"""The disk cache (hits, keys, matching, corrupt and stale entries, location, atomic writes, the
size limit) and the shipped paper assets, which must still match the solver."""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import rattle_core.paper.cases as paper
import rattle_core.store.assets as assets
import rattle_core.store.cache as cache
from rattle_core import RattleParams, sweep
from rattle_core.paper.cases import CASES, SWEEP_CASES
from rattle_core.store.assets import find_asset, load_asset
from rattle_core.store.cache import cache_dir, cached_sweep, sweep_key
from rattle_core.store.files import load_result, save_result

BASE = RattleParams(lam=1.0)
VALS = np.linspace(1.5, 3.5, 12)
KW = {"transient": 30, "record": 10}


@pytest.fixture
def counted(monkeypatch):
    """Counts the sweeps ``cached_sweep`` really computes."""
    calls = []
    real = cache.sweep

    def wrapper(*a, **k):
        calls.append(a[2])
        return real(*a, **k)
    monkeypatch.setattr(cache, "sweep", wrapper)
    return calls


def _entries(d: Path) -> list[Path]:
    return sorted(d.glob("sweep-*.npz"))


def _same(a, b, compact=False):
    np.testing.assert_array_equal(a.values, b.values)
    tol = 1e-6 if compact else 0
    np.testing.assert_allclose(a.table["impulse"], b.table["impulse"], rtol=tol, atol=tol)
    np.testing.assert_allclose(a.table["phase"], b.table["phase"], rtol=tol, atol=tol)
    np.testing.assert_array_equal(a.table["value"], b.table["value"])
    np.testing.assert_array_equal(a.table["flank"], b.table["flank"])
    assert list(a.summary["regime"]) == list(b.summary["regime"])
    np.testing.assert_array_equal(a.summary["period"], b.summary["period"])


def test_second_call_is_served_from_disk(tmp_path, counted, monkeypatch):
    """The second identical request reads the disk: ``sweep`` is not called again."""
    first = cached_sweep(BASE, "lam", VALS, directory=tmp_path, **KW)
    assert len(counted) == 1 and len(_entries(tmp_path)) == 1

    def boom(*a, **k):
        raise AssertionError("recomputed although cached")
    monkeypatch.setattr(cache, "sweep", boom)
    calls = []
    second = cached_sweep(BASE, "lam", list(VALS), directory=tmp_path,
                          progress=lambda d, n: calls.append((d, n)), **KW)
    _same(first, second)
    assert calls == [(12, 12)]
    assert second.settings["transient"] == 30 and second.params == BASE


def test_read_only_serves_a_hit_and_computes_nothing_on_a_miss(tmp_path, counted):
    """Inside ``read_only()`` a miss raises NotCached without computing; a hit is served."""
    with cache.read_only(), pytest.raises(cache.NotCached):
        cached_sweep(BASE, "lam", VALS, directory=tmp_path, **KW)
    assert counted == [] and _entries(tmp_path) == []
    first = cached_sweep(BASE, "lam", VALS, directory=tmp_path, **KW)
    with cache.read_only():
        second = cached_sweep(BASE, "lam", VALS, directory=tmp_path, **KW)
    assert len(counted) == 1 and second.from_cache
    _same(first, second)


def test_different_settings_different_key(tmp_path, counted):
    """Any change of parameters, name, values or settings gives a new key and a new entry."""
    settings = {"transient": 30, "record": 10, "mode": "fresh", "x0": None, "v0": 0.0}
    variants = [
        (BASE, "lam", VALS, settings),
        (BASE.replace(r=0.6), "lam", VALS, settings),
        (BASE.replace(j=7.0), "lam", VALS, settings),
        (BASE, "lam", VALS[:-1], settings),
        (BASE, "lam", VALS + 1e-12, settings),
        (BASE, "lam", VALS[::-1], settings),
        (BASE.replace(lam=2.0), "r", np.linspace(0.5, 0.7, 12), settings),
        (BASE, "lam", VALS, {**settings, "transient": 31}),
        (BASE, "lam", VALS, {**settings, "record": 11}),
        (BASE, "lam", VALS, {**settings, "mode": "continuation"}),
        (BASE, "lam", VALS, {**settings, "x0": 2.0}),
        (BASE, "lam", VALS, {**settings, "v0": 0.5}),
    ]
    keys = [sweep_key(*v) for v in variants]
    assert len(set(keys)) == len(keys)
    # extra settings that do not change the result do not change the key
    assert sweep_key(BASE, "lam", VALS, {**settings, "chunk_size": 3}) == keys[0]
    # a trailing zero harmonic is the same excitation, hence the same key
    same = RattleParams(lam=1.0, amplitudes=(1.0, 0.0), phases_deg=(0.0, 0.0))
    assert sweep_key(same, "lam", VALS, settings) == keys[0]
    cached_sweep(BASE, "lam", VALS, directory=tmp_path, **KW)
    cached_sweep(BASE, "lam", VALS, directory=tmp_path, transient=31, record=10)
    cached_sweep(BASE, "lam", VALS, directory=tmp_path, mode="continuation", **KW)
    assert len(counted) == 3 and len(_entries(tmp_path)) == 3


@pytest.mark.parametrize("damage", ["garbage", "truncated", "empty", "foreign"])
def test_corrupt_entry_is_recomputed(tmp_path, counted, damage):
    """A corrupt, truncated, empty or foreign entry is recomputed and overwritten, no error."""
    good = cached_sweep(BASE, "lam", VALS, directory=tmp_path, **KW)
    (path,) = _entries(tmp_path)
    data = path.read_bytes()
    if damage == "garbage":
        path.write_bytes(b"not an npz file at all" * 100)
    elif damage == "truncated":
        path.write_bytes(data[: len(data) // 2])
    elif damage == "empty":
        path.write_bytes(b"")
    else:
        other = sweep(BASE, "lam", [2.0], **KW)
        save_result(path, other, key="0" * 64)
    again = cached_sweep(BASE, "lam", VALS, directory=tmp_path, **KW)
    assert len(counted) == 2
    _same(good, again)
    res, meta = load_result(path)  # overwritten with a good entry
    _same(good, res)


def test_stale_solver_version_is_recomputed(tmp_path, counted):
    """An entry written by another solver (or schema) version is recomputed."""
    good = cached_sweep(BASE, "lam", VALS, directory=tmp_path, **KW)
    (path,) = _entries(tmp_path)
    res, meta = load_result(path)
    for field in ("solver", "schema"):
        save_result(path, res, key=meta["key"], request={**meta["request"], field: "0.0.1-stale"})
        again = cached_sweep(BASE, "lam", VALS, directory=tmp_path, **KW)
        _same(good, again)
        assert load_result(path)[1]["request"] == meta["request"]
    assert len(counted) == 3


@pytest.mark.parametrize("forged", ["values", "params", "request"])
def test_entry_must_hold_what_was_asked(tmp_path, counted, forged):
    """An entry under the right key whose stored values, parameters or request differ from the
    request is recomputed and overwritten, not served."""
    good = cached_sweep(BASE, "lam", VALS, directory=tmp_path, **KW)
    (path,) = _entries(tmp_path)
    _, meta = load_result(path)
    if forged == "values":
        other = sweep(BASE, "lam", VALS + 0.01, **KW)
        save_result(path, other, key=meta["key"], request=meta["request"])
    elif forged == "params":
        other = sweep(BASE.replace(r=0.5), "lam", VALS, **KW)
        save_result(path, other, key=meta["key"], request=meta["request"])
    else:
        request = dict(meta["request"], settings={**meta["request"]["settings"], "record": 11})
        save_result(path, good, key=meta["key"], request=request)
    again = cached_sweep(BASE, "lam", VALS, directory=tmp_path, **KW)
    assert len(counted) == 2 and not again.from_cache
    _same(good, again)
    assert cached_sweep(BASE, "lam", VALS, directory=tmp_path, **KW).from_cache


def test_a_directory_at_an_entry_path_is_left_alone(tmp_path, counted):
    """When a directory stands where an entry goes, the result is computed and returned, and the
    directory and its contents are never touched."""
    key = sweep_key(BASE, "lam", VALS, {"mode": "fresh", "x0": None, "v0": 0.0, **KW})
    blocker = tmp_path / f"sweep-{key[:32]}.npz"
    blocker.mkdir()
    (blocker / "keep.txt").write_text("mine")
    for _ in range(2):
        res = cached_sweep(BASE, "lam", VALS, directory=tmp_path, **KW)
        assert len(res.values) == len(VALS) and not res.from_cache
    assert len(counted) == 2
    assert blocker.is_dir() and (blocker / "keep.txt").read_text() == "mine"
    assert sorted(p.name for p in tmp_path.iterdir()) == [blocker.name]


def test_size_limit_evicts_the_least_recently_used(tmp_path, monkeypatch, counted):
    """Past ``RATTLE_CACHE_SIZE_MB`` the least recently used entries go; a hit counts as a use,
    and the entry just written stays."""
    runs = [VALS, VALS + 0.1, VALS + 0.2]
    for v in runs:
        cached_sweep(BASE, "lam", v, directory=tmp_path, **KW)
    sizes = {e.path: e.size for e in cache.entries(tmp_path)}
    assert len(sizes) == 3
    paths = [tmp_path / f"sweep-{sweep_key(BASE, 'lam', v, {'mode': 'fresh', 'x0': None, 'v0': 0.0, **KW})[:32]}.npz"
             for v in runs]
    for age, p in enumerate(paths):  # oldest first, a second apart
        os.utime(p, (1000 + age, 1000 + age))
    assert cached_sweep(BASE, "lam", runs[0], directory=tmp_path, **KW).from_cache  # a use
    limit_mb = (sizes[paths[0]] + sizes[paths[1]] + sizes[paths[2]] - 1) / 1e6
    monkeypatch.setenv("RATTLE_CACHE_SIZE_MB", repr(limit_mb))
    cached_sweep(BASE, "lam", VALS + 0.3, directory=tmp_path, **KW)  # a new entry
    left = {e.path for e in cache.entries(tmp_path)}
    assert paths[0] in left and paths[1] not in left  # runs[1] was the least recently used
    assert sum(e.size for e in cache.entries(tmp_path)) <= limit_mb * 1e6
    monkeypatch.setenv("RATTLE_CACHE_SIZE_MB", "0")
    cached_sweep(BASE, "lam", VALS + 0.4, directory=tmp_path, **KW)
    assert [e.path.name for e in cache.entries(tmp_path)] == [
        f"sweep-{sweep_key(BASE, 'lam', VALS + 0.4, {'mode': 'fresh', 'x0': None, 'v0': 0.0, **KW})[:32]}.npz"]


@pytest.mark.parametrize("text", ["-1", "abc", "nan", "1e99"])
def test_bad_size_limit_names_the_variable(monkeypatch, text):
    """A size limit that is not a number of megabytes in range is refused by name."""
    monkeypatch.setenv("RATTLE_CACHE_SIZE_MB", text)
    with pytest.raises(ValueError, match="RATTLE_CACHE_SIZE_MB"):
        cache.size_limit()


def test_clear_deletes_entries_and_nothing_else(tmp_path):
    """``clear`` removes the entries and interrupted writes' temporary files, nothing else."""
    cached_sweep(BASE, "lam", VALS, directory=tmp_path, **KW)
    (tmp_path / ".tmp-x.npz").write_bytes(b"partial")
    (tmp_path / "notes.txt").write_text("mine")
    (tmp_path / "sweep-dir.npz").mkdir()
    n, freed = cache.clear(tmp_path)
    assert n == 2 and freed > 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["notes.txt", "sweep-dir.npz"]
    assert cache.entries(tmp_path) == []


def test_cache_location_from_environment(tmp_path, monkeypatch):
    """``RATTLE_CACHE_DIR`` is honoured; else ``$XDG_CACHE_HOME/rattle-explorer``; else ~/.cache."""
    target = tmp_path / "mycache"
    monkeypatch.setenv("RATTLE_CACHE_DIR", str(target))
    assert cache_dir() == target
    cached_sweep(BASE, "lam", VALS, **KW)
    assert len(_entries(target)) == 1
    monkeypatch.delenv("RATTLE_CACHE_DIR")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert cache_dir() == tmp_path / "xdg" / "rattle-explorer"
    monkeypatch.delenv("XDG_CACHE_HOME")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert cache_dir() == tmp_path / "home" / ".cache" / "rattle-explorer"


def test_failed_write_leaves_no_partial_file(tmp_path, monkeypatch):
    """A write that fails midway leaves neither a partial entry nor a temporary file, and an
    existing entry at the same path is kept intact."""
    res = sweep(BASE, "lam", VALS, **KW)
    path = tmp_path / "entry.npz"
    save_result(path, res)
    before = path.read_bytes()

    def half_then_fail(f, **arrays):
        f.write(b"PK\x03\x04 partial zip data")
        raise OSError("disk full")
    monkeypatch.setattr(np, "savez_compressed", half_then_fail)
    with pytest.raises(OSError, match="disk full"):
        save_result(path, res)
    with pytest.raises(OSError):
        save_result(tmp_path / "new.npz", res)
    assert path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["entry.npz"]

    def interrupted(f, **arrays):
        raise KeyboardInterrupt
    monkeypatch.setattr(np, "savez_compressed", interrupted)
    with pytest.raises(KeyboardInterrupt):
        save_result(path, res)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["entry.npz"]


def test_unwritable_cache_still_returns_the_result(tmp_path, monkeypatch):
    """A failing cache write costs the entry, not the computed diagram."""
    def disk_full(f, **arrays):
        raise OSError("disk full")
    monkeypatch.setattr(np, "savez_compressed", disk_full)
    res = cached_sweep(BASE, "lam", VALS, directory=tmp_path, **KW)
    assert len(res.values) == 12 and not _entries(tmp_path)
    assert not list(tmp_path.iterdir())


def test_cancelled_sweep_is_not_stored(tmp_path):
    """A cancelled sweep is returned but never cached."""
    res = cached_sweep(BASE, "lam", VALS, directory=tmp_path, cancel=lambda: True, **KW)
    assert res.cancelled and not _entries(tmp_path)


@pytest.mark.parametrize("compact", [False, True])
def test_round_trip(tmp_path, compact):
    """save/load keeps values, table and summary (float32 impulses and phases when compact)."""
    res = sweep(BASE, "lam", VALS, **KW)
    save_result(tmp_path / "r.npz", res, compact=compact, key="k")
    back, meta = load_result(tmp_path / "r.npz")
    _same(res, back, compact=compact)
    assert meta["key"] == "k" and back.name == "lam" and back.params == BASE
    # the value column still identifies the summary row exactly
    assert set(back.table["value"]) <= set(back.summary["value"])
    pd.testing.assert_frame_equal(back.summary.drop(columns=["regime"]),
                                  res.summary.drop(columns=["regime"]), check_dtype=False)


def test_bad_request_is_refused_before_the_cache(tmp_path):
    """Bad sweep input raises ``ValueError`` naming it, and nothing is written."""
    with pytest.raises(ValueError, match="values"):
        cached_sweep(BASE, "lam", [], directory=tmp_path)
    with pytest.raises(ValueError, match="foo"):
        cached_sweep(BASE, "foo", [1.0], directory=tmp_path)
    assert not list(tmp_path.iterdir())


# ----- shipped assets ------------------------------------------------------------------------

@pytest.mark.parametrize("key", SWEEP_CASES)
def test_asset_matches_preset_and_is_small(key):
    """Each shipped asset loads, is keyed to its preset and the current solver, and is small."""
    path = assets.ASSETS_DIR / f"{key}.npz"
    assert path.exists(), f"{path} missing: run scripts/make_assets.py"
    assert path.stat().st_size < 2e6
    res = load_asset(key)
    assert res is not None
    _, meta = load_result(path)
    case = CASES[key]
    assert meta["key"] == case.cache_key(), "stale asset: run scripts/make_assets.py"
    np.testing.assert_array_equal(res.values, case.values)
    assert res.name == case.name and res.params == case.params
    assert len(res.summary) == len(case.values) and (res.summary["status"] == 0).all()
    counts = res.summary["n_active"] + res.summary["n_reverse"]
    assert counts.sum() == len(res.table)
    assert res.table["impulse"].dtype == np.float64  # widened on load
    name, found = find_asset(case.params.with_value(case.name, 1.23), case.name)
    assert name == key and found is res


@pytest.mark.parametrize("key", SWEEP_CASES)
def test_asset_still_matches_the_solver(key):
    """Ten values of each asset, recomputed now, give the stored impulses (float32 tolerance);
    where the stored response does not repeat (chaos), its statistics instead."""
    res = load_asset(key)
    case = CASES[key]
    idx = np.linspace(0, len(case.values) - 1, 10).round().astype(int)
    sub = sweep(case.params, case.name, case.values[idx], **case.sweep_settings())
    counts = (res.summary["n_active"] + res.summary["n_reverse"]).to_numpy()
    offsets = np.concatenate([[0], np.cumsum(counts)])
    sub_counts = (sub.summary["n_active"] + sub.summary["n_reverse"]).to_numpy()
    sub_off = np.concatenate([[0], np.cumsum(sub_counts)])
    stale = "assets no longer match the solver: run scripts/make_assets.py"
    for n, i in enumerate(idx):
        stored = res.table.iloc[offsets[i]:offsets[i + 1]]
        now = sub.table.iloc[sub_off[n]:sub_off[n + 1]]
        s_old, s_new = res.summary.iloc[i], sub.summary.iloc[n]
        assert (now["value"] == case.values[i]).all()
        if s_old["period"] > 0:
            assert s_new["regime"] == s_old["regime"], stale
            assert len(now) == len(stored), stale
            np.testing.assert_allclose(now["impulse"], stored["impulse"], rtol=1e-5, atol=1e-5,
                                       err_msg=stale)
            np.testing.assert_array_equal(now["flank"], stored["flank"], err_msg=stale)
            np.testing.assert_allclose(now["phase"], stored["phase"], rtol=1e-5, atol=1e-5,
                                       err_msg=stale)
        else:
            assert s_new["period"] == 0, stale
            for col in ("active_per_period", "reverse_per_period"):
                assert s_new[col] == pytest.approx(s_old[col], rel=0.2, abs=0.05), stale
            assert now["impulse"].max() == pytest.approx(stored["impulse"].max(), rel=0.2), stale


def test_paper_sweep_uses_the_asset(monkeypatch, tmp_path):
    """``paper_sweep`` serves a matching asset without computing; a stale one is recomputed."""
    def boom(*a, **k):
        raise AssertionError("computed although the asset matches")
    monkeypatch.setattr(paper, "cached_sweep", boom)
    res = paper.paper_sweep("fig5")
    assert len(res.values) == 600
    # an asset whose key no longer matches (here: a different solver version) is not used
    monkeypatch.setattr(assets, "ASSETS_DIR", tmp_path)
    save_result(tmp_path / "fig5.npz", res, compact=True, key="stale")
    with pytest.raises(AssertionError, match="computed"):
        paper.paper_sweep("fig5")
    # an asset under the right key whose values differ is not used either
    save_result(tmp_path / "fig5.npz", sweep(res.params, "lam", [1.0, 2.0], transient=5, record=5),
                key=CASES["fig5"].cache_key())
    with pytest.raises(AssertionError, match="computed"):
        paper.paper_sweep("fig5")
    with pytest.raises(ValueError, match="fig3"):
        paper.paper_sweep("fig3")
    with pytest.raises(ValueError, match="fig99"):
        paper.paper_sweep("fig99")


def test_missing_or_corrupt_asset_loads_as_none(monkeypatch, tmp_path):
    """A missing or unreadable asset is ``None``, not an error."""
    monkeypatch.setattr(assets, "ASSETS_DIR", tmp_path)
    assert load_asset("fig2") is None
    (tmp_path / "fig2.npz").write_bytes(b"junk")
    assert load_asset("fig2") is None
    assert find_asset(BASE, "lam") is None
    assert os.listdir(tmp_path) == ["fig2.npz"]
