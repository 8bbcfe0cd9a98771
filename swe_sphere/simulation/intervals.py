"""A run's intervals of whole steps and Δt fitted to them where it is the simulation's own
(the running policy's fitted Δt: docs/explanation/design.md, "Where Δt is decided"): ``Intervals``, a
``Simulation``'s ``intervals``, whose ``every``, ``fitted_dt``, ``use_dt`` and ``fit_dt`` are the
simulation's (Oceananigans' ``IterationInterval``)."""

from __future__ import annotations

import dataclasses
import functools

from ..config.parts import scene_stepper
from ..core.clock import is_interval
from ..core.constants import DAY
from ..core.errors import ArgumentError, SceneError
from ..integrator.core import FixedDt
from .schedules import EverySteps


class Intervals:
    """The intervals of a run ``run`` (a ``run_state.RunState``: its integrator, scene and t = 0
    diagnostics) in whole steps; where Δt is fitted to one, the run's ``activities`` scheduled in
    days rescheduled and the start's ``diagnostics`` taken again. ``own``: Δt is the simulation's
    own to fit (not given, restored or stated in a ``Scene``)."""

    def __init__(self, run, activities: dict, diagnostics, own: bool):
        self.run, self.activities, self.diagnostics, self.own = run, activities, diagnostics, own

    def fitted_dt(self, every: float, what: str = "every") -> tuple:
        """(scene, stepper) at Δt shortened to the largest that divides ``every`` (days), the
        run, its output intervals (where shorter than the run) and the intervals of the
        activities scheduled in days: the running policy's (``integrator.core.FixedDt.fitted``),
        the scene with its clock (a note in its ``notes`` naming ``what``) and the stepper to
        step at it: one built anew at that Δt where Δt is folded into what it builds
        (``variable_dt`` False), else this one (its ``set_dt`` called where the pair is used,
        ``use_dt``). Nothing of the simulation written. ``SceneError`` (one line) after the first
        step, for ``every`` <= 0, and where that Δt is less than half the present one (an
        interval of odd decimals: give a dt, or an interval of whole steps)."""
        s = self.run.scene
        if self.run.step != 0 or not is_interval(every):
            raise SceneError(
                f"dt is fitted to an interval > 0 before the first step (got {every!r} at step {self.run.step})"
            )
        outputs = [s.output_every_days, *(st["every_days"] for st in s.output_streams)]
        days = [a.schedule.days for a in self.activities.values() if getattr(a.schedule, "days", None) is not None]
        policy = FixedDt.fitted(s.clock, every, what, s.run_days, *(d for d in outputs if d < s.run_days), *days)
        scene = dataclasses.replace(s, dt=policy.clock.dt, notes=(*s.notes, policy.note), dt_source=policy.clock.source)
        return scene, policy.stepper_for(self.run.core.units[0], functools.partial(scene_stepper, scene))

    def use_dt(self, scene, stepper) -> None:
        """Step on at ``scene``'s Δt (``fitted_dt``'s pair), the one place a simulation's Δt is
        rewritten: the running policy's at it (``FixedDt.use``), the first unit's stepper
        ``stepper``, every other unit's its own or one built anew alike; the activities scheduled
        in days rescheduled in its steps and the start's diagnostics taken again (their Courant
        numbers)."""
        policy = FixedDt(self.run.core.policy.take, clock=scene.clock)
        for i, unit in enumerate(self.run.core.units):
            policy.use(unit, stepper if i == 0 else policy.stepper_for(unit, functools.partial(scene_stepper, scene)))
        self.run.core.policy, self.run.scene = policy, scene
        for activity in self.activities.values():  # the schedules in days: their steps at the new Δt
            if getattr(activity.schedule, "days", None) is not None:
                activity.schedule = self.every(days=activity.schedule.days)
        self.run.initial = self.diagnostics.diagnose(scene.start_day * DAY)

    def steps_in(self, days: float, what: str) -> int:
        """The whole number of steps in ``days`` (``what`` names it in a refusal), Δt first
        fitted to it (``fit_dt``) where Δt is the simulation's own and no step was taken."""
        if self.own and self.run.step == 0 and is_interval(days) and not self.run.scene.clock.is_whole(days):
            self.fit_dt(days, what)
        return self.run.scene.clock.steps(days, f"the interval {what}")

    def fit_dt(self, every: float, what: str = "every") -> tuple:
        """Shorten Δt before the first step (``fitted_dt``, with its ``SceneError``; then ``use_dt``:
        set on the stepper, or one built anew, the activities' steps and the start's diagnostics
        following); a note in ``scene.notes`` naming ``what``. Returns the new (scene, stepper)."""
        scene, stepper = self.fitted_dt(every, what)
        self.use_dt(scene, stepper)
        return scene, stepper

    def every(self, *, days: float | None = None, steps: int | None = None) -> EverySteps:
        """The schedule of an activity (``activities``) due after every step that is a
        multiple of ``steps``, or of the steps in ``days`` (whole steps), counted from
        step 0 (Oceananigans' ``IterationInterval``); not at step 0, whose state the
        caller has (under step control, of the accepted steps). ``ArgumentError`` (a ValueError)
        for not exactly one of the two, or ``days`` under step control; ``SceneError`` for an
        interval that is not whole steps."""
        if (days is None) == (steps is None):
            raise ArgumentError("an interval needs exactly one of every_steps, every_days")
        if steps is not None and not (isinstance(steps, int) and steps >= 1):
            raise ArgumentError(f"every_steps must be an integer >= 1 (got {steps!r})")
        if days is not None and self.run.control is not None:
            raise ArgumentError("every_days: under step control the steps are the controller's (give every_steps)")
        return EverySteps(steps) if days is None else EverySteps(self.steps_in(days, "every_days"), days)
