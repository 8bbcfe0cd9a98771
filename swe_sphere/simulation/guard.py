"""What a run adds to the integrator's guard (``integrator.Integrator``): where its blocks end,
its signals, counts and activities (``RunObserver``); a blow-up's line is the integrator's
(``integrator.trouble_line``)."""

from __future__ import annotations

import time

from ..integrator import Observer
from .schedules import next_multiple


class RunObserver(Observer):
    """A run's hooks on its integrator (``Simulation.core``, ``Ensemble.core``; made by
    ``loop.run_observer``), to ``stop_step``.

    The state is flagged on the device after every step (``ShallowWater.watch``) and the flag
    read back once a block of steps (``block_end``: every ``check_every`` steps and at every step
    an activity is due), so that a GPU step needs no host round trip; the solvers' iteration
    counters of the semi-implicit and IMEX steps are read there too (``Stepper.deferred``,
    ``Stepper.counts``), and a solve that missed its tolerance fails the block like a bad state.
    A block that fails is taken again from its start (state, stepper history and the run's
    ``counters`` kept there), one checked step at a time: the blow-up is reported at the step,
    time and place (a failed solve at the step and time), and the output holds, as with a check
    every step (the same bits either way). ``run`` the run's parts: its first step, check interval
    (``Simulation.check_every``), ``activities`` and ``counters`` (``Simulation``'s) and
    ``summary.Ledger``; ``signals`` a ``StopSignals``, ``after(n, done)`` the loop's activities
    and progress after good steps. Under step control ``steered`` (an ``integrator.ControlledDt``):
    each accepted step a block, to the policy's last day, its state vouched for where the
    control's norm or Courant pass found it good (``StepControl.vouched``), not abandoned by a
    signal (a try's state is the control's). ``timed`` False: no first step alone and no steps
    the wall time is estimated from (an ensemble's ``step(n)`` and ``advance``: blocks as long as
    they may be). An ensemble's (``dropped`` given): each (index, unit, first bad node) dropped
    told to ``dropped(bad, step)``, a stop asked between blocks alone and no step abandoned by a
    signal (members stepped in turn are not put back a step)."""

    def __init__(self, run: tuple, stop_step: int, signals=None, after=None, timed: bool = True, dropped=None):
        self.first_step, every, self.activities, self.counters, self.ledger = run
        self.stop_step, self.signals, self._after, self.steered = stop_step, signals, after, None
        self.every, self.timed, self._dropped = max(1, int(every)), timed, dropped

    def block_end(self, b: int) -> int:
        """The last step of the block that starts after step b: the next multiple of
        ``check_every``, the next step an activity is due (``Simulation.activities``:
        output, restart, callback, log), the last step of the run's wall-time estimate
        or its end, whichever comes first (``timed`` False: not the first step alone nor the
        estimate's steps); under step control b + 1, or b at its last day. The same on every rank."""
        if self.steered is not None:
            return b if self.steered.reached else b + 1
        if self.every == 1 or (self.timed and b == self.first_step):  # the first step alone: first_step_time
            return b + 1
        due = (a.schedule.next_after(b) for a in self.activities.values())
        estimate = self.ledger.next_steps(b) if self.timed else ()
        return min(self.stop_step, next_multiple(b, self.every), *(n for n in due if n is not None), *estimate)

    def asked(self) -> int:
        return self.signals.asked() if self.signals is not None else 0

    def vouched(self) -> bool:
        return self.steered is not None and self.steered.control.vouched()

    def within(self) -> int:
        return self.asked() if self._dropped is None else 0  # an ensemble's ranks may hold units unalike

    def dropped(self, step: int, bad: list) -> None:
        self._dropped(bad, step)

    def stepping(self, on: bool) -> None:
        if (
            self.signals is not None and self.steered is None and self._dropped is None
        ):  # a step may be abandoned from here (``StopSignals``)
            self.signals.in_step = time.perf_counter() if on else None

    def add(self, stats) -> None:
        self.ledger.add(stats)

    def account(self, step: int, t0: float, cpu0: float) -> None:
        self.ledger.account(step, t0, cpu0)

    def after(self, step: int, done: int) -> None:
        if self._after is not None:
            self._after(step, done)

    def keep(self):
        return self.counters["rhs_evals"], dict(self.counters["iterations"])

    def put_back(self, kept) -> None:
        self.counters["rhs_evals"], self.counters["iterations"] = kept
