"""The disk cache serves only entries its user signed: five forgeries, and the key itself.

Whoever can write to the cache directory can recompute a SHA-256 digest, so each forgery
here keeps the file's format valid (digest recomputed, the original signature kept where one
is copied): arrays changed; another request's entry with its stored request rewritten to this
one's; an entry signed in another cache, under another key; an entry renamed to another
request's file name; a verdict of another gearbox at the same speeds.  For sweeps, maps,
verdicts, continued branches and bifurcation curves (the last two through the same wrapper,
with the app's own file formats), each must be a miss: recomputed, rewritten, then served
again.  The key is made on first use with mode 0600 in the config directory, or taken from
``RATTLE_CACHE_KEY``; a bad key is an error naming it.
"""
from __future__ import annotations

import dataclasses
import json
import os
import stat
import subprocess
import sys
import zipfile

import numpy as np
import pytest

from app.work import atlas as atlas_job
from app.work import branch as branch_job
from rattle_core import RattleParams
from rattle_core.model.gearbox import Gearbox
from rattle_core.store import cache, signing
from rattle_core.store.files import atomic_savez, content_digest, read_checked
from rattle_core.store.files import signing as sign_with
from rattle_core.store.verdicts import save_verdict
from rattle_core.store.verdicts import cached_verdict
from gearboxes import SAMPLE_ONE_GEAR

P = RattleParams(lam=3.3, amplitudes=(1.0, 0.25), phases_deg=(0.0, 45.0))
KEY_OURS, KEY_THEIRS = "a1" * 32, "5e" * 32

TOML = SAMPLE_ONE_GEAR
BOX = Gearbox.from_text(TOML)
BOX_DRAG = BOX.replace(gears=(BOX.gears[0].replace(drag_torque_Nm=0.08),))
BOX_RENAMED = BOX.replace(gears=(BOX.gears[0].replace(name="6th idler"),))


@pytest.fixture(autouse=True)
def own_config(tmp_path, monkeypatch):
    """Each test has a config directory (hence a key) of its own."""
    monkeypatch.setenv("RATTLE_CONFIG_DIR", str(tmp_path / "config"))
    monkeypatch.delenv("RATTLE_CACHE_KEY", raising=False)


# ----- the kinds of entry: two requests each (0 and 1), and what the forger changes -----------

@dataclasses.dataclass
class Kind:
    prefix: str
    run: callable          # (directory, which request) -> (result, served from the cache)
    seen: callable         # result -> the array a user reads
    field: str             # the array the forger scales


def _sweep(d, which):
    res = cache.cached_sweep(P, "lam", np.linspace(1.0, 3.0, 4), transient=40,
                             record=15 + which, directory=d)
    return res, res.from_cache


def _map(d, which):
    res = cache.cached_map("regime", P, "lam", [1.0, 2.0, 3.0], "r", [0.5, 0.7], directory=d,
                           transient=20, record=10 + which)
    return res, res.from_cache


def _verdict(d, which):
    res = cached_verdict((BOX, BOX_DRAG)[which], np.array([1500.0, 2500.0]), transient=40,
                         record=20, directory=d, ensemble_runs=0)
    return res, res.from_cache


def _branch(d, which):
    def compute():
        x = np.linspace(0.5, 3.3, 5) * (1 + which)
        return branch_job.Branches({"up/points/value": x, "up/points/impulse": 3.732 + x},
                                   {"up": {"status": "bound"}, "which": which})
    return cache.cached("cont", {"branch": which}, compute, branch_job._load, branch_job._save,
                        lambda b: True, d)


def _curve(d, which):
    def compute():
        x = np.linspace(0.5, 3.3, 5)
        return atlas_job._Out(arrays={"0/lam": x, "0/r": 0.5 + 0.1 * x + which},
                              meta={"kind": "curve", "cancelled": False})
    return cache.cached("atlas", {"curve": which}, compute, atlas_job._load, atlas_job._save,
                        lambda o: True, d)


KINDS = {
    "sweep": Kind("sweep", _sweep, lambda r: r.table["impulse"].to_numpy(), "t_impulse"),
    "map": Kind("map", _map, lambda r: r.fields["intensity"], "f_intensity"),
    "verdict": Kind("gearbox", _verdict, lambda r: r.table["intensity"].to_numpy(float),
                    "c_intensity"),
    "branch": Kind("cont", _branch, lambda r: r.arrays["up/points/impulse"],
                   "up/points/impulse"),
    "curve": Kind("atlas", _curve, lambda r: r["arrays"]["0/r"], "0/r"),
}


def entry(d, prefix, meta_key):
    return d / f"{prefix}-{meta_key[:32]}.npz"


def arrays_of(path):
    with np.load(path, allow_pickle=False) as z:
        return {k: z[k] for k in z.files}


def comment_of(path):
    with zipfile.ZipFile(path) as zf:
        return zf.comment


def write(path, arrays, comment):
    """The forger's file: the arrays with their digest recomputed, and ``comment`` (a signature
    copied from a genuine entry) as the zip's comment."""
    arrays = {k: v for k, v in arrays.items() if k != "digest"}
    arrays["digest"] = np.array(content_digest(arrays))
    with open(path, "wb") as f:
        np.savez_compressed(f, **arrays)
    with zipfile.ZipFile(path, "a") as zf:
        zf.comment = comment


def meta_of(arrays):
    return json.loads(str(arrays["meta"]))


def with_meta(arrays, meta):
    return {**arrays, "meta": np.array(json.dumps(meta))}


# ----- the forgeries --------------------------------------------------------------------------

def redigested(kind, d, path):
    """Arrays changed, digest recomputed, the genuine signature kept."""
    a = arrays_of(path)
    a[kind.field] = a[kind.field] * 12.0
    write(path, a, comment_of(path))


def request_changed(kind, d, path):
    """The other request's genuine entry, its stored key and request rewritten to this one's."""
    ours = meta_of(arrays_of(path))
    kind.run(d, 1)
    theirs_path = next(p for p in d.glob(f"{kind.prefix}-*.npz") if p != path)
    a = arrays_of(theirs_path)
    write(path, with_meta(a, {**meta_of(a), "key": ours["key"], "request": ours["request"]}),
          comment_of(theirs_path))


def other_key(kind, d, path):
    """A poisoned entry made and signed in another cache, under its owner's key."""
    a = arrays_of(path)
    a[kind.field] = a[kind.field] * 12.0
    context = f"{kind.prefix}:{meta_of(a)['key']}"
    with sign_with(bytes.fromhex(KEY_THEIRS), context):
        atomic_savez(path, a)
    read_checked(path, key=bytes.fromhex(KEY_THEIRS), context=context)  # valid in its cache


def renamed(kind, d, path):
    """The other request's genuine entry moved to this request's file name, untouched."""
    kind.run(d, 1)
    theirs_path = next(p for p in d.glob(f"{kind.prefix}-*.npz") if p != path)
    os.replace(theirs_path, path)


FORGERIES = {"changed arrays, digest recomputed": redigested,
             "stored request changed": request_changed,
             "signed under another key": other_key,
             "renamed to another request": renamed}


@pytest.mark.parametrize("kind", list(KINDS))
@pytest.mark.parametrize("forgery", list(FORGERIES))
def test_a_forged_entry_is_a_miss_recomputed_and_rewritten(tmp_path, kind, forgery):
    """Each forgery of each kind of entry is recomputed (never served), rewritten, then served."""
    k, d = KINDS[kind], tmp_path / "cache"
    truth, hit = k.run(d, 0)
    assert not hit
    (path,) = d.glob(f"{k.prefix}-*.npz")
    FORGERIES[forgery](k, d, path)
    again, hit = k.run(d, 0)
    assert not hit, f"{kind}: {forgery} was served"
    np.testing.assert_array_equal(k.seen(again), k.seen(truth))
    third, hit = k.run(d, 0)
    assert hit
    np.testing.assert_array_equal(k.seen(third), k.seen(truth))


def test_a_verdict_of_another_gearbox_at_the_same_speeds_is_not_served_even_if_signed(tmp_path):
    """A verdict is checked on its whole request, not on its speeds: a genuinely signed entry
    of another gearbox at the same speeds, stored under this request, is recomputed."""
    d = tmp_path / "cache"
    rpm = np.array([1500.0, 2500.0])
    truth = cached_verdict(BOX, rpm, transient=40, record=20, directory=d, ensemble_runs=0)
    (path,) = d.glob("gearbox-*.npz")
    meta = meta_of(arrays_of(path))
    other = cached_verdict(BOX_RENAMED, rpm, transient=40, record=20, ensemble_runs=0,
                           use_cache=False)
    with sign_with(signing.secret(), f"gearbox:{meta['key']}"):  # as if the cache had written it
        save_verdict(path, other, key=meta["key"], request=meta["request"])
    again = cached_verdict(BOX, rpm, transient=40, record=20, directory=d, ensemble_runs=0)
    assert not again.from_cache
    assert set(again.table["gear"]) == set(truth.table["gear"])


# ----- the key ----------------------------------------------------------------------------------

def test_the_key_is_made_on_first_use_with_mode_0600_and_kept(tmp_path):
    """The first cached run makes a 32-byte key, mode 0600, in RATTLE_CONFIG_DIR; later runs
    (and other processes) use the same key."""
    path = tmp_path / "config" / signing.KEY_FILE
    assert not path.exists()
    _sweep(tmp_path / "cache", 0)
    assert stat.S_IMODE(path.stat().st_mode) == 0o600
    key = bytes.fromhex(path.read_text())
    assert len(key) == 32 and signing.secret() == key
    child = subprocess.run([sys.executable, "-c", "from rattle_core.store.signing import secret;"
                            "print(secret().hex())"], capture_output=True, text=True, check=True)
    assert child.stdout.strip() == key.hex()
    assert [p.name for p in path.parent.iterdir()] == [signing.KEY_FILE]  # no temporary left
    assert _sweep(tmp_path / "cache", 0)[1]


def test_concurrent_first_uses_agree_on_one_key(tmp_path):
    """Processes that make the key at the same moment all end up with the one key on disk."""
    code = "from rattle_core.store.signing import secret; print(secret().hex())"
    procs = [subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
             for _ in range(4)]
    keys = {p.communicate()[0].strip() for p in procs}
    assert keys == {(tmp_path / "config" / signing.KEY_FILE).read_text().strip()}


def test_config_directory_from_environment(tmp_path, monkeypatch):
    """RATTLE_CONFIG_DIR, else $XDG_CONFIG_HOME/rattle-explorer, else ~/.config/rattle-explorer."""
    assert signing.key_path() == tmp_path / "config" / "cache.key"
    monkeypatch.delenv("RATTLE_CONFIG_DIR")
    monkeypatch.setenv("XDG_CONFIG_HOME", str(tmp_path / "xdg"))
    assert signing.config_dir() == tmp_path / "xdg" / "rattle-explorer"
    monkeypatch.delenv("XDG_CONFIG_HOME")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert signing.config_dir() == tmp_path / "home" / ".config" / "rattle-explorer"


def test_the_key_from_the_environment_is_used_and_no_file_is_made(tmp_path, monkeypatch):
    """RATTLE_CACHE_KEY signs the entries; an entry signed under it is a miss under another."""
    monkeypatch.setenv("RATTLE_CACHE_KEY", KEY_OURS)
    d = tmp_path / "cache"
    _sweep(d, 0)
    assert _sweep(d, 0)[1]
    assert not (tmp_path / "config").exists()
    (path,) = d.glob("sweep-*.npz")
    meta = meta_of(arrays_of(path))
    read_checked(path, key=bytes.fromhex(KEY_OURS), context=f"sweep:{meta['key']}")
    monkeypatch.setenv("RATTLE_CACHE_KEY", KEY_THEIRS)
    assert not _sweep(d, 0)[1]


@pytest.mark.parametrize("text", ["abc", "zz" * 32, "ab" * 31])
def test_a_bad_key_in_the_environment_is_an_error_naming_it(tmp_path, monkeypatch, text):
    """A malformed or short RATTLE_CACHE_KEY is a ValueError naming it, without the key."""
    monkeypatch.setenv("RATTLE_CACHE_KEY", text)
    with pytest.raises(signing.CacheKeyError, match="RATTLE_CACHE_KEY must hold at least 64") as e:
        _sweep(tmp_path / "cache", 0)
    assert text not in str(e.value)


@pytest.mark.parametrize("damage", ["short", "not hex", "mode 0644", "directory"])
def test_a_bad_key_file_is_an_error_naming_it(tmp_path, damage):
    """A key file that holds no key, or that others may read, is an error naming the file and
    the remedy; it is not replaced behind the user's back."""
    path = tmp_path / "config" / signing.KEY_FILE
    path.parent.mkdir()
    if damage == "directory":
        path.mkdir()
    else:
        path.write_text({"short": "ab" * 8, "not hex": "x" * 64}.get(damage, "ab" * 32))
        path.chmod(0o644 if damage == "mode 0644" else 0o600)
    with pytest.raises(signing.CacheKeyError, match="cache key") as e:
        _sweep(tmp_path / "cache", 0)
    assert str(path) in str(e.value)
    assert ("chmod 600" if damage == "mode 0644" else "delete it") in str(e.value)
    assert not (tmp_path / "cache").exists() or not list((tmp_path / "cache").glob("*.npz"))


def test_no_key_can_be_made_the_result_is_computed_and_nothing_stored(tmp_path, monkeypatch):
    """A config directory that cannot be made: the result is computed, nothing is cached."""
    blocker = tmp_path / "file"
    blocker.write_text("")
    monkeypatch.setenv("RATTLE_CONFIG_DIR", str(blocker / "config"))
    d = tmp_path / "cache"
    res, hit = _sweep(d, 0)
    assert not hit and len(res.values) == 4
    assert not d.exists() or not list(d.iterdir())


def test_every_kind_of_entry_is_listed_and_cleared(tmp_path):
    """Sweeps, maps, verdicts, branches and curves are all entries: listed, evicted, cleared."""
    d = tmp_path / "cache"
    for kind in KINDS.values():
        kind.run(d, 0)
    assert sorted(e.kind for e in cache.entries(d)) == sorted(k.prefix for k in KINDS.values())
    assert cache.clear(d)[0] == len(KINDS) and not list(d.glob("*.npz"))
