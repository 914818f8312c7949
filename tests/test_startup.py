"""``rattle --help`` and every subcommand's ``--help`` start without the numerical stack.

Each is run in a fresh interpreter with ``-X importtime``, which lists every module the process
imported; none of numpy, numba, scipy, pandas, Panel, Bokeh, matplotlib or ``rattle_core`` may
be among them (they load inside a command's ``run``).  A module-level import of any of them in
``rattle_cli`` makes these tests fail, whatever the machine's speed.
"""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from rattle_cli import commands as _commands

ROOT = Path(__file__).resolve().parent.parent
HEAVY = ("numpy", "numba", "scipy", "pandas", "panel", "bokeh", "holoviews", "matplotlib",
         "mosqito", "dask", "distributed", "pyarrow", "rattle_core", "app")
# every command the CLI lists, so a new one is covered without editing this file
COMMANDS = tuple(m.__name__.rsplit(".", 1)[1].rstrip("_") for m in _commands.COMMANDS)


def imported(*argv: str) -> tuple[set[str], str]:
    """Top-level packages a ``python -m rattle_cli ARGV`` process imported, and its stdout."""
    r = subprocess.run([sys.executable, "-X", "importtime", "-m", "rattle_cli", *argv],
                       capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert r.returncode == 0, r.stderr[-2000:]
    names = set()
    for line in r.stderr.splitlines():
        if line.startswith("import time:") and "|" in line:
            name = line.rsplit("|", 1)[1].strip()
            if name != "package":
                names.add(name.split(".")[0])
    assert "rattle_cli" in names  # the listing is there to be read
    return names, r.stdout


def test_rattle_help_imports_no_numerical_stack():
    """``rattle --help`` lists every command and imports none of the heavy packages."""
    names, out = imported("--help")
    assert all(c in out for c in COMMANDS)
    assert sorted(names & set(HEAVY)) == []


@pytest.mark.parametrize("command", COMMANDS)
def test_subcommand_help_imports_no_numerical_stack(command):
    """``rattle COMMAND --help`` prints its options and imports none of the heavy packages."""
    names, out = imported(command, "--help")
    assert f"usage: rattle {command}" in out
    assert sorted(names & set(HEAVY)) == []


def test_the_orders_default_written_out_in_the_cli_is_the_core_default():
    """``rattle orders`` spells its default orders out (to import nothing at --help): they are
    the core's ``DEFAULT_ORDERS``."""
    from rattle_cli.commands import orders
    from rattle_core.model.orders import DEFAULT_ORDERS
    assert tuple(float(k) for k in orders.DEFAULT_ORDERS.split(",")) == DEFAULT_ORDERS
