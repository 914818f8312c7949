"""Results on disk: the content-addressed cache, the shipped diagrams, exported tables.

* ``files``: the ``.npz`` format of sweeps and maps, written atomically.
* ``cache``: the disk cache (one wrapper for sweeps and maps, a size limit, eviction).
* ``assets``: the paper's diagrams shipped as package data.
* ``requests``: maps over any two axes, as the CLI and the dashboard ask for them.
* ``exports``: CSV and Parquet tables of runs, sweeps and maps.
* ``verdicts``: gearbox verdicts on disk, and their cached run.

Imports only the layers below it (model, solver, analysis, batch).
"""
