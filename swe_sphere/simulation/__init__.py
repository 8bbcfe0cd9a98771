"""The simulation layer: a run of a scene.

``simulation.Simulation`` of one member or N (its loop, ``run``; its members built and
diagnosed by ``members.members.Members``; restarts, ``checkpoint``; driven from Python), the
step graphs (``core.graphs.GraphedSteps``), its activities (``activities``: one shape, a schedule
and a call; ``writers``: run and restart files; ``schedules``), ``guard`` (what a run adds to the
integrator's bad-state check), ``names`` (how its public names read its members: the squeeze
rule), signals (``core.interrupts``), ``summary`` (counts and the result),
``checkpoint`` (a restart file as a run; branches).

May import: every layer below (``core`` to ``config``, the ``integrator``, ``adjoint``, ``members``).
"""
