"""``--dask local`` cleans up after itself: no process of the command outlives it, and nothing
is reported on the way out (no leaked semaphore, no traceback).

The command runs in a session of its own, so every process it started (the Dask workers,
multiprocessing's resource tracker) is found by its session id even once reparented.
"""
from __future__ import annotations

import os
import subprocess
import sys

from conftest import wait_for

RATTLE = [sys.executable, "-m", "rattle_cli"]
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def _alive_in_session(sid: int) -> list[str]:
    """Command lines of the running (not zombie) processes of session ``sid``."""
    out = []
    for pid in os.listdir("/proc"):
        if not pid.isdigit():
            continue
        try:
            with open(f"/proc/{pid}/stat") as f:
                fields = f.read().rsplit(")", 1)[1].split()
            with open(f"/proc/{pid}/cmdline") as f:
                cmdline = f.read().replace("\0", " ").strip()
        except OSError:
            continue  # ended meanwhile
        state, session = fields[0], int(fields[3])
        if session == sid and state != "Z":
            out.append(f"{pid}: {cmdline[:120]}")
    return out


def test_sweep_on_dask_local_leaves_no_process_and_no_warning(tmp_path):
    """After ``sweep --dask local`` exits, none of its processes runs on, and its stderr holds
    no leaked-semaphore warning or traceback."""
    cmd = RATTLE + ["sweep", "--param", "lam", "--values", "1.5,2.5,3.3", "--transient", "40",
                    "--record", "10", "--no-png", "--no-cache", "-q",
                    "--out", str(tmp_path / "d.csv"), "--dask", "local", "--workers", "2"]
    env = {**os.environ, "RATTLE_CACHE_DIR": str(tmp_path / "cache")}
    proc = subprocess.Popen(cmd, cwd=ROOT, env=env, start_new_session=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        # the pipes close when every process holding them has ended, the workers included
        out, err = proc.communicate(timeout=600)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, 9)
    assert proc.returncode == 0, err
    assert (tmp_path / "d.csv").exists()
    # multiprocessing's resource tracker ends once it reads that its parent has gone
    wait_for(lambda: _alive_in_session(proc.pid) == [], 15,
             f"the command's processes to end: {_alive_in_session(proc.pid)}")
    assert "leaked semaphore" not in err
    assert "Traceback" not in err, err
