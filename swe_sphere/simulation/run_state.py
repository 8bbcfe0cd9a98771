"""A run's state beside its built parts (issue 100): ``RunState``, what the simulation's
collaborators (its diagnostics, ``state_diagnostics.StateDiagnostics``) read of the run, not the
``Simulation``: the step, the state x and the last good one, the stepper (the integrator's), the
scene it runs, its step control, its t = 0 diagnostics and counters, the model time reached."""

from __future__ import annotations

from dataclasses import dataclass, field

from ..config.scene import Scene
from ..core.constants import DAY
from ..integrator import Integrator


@dataclass
class RunState:
    """A run's state: ``core`` its integrator (the step, and one unit's state x (3, N), last good
    state and stepper), ``scene`` the scene it runs (replaced by a fitted Δt or a lengthened run),
    ``control`` its step control (``adaptive.StepControl``; None at a fixed Δt), ``initial`` its
    t = 0 diagnostics (relative changes are taken against them), ``counters`` its RHS evaluations,
    wall and CPU seconds and solver iterations (by name), from zero."""

    core: Integrator
    scene: Scene
    control: object = None
    initial: dict | None = None
    counters: dict = field(
        default_factory=lambda: {"rhs_evals": 0, "wall_time": 0.0, "cpu_time": 0.0, "iterations": {}}
    )

    @property
    def step(self) -> int:
        return self.core.step

    @property
    def x(self):
        return self.core.units[0].x

    @property
    def last_good(self):
        return self.core.units[0].start

    @property
    def stepper(self):
        return self.core.units[0].stepper

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


def run_property(name: str, doc: str) -> property:
    """A simulation's property (read and set) that is its run state's (``Simulation.run_state``) ``name``."""
    return property(lambda s: getattr(s.run_state, name), lambda s, value: setattr(s.run_state, name, value), doc=doc)
