"""``python -m rattle_cli``: the ``rattle`` command."""
import sys

from rattle_cli.main import main

sys.exit(main())
