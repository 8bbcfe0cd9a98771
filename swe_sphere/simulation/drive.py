"""A simulation driven from Python (Oceananigans' ``Simulation``: step, inspect, call back):
``Driven``, the methods ``advance``, ``steps``, ``state``, ``every``, ``add_callback`` and
``fit_dt`` of a ``Simulation`` (which is one), their steps by ``Simulation.run``'s loop; Δt
fitted to the user's intervals where it is the simulation's own (``_own_dt``: not given,
restored or stated in a ``Scene``)."""

from __future__ import annotations

import dataclasses

from ..config.parts import scene_stepper
from ..config.scene import with_days
from ..core.arguments import callable_argument, got, number_argument
from ..core.clock import is_interval
from ..core.constants import DAY
from ..core.errors import ArgumentError, SceneError
from ..io.run_file import OUTPUT_FIELDS, node_dataset
from .activities import add_callback
from .schedules import EverySteps, steps_of
from .summary import RunResult


class Driven:
    """A ``Simulation``'s steps driven from Python (module doc); its attributes are the
    simulation's (``scene``, ``step``, ``stepper``, ``activities``, ``control``, ``run``, ...)."""

    _own_dt = False

    def fitted_dt(self, every: float, what: str = "every") -> tuple:
        """(scene, stepper) at Δt shortened to the largest that divides ``every`` (days), the
        run, its output intervals (where shorter than the run) and the intervals of the
        activities scheduled in days: the scene with its clock fitted to them (``Clock.fitted``;
        a note in its ``notes`` naming ``what``) and the stepper to step at it: one built anew
        at that Δt where Δt is folded into what it builds (``variable_dt`` False), else this one
        (its ``set_dt`` called where the pair is used, ``use_dt``). Nothing of the simulation
        written. ``SceneError`` (one line) after the first step, for ``every`` <= 0, and where
        that Δt is less than half the present one (an interval of odd decimals: give a dt, or an
        interval of whole steps)."""
        s = self.scene
        if self.core.step != 0 or not is_interval(every):
            raise SceneError(
                f"dt is fitted to an interval > 0 before the first step (got {every!r} at step {self.core.step})"
            )
        outputs = [s.output_every_days, *(st["every_days"] for st in s.output_streams)]
        days = [a.schedule.days for a in self.activities.values() if getattr(a.schedule, "days", None) is not None]
        spans = (every, s.run_days, *(d for d in outputs if d < s.run_days), *days)
        clock = s.clock.fitted(*spans, source=f"{s.dt_source}, shortened to divide {what} = {every:g} days")
        if clock.dt < s.dt / 2:
            raise SceneError(
                f"{what} = {every:g} days is not a whole number of steps of dt = {s.dt:g} s, and the longest dt "
                f"that divides it, the run and its output intervals is {clock.dt:g} s, less than half: give a dt, "
                "or an interval of whole steps"
            )
        note = f"dt shortened from {s.dt:g} s to {clock.dt:g} s to divide {what} = {every:g} days"
        scene = dataclasses.replace(s, dt=clock.dt, notes=(*s.notes, note), dt_source=clock.source)
        # Δt folded into what it builds (a Helmholtz operator, a history's weights, element levels): anew
        return scene, self.stepper if self.stepper.variable_dt else scene_stepper(scene, self.model)

    def use_dt(self, scene, stepper) -> None:
        """Step on at ``scene``'s Δt with ``stepper`` (``fitted_dt``'s pair): the one place a
        simulation's Δt is rewritten. This stepper's Δt set in place (``set_dt``: what was
        built for the old Δt dropped), a new one prepared from the state; the activities
        scheduled in days rescheduled in its steps and the start's diagnostics taken again
        (their Courant numbers)."""
        if stepper is self.stepper:
            stepper.set_dt(scene.dt)
        else:
            stepper.prepare(self.x)
        self.scene, self.stepper = scene, stepper
        for activity in self.activities.values():  # the schedules in days: their steps at the new Δt
            if getattr(activity.schedule, "days", None) is not None:
                activity.schedule = self.every(days=activity.schedule.days)
        self.initial = self.diagnostics.diagnose(scene.start_day * DAY)

    def _steps_in(self, days: float, what: str) -> int:
        """The whole number of steps in ``days`` (``what`` names it in a refusal), Δt first
        fitted to it (``fit_dt``) where Δt is the simulation's own and no step was taken."""
        if self._own_dt and self.core.step == 0 and is_interval(days) and not self.scene.clock.is_whole(days):
            self.fit_dt(days, what)
        return steps_of(self.scene, days, f"the interval {what}")

    def _fixed_dt(self, what: str) -> None:
        """Refuse (``ArgumentError``) ``what`` (a call by whole steps) under step control."""
        if self.control is not None:
            raise ArgumentError(
                f"{what} steps a fixed dt: under step control ([time] control) the controller chooses the "
                "steps, and a run goes to its end (Simulation.run)"
            )

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
        if days is not None and self.control is not None:
            raise ArgumentError("every_days: under step control the steps are the controller's (give every_steps)")
        return EverySteps(steps) if days is None else EverySteps(self._steps_in(days, "every_days"), days)

    def add_callback(
        self, fn, *, every_days: float | None = None, every_steps: int | None = None, name: str | None = None
    ) -> None:
        """Call ``fn(self)`` after every ``every_steps``-th step, or every ``every_days``
        (``every``), in ``run``, ``advance`` and ``steps`` (Oceananigans' ``add_callback!``):
        an activity in ``activities`` under ``name`` (default "callback N"). ``fn`` may read
        ``sim.step``, ``sim.time``, ``sim.state()``; what it raises ends the run (its
        output files dropped). Under MPI add it on every rank. ``SceneError`` for ``fn`` not
        callable, ``name`` not a str, and as ``every``."""
        callable_argument("fn", fn, "a callable fn(sim)", SceneError)
        if name is not None and not isinstance(name, str):
            raise SceneError(f"name must be a str or None (got {got(name)})")
        add_callback(self.activities, fn, self.every(days=every_days, steps=every_steps), name)

    def advance(self, days: float) -> RunResult:
        """Step ``days`` further with ``run``'s loop (the same bits as one run; blow-up,
        signals and callbacks as there; no output file); under step control the steps land
        on the day reached. Past the scene's end the run is lengthened (``config.with_days``).

        Parameters
        ----------
        days : float
            Model days, a whole number of steps at a fixed Δt.

        Returns
        -------
        RunResult
            Of these steps.

        Raises
        ------
        ValueError
            ``days`` is not a whole number of steps (at a fixed Δt), or not a number ≥ 0.
        BlowUp, StepFailure, Interrupted
            As ``run``.
        """
        number_argument("days", days, "days", low=0.0, error=SceneError)
        if self.control is not None:  # Δt the controller's, landing on the day reached
            end = self.time + days
            if end > self.scene.days:
                self.scene = with_days(self.scene, end, "the scene's")
            return self.run(None, until_day=end)
        target = self.core.step + (self._steps_in(days, "days") if days else 0)
        if target > self.scene.nsteps:
            self.scene = with_days(self.scene, self.scene.start_day + target * self.scene.dt / DAY, "the scene's")
        return self.run(None, until_step=target)

    def steps(self, every: float):
        """Iterate the run to the scene's end, one multiple of ``every`` days from t = 0
        at a time (``for t in sim.steps(every=0.5): ds = sim.state()``); stops at the last
        multiple at or before the end.

        Where Δt is the simulation's own (no ``dt`` given, the scene named or a file:
        ``swe-sphere run`` shortens it likewise to divide the output interval) and no step
        has been taken, a Δt that does not divide ``every`` is first shortened to the
        largest that divides ``every``, the run, its output intervals and the callbacks'
        (``fit_dt``; so do ``advance`` and ``every`` for their intervals).

        Parameters
        ----------
        every : float
            Model days between yields, a whole number of steps.

        Yields
        ------
        float
            The model time reached (days since t = 0).

        Raises
        ------
        ValueError
            ``every`` is not then a whole number of steps (naming a Δt that was given).
        ArgumentError
            Under step control, as ``advance``.
        BlowUp, StepFailure, Interrupted
            As ``run``.
        """
        self._fixed_dt("Simulation.steps")
        per = self._steps_in(every, "every")
        while (target := (self.core.step // per + 1) * per) <= self.scene.nsteps:
            self.run(None, until_step=target)
            yield self.time

    def state(self, remap: float | None = None):
        """The current state as an ``xarray.Dataset``; call on every rank.

        Parameters
        ----------
        remap : float, optional
            Grid spacing in degrees: the state on a regular lat-lon grid
            (``remap.remap_dataset``, with h_surface = h + hs). None: on the nodes.

        Returns
        -------
        xarray.Dataset or None
            On the nodes, as a run file holds one output time: h (m), u, v (m s⁻¹),
            vorticity, divergence (s⁻¹) on ``ncol`` with hs, area, lat, lon and ``time``
            in days (``run_file.node_dataset``); or on (lat, lon). None on ranks other
            than 0.

        Raises
        ------
        ValueError
            A ``remap`` spacing that does not divide 180 degrees.
        """
        whole = self.diagnostics.gather_fields(divergence=True)
        if not self.root:
            return None
        fields = {k: getattr(whole, k) for k in OUTPUT_FIELDS}
        attrs = {"scene": self.scene.as_dict(), "ne": self.scene.ne, "np": self.scene.np, "step": self.core.step}
        ds = node_dataset(self.grid, self.hs, self.time, fields, attrs)
        if remap is None:
            return ds
        from ..io.remap import remap_dataset  # here: xarray and scipy.sparse, for the Python API's maps only

        return remap_dataset(ds, remap)
