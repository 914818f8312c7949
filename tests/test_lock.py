"""The environment the suite runs in is the one constraints.txt pins.

scripts/env.sh installs with ``pip -c constraints.txt``; these tests fail when a package in the
running environment differs from the lock (a venv reused across releases, an install by hand),
and when the lock and pyproject.toml's ranges disagree.
"""
from __future__ import annotations

import importlib.metadata
import tomllib
from pathlib import Path

from packaging.requirements import Requirement
from packaging.utils import canonicalize_name
from packaging.version import Version

ROOT = Path(__file__).resolve().parents[1]


def _lock() -> dict[str, str]:
    pins = {}
    for n, line in enumerate((ROOT / "constraints.txt").read_text().splitlines(), 1):
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        name, sep, version = line.partition("==")
        assert sep and name and version, f"constraints.txt:{n}: expected NAME==VERSION, got {line!r}"
        pins[canonicalize_name(name)] = version.strip()
    return pins


def _project_requirements() -> list[Requirement]:
    meta = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    reqs = [Requirement(r) for r in meta["dependencies"]]
    for extra in meta.get("optional-dependencies", {}).values():
        reqs += [Requirement(r) for r in extra]
    return reqs


def _installed() -> dict[str, str]:
    found = {}
    for dist in importlib.metadata.distributions():
        name = canonicalize_name(dist.metadata["Name"])
        if name != "rattle-explorer":
            found[name] = dist.version
    return found


def test_every_installed_package_has_its_locked_version():
    """A package whose installed version is not the pinned one fails, naming both versions."""
    pins, installed = _lock(), _installed()
    drift = {n: (installed[n], v) for n, v in pins.items() if n in installed and installed[n] != v}
    assert not drift, "installed ≠ constraints.txt: " + ", ".join(
        f"{n} {have} (locked {want})" for n, (have, want) in sorted(drift.items()))


def test_every_installed_package_is_locked():
    """Nothing in the environment was resolved outside the lock (a new dependency must be locked)."""
    unlocked = sorted(set(_installed()) - set(_lock()))
    assert not unlocked, f"installed but not in constraints.txt: {unlocked} (refresh: scripts/lock.sh)"


def test_every_locked_package_is_installed():
    """The lock holds nothing this environment lacks, so it is the environment the suite ran in."""
    missing = sorted(set(_lock()) - set(_installed()))
    assert not missing, f"in constraints.txt but not installed: {missing}"


def test_the_lock_meets_the_ranges_of_pyproject():
    """pyproject.toml keeps compatible ranges; each direct dependency's pin lies inside its range."""
    pins = _lock()
    for req in _project_requirements():
        name = canonicalize_name(req.name)
        assert name in pins, f"{req.name} is a dependency but has no pin in constraints.txt"
        assert req.specifier.contains(Version(pins[name]), prereleases=True), (
            f"{req.name}=={pins[name]} in constraints.txt is outside pyproject's {req.specifier}")


def test_pyproject_keeps_ranges_not_pins():
    """People installing the package into their own environment get ranges: only MOSQITO, whose
    private loudness steps are the test reference, is pinned exactly."""
    exact = [str(r) for r in _project_requirements()
             if any(s.operator == "==" for s in r.specifier) and canonicalize_name(r.name) != "mosqito"]
    assert not exact, f"exact pins belong in constraints.txt, not pyproject.toml: {exact}"
