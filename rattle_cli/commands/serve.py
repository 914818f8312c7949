"""``rattle serve``: the Panel dashboard, optionally with its maps on Dask."""
from __future__ import annotations

import argparse

from ..common import CLIError, add_command, info

HELP = "serve the Panel dashboard"


def add_parser(sub) -> None:
    p = add_command(sub, run, HELP)
    p.add_argument("--port", type=int, default=5006, help="TCP port (default 5006)")
    p.add_argument("--address", default="localhost",
                   help="address to listen on (default localhost; 0.0.0.0 for every interface)")
    p.add_argument("--show", action="store_true", help="open a browser tab")
    d = p.add_argument_group("2-D maps on Dask (default: the server's own cores)",
                             "Where every session's maps run; no page can change it.")
    d.add_argument("--scheduler", metavar="tcp://HOST:PORT",
                   help="run the dashboard's maps on this Dask scheduler")
    d.add_argument("--dask", choices=("local",),
                   help="'local': run them on a 2-worker Dask LocalCluster started by the server")


def run(args: argparse.Namespace) -> int:
    """Serve the Panel dashboard (every script from the local server)."""
    if not 1 <= args.port <= 65535:
        raise CLIError(f"--port {args.port} is outside the allowed range [1, 65535]")
    if args.scheduler is not None and args.dask is not None:
        raise CLIError("give --dask local or --scheduler ADDRESS, not both")
    kwargs = {"port": args.port, "address": args.address, "show": args.show, "quiet": args.quiet}
    if args.scheduler is not None:
        if "://" not in args.scheduler or not args.scheduler.split("://", 1)[1]:
            raise CLIError(f"--scheduler {args.scheduler!r}: give a Dask scheduler address such as "
                           "tcp://HOST:PORT")
        kwargs["scheduler"] = args.scheduler
    if args.dask is not None:
        kwargs["dask"] = args.dask
    # the repository's app/ folder, installed as rattle_app (see the README)
    from rattle_app.main import serve
    try:  # serve() prints the address itself, once the port answers
        serve(**kwargs)
    except KeyboardInterrupt:  # Ctrl+C is how a server is meant to stop
        info(args, "stopped")
    return 0
