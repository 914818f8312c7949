"""The project works from a wheel: ``pip install .`` into a fresh venv, used outside the checkout.

The venv sees the project venv's packages through a ``.pth`` line (so nothing is downloaded:
``--no-deps --no-build-isolation``), but not the checkout, and its interpreter runs from a
directory outside it.  Checked there: every module of the checkout is installed, the shipped
diagrams and the sample run-up are found inside the package (as ``rattle paper`` and the
dashboard look them up),
``py.typed`` is present, the dashboard imports as ``rattle_app`` and no top-level ``app`` is
installed, and the ``rattle`` console script runs.
"""
from __future__ import annotations

import json
import os
import site
import subprocess
import sys
import venv
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent

CHECK = r"""
import importlib.metadata, importlib.util, json, sys
from pathlib import Path
import rattle_core, rattle_cli, rattle_app.main
from rattle_core.store import assets
from rattle_core.paper.cases import SWEEP_CASES
from rattle_core.measure.orders import SAMPLE_RUNUP
found = {name: assets.read_asset(name) is not None for name in assets.list_assets()}
files = [str(f) for f in importlib.metadata.distribution("rattle-explorer").files]
print(json.dumps({
    "core": rattle_core.__file__, "cli": rattle_cli.__file__, "app": rattle_app.main.__file__,
    "assets_dir": str(assets.ASSETS_DIR), "assets": found, "sweep_cases": list(SWEEP_CASES),
    "py_typed": (Path(rattle_core.__file__).parent / "py.typed").is_file(),
    "sample_runup": str(SAMPLE_RUNUP) if SAMPLE_RUNUP.is_file() else "",
    "serve": callable(rattle_app.main.serve) and callable(rattle_app.main.create_app),
    "top_level_app": any(f.startswith("app/") for f in files),
    "app_spec": importlib.util.find_spec("app") is not None,
    "files": files,
}))
"""


def _project_site_packages() -> list[str]:
    return [p for p in site.getsitepackages() if Path(p).is_dir()]


@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    """A fresh venv with the project installed from the checkout as a wheel would be."""
    base = tmp_path_factory.mktemp("wheel-install")
    env_dir = base / "venv"
    venv.EnvBuilder(system_site_packages=False, with_pip=False).create(env_dir)
    py = env_dir / "bin" / "python"
    purelib = Path(subprocess.run([str(py), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                                  capture_output=True, text=True, check=True).stdout.strip())
    # the project's dependencies, without its own (editable) install: a .pth line adds the
    # directory, but .pth files inside it are not run
    (purelib / "project-deps.pth").write_text("\n".join(_project_site_packages()) + "\n")
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
    build = subprocess.run([sys.executable, "-m", "pip", "--python", str(py), "install",
                            "--no-deps", "--no-build-isolation", "--no-cache-dir", str(ROOT)],
                           capture_output=True, text=True, timeout=600, env=env, cwd=base)
    assert build.returncode == 0, build.stderr[-3000:]
    return {"python": py, "bin": env_dir / "bin", "purelib": purelib, "cwd": base, "env": env,
            "log": build.stdout + build.stderr}


def test_the_build_warns_of_nothing(installed):
    """Building the wheel prints no setuptools deprecation (license table, data folders missing
    from the packages list): the configuration is the current one."""
    log = installed["log"]
    assert "Building wheel" in log or "Successfully installed" in log  # the build's output is here
    assert "deprecated" not in log and "absent from the `packages`" not in log, log[-3000:]


def _run(installed, argv, **kw):
    env = dict(installed["env"], RATTLE_CACHE_DIR=str(installed["cwd"] / "cache"))
    return subprocess.run(argv, capture_output=True, text=True, timeout=300, env=env,
                          cwd=installed["cwd"], **kw)


def test_the_installed_package_finds_its_assets_and_dashboard(installed):
    """Imports come from the venv, not the checkout; the shipped diagrams, py.typed and the
    dashboard are there; the dashboard is ``rattle_app``, never a top-level ``app``."""
    done = _run(installed, [str(installed["python"]), "-c", CHECK])
    assert done.returncode == 0, done.stderr[-3000:]
    got = json.loads(done.stdout)
    site_dir = str(installed["purelib"])
    for key in ("core", "cli", "app", "assets_dir", "sample_runup"):
        assert got[key].startswith(site_dir), (key, got[key])
    assert got["assets"] == {name: True for name in got["sweep_cases"]}
    assert got["py_typed"] and got["serve"]
    assert not got["top_level_app"] and not got["app_spec"]
    installed_py = {f for f in got["files"] if f.endswith(".py")}
    for folder, name in (("rattle_core", "rattle_core"), ("rattle_cli", "rattle_cli"),
                         ("app", "rattle_app")):
        for path in (ROOT / folder).rglob("*.py"):
            rel = Path(name) / path.relative_to(ROOT / folder)
            assert str(rel) in installed_py, f"{rel} is not installed"


def test_the_console_script_runs_from_the_wheel(installed, tmp_path):
    """The installed ``rattle`` script answers --help, shows its cache, and reports a bad
    argument in one line, from outside the checkout."""
    rattle = str(installed["bin"] / "rattle")
    ok = _run(installed, [rattle, "--help"])
    assert ok.returncode == 0 and "serve" in ok.stdout and "cache" in ok.stdout, ok.stderr
    shown = _run(installed, [rattle, "cache", "show"])
    assert shown.returncode == 0 and "0 entries" in shown.stdout, shown.stderr
    bad = _run(installed, [rattle, "paper", "--out", ""])
    assert bad.returncode == 2 and bad.stderr.startswith("rattle: error: --out is empty")
