"""One module per ``rattle`` command, each with ``add_parser(sub, quiet)`` and ``run(args)``.

A new command is a new module here, listed in :data:`COMMANDS` (the order of ``rattle --help``).
"""
from . import cache, paper, serve, simulate, sound, sweep, units

COMMANDS = (serve, simulate, sweep, sound, paper, units, cache)
