"""Entry point of the dashboard: ``create_app()`` per session, ``serve()`` for ``rattle serve``.

Also a Panel script: ``panel serve app/main.py`` builds one dashboard per session (add
``--warm`` to compile at start-up rather than in the first session).

Offline by construction: Panel and Bokeh resources are served by this server (resource mode
``server``, no CDN), and the Bootstrap template is used because it loads no web fonts (the
Fast and Material templates fetch Google Fonts). The UI tests check that no request leaves
the host.

Numba compiles the solver and the sweep kernel, and datashader its aggregation, in
:func:`warm_up` at server start, so the first visitor's first slider move is as fast as any.
"""
from __future__ import annotations

import logging
import os
import sys
import threading

import panel as pn

if __package__ in (None, ""):  # run as a script by `panel serve app/main.py`, from a checkout
    sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    from app import background, maps_panel, views
    from app.dashboard import Dashboard
else:  # imported as a package: `app` in a checkout, `rattle_app` when installed
    from . import background, maps_panel, views
    from .dashboard import Dashboard

log = logging.getLogger("app")

_warm_lock = threading.Lock()
_warm = False


def configure() -> None:
    """Serve every script and stylesheet from this server, never from a CDN."""
    os.environ.setdefault("BOKEH_RESOURCES", "server")
    pn.extension(inline=False)
    pn.config.inline = False


def warm_up() -> None:
    """Compile and load everything a session needs (once per process)."""
    global _warm
    with _warm_lock:
        if _warm:
            return
        import numpy as np
        from rattle_core import RattleParams, classify, simulate

        tr = simulate(RattleParams(lam=3.3, amplitudes=(1.0, 0.25), phases_deg=(0.0, -135.0)),
                      periods=50, transient=10, lyapunov=True)
        classify(tr)
        views.time_history_data(tr, 2)
        views.rasterize(np.random.default_rng(0).normal(size=100), np.zeros(100), (-3, 3),
                        (-1, 1), 50, 50)
        views.rasterize(np.zeros(10), np.zeros(10), (-1, 1), (-1, 1), 50, 50,
                        category=np.ones(10, dtype=np.int8), colors={1: "#ff0000", -1: "#0000ff"})
        background.warm_up()
        _warm = True


def create_app() -> pn.template.BootstrapTemplate:
    """The servable dashboard for one session (its own state, figures and background job)."""
    configure()
    warm_up()
    return Dashboard().layout


def serve(port: int = 5006, address: str = "localhost", show: bool = False,
          scheduler: str | None = None, dask: str | None = None, **kwargs):
    """Start the dashboard server and block (``threaded=True`` returns the server thread).

    ``scheduler`` (``tcp://host:port``) or ``dask="local"`` become the default of the Maps
    tab's "Dask scheduler" field in every session; by default maps use this server's cores.
    """
    if scheduler and dask:
        raise ValueError("give scheduler or dask='local', not both")
    if dask not in (None, "local"):
        raise ValueError(f"dask = {dask!r}; the only value is 'local'")
    maps_panel.set_default_scheduler(dask or scheduler or "")
    configure()
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s %(levelname)s %(message)s")
    log.info("warming up (numba compilation, shipped diagrams)…")
    warm_up()
    origins = kwargs.pop("websocket_origin", None) or [f"{address}:{port}", f"localhost:{port}",
                                                       f"127.0.0.1:{port}"]
    log.info("serving Rattle Explorer on http://%s:%d/", address, port)
    if maps_panel.default_scheduler():
        log.info("2-D maps run on Dask: %s", maps_panel.default_scheduler())
    return pn.serve(create_app, port=port, address=address, show=show, title="Rattle Explorer",
                    websocket_origin=origins, liveness=True, **kwargs)


if __name__ == "__main__":
    serve(show=False)
elif __name__.startswith("bokeh_app"):
    # Panel re-runs this script for every session; the imported module (and its warm-up
    # flag) lives once per process
    from app.main import create_app as _create_app

    _create_app().servable(title="Rattle Explorer")
