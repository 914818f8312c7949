"""The ``rattle`` command: the command-line face of Rattle Explorer (top layer, beside the dashboard)."""
