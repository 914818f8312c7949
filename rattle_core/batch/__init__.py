"""Many runs at once: bifurcation sweeps and 2-D maps, in chunks, locally or on Dask.

* ``sweep``: the chunk runner (a parallel numba kernel) and one-parameter sweeps.
* ``maps``: regime and intensity maps over two parameters, and basins of attraction.

Imports only the model, the solver and the analysis.
"""
