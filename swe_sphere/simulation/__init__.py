"""The simulation layer: a run of a scene.

``simulation.Simulation`` (grid, case, model and stepper; ``run``, stepping, restarts), its
activities (``writers``: run and restart files; ``callbacks``; ``schedules``), ``guard`` (the
bad-state check), ``summary`` (counts and the result), ``state_diagnostics``, ``checkpoint``
(a restart file as a run; branches).

May import: every layer below (``core`` to ``config``).
"""

__all__ = ["callbacks", "checkpoint", "guard", "schedules", "simulation", "state_diagnostics", "summary", "writers"]
