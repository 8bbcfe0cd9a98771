"""A run's state beside its built parts (issue 100): ``RunState``, what the simulation's
collaborators (its members, ``members.members.Members``) read of the run, not the
``Simulation``: the step, the state x, the stepper (the integrator's), the
scene it runs, its step control, its t = 0 diagnostics and counters, the model time reached."""

from __future__ import annotations

from dataclasses import dataclass

from ..config.scene import Scene
from ..core.constants import DAY
from ..integrator.core import Integrator, forwarded


@dataclass
class RunState:
    """A run's state: ``core`` its integrator (the step, and one unit's state x (3, N) and
    stepper), ``scene`` the scene it runs (replaced by a fitted Δt or a lengthened run),
    ``initial`` its t = 0 diagnostics (relative changes are taken against them); ``counters`` and
    ``control`` (a ``StepControl``; None at a fixed Δt) the integrator's."""

    core: Integrator
    scene: Scene
    initial: dict | None = None

    step = forwarded("core.step", "The steps taken (the integrator's).", False)
    counters = forwarded("core.counters", "The steps' counts (the integrator's).", False)
    control = forwarded("core.control", "The step control (the integrator's; None at a fixed Δt).")
    x = forwarded("core.units.0.x", "The state (3, N) (the one unit's).", False)
    stepper = forwarded("core.units.0.stepper", "The stepper (the one unit's).", False)

    @property
    def time(self) -> float:
        """The model time of the step, days since t = 0 (under step control the control's: a day
        as given where the step landed on it)."""
        return self.scene.day(self.step) if self.control is None else self.control.day

    def seconds(self, step: int) -> float:
        """The model time of ``step`` (a fixed Δt's; under step control the control's), s since t = 0."""
        return self.scene.start_day * DAY + step * self.scene.dt if self.control is None else self.control.t

    @property
    def event_day(self) -> float | None:
        """Under step control the day the step landed on (an output, restart or end time), else None."""
        return self.control.day if self.control is not None and self.control.landed else None
