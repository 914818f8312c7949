"""One module per ``rattle`` command, each with ``add_parser(sub, quiet)`` and ``run(args)``.

A new command is a new module here (named after the command; ``continue_`` because
``continue`` is a Python keyword), listed in :data:`COMMANDS` (the order of ``rattle --help``).
"""
from . import (atlas, cache, continue_, gearbox, orders, paper, runup, serve, simulate, sound, sweep,
               units)

COMMANDS = (serve, simulate, sweep, continue_, atlas, sound, orders, gearbox, runup, paper, units,
            cache)
