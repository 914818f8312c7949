"""The paper: its cases, its figures drawn again, and the evidence for its phase convention.

* ``cases``: each figure as a computation (:data:`~rattle_core.paper.cases.CASES`), its sweep
  served from the shipped assets, and the dashboard's presets derived from the cases.
* ``figures``: Figures 2 to 8 as PNG files (``rattle paper``).
* ``evidence``: which reading of the paper's phases reproduces its five claims.
* ``drawing``: matplotlib pictures of sweeps and maps, shared with the CLI's PNGs.

Imports every layer below it; nothing in :mod:`rattle_core` imports it.
"""
