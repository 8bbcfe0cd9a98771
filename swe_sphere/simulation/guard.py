"""The bad-state guard: blocks of steps checked once on the device, a failed block re-run step by step."""

from __future__ import annotations

import warp as wp

from ..core.errors import StepFailure
from ..steppers import StepStats
from .schedules import next_multiple


class Guard:
    """The bad-state check of one run of ``sim`` (``Simulation.check_every``).

    The state is checked for a non-finite value or h <= 0 after every step on the
    device (``ShallowWater.watch``) and the check read back once a block of steps
    (``block_end``: every ``check_every`` steps and at every step an activity is due), so that a GPU step needs no host round trip; the solvers'
    iteration counters of the semi-implicit and IMEX steps are read there too
    (``Stepper.deferred``, ``Stepper.counts``), and a solve that missed its
    tolerance fails the block like a bad state. A block whose check fails is
    re-run from its start (state, stepper history and counters kept there), one
    checked step at a time: the blow-up is reported at the step, time and place (a
    failed solve at the step and time), and the output holds, as with a check every
    step (the same bits either way). A single step is checked at once
    (``BadNodes.first``), its solvers' counters read inside it."""

    def __init__(self, sim, stop_step: int, ledger):
        """``stop_step``: the run's last step; ``ledger``: its ``summary.Ledger``."""
        self.sim, self.first_step, self.stop_step, self.ledger = sim, sim.step, stop_step, ledger
        self.every = max(1, int(sim.check_every))
        self._saved = None  # a block's stepper history and counters at its start

    def block_end(self, b: int) -> int:
        """The last step of the block that starts after step b: the next multiple of
        ``check_every``, the next step an activity is due (``Simulation.activities``:
        output, restart, callback, log), the last step of the run's wall-time estimate
        or its end, whichever comes first."""
        if self.every == 1 or b == self.first_step:  # the first step alone: its time is first_step_time
            return b + 1
        due = (a.schedule.next_after(b) for a in self.sim.activities.values())
        return min(
            self.stop_step, next_multiple(b, self.every), *(n for n in due if n is not None), *self.ledger.next_steps(b)
        )

    def begin(self, b: int, block: bool) -> None:
        """Keep the state of step b in ``last_good`` and, for a block, the stepper's
        history and counters there."""
        sim = self.sim
        c = sim.counters
        self._saved = (sim.stepper.state(), c["rhs_evals"], dict(c["iterations"])) if block else None
        wp.copy(sim.last_good, sim.x)

    def end(self, b: int, trouble: str | None, ledger) -> tuple[str | None, int | None]:
        """Read the check of the steps since ``begin(b)`` (the host's one read and
        synchronisation) and the solvers' counters of a block (into ``ledger``).
        ``trouble``: what the step path met, None, "failure" (a ``StepFailure``) or
        "abandoned". Returns (trouble, node): trouble None when every state was good,
        else that or "bad" (or, in a block, "unconverged": a solve missed its
        tolerance); node the whole-grid index of a single step's bad node. After
        trouble ``sim.step`` is b again; after a block's trouble or an abandoned step,
        so are the state, and for a block the stepper history and counters; a single
        step's bad state is kept for its report."""
        sim, node = self.sim, None
        if self._saved is not None:
            if sim.model.bad_nodes.watched_bad() and trouble is None:
                trouble = "bad"
            try:  # the solvers' device counters of the block's steps (zeroed, also after trouble)
                counts = sim.stepper.counts()
            except StepFailure:  # a solve in the block failed: which one, the re-run tells
                trouble = trouble or "unconverged"
            if trouble is None:
                ledger.add(StepStats(0, counts))
        else:
            node = sim.model.bad_nodes.first(sim.x) if trouble is None else None
            wp.synchronize_device(sim.device)
            trouble = "bad" if node is not None else trouble
        if trouble is not None:
            sim.step = b
            if self._saved is not None or trouble == "abandoned":
                wp.copy(sim.x, sim.last_good)
            if self._saved is not None:
                sim.stepper.restore(self._saved[0])
                sim.counters["rhs_evals"], sim.counters["iterations"] = self._saved[1], self._saved[2]
        return trouble, node

    def message(self, step: int, trouble: str, detail, day: float | None = None) -> str:
        """What went wrong in the single step ``step`` (at model ``day``, default the clock's):
        where ``detail`` (its bad node, a whole-grid index) went bad, or for a "failure" the
        solver's message ``detail``, on every rank (call on every rank)."""
        sim = self.sim
        day = sim.scene.day(step) if day is None else day
        if trouble == "failure":
            return f"step {step} failed (model time {day:.4f} days): {detail}"
        return f"blow-up at step {step} (model time {day:.4f} days): {sim.model.bad_nodes.describe(sim.x, detail)}"
