"""``rattle serve``: the Panel dashboard, optionally with its maps on Dask."""
from __future__ import annotations

import argparse
import ipaddress
import re
import socket
import threading

from ..common import CLIError, add_command, info

#: Seconds a host name may take to resolve before ``--address`` is refused.
RESOLVE_S = 5.0
_HOST_RE = re.compile(r"^(?=.{1,253}$)([A-Za-z0-9]([A-Za-z0-9-]{0,61}[A-Za-z0-9])?)"
                      r"(\.[A-Za-z0-9]([A-Za-z0-9-]{0,61}[A-Za-z0-9])?)*\.?$")


def check_listen(address: str, port: int) -> None:
    """Refuse, in one line and before any start-up work, an address this server cannot listen on:
    not an IP address or host name, a name that does not resolve within :data:`RESOLVE_S`, or
    an address and port it cannot bind (not this machine's, or taken)."""
    text = address.strip()
    if re.fullmatch(r"[0-9.]+", text) or ":" in text:
        try:
            ipaddress.ip_address(text)
        except ValueError:
            raise CLIError(f"--address {address!r} is not an IP address") from None
    elif not _HOST_RE.match(text):
        raise CLIError(f"--address {address!r} is not an IP address or a host name")
    found: dict = {}

    def resolve() -> None:
        try:
            found["infos"] = socket.getaddrinfo(text, port, type=socket.SOCK_STREAM)
        except OSError as exc:
            found["error"] = exc
    worker = threading.Thread(target=resolve, daemon=True)
    worker.start()
    worker.join(RESOLVE_S)
    if "infos" not in found:
        why = found.get("error") or f"no answer within {RESOLVE_S:g} s"
        raise CLIError(f"--address {address!r} does not resolve ({why})")
    family, kind, proto, _, where = found["infos"][0]
    try:
        with socket.socket(family, kind, proto) as s:
            s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            s.bind(where)
    except OSError as exc:
        raise CLIError(f"--address {address!r} --port {port}: cannot listen there "
                       f"({exc.strerror or exc})") from None

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
    check_listen(args.address, args.port)
    kwargs = {"port": args.port, "address": args.address, "show": args.show, "quiet": args.quiet}
    if args.scheduler is not None:
        if "://" not in args.scheduler or not args.scheduler.split("://", 1)[1]:
            raise CLIError(f"--scheduler {args.scheduler!r}: give a Dask scheduler address such as "
                           "tcp://HOST:PORT")
        kwargs["scheduler"] = args.scheduler
    if args.dask is not None:
        kwargs["dask"] = args.dask
    # Panel, Bokeh and numba load for seconds: a Ctrl-C meanwhile is noted, not raised, since
    # raised there it can land in a callback Python calls on its own (a weak reference's),
    # which prints it as "Exception ignored" and drops it, and the server would go on to serve
    from rattle_app.signals import sigint_noted  # light: the standard library only

    with sigint_noted() as noted:
        # the repository's app/ folder, installed as rattle_app (see the README)
        from rattle_app.main import serve
    if noted.is_set():
        info(args, "stopped")
        return 0
    try:  # serve() prints the address itself, once the port answers
        serve(**kwargs)
    except KeyboardInterrupt:  # Ctrl+C is how a server is meant to stop
        info(args, "stopped")
    return 0
