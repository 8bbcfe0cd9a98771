"""The simulation layer: a run of a scene.

``simulation.Simulation`` (grid, case, model and stepper; ``run``, stepping, restarts), its
activities (``activities``: one shape, a schedule and a call; ``writers``: run and restart
files; ``schedules``), ``guard`` (the
bad-state check), ``summary`` (counts and the result), ``state_diagnostics``, ``checkpoint``
(a restart file as a run; branches).

May import: every layer below (``core`` to ``config``).
"""

__all__ = ["activities", "checkpoint", "guard", "schedules", "simulation", "state_diagnostics", "summary", "writers"]
