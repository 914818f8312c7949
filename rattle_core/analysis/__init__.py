"""Analysis of trajectories: sections, regimes, overlays, sound, and the words for them.

* ``sections``: Poincaré (stroboscopic) and impact maps.
* ``classify``: regimes A–E, period, Lyapunov exponent, rattle metrics.
* ``sound``: the rattle sound synthesised from the impacts.

Imports only the model and the solver.
"""
