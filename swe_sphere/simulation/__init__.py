"""The simulation layer: a run of a scene.

``simulation.Simulation`` (its loop, ``run``; its ``build``, ``restart`` and Python ``drive``), the
step graphs (``core.graphs.GraphedSteps``), its activities (``activities``: one shape, a schedule
and a call; ``writers``: run and restart files; ``schedules``), ``guard`` (what a run adds to the
integrator's bad-state check), signals (``core.interrupts``), ``summary`` (counts and the result),
``state_diagnostics``, ``checkpoint`` (a restart file as a run; branches).

May import: every layer below (``core`` to ``config``, the ``integrator``, ``adjoint``).
"""

__all__ = [
    "activities",
    "build",
    "checkpoint",
    "drive",
    "guard",
    "restart",
    "schedules",
    "simulation",
    "state_diagnostics",
    "summary",
    "writers",
]
