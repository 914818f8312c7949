"""Analysis of trajectories: sections, regimes, overlays, sound, and the words for them.

* ``sections``: Poincaré (stroboscopic) and impact maps.
* ``classify``: regimes A–E, period, Lyapunov exponent, rattle metrics.
* ``overlays``: closed-form curves (contact boundary, one-sided orbits) drawn over results.
* ``continuation``: periodic orbits by Newton's method on the impact map, followed as a
  parameter changes (pseudo-arclength), with their bifurcations located.
* ``vocabulary``: each regime's letter, code, meaning and colour; flank colours, labels and
  exported values; the side-by-side table of physical and dimensionless parameters.
* ``sound``: the rattle sound synthesised from the impacts.
* ``loudness``: ISO 532-1 loudness and DIN 45692 sharpness of a sound (MOSQITO).

Imports only the model and the solver.
"""
