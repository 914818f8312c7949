"""Many runs at once: bifurcation sweeps and 2-D maps, in chunks, locally or on Dask.

* ``chunks``: the chunk runner, a parallel numba kernel over many parameter rows.
* ``executor``: where chunks run (this process or a Dask cluster), and Dask clients.
* ``sweep``: one parameter over many values (:func:`~rattle_core.batch.sweep.sweep`).
* ``maps``: regime and intensity maps over two parameters, and basins of attraction.
* ``plan``: maps over physical axes, worked out and checked before they run.
* ``gearbox``: the verdict on a gearbox of loose gears, every gear at every speed as one batch.

Imports only the model, the solver and the analysis.
"""
