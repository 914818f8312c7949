"""The disk cache serves only what it wrote: forged, incomplete or oversized entries are misses.

Each test lets the cache write an entry, edits the file the way a forger or a dying writer
would (the header, key and request left intact), and checks that the next request recomputes
the true result, rewrites the entry, and is then served from it again.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import time
import tracemalloc
import zipfile

import numpy as np
import pytest

from rattle_core import RattleParams
from rattle_core.store import cache
from rattle_core.store.files import TMP_PREFIX, atomic_savez, content_digest

P = RattleParams(lam=3.3, amplitudes=(1.0, 0.25), phases_deg=(0.0, 45.0))
VALUES = np.linspace(1.0, 3.0, 6)


def sweep(tmp_path):
    return cache.cached_sweep(P, "lam", VALUES, transient=50, record=20, directory=tmp_path)


def regime_map(tmp_path):
    return cache.cached_map("regime", P, "lam", [1.0, 2.0, 3.0], "r", [0.5, 0.7],
                            directory=tmp_path, transient=20, record=10)


def only_entry(tmp_path, prefix):
    found = list(tmp_path.glob(f"{prefix}-*.npz"))
    assert len(found) == 1, found
    return found[0]


def rewrite(path, change, redigest=False):
    """Replace the entry at ``path`` by its arrays after ``change``; the digest is kept as it
    was unless ``redigest`` (a forger who knows the format)."""
    with np.load(path, allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    change(arrays)
    if redigest:
        arrays["digest"] = np.array(content_digest(arrays))
    with open(path, "wb") as f:
        np.savez_compressed(f, **arrays)


def scale(name, factor):
    def change(a):
        a[name] = a[name] * factor
    return change


def drop_last_summary_row(a):
    for k in list(a):
        if k.startswith("s_"):
            a[k] = a[k][:-1]


FORGERIES = [
    ("impulses ×10", scale("t_impulse", 10.0), False),
    ("impulses NaN", scale("t_impulse", np.nan), False),
    ("summary row dropped", drop_last_summary_row, False),
    ("summary row dropped, digest redone", drop_last_summary_row, True),
    ("no digest", lambda a: a.pop("digest"), False),
    ("no intensity column, digest redone", lambda a: a.pop("s_intensity"), True),
]


@pytest.mark.parametrize("what, change, redigest", FORGERIES, ids=[f[0] for f in FORGERIES])
def test_a_forged_sweep_is_recomputed_and_rewritten(tmp_path, what, change, redigest):
    """A sweep entry edited after it was written is a miss: recomputed, rewritten, then served."""
    truth = sweep(tmp_path)
    path = only_entry(tmp_path, "sweep")
    rewrite(path, change, redigest)
    again = sweep(tmp_path)
    assert not again.from_cache, what
    np.testing.assert_array_equal(again.table["impulse"], truth.table["impulse"])
    assert again.summary.equals(truth.summary)
    third = sweep(tmp_path)
    assert third.from_cache
    np.testing.assert_array_equal(third.table["impulse"], truth.table["impulse"])


@pytest.mark.parametrize("field", ["f_regime", "f_intensity"])
def test_a_map_without_a_field_is_recomputed(tmp_path, field):
    """A map entry missing one of its fields (its digest redone to match) is recomputed."""
    truth = regime_map(tmp_path)
    rewrite(only_entry(tmp_path, "map"), lambda a: a.pop(field), redigest=True)
    again = regime_map(tmp_path)
    assert not again.from_cache
    np.testing.assert_array_equal(again.fields["regime"], truth.fields["regime"])
    assert regime_map(tmp_path).from_cache


def test_a_map_with_a_forged_field_is_recomputed(tmp_path):
    """A map whose regimes were changed after writing is recomputed, not served."""
    truth = regime_map(tmp_path)
    rewrite(only_entry(tmp_path, "map"), lambda a: a.update(f_regime=np.zeros_like(a["f_regime"])))
    again = regime_map(tmp_path)
    assert not again.from_cache
    np.testing.assert_array_equal(again.fields["regime"], truth.fields["regime"])


def test_a_forged_continuation_entry_is_recomputed(tmp_path):
    """Any entry written through the one wrapper (as continued branches are) is checked alike."""
    calls = []

    def compute():
        calls.append(1)
        return Stored({"impulse": np.array([1.5, -0.5])})

    def load(f):
        with np.load(f, allow_pickle=False) as z:
            meta = json.loads(str(z["meta"]))
            return Stored({"impulse": z["impulse"]}), meta

    def save(path, result, key=None, request=None):
        atomic_savez(path, {**result.arrays, "meta": np.array(json.dumps(
            {"key": key, "request": request}))})

    def run():
        return cache.cached("cont", {"branch": 1}, compute, load, save, lambda r: True, tmp_path)

    run()
    rewrite(only_entry(tmp_path, "cont"), scale("impulse", 10.0))
    result, hit = run()
    assert not hit and len(calls) == 2
    np.testing.assert_array_equal(result.arrays["impulse"], [1.5, -0.5])
    assert run()[1] and len(calls) == 2


class Stored:
    cancelled = False

    def __init__(self, arrays):
        self.arrays = arrays


def test_a_declared_giant_array_is_never_loaded(tmp_path):
    """An entry of 1.6 MB whose header declares a 1.6 GB array is a miss without allocating it."""
    truth = sweep(tmp_path)
    path = only_entry(tmp_path, "sweep")
    with np.load(path, allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    forged = tmp_path / "forged.npz"
    with zipfile.ZipFile(forged, "w", zipfile.ZIP_STORED) as zf:
        for k, v in arrays.items():
            with zf.open(f"{k}.npy", "w") as f:
                if k == "t_impulse":
                    np.lib.format.write_array_header_1_0(
                        f, {"descr": "<f8", "fortran_order": False, "shape": (200_000_000,)})
                    f.write(np.random.default_rng(0).bytes(1_600_000))
                else:
                    np.lib.format.write_array(f, v)
    os.replace(forged, path)
    assert 1_500_000 < path.stat().st_size < 1_800_000
    tracemalloc.start()
    try:
        again = sweep(tmp_path)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert not again.from_cache
    np.testing.assert_array_equal(again.table["impulse"], truth.table["impulse"])
    assert peak < 200_000_000, f"{peak / 1e6:.0f} MB allocated while reading the entry"


def test_temporaries_of_dead_writers_are_evicted(tmp_path):
    """After a write, .tmp files of writers that died are deleted; a live writer's stays."""
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True, check=True)
    dead_pid = int(dead.stdout)
    live = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        tmp_path.mkdir(exist_ok=True)
        orphan = tmp_path / f"{TMP_PREFIX}{dead_pid}-abc.npz"
        orphan.write_bytes(b"x" * 1000)
        writing = tmp_path / f"{TMP_PREFIX}{live.pid}-def.npz"
        writing.write_bytes(b"x" * 1000)
        ancient = tmp_path / f"{TMP_PREFIX}old.npz"
        ancient.write_bytes(b"x")
        old = time.time() - 2 * cache.TMP_MAX_AGE
        os.utime(ancient, (old, old))
        fresh_unnamed = tmp_path / f"{TMP_PREFIX}new.npz"
        fresh_unnamed.write_bytes(b"x")
        sweep(tmp_path)
        assert not orphan.exists() and not ancient.exists()
        assert writing.exists() and fresh_unnamed.exists()
    finally:
        live.kill()
        live.wait()


def test_written_files_carry_a_digest_of_their_content(tmp_path):
    """The digest stored with an entry is the SHA-256 of its other arrays, recomputable."""
    sweep(tmp_path)
    with np.load(only_entry(tmp_path, "sweep"), allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    assert str(arrays["digest"]) == content_digest(arrays)
    arrays["t_flank"] = -arrays["t_flank"]
    assert str(arrays["digest"]) != content_digest(arrays)
