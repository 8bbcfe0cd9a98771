"""Which steps of a run do what: output times, restart files, intervals of whole steps, and the
schedules of a run's activities (``AtSteps``, ``EverySteps``; Oceananigans' ``IterationInterval``)."""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass
from fractions import Fraction

from ..config.scene import Scene


def output_marks(scene: Scene, every_days: float) -> set:
    """Steps with an output: every output interval (the scene's ``output.every_days``, or a
    stream's) from step 0 (t = 0, or a branch's day), and the last; under step control
    (``Scene.control``) their days (``interval_days``), the start's and the end's."""
    if scene.control is not None:
        return interval_days(scene, every_days) | {float(scene.start_day)}
    clock = scene.clock
    steps = {min(clock.nsteps, clock.steps_in(k * every_days)) for k in range(clock.times_in(every_days) + 1)}
    return steps | {clock.nsteps}


def interval_days(scene: Scene, every_days: float) -> set[float]:
    """The model days (from t = 0) of every ``every_days`` from the scene's ``start_day`` to
    its end, and the end: under step control (``Scene.control``) the times the steps land on.
    Exact from the days as written (as ``Clock.day``), so day 3 is 3.0, not 3.0000000000000004."""
    start, end, every = (Fraction(repr(float(d))) for d in (scene.start_day, scene.days, every_days))
    return {float(start + k * every) for k in range(1, math.floor((end - start) / every) + 1)} | {float(end)}


def restart_marks(scene: Scene, every_days: float) -> set:
    """The steps at which a run with ``--restart-every every_days`` writes its restart file (and
    the last step); under step control (``Scene.control``) their days (``interval_days``). Refuses
    (``SceneError``) an interval of more than ``clock.MAX_TIMES`` restart files, before any is
    listed, or, under a fixed Δt, not whole steps (under step control any interval lands): the
    checkpointer's, and the command line's check before a run."""
    scene.clock.check_times("the restart interval", every_days)
    if scene.control is not None:
        return interval_days(scene, every_days)
    per = scene.clock.steps(every_days, "the restart interval")  # ``SceneError`` unless dt divides it
    return set(range(per, scene.nsteps + 1, per)) | {scene.nsteps}


def at_its_end(caller: str, step: int, scene: Scene) -> str:
    """The refusal of ``caller``'s ``run`` at ``step``, the end of ``scene`` or past it (``advance``
    went there): nothing is left to run, and its run file would hold no time."""
    return (
        f"{caller}.run: at step {step} (day {scene.day(step):g}) the run is at its end (days = {scene.days:g}): "
        "nothing is left to run, and its file would hold no time (a later end: a scene with more days)"
    )


def next_multiple(step: int, every: int) -> int:
    """The first multiple of ``every`` after ``step``."""
    return (step // every + 1) * every


@dataclass(frozen=True)
class AtSteps:
    """Due at the steps in ``steps`` (sorted; a run's output times, its restart steps): ``at_marks(a_set, False)``."""

    steps: tuple

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


@dataclass(frozen=True)
class AtDays:
    """Due at the model days in ``days`` (sorted): a run's output and restart times under step
    control (``StepControl``), whose steps land on them; ``due(step, day)`` asks of the day a
    step landed on (None: a step between them; ``is_due`` passes it). No ``next_after``: steps do
    not say when a day falls, and under step control each accepted step is a block landed on
    ``days`` (``guard.RunObserver.steer``, ``block_end``)."""

    days: tuple

    def due(self, step: int, day: float | None) -> bool:
        return day is not None and day in self.days


def at_marks(marks, controlled: bool) -> AtSteps | AtDays:
    """The schedule due at ``marks`` (a set): steps (``AtSteps``), or under step control
    (``controlled``) days (``AtDays``)."""
    return (AtDays if controlled else AtSteps)(tuple(sorted(marks)))


def is_due(schedule, run) -> bool:
    """Whether ``schedule`` is due at ``run``'s step (``run_state.RunState``; an ``AtDays`` at the
    day the step landed on, ``RunState.event_day``): an activity's, and whether a run's file or
    restart file holds its current step (``writers.RunFiles``, ``writers.Checkpointer``)."""
    return schedule.due(run.step, run.event_day) if isinstance(schedule, AtDays) else schedule.due(run.step)
