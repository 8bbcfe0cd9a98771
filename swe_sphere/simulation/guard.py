"""What a run adds to the integrator's guard (``integrator.core.Integrator``): where its blocks end,
its signals, counts and activities (``RunObserver``); a blow-up's line is the integrator's
(``integrator.core.trouble_line``)."""

from __future__ import annotations

import time

from ..integrator.core import Observer
from .activities import call_due
from .schedules import next_multiple


class RunObserver(Observer):
    """A run's hooks on its integrator (``Simulation.core``) to ``stop_step``:
    ``run`` its ``run_state.RunState``, ``activities`` its activities by name (the dict itself,
    read as it is at each step), each called with ``caller`` (the ``Simulation``:
    what a user's callback is handed, read by nothing here), ``ledger``
    its ``summary.Ledger`` (the counts, kept at a block's start and put back where the block is
    taken again), ``signals`` a ``StopSignals``; after good steps the activities due and the
    progress on ``bar`` (tqdm) and ``lines`` (``progress.ProgressLines``). A block of steps, its
    states flagged on the device and read once at its end (the integrator's guard: its module
    doc), ends every ``every`` steps (``Simulation.check_every``) and at each step an activity is
    due (``block_end``). Under step control ``steered`` (an ``integrator.core.ControlledDt``): each
    accepted step a block, to the policy's last day, its state vouched for where the control's
    norm or Courant pass found it good (``StepControl.vouched``), not abandoned by a signal (a
    try's state is the control's). ``timed`` False: no first step alone and no steps the wall
    time is estimated from (an ensemble's ``step(n)`` and ``advance``: blocks as long as they may
    be). An ensemble's (``dropped`` given): each (index, unit, first bad node) dropped told to
    ``dropped(bad, step)``, a stop asked between blocks alone and no step abandoned by a signal
    (members stepped in turn are not put back a step)."""

    def __init__(
        self,
        run,
        activities: dict,
        caller,
        ledger,
        stop_step: int,
        every: int,
        signals=None,
        bar=None,
        lines=None,
        timed=True,
        dropped=None,
    ):
        self.run, self.activities, self.caller, self.ledger, self.first_step = run, activities, caller, ledger, run.step
        self.stop_step, self.signals, self.bar, self.lines, self.steered = stop_step, signals, bar, lines, None
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
        if self.signals is not None and self.steered is None and self._dropped is None:  # abandoned from here
            self.signals.in_step = time.perf_counter() if on else None

    def add(self, stats) -> None:
        self.ledger.add(stats)

    def account(self, step: int, t0: float, cpu0: float) -> None:
        self.ledger.account(step, t0, cpu0)

    def after(self, step: int, done: int) -> None:
        """The activities due (``call_due``), then the progress on ``bar`` and ``lines``, where given."""
        run, bar = self.run, self.bar
        call_due(self.activities, run, self.caller)
        if bar is None:
            return
        bar.update(done)
        if self.lines is not None:
            self.lines.tick(step, run.time)
        if step % 50 < done or step == run.scene.nsteps:  # a multiple of 50 in the steps done
            speed = (run.time - run.scene.start_day) / max(run.counters["wall_time"], 1e-9)
            bar.set_postfix(day=f"{run.time:.2f}", sim_days_per_s=f"{speed:.3g}")

    def keep(self):
        return self.run.counters["rhs_evals"], dict(self.run.counters["iterations"])

    def put_back(self, kept) -> None:
        self.run.counters["rhs_evals"], self.run.counters["iterations"] = kept
