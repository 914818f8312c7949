"""Entry point of the dashboard: ``create_app()`` per session, ``serve()`` for ``rattle serve``.

Also a Panel script: ``panel serve app/main.py`` builds one dashboard per session (add
``--warm`` to compile at start-up rather than in the first session).

* Offline by construction: Panel and Bokeh resources are served by this server (resource mode
  ``server``, no CDN), and the Bootstrap template loads no web fonts.
* :func:`warm_up` loads everything a session needs before the server answers (numba's
  compiled kernels, datashader's, the shipped diagrams, the job pool's worker processes), so
  the first page is as fast as any; :func:`serve` prints the address only once the port
  answers.
* A page is sent at once, as a frame with a "computing…" note (:class:`~app.dashboard.Shell`);
  its dashboard is built into it once the browser has connected (``pn.state.onload``), and
  not at all for a client that has gone: a request nobody reads (a readiness poll that gave
  up) costs a frame, not a dashboard.
* A closed session is freed: its jobs are cancelled and its dashboard dropped
  (``pn.state.on_session_destroyed``), and unused sessions are reaped within seconds; no
  timer of the server holds a copy of a session's context (:func:`_start_panel_timers`).
* Bokeh recomputes the set of a document's models at the end of every batch of changes,
  whether or not the batch changed which models exist. HoloViews wraps each plot update in
  such a batch, so on a full page every redraw paid for a walk of every model (about 25 ms).
  :func:`_recompute_only_when_needed` makes that walk happen only when a model was added or
  removed (Bokeh signals those by ``invalidate``) or the roots changed; a test checks the
  model set stays exact.
* The page lays itself out once per frame of the server's changes (:mod:`app.ui.relayout`):
  a click on "Present this" no longer lays the page out once per property it changes.
"""
from __future__ import annotations

import contextlib
import contextvars
import logging
import os
import socket
import sys
import threading
import time
from typing import Iterator

import panel as pn

if __package__ in (None, ""):  # run as a script by `panel serve app/main.py`
    sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    from app import query
    from app.signals import no_sigint, sigint_deferred, sigint_ignored, sigint_noted
    from app.ui import relayout
    from app.work import jobs, map_plan, registries, tasks, threads
    from app.dashboard import Abandoned, Dashboard, Shell
else:  # imported as a package: `app` in a checkout, `rattle_app` when installed
    from . import query
    from .signals import no_sigint, sigint_deferred, sigint_ignored, sigint_noted
    from .ui import relayout
    from .work import jobs, map_plan, registries, tasks, threads
    from .dashboard import Abandoned, Dashboard, Shell

log = logging.getLogger("app")

_warm_lock = threading.Lock()
_warm = False
#: Seconds after which a session whose page is closed is destroyed, and how often to look.
UNUSED_SESSION_S = 5
#: Largest websocket message the server takes [bytes]. An upload travels base64-encoded in one
#: message, 4/3 of its size: the 20 MB measurement limit needs 26.7 MB, over Bokeh's default
#: 20 MiB. At 64 MiB a file of up to 48 MB reaches the server and is refused with a message
#: naming the limit, instead of cutting the page's connection. (``panel serve app/main.py``
#: takes the same as ``--websocket-max-message-size``.)
WEBSOCKET_MAX_BYTES = 64 * 2**20


def _recompute_only_when_needed() -> None:
    """Skip Bokeh's walk of a document's models when a batch of changes added or removed none."""
    from bokeh.document import models as bm

    manager = bm.DocumentModelManager
    if getattr(manager, "_rattle_patched", False):
        return
    invalidate = manager.invalidate

    def roots(self) -> tuple:
        doc = self._document()
        return tuple(id(r) for r in doc.roots) if doc is not None else ()

    def patched_invalidate(self) -> None:
        self._rattle_dirty = True
        invalidate(self)

    def push(self) -> None:
        if self._freeze_count == 0:
            self._rattle_dirty = False
            self._rattle_roots = roots(self)
        self._freeze_count += 1

    def pop(self) -> None:
        self._freeze_count -= 1
        if self._freeze_count == 0:
            if getattr(self, "_rattle_dirty", True) or roots(self) != getattr(self, "_rattle_roots", None):
                self.recompute()

    manager.invalidate, manager._push_freeze, manager._pop_freeze = patched_invalidate, push, pop
    manager._rattle_patched = True


def configure() -> None:
    """Serve every script and stylesheet from this server; load HoloViews' Bokeh backend; let
    one session's redraw run while another's page is built (:mod:`app.work.registries`,
    :func:`app.work.threads.share_the_interpreter`)."""
    import holoviews as hv

    os.environ.setdefault("BOKEH_RESOURCES", "server")
    pn.extension(inline=False)
    pn.config.inline = False
    hv.extension("bokeh", logo=False)
    _recompute_only_when_needed()
    query.install()
    registries.install()
    threads.give_way_at_each_model()
    threads.share_the_interpreter()


def warm_up(pool: bool = True) -> None:
    """Compile and load everything a session needs (once per process)."""
    global _warm
    with _warm_lock:
        if _warm:
            return
        import holoviews as hv
        import numpy as np
        from holoviews.operation.datashader import datashade, dynspread

        from rattle_core import RattleParams, classify, simulate

        from .work.diagram_data import _assets
        tr = simulate(RattleParams(lam=3.3, amplitudes=(1.0, 0.25), phases_deg=(0.0, -135.0)),
                      periods=50, transient=10, lyapunov=True)
        classify(tr)
        pts = hv.Points((np.random.default_rng(0).normal(size=100), np.zeros(100)))
        dynspread(datashade(pts, dynamic=False, width=50, height=50), dynamic=False)
        _assets()
        if pool:
            jobs.pool(warm=tasks.warm_up)  # the workers load the compiled kernels before a job
        _warm = True


def client_gone(doc) -> bool:
    """Whether the browser of ``doc``'s session has gone: the session was destroyed, or no
    websocket is open on it (a page without a server session is never gone)."""
    ctx = getattr(doc, "session_context", None)
    if ctx is None:
        return False
    if getattr(ctx, "destroyed", False):
        return True
    session = getattr(ctx, "_session", None)
    return session is not None and getattr(session, "connection_count", 1) == 0


def create_app() -> pn.template.BootstrapTemplate:
    """The servable dashboard for one session (its own state, views and background jobs).

    In a server session the frame (:class:`~app.dashboard.Shell`) is returned at once and the
    dashboard built into it when the browser has connected, unless it has gone by then or
    goes while the build runs (then the build stops where it is and frees what it made).
    """
    configure()
    warm_up()
    doc, location = pn.state.curdoc, pn.state.location
    shell = Shell()
    if doc is not None:
        relayout.install(doc)
    if doc is None or doc.session_context is None:
        Dashboard(location=location, doc=doc, shell=shell)
        return shell.layout
    built: list[Dashboard] = []

    def build() -> None:
        if client_gone(doc):
            log.info("the page's client has gone: its dashboard is not built")
            return
        try:
            built.append(Dashboard(location=location, doc=doc, shell=shell,
                                   alive=lambda: not client_gone(doc)))
        except Abandoned:
            log.info("the page's client went away: its dashboard's build was abandoned")
        except Exception as exc:
            if client_gone(doc):
                # the session was torn down under the build: nobody is there to be told
                log.info("the page's client went away; its dashboard's build ended in %s: %s",
                         type(exc).__name__, exc)
                return
            log.exception("building a page failed")  # the page says so, not "computing…" for ever
            shell.fail(f"The page could not be built ({type(exc).__name__}: {exc}). "
                       "Reload it; if it fails again, the server's log says why.")

    def destroyed(session_context) -> None:
        try:
            for dash in built:
                dash.destroy()
        except Exception:
            log.exception("closing a session failed")
    pn.state.on_session_destroyed(destroyed)
    pn.state.onload(build)
    return shell.layout


def _answers(address: str, port: int) -> bool:
    host = "127.0.0.1" if address in ("", "0.0.0.0", "localhost") else address
    try:
        with socket.create_connection((host, port), timeout=0.5):
            return True
    except OSError:
        return False


def _start_panel_timers(server) -> None:
    """Start Panel's process-wide periodic callback (its busy indicator's clean-up) on the
    server's loop, from an empty context.

    Panel starts it in the first session that reports activity; its asyncio task keeps a copy
    of the context it was created in, where Panel's current document is that session's, so
    the task held that session's document (and so its models) for the life of the server.
    Started here, its context holds no session.
    """
    loop = getattr(server, "asyncio_loop", None)
    schedule = getattr(pn.state, "_schedule_busy_cleanup", None)
    if loop is None or schedule is None:
        return
    started = threading.Event()

    def start() -> None:
        try:
            schedule()
        finally:
            started.set()
    loop.call_soon_threadsafe(start, context=contextvars.Context())
    started.wait(10)


def _stop(server) -> None:
    try:
        server.stop()
    except RuntimeError:  # already stopping
        server.join(10)


def serve(port: int = 5006, address: str = "localhost", show: bool = False,
          scheduler: str | None = None, dask: str | None = None, threaded: bool = False,
          quiet: bool = False, **kwargs):
    """Start the dashboard server; print its address once the port answers.

    ``scheduler`` (``tcp://host:port``) or ``dask="local"`` (a 2-worker ``LocalCluster``
    started here) is where every session's maps run; no page can change it. Blocks, unless
    ``threaded`` (then returns the server thread, already answering).
    """
    if scheduler and dask:
        raise ValueError("give scheduler or dask='local', not both")
    if dask not in (None, "local"):
        raise ValueError(f"dask = {dask!r}; the only value is 'local'")
    with contextlib.ExitStack() as stack:
        # until the server is warm a Ctrl-C is noted and raised here at the end: loading HoloViews'
        # extension and numba's kernels calls back into Python, where it would be lost
        with sigint_deferred():
            if dask == "local":
                from .core import local_cluster
                with sigint_ignored():
                    cluster = local_cluster(2)
                if not threaded:  # a server that returns keeps its cluster; one that ends closes it
                    stack.callback(cluster.close)
                scheduler = cluster.scheduler_address
            map_plan.set_scheduler(scheduler or "")
            configure()
            logging.basicConfig(level=logging.INFO,
                                format="%(asctime)s %(name)s %(levelname)s %(message)s")
            log.info("warming up (compiled kernels, shipped diagrams, worker processes)…")
            with no_sigint():
                jobs.pool(warm=tasks.warm_up)
            warm_up()
        origins = kwargs.pop("websocket_origin", None) or [f"{address}:{port}", f"localhost:{port}",
                                                           f"127.0.0.1:{port}"]
        kwargs.setdefault("check_unused_sessions", UNUSED_SESSION_S * 1000)
        kwargs.setdefault("websocket_max_message_size", WEBSOCKET_MAX_BYTES)
        kwargs.setdefault("unused_session_lifetime", UNUSED_SESSION_S * 1000)
        server = None
        try:
            with no_sigint():  # held back until the server's thread is known, to be stopped
                server = pn.serve(create_app, port=port, address=address, show=show,
                                  title="Rattle Explorer", websocket_origin=origins,
                                  liveness=True, threaded=True, **kwargs)
            deadline = time.monotonic() + 60
            while not _answers(address, port):
                if time.monotonic() > deadline:
                    raise RuntimeError(f"the dashboard did not start answering on port {port}")
                time.sleep(0.05)
            _start_panel_timers(server)
            if not quiet:
                print(f"serving Rattle Explorer on http://{address}:{port}/ (Ctrl+C stops)",
                      flush=True)
                if scheduler:
                    print(f"2-D maps run on Dask: {scheduler}", flush=True)
            if threaded:
                return server
            with sigint_noted() as stop:  # Ctrl-C ends the wait, and the server stops below
                while server.is_alive() and not stop.wait(0.5):
                    pass
            if stop.is_set():
                raise KeyboardInterrupt
        except BaseException:
            if server is not None:
                _stop(server)
            raise
        return server


if __name__ == "__main__":
    serve(show=False)
elif __name__.startswith("bokeh_app"):
    # Panel re-runs this script for every session; the imported module (and its warm-up
    # flag) lives once per process
    from app.main import create_app as _create_app

    _create_app().servable(title="Rattle Explorer")
