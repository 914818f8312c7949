"""The ``rattle`` command: the command-line face of Rattle Explorer (top layer, beside the dashboard).

* ``main``: the parser and :func:`~rattle_cli.main.main`, the console script's entry point.
* ``commands``: one module per command (``serve``, ``simulate``, ``sweep``, ``sound``,
  ``paper``, ``units``, ``cache``).
* ``options``: the model's options (dimensionless or physical) and the parameters they build.
* ``common``: errors, the progress bar, output checks and labels.
"""
