"""The solver: exact, event-driven motion of the idle gear.

* ``events``: proven root-free step lengths, so no contact is ever stepped over.
* ``kernel``: the compiled event loop (flight, impact, chatter, stick, release, tangents).
* ``noise``: the seeded stream that scatters each rebound's restitution (``RattleParams.noise``).
* ``trajectory``: :func:`simulate` and the :class:`Trajectory` it returns.

Imports only :mod:`rattle_core.model`.
"""
