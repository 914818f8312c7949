"""The ``rattle`` command: parse the arguments, run one command, report errors in one line.

Each command lives in :mod:`rattle_cli.commands` (one module per command).  Bad arguments print
one line, ``rattle: error: ...``, on stderr and exit with status 2; a run that stops at a solver
limit or cannot write exits with status 1.  Never a traceback (``RATTLE_DEBUG=1`` shows one).
"""
from __future__ import annotations

import argparse
import os
import sys
import threading
from typing import Any, Callable, Sequence

# nothing heavy at import: the libraries load inside main(), where a Ctrl-C is handled
from .common import CLIError, Parser, check_cache_dir

PROG = "rattle"

EPILOG = """\
examples:
  rattle serve --port 5006
  rattle serve --dask local
  rattle simulate --lam 3.3 --h2 0.25 --phi2 45 --periods 100 --impacts imp.csv --history hist.parquet
  rattle sweep --param lam --start 0.5 --stop 4 --num 400 --out fig2.npz
  rattle sweep --inertia 2e-4 --radius 0.04 --drag-torque 0.02 --backlash-um 160 --rpm 1500 \\
      --theta-amp 5e-4,1.25e-4 --theta-phase 0,45 --param rpm --start 800 --stop 6000 --out rpm.csv
  rattle atlas --lam 1.2 --from c:lam:pd --param2 r --bounds 0.3,0.9 --out pd.csv --png pd.png
  rattle sound --lam 3.3 --out rattle.wav
  rattle orders runup.csv --orders 2,4,6 --rpm-step 100 --out orders.csv --png
  rattle paper --out paper/
  rattle units --inertia 2e-4 --radius 0.04 --drag-torque 0.02 --backlash-um 160 --rpm 1500 --theta-amp 5e-4
  rattle cache show

Exit status: 0 success, 1 the run stopped at a solver limit or could not write, 2 bad arguments.
"""


def build_parser() -> argparse.ArgumentParser:
    """The ``rattle`` argument parser (all subcommands)."""
    from .commands import COMMANDS
    parser = Parser(prog=PROG, formatter_class=argparse.RawDescriptionHelpFormatter, epilog=EPILOG,
                    description="Rattle Explorer: exact gear-rattle (vibro-impact idle gear) "
                                "dynamics from the command line.")
    try:
        from importlib.metadata import version
        ver = version("rattle-explorer")
    except Exception:  # a checkout that was never installed has no metadata
        ver = "unknown"
    # a flag rather than argparse's version action, which prints and exits at once and so
    # would let anything after it pass unread
    parser.add_argument("--version", action="store_true",
                        help=f"print the version ({PROG} {ver}) and exit; takes no other argument")
    parser.set_defaults(version_text=f"{PROG} {ver}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=Parser)
    for command in COMMANDS:
        command.add_parser(sub)
    return parser


def _one_line(text: object) -> str:
    return " ".join(str(text).split())


def _end_children() -> None:
    """Kill the worker processes this command started (a ``--dask local`` cluster's): exiting
    at once, it would leave them to find their scheduler gone and say so at length."""
    import multiprocessing

    children = multiprocessing.active_children()
    for child in children:
        child.kill()
    for child in children:
        child.join(2.0)


def _interruptible(func: Callable[[Any], int], args: argparse.Namespace) -> int:
    """Run a command on a worker thread, so that Ctrl-C stops it at once.

    A compiled run releases the GIL and does not return to Python until it ends, so a
    KeyboardInterrupt raised in it would wait for the whole sweep.  The main thread only
    waits here: it takes the interrupt, says so and ends the process (status 130); files are
    written atomically, so none is left half-written.
    """
    if threading.current_thread() is not threading.main_thread():
        return func(args)
    outcome: dict[str, Any] = {}

    def target() -> None:
        try:
            outcome["value"] = func(args)
        except BaseException as exc:  # handed to the main thread, which reports it
            outcome["error"] = exc

    worker = threading.Thread(target=target, name=f"{PROG}-{args.command}", daemon=True)
    worker.start()
    try:
        while worker.is_alive():
            worker.join(0.1)
    except KeyboardInterrupt:
        print(f"\n{PROG}: interrupted", file=sys.stderr, flush=True)
        sys.stdout.flush()
        _end_children()
        os._exit(130)
    if "error" in outcome:
        raise outcome["error"]
    return outcome["value"]


def main(argv: Sequence[str] | None = None) -> int:
    """Run the ``rattle`` command; returns the exit status (never raises, never a traceback).

    Parameters
    ----------
    argv : sequence of str, optional
        Arguments without the program name; default ``sys.argv[1:]``.

    Returns
    -------
    int
        0 on success, 1 when a run stopped at a solver limit or a file could not be written,
        2 for bad arguments, 130 when interrupted.
    """
    try:
        parser = build_parser()
        args = parser.parse_args(argv)
        if args.version:
            if args.command is not None:
                raise CLIError(f"--version takes no other argument; got the command "
                               f"{args.command!r} as well")
            print(args.version_text)
            return 0
        if args.command is None:
            parser.error("the following arguments are required: COMMAND")
        if args.command in ("sweep", "serve", "cache", "gearbox"):  # they use the disk cache
            from rattle_core.store.cache import size_limit
            size_limit()
            check_cache_dir()
        if args.command == "serve":  # the server handles Ctrl-C itself, on the main thread
            return int(args.func(args) or 0)
        return int(_interruptible(args.func, args) or 0)
    except SystemExit as exc:  # --help and --version
        return exc.code if isinstance(exc.code, int) else 0
    except (CLIError, ValueError) as exc:
        print(f"{PROG}: error: {_one_line(exc)}", file=sys.stderr)
        return 2
    except OSError as exc:
        print(f"{PROG}: error: {_one_line(exc)}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print(f"{PROG}: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:  # a bug: still one line, with a way to see the traceback
        from rattle_core import SolverError
        if isinstance(exc, SolverError):
            print(f"{PROG}: error: {_one_line(exc)}", file=sys.stderr)
            return 1
        if os.environ.get("RATTLE_DEBUG"):
            raise
        print(f"{PROG}: internal error: {type(exc).__name__}: {_one_line(exc)} "
              "(set RATTLE_DEBUG=1 to see the traceback)", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
