"""A simulation driven from Python (Oceananigans' ``Simulation``: step, inspect, call back):
``Drive``, the object a ``Simulation`` holds behind its methods ``advance``, ``steps``,
``state``, ``every``, ``add_callback`` and ``fit_dt`` (the fitted scene, ``fitted``, which the
simulation takes; their contracts are the simulation's docstrings); the steps go by
``Simulation.run``'s loop."""

from __future__ import annotations

import dataclasses
import itertools

from ..config.scene import with_days
from ..core.arguments import callable_argument, got
from ..core.clock import is_interval
from ..core.constants import DAY
from ..core.errors import ArgumentError, SceneError
from ..io.run_file import OUTPUT_FIELDS, node_dataset
from .activities import Callback
from .schedules import EverySteps, steps_of
from .summary import RunResult


class Drive:
    """A simulation's steps driven from Python: Δt fitted to the user's intervals (where it is
    the simulation's own, ``own_dt``: not given, restored or stated in a ``Scene``), schedules,
    callbacks, steps to a day, the state as a dataset."""

    def __init__(self, sim, own_dt: bool):
        self.sim, self.own_dt = sim, own_dt

    def fitted(self, every: float, what: str):
        """``Simulation.fit_dt``'s scene: its clock's Δt shortened to divide ``every`` and the run's
        intervals (``Clock.fitted``), a note naming ``what``; nothing of the simulation written.
        ``SceneError`` as ``Simulation.fit_dt``."""
        sim = self.sim
        s = sim.scene
        if sim.step != 0 or not is_interval(every):
            raise SceneError(
                f"dt is fitted to an interval > 0 before the first step (got {every!r} at step {sim.step})"
            )
        outputs = [s.output_every_days, *(st["every_days"] for st in s.output_streams)]
        days = [a.schedule.days for a in sim.activities.values() if getattr(a.schedule, "days", None) is not None]
        spans = (every, s.run_days, *(d for d in outputs if d < s.run_days), *days)
        clock = s.clock.fitted(*spans, source=f"{s.dt_source}, shortened to divide {what} = {every:g} days")
        if clock.dt < s.dt / 2:
            raise SceneError(
                f"{what} = {every:g} days is not a whole number of steps of dt = {s.dt:g} s, and the longest dt "
                f"that divides it, the run and its output intervals is {clock.dt:g} s, less than half: give a dt, "
                "or an interval of whole steps"
            )
        note = f"dt shortened from {s.dt:g} s to {clock.dt:g} s to divide {what} = {every:g} days"
        return dataclasses.replace(s, dt=clock.dt, notes=(*s.notes, note), dt_source=clock.source)

    def every(self, days: float | None, steps: int | None) -> EverySteps:
        """``Simulation.every``: the schedule of every ``steps`` steps, or of the steps in ``days``."""
        if (days is None) == (steps is None):
            raise ValueError("an interval needs exactly one of every_days, every_steps")
        if steps is not None and not (isinstance(steps, int) and steps >= 1):
            raise ValueError(f"every_steps must be an integer >= 1 (got {steps!r})")
        return EverySteps(steps) if days is None else EverySteps(self.steps_in(days, "every_days"), days)

    def steps_in(self, days: float, what: str) -> int:
        """The whole number of steps in ``days`` (``what`` names it in a refusal), Δt first
        fitted to it (``Simulation.fit_dt``) where Δt is the simulation's own and no step was taken."""
        sim = self.sim
        if self.own_dt and sim.step == 0 and is_interval(days) and not sim.scene.clock.is_whole(days):
            sim.fit_dt(days, what)
        return steps_of(sim.scene, days, f"the interval {what}")

    def add_callback(self, fn, every_days: float | None, every_steps: int | None, name: str | None) -> None:
        """``Simulation.add_callback``: ``fn`` an activity under ``name`` (default "callback N")."""
        sim = self.sim
        callable_argument("fn", fn, "a callable fn(sim)", SceneError)
        if name is not None and not isinstance(name, str):
            raise SceneError(f"name must be a str or None (got {got(name)})")
        schedule = sim.every(days=every_days, steps=every_steps)
        if name is None:
            name = next(f"callback {k}" for k in itertools.count(1) if f"callback {k}" not in sim.activities)
        sim.activities[name] = Callback(fn, schedule)

    def fixed_dt(self, what: str) -> None:
        """Refuse (``ArgumentError``) ``what`` (a call by whole steps) under step control."""
        if self.sim.control is not None:
            raise ArgumentError(
                f"{what} steps a fixed dt: under step control ([time] control) the controller chooses the "
                "steps, and a run goes to its end (Simulation.run)"
            )

    def advance(self, days: float) -> RunResult:
        """``Simulation.advance``: ``days`` further by ``run``'s loop, the scene lengthened past its end."""
        sim = self.sim
        self.fixed_dt("Simulation.advance")
        target = sim.step + self.steps_in(days, "days")
        if target > sim.scene.nsteps:
            sim.scene = with_days(sim.scene, sim.scene.start_day + target * sim.scene.dt / DAY, "the scene's")
        return sim.run(None, until_step=target)

    def steps(self, every: float):
        """``Simulation.steps``: the run to the scene's end, the model day after each multiple of ``every``."""
        sim = self.sim
        self.fixed_dt("Simulation.steps")
        per = self.steps_in(every, "every")
        while (target := (sim.step // per + 1) * per) <= sim.scene.nsteps:
            sim.run(None, until_step=target)
            yield sim.time

    def state(self, remap: float | None):
        """``Simulation.state``: the current state as an ``xarray.Dataset`` (None on ranks other than 0)."""
        sim = self.sim
        whole = sim.diagnostics.gather_fields(divergence=True)
        if not sim.root:
            return None
        ds = node_dataset(
            sim.grid,
            sim.hs,
            sim.time,
            {k: getattr(whole, k) for k in OUTPUT_FIELDS},
            {"scene": sim.scene.as_dict(), "ne": sim.scene.ne, "np": sim.scene.np, "step": sim.step},
        )
        if remap is None:
            return ds
        from ..io.remap import remap_dataset  # here: xarray and scipy.sparse, for the Python API's maps only

        return remap_dataset(ds, remap)
