"""Which steps of a run do what: output times, restart files, intervals of whole steps, and the
schedules of a run's activities (``AtSteps``, ``EverySteps``; Oceananigans' ``IterationInterval``)."""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass

from ..config.scene import Scene
from ..core.constants import DAY
from ..core.errors import SceneError


def is_interval(days) -> bool:
    """Whether ``days`` is a number > 0 and finite."""
    return isinstance(days, (int, float)) and math.isfinite(days) and days > 0


def whole_steps(scene: Scene, days) -> bool:
    """Whether ``days`` is a positive whole number of the scene's steps (to 1e-6 of a step)."""
    per = round(days * DAY / scene.dt) if is_interval(days) else 0
    return per >= 1 and abs(per * scene.dt - days * DAY) <= 1e-6 * scene.dt


def steps_of(scene: Scene, days: float, what: str, dt_source: str = "") -> int:
    """The whole number of steps in ``days``; ``SceneError`` (a ValueError) naming ``what`` (and
    where dt comes from, ``dt_source``, e.g. ", the dt given") unless dt divides it."""
    if not whole_steps(scene, days):
        raise SceneError(
            f"{what} must be a positive multiple of dt = {scene.dt:g} s = {scene.dt / DAY:.6g} days{dt_source} "
            f"(got {days!r} days)"
        )
    return round(days * DAY / scene.dt)


def output_steps(scene: Scene, every_days: float | None = None) -> set[int]:
    """Steps with an output: every output interval (default the scene's
    ``output.every_days``) from step 0 (t = 0, or a branch's day), and the last."""
    every_days = scene.output_every_days if every_days is None else every_days
    every = every_days * DAY / scene.dt
    n_out = math.floor(scene.run_days / every_days + 1e-9)
    return {min(scene.nsteps, round(k * every)) for k in range(n_out + 1)} | {scene.nsteps}


def restart_steps(scene: Scene, every_days: float) -> set[int]:
    """Steps at which a run with ``--restart-every every_days`` writes its restart
    file (and the last step). Raises ValueError unless dt divides the interval."""
    per = steps_of(scene, every_days, "restart interval")
    return set(range(per, scene.nsteps + 1, per)) | {scene.nsteps}


def next_multiple(step: int, every: int) -> int:
    """The first multiple of ``every`` after ``step``."""
    return (step // every + 1) * every


@dataclass(frozen=True)
class AtSteps:
    """Due at the steps in ``steps`` (sorted; a run's output times, its restart steps): ``AtSteps.of(a_set)``."""

    steps: tuple

    @classmethod
    def of(cls, steps) -> AtSteps:
        return cls(tuple(sorted(steps)))

    def due(self, step: int) -> bool:
        i = bisect.bisect_left(self.steps, step)
        return i < len(self.steps) and self.steps[i] == step

    def next_after(self, step: int) -> int | None:
        """The first step after ``step`` that is due; None when there is none."""
        i = bisect.bisect_right(self.steps, step)
        return self.steps[i] if i < len(self.steps) else None


@dataclass(frozen=True)
class EverySteps:
    """Due at every multiple of ``steps`` (an integer >= 1) counted from step 0, not at step 0;
    ``days``: the interval in days it was made from, if it was (``Simulation.every``)."""

    steps: int
    days: float | None = None

    def due(self, step: int) -> bool:
        return step % self.steps == 0

    def next_after(self, step: int) -> int:
        return next_multiple(step, self.steps)
