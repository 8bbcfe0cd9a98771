"""What a run adds to the integrator's guard (``integrator.core.Integrator``): where its blocks end,
its signals, counts and activities, its Δt policy under step control landed on its activities'
days (``RunObserver``); a blow-up's line is the integrator's (``integrator.core.trouble_line``)."""

from __future__ import annotations

import time

from ..core.constants import DAY
from ..integrator.core import ControlledDt, Observer
from .schedules import AtDays, is_due, next_multiple


class RunObserver(Observer):
    """A run's hooks on its integrator (``Simulation.core``):
    ``run`` its ``run_state.RunState``, ``activities`` its activities by name (the dict itself,
    read as it is at each step), each called with ``caller`` (the ``Simulation``:
    what a user's callback is handed, read by nothing here), ``ledger``
    its ``summary.Ledger`` (the steps' counts and times: its ``add`` and ``account`` the hooks),
    ``signals`` a ``StopSignals``; after good steps the activities due
    and the progress on ``bar`` (tqdm) and ``lines`` (``cli.progress.ProgressLines``). A block of
    steps, its states flagged on the device and read once at its end (the integrator's guard:
    its module doc), ends every ``every`` steps (``Simulation.check_every``) and at each step an
    activity is due (``block_end``). Under step control ``steered`` (``steer``'s
    ``integrator.core.ControlledDt``): each accepted step a block, to the policy's last day, not
    abandoned by a signal (a try's state is the control's). An ensemble's (``dropped`` given,
    the hook): each (index, unit, first bad node) dropped told to ``dropped(step, bad)``, a stop
    asked between blocks alone and no step abandoned by a signal (members stepped in turn are
    not put back a step)."""

    def __init__(self, run, activities: dict, caller, ledger, every: int, signals, bar, lines=None, dropped=None):
        self.run, self.activities, self.caller, self.ledger = run, activities, caller, ledger
        self.signals, self.bar, self.lines, self.steered, self.dropped = signals, bar, lines, None, dropped
        self.every, self.add, self.account = max(1, int(every)), ledger.add, ledger.account

    def steer(self, control, last_day: float) -> ControlledDt:
        """The Δt policy of the run under ``control`` (an ``integrator.control.StepControl``), made
        ``steered``: accepted steps (``integrator.core.ControlledDt``) to each day an ``AtDays``
        activity is due at (output and restart times) up to ``last_day`` and ``last_day`` in
        turn, each landed on exactly, a try launched ahead only where no activity of whole steps
        (``EverySteps``, ``AtSteps``: they read x) is due after the step."""
        schedules = [a.schedule for a in self.activities.values()]
        days = {float(last_day), *(d for s in schedules if isinstance(s, AtDays) for d in s.days)}
        counted = [s for s in schedules if not isinstance(s, AtDays)]  # of whole steps: due after a step, they read x
        ahead = sorted(d for d in days if control.t < d * DAY and d <= last_day)  # not past the run's last day
        self.steered = ControlledDt(control, ahead, lambda j: not any(s.due(j + 1) for s in counted))
        return self.steered

    def block_end(self, b: int) -> int:
        """The last step of the block that starts after step b: the next multiple of
        ``check_every``, the next step an activity is due (``Simulation.activities``:
        output, restart, callback, log) or the last step of the run's wall-time estimate,
        whichever comes first (the integrator's stop step bounds it); under step control b + 1,
        or b at its last day. The same on every rank."""
        if self.steered is not None:
            return b if self.steered.reached else b + 1
        if self.every == 1 or b == self.ledger.first_step:  # the first step alone: first_step_time
            return b + 1
        due = (a.schedule.next_after(b) for a in self.activities.values())
        return min(next_multiple(b, self.every), *(n for n in due if n is not None), *self.ledger.next_steps(b))

    def asked(self, within: bool = False) -> int:
        # an ensemble's ranks may hold units unalike: between blocks alone
        return 0 if within and self.dropped is not None else self.signals.asked()

    def stepping(self, on: bool) -> None:
        if self.steered is None and self.dropped is None:  # abandoned from here
            self.signals.in_step = time.perf_counter() if on else None

    def after(self, step: int, done: int) -> None:
        """The activities due at the run's step (``schedules.is_due``), each called in order with
        ``caller``, then the progress on ``bar`` and, where given, ``lines``."""
        for activity in list(self.activities.values()):
            if is_due(activity.schedule, self.run):
                activity(self.caller)
        self.bar.update(done)
        if self.lines is not None:
            self.lines.tick(step, self.run.time)
        if step % 50 < done or step == self.run.scene.nsteps:  # a multiple of 50 in the steps done
            speed = (self.run.time - self.run.scene.start_day) / max(self.run.counters["wall_time"], 1e-9)
            self.bar.set_postfix(day=f"{self.run.time:.2f}", sim_days_per_s=f"{speed:.3g}")
