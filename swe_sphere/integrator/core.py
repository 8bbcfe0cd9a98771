"""The package's one step loop (Oceananigans' ``time_step!`` and its callbacks; JAX codes' one
step mapped over members): ``Integrator`` advances ``Unit`` s, each a state with its members
side by side (one member, or an ensemble's copies of the grid, ``members.grid.MemberGrid``),
its model and its stepper, a block of steps at a time under the one bad-state guard:

- each state of a block is flagged on the device (``BadNodes.watch``) and the flag read once at
  the block's end with the solvers' device counters (``Stepper.counts``), so that a step needs
  no host round trip (a GPU step is its launches, or one graph);
- a block that found trouble is put back to its start (states, stepper histories, the
  counters) and taken again a checked step at a time (``BadNodes.first``), to name the step and
  the place: the same bits as a check every step;
- with ``drop``, a member bad at a step goes back to its last good state and is not stepped
  again while the others go on (an ensemble's ``blow_up="drop"``); else the loop stops there.

Each step's Δt is the loop's Δt policy's (Oceananigans' fixed ``Δt``, ``aligned_time_step`` and
``TimeStepWizard``), an object that takes a step, ``take(unit, j, watch)``, and keeps and puts
back a block's start, ``keep`` and ``put_back``: ``FixedDt`` (a fixed or fitted Δt) or
``ControlledDt`` (a step control's); a gradient's sweep is its own (a run's Δt replayed). What
a driver adds around the steps is an ``Observer``'s. ``Simulation.run`` and ``advance`` (of one
member or many) and the gradient's sweeps (``adjoint.gradient``) all advance through
``Integrator.advance``."""

from __future__ import annotations

import dataclasses
import time

import numpy as np
import warp as wp

from ..core.clock import Clock
from ..core.constants import DAY
from ..core.errors import SceneError, StepFailure
from ..core.graphs import GraphedSteps
from ..core.interrupts import StepAbandoned
from ..model.shallow_water import ShallowWater
from ..steppers import StepStats


@dataclasses.dataclass
class Unit:
    """Members stepped together: their ``model`` and ``stepper``, their states side by side ``x``
    (3, members·n), the state at the start of the step or block in progress ``start`` (the last
    good one: a block is taken again from it), the graphs of their steps ``graphed``."""

    model: ShallowWater
    stepper: object
    x: wp.array
    start: wp.array
    graphed: GraphedSteps
    members: int = 1

    @classmethod
    def of(cls, model: ShallowWater, stepper, starts: np.ndarray, backend, graphs: str) -> Unit:
        """The unit of ``model`` and ``stepper`` from ``starts`` (members, rows, n: u, v, h and
        the tracers' masses), prepared."""
        joined = np.concatenate(list(starts), axis=1)
        x = model.held.new(joined[: model.rows])  # the state the run holds (``model.held``)
        stepper.prepare(x)
        return cls(model, stepper, x, wp.clone(x), GraphedSteps(backend, model.launches.guard, graphs), len(starts))

    def try_step(self, x: wp.array) -> StepStats:
        """One step of the stepper on x (3, members·n) in place, a graph where ``graphed`` lets it,
        the bad-state flag not watched and the solvers' counters not read: a controlled run's
        tries (``control.StepControl``). Its ``StepStats``."""
        return self.graphed.step(self.stepper, self.model, x, False)


@dataclasses.dataclass
class Stop:
    """Why ``Integrator.advance`` stopped before its last step: nothing (it did not), a signal
    ``signum`` (with ``abandoned`` = (b, m) when it abandoned step m + 1 of a block from b), or
    trouble in a checked step, ``bad`` = (step, trouble, detail): trouble "bad" (detail the
    [(unit index, unit, first bad whole-grid node)] bad there) or "failure" (detail the
    solver's message); ``blowup`` the driver's line for it."""

    signum: int | None = None
    abandoned: tuple | None = None
    blowup: str | None = None
    bad: tuple | None = None


class Observer:
    """What a driver adds around ``Integrator.advance``'s steps; each hook a no-op here, but two
    each driver's own: ``block_end(b)``, the last step of the block after step b (the state read
    then: activities due); b: no step more (a controlled run's last day reached,
    ``ControlledDt.reached``); and where units drop (``Integrator.drop``), ``dropped(step, bad)``:
    the units (index, unit, first bad node) ``bad`` dropped at ``step``."""

    def asked(self, within: bool = False) -> int:
        """A stop asked between blocks, or ``within`` a block between a lone unit's steps (where
        every process steps one unit): the signal's number, 0 for none."""
        return 0

    def checked(self, b: int, e: int) -> bool:
        """Whether the states of steps b+1..e are checked (False: known good, taken again)."""
        return True

    def stepping(self, on: bool) -> None:
        """A step begins (``on``) or ends: where a signal may abandon it."""

    def add(self, stats: StepStats) -> None:
        """A step's counts (``StepStats``), or a block's solver counters read at its end."""

    def account(self, step: int, t0: float, cpu0: float) -> None:
        """Steps to ``step`` taken since ``time.perf_counter()`` t0 and ``process_time()`` cpu0."""

    def after(self, step: int, done: int) -> None:
        """``done`` steps to ``step`` found good."""


def trouble_line(model, x, bad: tuple, day: float, of: str = "") -> str:
    """What went wrong in a checked step, ``bad`` = (step, trouble, detail) of a ``Stop``, at model
    ``day`` (``of``: whose run, said after the time): where the state ``x`` (3, N) of ``model`` went
    bad (detail [(unit index, unit, whole-grid node)]), or for a "failure" the solver's message
    ``detail``; the same line on every rank (call on every rank): a run's and a gradient's."""
    step, trouble, detail = bad
    if trouble == "failure":
        return f"step {step} failed (model time {day:.4f} days){of}: {detail}"
    return f"blow-up at step {step} (model time {day:.4f} days){of}: {model.bad_nodes.describe(x, detail[0][2])}"


def forwarded(path: str, doc: str, settable: bool = True) -> property:
    """A driver's property that is the attribute at the dotted ``path`` from it (a number an
    index: ``"core.units.0.x"``, a run's one unit's state), read and, where ``settable``, set."""
    *way, name = path.split(".")

    def owner(d):
        for part in way:
            d = d[int(part)] if part.isdigit() else getattr(d, part)
        return d

    setter = (lambda d, value: setattr(owner(d), name, value)) if settable else None
    return property(lambda d: getattr(owner(d), name), setter, doc=doc)


def counted(stats: StepStats, stepper) -> StepStats:
    """``stats`` with ``stepper``'s solver counters read (``Stepper.counts``: raises ``StepFailure``)."""
    return StepStats(stats.rhs_evals, {**stats.iterations, **stepper.counts()})


def graphed_step(unit: Unit, j: int, watch: bool) -> StepStats:
    """Step j + 1 of ``unit``, a graph where its ``graphed`` lets it (``GraphedSteps.step``), and
    with ``watch`` the bad-state flag's launch (``ShallowWater.watch``; the solvers' device
    counters left for the block's read), else its solvers' counters read (``counted``)."""
    stats = unit.graphed.step(unit.stepper, unit.model, unit.x, watch)
    return stats if watch else counted(stats, unit.stepper)


class FixedDt:
    """The Δt policy of a fixed Δt: each step at its stepper's Δt, the clock's (a scene's, or one
    fitted to a driver's output times before the first step: ``fitted``), taken by ``step(unit,
    j, watch)`` (default ``graphed_step``), which is its ``take``: step j + 1 of ``unit``, its
    state flagged on the device where ``watch``; its ``StepStats``. ``clock`` the
    ``core.clock.Clock`` a fitted policy steps at and ``note`` what fitting it did (None: the
    stepper's Δt as built)."""

    def __init__(self, step=graphed_step, clock=None, note=None):
        self.take, self.clock, self.note = step, clock, note

    @classmethod
    def fitted(cls, clock: Clock, every: float, what: str, *spans: float) -> FixedDt:
        """The policy of ``clock``'s Δt (a scene's) shortened to the longest that divides ``every``
        (days, the interval a driver was asked for, named ``what``) and ``spans`` (days: the run,
        its output intervals, its activities'; ``Clock.fitted``), its clock's source and ``note``
        saying so. ``SceneError`` (one line) where that Δt is less than half ``clock``'s (an
        interval of odd decimals: give a dt, or an interval of whole steps)."""
        divide = f"divide {what} = {every:g} days"  # the clock's source and the note say it alike
        fit = clock.fitted(every, *spans, source=f"{clock.source}, shortened to {divide}")
        if fit.dt < clock.dt / 2:
            raise SceneError(
                f"{what} = {every:g} days is not a whole number of steps of dt = {clock.dt:g} s, and the longest dt "
                f"that divides it, the run and its output intervals is {fit.dt:g} s, less than half: give a dt, "
                "or an interval of whole steps"
            )
        return cls(clock=fit, note=f"dt shortened from {clock.dt:g} s to {fit.dt:g} s to {divide}")

    def stepper_for(self, unit: Unit, build):
        """The stepper ``unit`` steps at this policy's Δt with, nothing written: its own where its Δt
        changes in place (``variable_dt``; set by ``use``), else ``build(unit.model)`` (Δt folded
        into what it builds: a Helmholtz operator, a history's weights, element levels)."""
        return unit.stepper if unit.stepper.variable_dt else build(unit.model)

    def use(self, unit: Unit, stepper) -> None:
        """``unit`` steps on at this policy's Δt with ``stepper`` (``stepper_for``'s): its own Δt
        set in place (``set_dt``: what was built for the old Δt dropped), or a new one prepared
        from the unit's state."""
        if stepper is unit.stepper:
            stepper.set_dt(self.clock.dt)
        else:
            stepper.prepare(unit.x)
            unit.stepper = stepper

    def keep(self, active: list, whole: bool) -> dict:
        """How a fixed-Δt loop keeps the ``active`` units ((index, unit)) at a block's start: x
        copied to ``start`` (the last good state) and, where ``whole`` (for a block or where
        members drop), the steppers' ``state()`` returned by index."""
        for _, u in active:
            wp.copy(u.start, u.x)
        return {i: u.stepper.state() for i, u in active} if whole else {}

    def put_back(self, active: list, saved: dict) -> None:
        """The ``active`` units back to their ``start`` and, where ``saved`` holds it, their
        stepper's state (``keep``'s)."""
        for i, u in active:
            wp.copy(u.x, u.start)
            if i in saved:
                u.stepper.restore(saved[i])


class ControlledDt:
    """The Δt policy of step control (Oceananigans' ``TimeStepWizard`` with ``aligned_time_step``):
    each step an accepted step of ``control`` (a ``control.StepControl``: its tries,
    rejected ones retried) toward the first of ``days`` (model days from t = 0, increasing) after
    the time it reached, landed on it exactly; ``quiet(j)`` whether nothing reads the state after
    step j + 1, so that the next try may be launched ahead (``StepControl.lookahead``).
    ``reached``: the last of ``days`` reached (a driver's blocks end there). It is also how the
    loop keeps and puts back a controlled step (``keep``, ``put_back``): the state of
    ``control``, kept here (``keep`` hands the loop nothing; the step's start is the control's
    own, its unit's ``start``)."""

    def __init__(self, control, days, quiet):
        self.control, self.days, self.quiet, self.saved = control, list(days), quiet, None

    @property
    def reached(self) -> bool:
        return not self.days or self.control.t >= self.days[-1] * DAY

    def take(self, unit: Unit, j: int, watch: bool) -> StepStats:
        """An accepted step j + 1 of ``unit`` toward the next day, its solvers' device counters read
        (``Stepper.counts``: raises ``StepFailure``); the ``StepStats`` of its tries."""
        day = next(d for d in self.days if d * DAY > self.control.t)
        return counted(self.control.step_to(unit.x, day, self.quiet(j)), unit.stepper)

    def keep(self, active: list, whole: bool) -> None:
        self.saved = self.control.state()

    def put_back(self, active: list, saved: dict) -> None:
        """The control's unit back to the step's start and the control to its state then (after a
        bad step, a try launched ahead already undone: ``StepControl.settle``)."""
        wp.copy(self.control.unit.x, self.control.unit.start)
        self.control.restore(self.saved)


class Integrator:
    """``units`` (``Unit`` s, the members of this process) advanced by ``policy.take(unit, j,
    watch)`` (the Δt policy's step j + 1 of a unit, the state flagged on the device where
    ``watch``; its ``StepStats``; default ``FixedDt()``) under one guard (module doc). ``anywhere(flag)``: whether ``flag``
    holds on any process stepping members of the same run (default: here). ``drop``: a unit bad
    at a checked step is dropped and the others go on (``out``: {unit index: step}). ``lone``: a
    block of one step is checked at once (a run's first step, to time it alone) rather than
    watched. A block is kept and put back by its policy (``keep``, ``put_back``: ``FixedDt``'s,
    a controlled step's ``ControlledDt``'s, a gradient's sweep's own). ``step``: the steps taken;
    ``counters``: their RHS evaluations, wall and CPU seconds and solver iterations (by
    name), kept by a driver's ledger (``simulation.summary.Ledger``) and its restart files, put
    back with a block taken again; ``control``: the ``control.StepControl`` of a controlled Δt
    (None: fixed), which vouches for its steps' states (``StepControl.vouched``)."""

    def __init__(self, units: list, policy=None, *, anywhere=bool, drop=False, lone=True):
        self.units, self.policy, self.anywhere = list(units), policy or FixedDt(), anywhere
        self.drop, self.lone, self.out, self.step = drop, lone, {}, 0  # out: the units dropped ({index: step})
        # what the loop counts (a driver's ``Ledger`` adds to them; a restart file carries them)
        self.counters = {"rhs_evals": 0, "wall_time": 0.0, "cpu_time": 0.0, "iterations": {}}
        self.control = None  # the step control (``control.StepControl``) under a controlled Δt

    def advance(self, stop_step: int, observer: Observer) -> Stop:
        """Blocks of steps to ``stop_step`` (``observer.block_end``), ``observer.after`` called
        after each good block or checked step; a block that finds trouble is taken again from
        its start a checked step at a time. Returns why it stopped (``Stop``): nothing, a
        signal between blocks (``observer.asked``) or an abandoned step, or trouble in a checked
        step (``step`` is then the last good step; a bad state is kept for its report)."""
        again_to = self.step  # steps up to here are taken again one at a time: their block found trouble
        while self.step < stop_step:
            b = self.step
            if b >= again_to and (signum := observer.asked()):  # every rank stops at the same step
                return Stop(signum=signum)
            e = min(observer.block_end(b), stop_step) if b >= again_to else b + 1
            if e <= b:  # the driver's end (a controlled run's last day)
                break
            watched = b >= again_to and (e > b + 1 or not self.lone)
            m, trouble, detail = self.block(b, e, watched, observer)
            if trouble is None:  # m > b: a step without trouble was taken
                observer.after(m, m - b)
            elif trouble == "abandoned":
                return Stop(signum=detail, abandoned=(b, m))
            elif watched:  # the block again from b, a checked step at a time (a failure: to step m + 1)
                again_to = m + 1 if trouble == "failure" else m
            else:
                return Stop(bad=(b + 1, trouble, detail))
        return Stop()

    def block(self, b: int, e: int, watched: bool, observer: Observer) -> tuple:
        """Steps b+1..e of the active units, the one step path: ``watched``, each state flagged on
        the device and the flag read at the end, else each step checked at once (one step).
        Returns (m, trouble, detail): m the last step taken; trouble None when every state to m
        was good, else "bad", "unconverged", "failure" (a ``StepFailure`` in step m + 1) or
        "abandoned" (step m + 1; detail the signal), and then ``step`` is b again and, but for
        a checked step's bad state, the units are put back."""
        active = [(i, u) for i, u in enumerate(self.units) if i not in self.out]  # all but those dropped
        check = observer.checked(b, e)
        saved = self.policy.keep(active, watched and check or self.drop)
        # the counts at the block's start, put back where the block is taken again
        kept = (self.counters["rhs_evals"], dict(self.counters["iterations"])) if watched else None
        t0, cpu0 = time.perf_counter(), time.process_time()
        m, trouble, detail = self._steps(active, b, e, watched and check, observer)
        if check and watched:
            trouble = self._read(active, trouble, observer)
        elif check and trouble is None:
            trouble, detail = self._checked(active, b, observer, saved)
        if trouble == "failure" and len(active) > 1:
            m = e - 1  # which unit's step failed is not known: every step of the block again
        observer.account(m if watched else b + 1, t0, cpu0)
        if trouble is not None:
            self.step = b
            if watched or trouble == "abandoned":
                self.policy.put_back(active, saved)
            if watched:
                self.counters["rhs_evals"], self.counters["iterations"] = kept
        return m, trouble, detail

    def _steps(self, active: list, b: int, e: int, watch: bool, observer: Observer) -> tuple:
        """Steps b+1..e of ``active``, a unit's steps and then the next's (its arrays in the cache);
        one unit's stop early for a signal (``observer.asked``). Returns (m, trouble, detail)."""
        m, one = b, len(active) == 1
        for _, u in active:
            for j in range(b, e):
                if one and j > b and observer.asked(within=True):  # the loop stops at j, once checked
                    return m, None, None
                try:
                    observer.stepping(True)
                    stats = self.policy.take(u, j, watch)
                except StepFailure as err:
                    return j, "failure", str(err)
                except StepAbandoned as err:  # the state of the last complete step is kept
                    return j, "abandoned", err.signum
                finally:
                    observer.stepping(False)
                observer.add(stats)
                m = j + 1
                self.step = m if one else self.step  # the steps x holds (not yet checked)
        self.step = m
        return m, None, None

    def _read(self, active: list, trouble: str | None, observer: Observer) -> str | None:
        """A block's check (``trouble`` what its steps met): each unit's flag (one read, resetting
        it) and solver counters (added to ``observer`` where all is good). Returns the trouble:
        that, else "bad" (a state flagged) or "unconverged" (a solve missed its tolerance)."""
        flags = [u.model.bad_nodes.watched_bad() for _, u in active]
        if self.anywhere(any(flags)) and trouble is None:
            trouble = "bad"
        for _, u in active:
            if not u.stepper.deferred:  # its solvers' counters read in each step
                continue
            try:  # the solvers' device counters of the block's steps (zeroed, also after trouble)
                counts = u.stepper.counts()
            except StepFailure:  # a solve in the block failed: which one, the steps again tell
                trouble = trouble or "unconverged"
                continue
            if trouble is None:
                observer.add(StepStats(0, counts))
        return trouble

    def _checked(self, active: list, b: int, observer: Observer, saved: dict) -> tuple:
        """A checked step's first bad nodes (one read a unit), members dropped there (``drop``)
        while others are good. Returns (trouble, detail): (None, None) or ("bad", the
        [(index, unit, node)] bad)."""
        if self.control is not None and self.control.vouched():  # its state found good by the step control
            return None, None
        bad = [(i, u, node) for i, u in active if (node := u.model.bad_nodes.first(u.x)) is not None]
        wp.synchronize_device(active[0][1].x.device)
        if not self.anywhere(bool(bad)):
            return None, None
        if not self.drop or not self.anywhere(len(bad) < len(active)):
            return "bad", bad
        self.policy.put_back([(i, u) for i, u, _ in bad], saved)  # back to their last good state, not stepped again
        self.out |= {i: b + 1 for i, _, _ in bad}
        observer.dropped(b + 1, bad)
        return None, None
