"""Results on disk: the content-addressed cache, the shipped diagrams, exported tables.

* ``cache``: the disk cache of sweeps and maps, and the ``.npz`` format they are kept in.

Imports only the layers below it (model, solver, analysis, batch).
"""
