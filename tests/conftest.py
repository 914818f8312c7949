"""Shared pytest configuration.

* Browser tests (``@pytest.mark.ui``) drive Debian's Chromium through pytest-playwright, since
  Playwright cannot download its own browser here; they are skipped, with the reason, when
  Chromium or Playwright is missing, except under ``scripts/test.sh`` (which installs both and
  sets ``RATTLE_REQUIRE_UI=1``), where a missing browser is an error.
* ``dash`` is one dashboard session built without a server or browser (the update path, the
  views), torn down like a closed session; its background jobs run in ``job_pool``'s worker
  processes, and ``wait_for`` waits for their results.
* ``dashboard_server`` serves the real dashboard once per test process on a free port and
  records every log line, so tests can assert that the server printed no traceback.
* ``scripts/test.sh`` runs the suite on two processes (pytest-xdist, a file each at a time),
  browser-test files in turn with the others (:func:`_alternated`).
* The run has a disk cache of its own, empty at the start, so no test is served a result that
  an earlier run left, and a config directory of its own for the cache's signing key (the
  worker processes inherit both).
"""
from __future__ import annotations

import importlib.util
import logging
import os
import shutil
import signal
import socket
import sys
import tempfile
import threading
import time
import traceback
import urllib.request

import pytest

CHROMIUM = os.environ.get("RATTLE_CHROMIUM") or shutil.which("chromium") or "/usr/bin/chromium"
CHROMIUM_ARGS = ["--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync"]


def _ui_unavailable() -> str | None:
    if importlib.util.find_spec("playwright") is None:
        return "pytest-playwright is not installed (scripts/test.sh installs it)"
    if not os.path.exists(CHROMIUM):
        return f"Chromium not found at {CHROMIUM} (scripts/test.sh installs Debian's chromium)"
    return None


def pytest_configure(config):
    """A fresh, empty disk cache for the run: no test is served by a result from earlier runs.

    Ctrl-C is delivered as usual: a run started as a background job (``cmd &`` in a script)
    inherits SIGINT ignored, and so would every command it starts, while the Ctrl-C tests
    check what those commands do with it.
    """
    os.environ["RATTLE_CACHE_DIR"] = tempfile.mkdtemp(prefix="rattle-test-cache-")
    # the cache's signing key too: made in a directory of the run's own, never the user's
    os.environ["RATTLE_CONFIG_DIR"] = tempfile.mkdtemp(prefix="rattle-test-config-")
    os.environ.pop("RATTLE_CACHE_KEY", None)
    if signal.getsignal(signal.SIGINT) == signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)


def pytest_unconfigure(config):
    for name, prefix in (("RATTLE_CACHE_DIR", "rattle-test-cache-"),
                         ("RATTLE_CONFIG_DIR", "rattle-test-config-")):
        path = os.environ.get(name, "")
        if os.path.basename(path).startswith(prefix):
            shutil.rmtree(path, ignore_errors=True)


def _alternated(items: list) -> list:
    """The test files in turn: a browser-test file, then its share of the others, so the
    processes of ``scripts/test.sh`` (``--dist loadfile --no-loadscope-reorder``) mostly run
    both kinds at once. A browser test waits on its page and leaves a core partly idle, which a
    computing test fills; browser files only, at the end, contend for the same core.

    Files marked ``long`` come first: the processes take files in this order, and one that
    took such a file last would end the run with it alone while the other stood idle."""
    files: dict[str, list] = {}
    for item in items:
        files.setdefault(item.nodeid.split("::", 1)[0], []).append(item)
    def marked(f: list, mark: str) -> bool:
        return any(mark in item.keywords for item in f)
    first = [f for f in files.values() if marked(f, "long")]
    rest = [f for f in files.values() if not marked(f, "long")]
    ui = [f for f in rest if marked(f, "ui")]
    other = [f for f in rest if not marked(f, "ui")]
    if not ui:
        return [item for f in first + other for item in f]
    order: list = [item for f in first for item in f]
    for k, browser_file in enumerate(ui):
        order += browser_file
        for f in other[k * len(other) // len(ui):(k + 1) * len(other) // len(ui)]:
            order += f
    return order


def pytest_collection_modifyitems(config, items):
    items[:] = _alternated(items)
    reason = _ui_unavailable()
    if reason is None:
        return
    if os.environ.get("RATTLE_REQUIRE_UI") == "1" and any("ui" in item.keywords for item in items):
        # the project's test command installs the browser: a skip there would hide a failure
        raise pytest.UsageError(f"browser tests cannot run: {reason}")
    skip = pytest.mark.skip(reason=reason)
    for item in items:
        if "ui" in item.keywords:
            item.add_marker(skip)


@pytest.fixture(scope="session")
def browser_type_launch_args(browser_type_launch_args):
    """Launch Debian's Chromium headless, offline-friendly, instead of a downloaded browser."""
    return {**browser_type_launch_args, "executable_path": CHROMIUM, "args": CHROMIUM_ARGS,
            "headless": True}


@pytest.fixture(scope="session")
def browser_context_args(browser_context_args):
    return {**browser_context_args, "viewport": {"width": 1400, "height": 1000}}


#: How long a page may take to load: a session's page is built on the server before the first
#: byte, which takes seconds on a loaded two-core machine.
NAVIGATION_TIMEOUT_MS = 180_000


@pytest.fixture(autouse=True)
def _whose_log(request):
    """Tell the server's log recorder whether this test drives the served dashboard."""
    LogRecorder.in_ui_test = "ui" in request.keywords
    yield


@pytest.fixture(autouse=True)
def _patient_navigation(request):
    """Browser tests wait for a page load as long as a loaded CI machine may need."""
    if "page" in request.fixturenames:
        request.getfixturevalue("page").set_default_navigation_timeout(NAVIGATION_TIMEOUT_MS)
    yield


def patient_context(browser, **kwargs):
    """A new browser context whose page loads wait as long as :func:`_patient_navigation`'s."""
    kwargs.setdefault("viewport", {"width": 1400, "height": 1000})
    context = browser.new_context(**kwargs)
    context.set_default_navigation_timeout(NAVIGATION_TIMEOUT_MS)
    return context


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class LogRecorder(logging.Handler):
    """Keeps every record the server logs while the UI tests run.

    :meth:`tracebacks` reports the tracebacks logged since its last call: an error is reported
    by the first check after it (in its own test, or the next one's), and does not fail every
    later test too.
    """

    #: Whether the running test drives the served dashboard. The suite's processes run both
    #: kinds of test, and another test's own log lines (a page build made to fail on purpose,
    #: in the test's thread) are not the server's; the server logs from threads of its own.
    in_ui_test = True

    def __init__(self):
        super().__init__(level=logging.DEBUG)
        self.records: list[logging.LogRecord] = []
        self._seen = 0

    def emit(self, record: logging.LogRecord) -> None:
        if not LogRecorder.in_ui_test and record.thread == threading.main_thread().ident:
            return
        if record.name.startswith("distributed"):
            return  # a Dask cluster another test of this process started (the server runs none)
        self.records.append(record)

    def tracebacks(self) -> list[str]:
        end = len(self.records)
        out = self._tracebacks(self.records[self._seen:end])
        self._seen = end
        for text in out:  # whole, in the failing test's captured stderr: pytest shortens the diff
            print(f"server traceback: {text}", file=sys.stderr)
        return out

    @staticmethod
    def _tracebacks(records: list[logging.LogRecord]) -> list[str]:
        out = []
        for r in records:
            text = r.getMessage()
            if "WebSocketClosedError" in text and "Task exception was never retrieved" in text:
                # tornado reports a patch Bokeh wrote to a socket the browser had just closed;
                # the session itself is destroyed a few seconds later, as it should be
                continue
            if (r.exc_info and r.exc_info[0] is AssertionError and "GET /ws" in text
                    and "bokeh/server/connection.py" in "".join(traceback.format_tb(r.exc_info[2]))):
                # Bokeh asserts when a page closes its socket before its session was attached
                # (bokeh.server.connection.ServerConnection.session); nothing was served yet
                continue
            if r.exc_info:
                # the exception itself, so a failing check says what was raised and where
                text += "\n" + "".join(traceback.format_exception(*r.exc_info))[-2000:]
            if r.exc_info or "Traceback (most recent call last)" in text:
                out.append(f"{r.name}: {text}")
        return out


@pytest.fixture(scope="session")
def dashboard_server():
    """URL of the dashboard served in this process (threaded), and its log recorder."""
    from app.main import serve

    recorder = LogRecorder()
    root = logging.getLogger()
    root.addHandler(recorder)
    port = free_port()
    server = serve(port=port, address="localhost", show=False, threaded=True)
    url = f"http://localhost:{port}"
    deadline = time.monotonic() + 120
    while True:
        try:
            with urllib.request.urlopen(f"{url}/liveness", timeout=2) as resp:
                if resp.status == 200:
                    break
        except OSError:
            pass
        if time.monotonic() > deadline:
            server.stop()
            raise RuntimeError(f"dashboard did not become live at {url}")
        time.sleep(0.2)
    yield {"url": url, "log": recorder}
    server.stop()
    root.removeHandler(recorder)


@pytest.fixture(scope="session")
def job_pool():
    """Worker processes for the background jobs of the dashboards built by the tests."""
    from app.work.jobs import JobPool
    from app.work.tasks import warm_up

    pool = JobPool(size=2, warm=warm_up)
    yield pool
    pool.shutdown()


def new_dashboard(pool, search: str | None = None, **kwargs):
    """A Dashboard with all its views on the link ``search`` (if given), no server or browser,
    set up as the server sets up a session; the caller closes it (``destroy()``)."""
    from panel.io.location import Location

    from app.dashboard import Dashboard
    from app.main import configure, warm_up

    configure()
    warm_up(pool=False)
    if search is not None:
        kwargs["location"] = Location(search=search)
    return Dashboard(pool=pool, **kwargs)


@pytest.fixture()
def dash(job_pool):
    """A Dashboard with all its views, no server or browser; closed like a session afterwards."""
    d = new_dashboard(job_pool)
    yield d
    d.destroy()


def wait_for(condition, timeout: float = 120.0, what: str = "") -> None:
    """Wait until ``condition()`` is true (background jobs call back from their own thread)."""
    deadline = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out waiting for {what or condition}")
        time.sleep(0.05)
