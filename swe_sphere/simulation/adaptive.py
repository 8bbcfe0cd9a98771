"""A run's step control (``Scene.control``): the integrator's ``StepControl`` (``integrator.control``,
its names here as the run knows them) steered to the days the run's activities are due at
(``steered``)."""

from __future__ import annotations

from ..core.constants import DAY
from ..integrator.control import ATOL_FLOOR, BALANCE_EVERY, CAP_EVERY, DT_GRID, StepControl, on_grid
from ..integrator.core import ControlledDt
from .schedules import AtDays

__all__ = ["ATOL_FLOOR", "BALANCE_EVERY", "CAP_EVERY", "DT_GRID", "StepControl", "on_grid", "steered"]


def steered(control: StepControl, last_day: float, activities: dict) -> ControlledDt:
    """The Δt policy of a run (``loop.run_steps``: a ``Simulation``'s, of one member or many) under
    ``control`` (a ``StepControl``): accepted steps (``integrator.core.ControlledDt``) to each day an
    ``AtDays`` activity of ``activities`` is due at (output and restart times) up to ``last_day``
    and ``last_day`` in turn, each landed on exactly, a try launched ahead only where no activity
    of whole steps (``EverySteps``, ``AtSteps``: they read x) is due after the step."""
    schedules = [a.schedule for a in activities.values()]
    days = {float(last_day), *(d for s in schedules if isinstance(s, AtDays) for d in s.days)}
    counted = [s for s in schedules if not isinstance(s, AtDays)]  # of whole steps: due after a step, they read x
    ahead = sorted(d for d in days if control.t < d * DAY and d <= last_day)  # not past the run's last day
    return ControlledDt(control, ahead, lambda j: not any(s.due(j + 1) for s in counted))
