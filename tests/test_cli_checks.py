"""The ``rattle`` command checks everything before computing, and Ctrl-C leaves nothing behind.

Bad arguments exit with status 2 and one line before any work (no cache entry is written, no
orbit is searched).  ``serve`` and ``sweep --dask local`` are run as real processes in their
own session, interrupted as a terminal's Ctrl-C does (SIGINT to the whole process group), and
must end without a traceback and without leaving one process of that session alive.
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from rattle_cli.main import main

ROOT = Path(__file__).resolve().parents[1]
SWEEP = ["sweep", "--param", "lam", "--start", "1", "--stop", "2", "--num", "3",
         "--transient", "10", "--record", "5"]


@pytest.fixture(autouse=True)
def private_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("RATTLE_CACHE_DIR", str(tmp_path / "cache"))
    return tmp_path / "cache"


def one_line_error(argv, capsys, *words):
    code = main(argv)
    out, err = capsys.readouterr()
    assert code == 2, (code, out, err)
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("rattle: error:"), err
    for w in words:
        assert w in lines[0], (w, lines[0])
    return lines[0]


@pytest.mark.parametrize("argv, words", [
    (SWEEP + ["--out", "{tmp}/a.npz", "--workers", "0"], ["--workers 0"]),
    (SWEEP + ["--out", "{tmp}/a.npz", "--png", "x.jpg"], ["--png", ".png"]),
    (["continue", "--lam", "3.3", "--ds-max", "-1", "--out", "{tmp}/c.csv"], ["--ds-max", "-1"]),
    (["serve", "--address", "256.0.0.1"], ["--address", "256.0.0.1"]),
    (["serve", "--address", "no such host!"], ["--address"]),
    (["sound", "--lam", "3.3", "--periods", "1", "--excitation-hz", "0.0017", "--tail", "10",
      "--rate", "384000", "--out", "{tmp}/s.wav"], ["samples"]),
    (["sound", "--lam", "3.3", "--periods", "100000", "--out", "{tmp}/s.wav"], ["duration"]),
    (["sound", "--lam", "3.3", "--rate", "1000", "--out", "{tmp}/s.wav"], ["sample_rate", "1000"]),
    (["simulate", "--impacts", "{tmp}/x.csv", "--history", "{tmp}/x.csv"], ["same file"]),
])
def test_bad_arguments_exit_2_in_one_line_at_once(argv, words, tmp_path, capsys, private_cache):
    """Each bad argument exits 2 with one line, within seconds, before anything is computed."""
    argv = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    t0 = time.monotonic()
    one_line_error(argv, capsys, *words)
    assert time.monotonic() - t0 < 10
    assert not private_cache.exists() or not any(private_cache.iterdir())


ATLAS = ["atlas", "--lam", "1.2", "--from", "simulate:lam:pd", "--param2", "r", "--bounds",
         "0.3,0.9", "--out", "{tmp}/a.csv"]
GEARBOX_TOML = """[excitation]
orders = [{order = 2, accel_rad_s2 = 400}]
harmonics = 1
[[gear]]
name = "g"
inertia_kgm2 = 4e-4
base_radius_m = 0.035
drag_torque_Nm = 0.05
backlash_um = 80
"""
GEARBOX = ["gearbox", "{tmp}/box.toml", "--rpm", "1000:3000:3", "--out", "{tmp}/v.csv"]
BASINS = ["sweep", "--param", "x0", "--start", "-100", "--stop", "100", "--num", "3",
          "--param2", "v0", "--start2", "0", "--stop2", "1", "--num2", "2", "--transient", "10",
          "--record", "5", "--no-png"]


@pytest.mark.parametrize("argv, words", [
    (ATLAS + ["--transient", "-1"], ["--transient -1", "[0,"]),
    (ATLAS + ["--x0", "nan"], ["--x0 nan", "finite"]),
    (ATLAS + ["--x0", "inf"], ["--x0 inf"]),
    (GEARBOX + ["--workers", "0"], ["--workers 0", "[1, 256]"]),
    (GEARBOX + ["--workers", "-3"], ["--workers -3"]),
    (["--version", "extra"], ["'extra'"]),
    (["--version", "cache"], ["--version takes no other argument", "'cache'"]),
    (SWEEP + ["--out", "{tmp}/a.npz", "--no-png", "--png", "{tmp}/x.jpg"], ["--no-png", "--png"]),
    (SWEEP + ["--out", "{tmp}/a.npz", "--no-png", "--png", "{tmp}/x.png"], ["--no-png", "--png"]),
    (BASINS + ["--out", "{tmp}/b.npz"], ["--param x0", "backlash", "[1, 9]"]),
    (["sweep", "--param", "v0", "--start", "0", "--stop", "1", "--num", "2", "--param2", "x0",
      "--values2", "5,20", "--no-png", "--out", "{tmp}/b.npz"], ["--param2 x0", "backlash"]),
    (GEARBOX[:1] + ["{tmp}/deep.toml"] + GEARBOX[2:], ["deep.toml", "line 1", "depth is 8"]),
    (GEARBOX[:1] + ["{tmp}/bidi.toml"] + GEARBOX[2:], ["bidi.toml", "[[gear]] number 1",
                                                        "U+202E"]),
])
def test_bad_or_conflicting_arguments_are_refused_before_any_progress(argv, words, tmp_path,
                                                                      capsys, private_cache):
    """Bad or conflicting arguments, a basin start outside the backlash and a hostile gearbox
    file exit 2 with one line, before any progress bar, worker or cache entry."""
    (tmp_path / "box.toml").write_text(GEARBOX_TOML)
    (tmp_path / "deep.toml").write_text("x = " + "[" * 5000 + "]" * 5000 + "\n")
    (tmp_path / "bidi.toml").write_text(GEARBOX_TOML.replace('"g"', '"g\\u202egnittar"'))
    argv = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    t0 = time.monotonic()
    line = one_line_error(argv, capsys, *words)
    assert time.monotonic() - t0 < 30
    assert "%|" not in line and "\u202e" not in line
    assert not private_cache.exists() or not any(private_cache.iterdir())
    assert not (tmp_path / "a.csv").exists() and not (tmp_path / "v.csv").exists()


def test_the_version_alone_is_printed(capsys):
    """--version alone prints the version and exits 0; no command at all is still an error."""
    assert main(["--version"]) == 0
    out, err = capsys.readouterr()
    assert out.startswith("rattle ") and len(out.strip().splitlines()) == 1 and not err
    one_line_error([], capsys, "required: COMMAND")


@pytest.mark.parametrize("action", ["clear", "show"])
@pytest.mark.parametrize("below", [False, True], ids=["file", "under-a-file"])
def test_a_cache_directory_that_is_a_file_is_refused(action, below, tmp_path, capsys,
                                                     monkeypatch):
    """RATTLE_CACHE_DIR naming a file (or a folder under one) makes cache clear and show, and
    the commands that use the cache, exit 2 with one line; the file is left as it was."""
    blocker = tmp_path / "not-a-dir"
    blocker.write_text("keep")
    monkeypatch.setenv("RATTLE_CACHE_DIR", str(blocker / "sub" if below else blocker))
    one_line_error(["cache", action], capsys, "RATTLE_CACHE_DIR", "is not a directory")
    one_line_error(SWEEP + ["--out", str(tmp_path / "a.npz")], capsys, "RATTLE_CACHE_DIR")
    assert blocker.read_text() == "keep"


def test_the_cache_size_variable_is_checked_first(tmp_path, capsys, monkeypatch, private_cache):
    """A RATTLE_CACHE_SIZE_MB that is not a size stops the command before it runs."""
    monkeypatch.setenv("RATTLE_CACHE_SIZE_MB", "lots")
    one_line_error(SWEEP + ["--out", str(tmp_path / "a.npz")], capsys, "RATTLE_CACHE_SIZE_MB", "lots")
    assert not private_cache.exists()


def test_derived_outputs_are_checked_before_the_sweep(tmp_path, capsys, private_cache):
    """The PNG a sweep writes beside --out is checked first: a directory there stops it at once."""
    (tmp_path / "a.png").mkdir()
    one_line_error(SWEEP + ["--out", str(tmp_path / "a.npz")], capsys, "a.png", "directory")
    assert not private_cache.exists()
    (tmp_path / "b_summary.csv").mkdir()
    one_line_error(SWEEP + ["--out", str(tmp_path / "b.csv"), "--no-png"], capsys, "b_summary.csv")


@pytest.mark.parametrize("tail", ["_impacts", "_bifurcations"])
def test_continuation_tables_are_checked_before_the_search(tail, tmp_path, capsys, monkeypatch):
    """continue checks OUT_impacts and OUT_bifurcations before it looks for an orbit."""
    def no_search(*a, **k):
        raise AssertionError("an orbit was searched before the outputs were checked")
    monkeypatch.setattr("rattle_core.analysis.continuation.find_orbit", no_search)
    (tmp_path / f"c{tail}.csv").mkdir()
    one_line_error(["continue", "--lam", "3.3", "--out", str(tmp_path / "c.csv")], capsys,
                   f"c{tail}.csv")


# ----- Ctrl-C ---------------------------------------------------------------------------------

def _environment(tmp_path) -> dict:
    """The checkout's rattle_cli and app (as rattle_app) first on the path of a subprocess."""
    shim = tmp_path / "shim"
    shim.mkdir(exist_ok=True)
    link = shim / "rattle_app"
    if not link.exists():
        link.symlink_to(ROOT / "app", target_is_directory=True)
    return dict(os.environ, PYTHONPATH=os.pathsep.join([str(shim), str(ROOT)]),
                RATTLE_CACHE_DIR=str(tmp_path / "cache"))


def _session_processes(sid: int) -> list[str]:
    found = []
    for pid in os.listdir("/proc"):
        if not pid.isdigit():
            continue
        try:
            if os.getsid(int(pid)) == sid:
                found.append(Path(f"/proc/{pid}/cmdline").read_text().replace("\0", " ")[:120])
        except OSError:
            pass
    return found


def _interrupt(proc, tmp_path, wait_for_line: str | None, after: float = 0.0) -> tuple[str, list]:
    """SIGINT to the process group of ``proc`` (once its stdout printed ``wait_for_line``, or
    ``after`` seconds); returns its stderr and whatever of its session is alive after."""
    try:
        if wait_for_line is not None:
            deadline = time.monotonic() + 240
            while wait_for_line not in proc.stdout.readline():
                assert time.monotonic() < deadline and proc.poll() is None, "never got ready"
        else:
            time.sleep(after)
        os.killpg(proc.pid, signal.SIGINT)
        _, err = proc.communicate(timeout=90)
        deadline = time.monotonic() + 15
        while _session_processes(proc.pid) and time.monotonic() < deadline:
            time.sleep(0.2)
        return err, _session_processes(proc.pid)
    finally:
        for _ in _session_processes(proc.pid):
            try:
                os.killpg(proc.pid, signal.SIGKILL)
            except OSError:
                pass


def _start(args, tmp_path):
    return subprocess.Popen([sys.executable, "-m", "rattle_cli", *args], cwd=tmp_path,
                            env=_environment(tmp_path), stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True)


def _free_port() -> int:
    import socket
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.mark.parametrize("extra", [[], ["--dask", "local"]], ids=["own-workers", "dask-local"])
def test_ctrl_c_stops_serve_cleanly(extra, tmp_path):
    """Ctrl-C to a serving dashboard: status 0, no traceback, no process of it left."""
    proc = _start(["serve", "--port", str(_free_port()), *extra], tmp_path)
    err, left = _interrupt(proc, tmp_path, "serving Rattle Explorer")
    assert proc.returncode == 0, err
    assert "Traceback" not in err, err
    assert left == []


@pytest.mark.parametrize("after", [1.5, 5.0])
def test_ctrl_c_during_start_up_leaves_nothing(after, tmp_path):
    """Ctrl-C while the server starts (imports, compiled kernels, worker processes) ends it
    without a traceback and without a process left."""
    proc = _start(["serve", "--port", str(_free_port())], tmp_path)
    err, left = _interrupt(proc, tmp_path, None, after)
    assert proc.returncode in (0, 130), err
    assert "Traceback" not in err, err
    assert left == []


def test_ctrl_c_in_a_dask_sweep_ends_its_workers(tmp_path):
    """Ctrl-C in ``sweep --dask local``: status 130, one line, the Dask workers gone.

    (A Dask worker still importing when the signal arrives may print its own interrupted
    import; the command itself prints none.)
    """
    proc = _start(["sweep", "--param", "lam", "--start", "0.5", "--stop", "4", "--num", "20000",
                   "--transient", "2000", "--out", str(tmp_path / "d.npz"), "--no-cache",
                   "--dask", "local"], tmp_path)
    err, left = _interrupt(proc, tmp_path, None, 12.0)
    assert proc.returncode == 130, err
    assert "rattle: interrupted" in err
    assert "rattle_cli" not in err and "rattle_core" not in err, err
    assert left == []


def test_the_atlas_codim2_table_is_checked_first(tmp_path, capsys, monkeypatch):
    """atlas checks OUT_codim2 (and that no two outputs coincide) before it computes a curve."""
    import rattle_cli.commands.atlas as atlas_command

    def no_curve(*a, **k):
        raise AssertionError("a curve was computed before the outputs were checked")
    monkeypatch.setattr(atlas_command, "parse_spec", no_curve)
    (tmp_path / "pd_codim2.csv").mkdir()
    argv = ["atlas", "--lam", "1.2", "--from", "c:lam:pd", "--param2", "j", "--bounds", "1,8",
            "--out", str(tmp_path / "pd.csv")]
    one_line_error(argv, capsys, "pd_codim2.csv")


def test_a_ctrl_c_while_the_server_warms_up_is_raised_once_it_is_warm():
    """A Ctrl-C during warm-up is not raised inside it (numba's compiled code would print and
    drop it, and the server would go on serving), but as soon as warm-up ends."""
    from app.signals import sigint_deferred
    steps = []
    with pytest.raises(KeyboardInterrupt):
        with sigint_deferred():
            os.kill(os.getpid(), signal.SIGINT)
            steps.append("after the signal")  # a callback inside compiled code stands here
            steps.append("warm")
    assert steps == ["after the signal", "warm"]
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_a_ctrl_c_inside_a_weak_reference_callback_still_stops_the_server():
    """The served dashboard waits for Ctrl-C with :func:`app.signals.sigint_noted` (and
    ``rattle serve`` imports the server inside it): an
    interrupt that lands while Python runs a weak reference's callback (where a raised
    KeyboardInterrupt is printed and dropped) is still noted, and the handler is put back."""
    import weakref

    from app.signals import sigint_noted

    class Thing:
        pass
    before = signal.getsignal(signal.SIGINT)
    with sigint_noted() as stop:
        thing = Thing()
        ref = weakref.ref(thing, lambda _: os.kill(os.getpid(), signal.SIGINT))
        del thing  # the callback runs here, and the signal arrives inside it
        assert stop.wait(10) and ref() is None
    assert signal.getsignal(signal.SIGINT) is before
