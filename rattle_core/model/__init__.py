"""The model: what the rattle problem is, before anything is solved.

* ``params``: :class:`RattleParams`, the one canonical, validated parameter set, and its cache key.
* ``excitation``: the driving tooth's motion ``y(t) = Σ h_k cos(k t − φ_k)`` and its bounds.
* ``phases``: the paper's phase convention and the core's, and angle wrapping.
* ``units``: physical units (kg·m², N·m, µm, rpm) to and from the dimensionless model.
* ``engine``: engine speed, ω and sweeps over rpm as sweeps of Λ or j.
* ``orders``: a measured shaft speed split into engine orders per rpm bin (:class:`OrderMap`).
* ``gearbox``: a gearbox of loose gears driven by one measured shaft (``GEARBOX.toml``).

Imports nothing else from :mod:`rattle_core`; no formatting, no colours.
"""
