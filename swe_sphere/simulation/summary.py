"""What a run counts and reports: its ledger of steps and times, and its result."""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path

from ..core.constants import DAY

# A run's wall time is estimated from the steps after its first (which compiles kernels):
# this many of them, or as many as take this many seconds, whichever comes first.
ESTIMATE_STEPS, ESTIMATE_SECONDS = 3, 10.0


@dataclass
class RunResult:
    """What a run produced: final diagnostics, counts and timings."""

    steps: int
    rhs_evals: int
    wall_time: float  # s in the time loop, compilation included (cumulative over restarts)
    setup_time: float
    diagnostics: dict
    courant: dict
    output: Path | None
    blowup: str | None = None
    history: list = field(default_factory=list)
    iterations: dict = field(default_factory=dict)
    compile_time: float = 0.0  # s of Warp module loading/compiling, setup and loop, this process
    first_step_time: float = math.nan  # s of this process's first step (launch recording, compilation)
    first_step: int = 0  # the step the run started from (0, or a checkpoint's)
    loop_time: float = 0.0  # s in this process's time loop
    checkpoint: Path | None = None  # the last restart file written


class Ledger:
    """The counts and times of a run's steps, kept in ``counters`` (the simulation's,
    carried by its restart files): RHS evaluations, solver iterations, wall and CPU
    time; and this run's first step's time. ``notify(line)`` (rank 0), when given, is
    told once when the wall time estimated from the steps after the first exceeds a day."""

    def __init__(self, counters: dict, scene, first_step: int, notify=None):
        self.c, self.scene, self.first_step, self.notify = counters, scene, first_step, notify
        counters.setdefault("cpu_time", 0.0)  # a restart file written before runs kept their CPU time
        self.wall0, self.first_time = counters["wall_time"], math.nan
        self.estimating, self._since = notify is not None, math.nan  # the wall clock at the end of the first step

    def add(self, stats) -> None:
        """Count a step's ``StepStats`` (None: nothing)."""
        if stats is not None:
            self.c["rhs_evals"] += stats.rhs_evals
            for k, it in stats.iterations.items():
                self.c["iterations"][k] = self.c["iterations"].get(k, 0) + it

    def account(self, n: int, t0: float, cpu0: float) -> None:
        """Book the time since ``time.perf_counter()`` t0 and ``time.process_time()``
        cpu0 (the device synchronised after step n)."""
        c, s, first = self.c, self.scene, self.first_step
        dt_wall = time.perf_counter() - t0
        c["wall_time"] += dt_wall
        c["cpu_time"] += time.process_time() - cpu0  # the process's threads summed: one thread for a reproducible cost
        if n == first + 1:
            self.first_time, self._since = dt_wall, time.perf_counter()
        elif self.estimating:  # the loop's own time (output, progress bar) counted
            timed, spent = n - first - 1, time.perf_counter() - self._since
            if timed >= ESTIMATE_STEPS or spent >= ESTIMATE_SECONDS:
                self.estimating, left = False, spent / timed * (s.nsteps - n)
                if left > DAY:
                    self.notify(
                        f"this run will take about {left / DAY:.3g} days of wall time to day {s.days:g} "
                        f"({spent / timed:.3g} s a step over steps {first + 2}-{n}; {s.nsteps - n} steps left)"
                    )

    def next_steps(self, step: int) -> list[int]:
        """The last step the wall-time estimate needs, while ``step`` is before it
        (on every rank alike: blocks end there)."""
        end = self.first_step + 1 + ESTIMATE_STEPS
        return [end] if step < end else []

    def result(self, step: int, history: list, **rest) -> RunResult:
        """The ``RunResult`` of the run at ``step`` with ``history`` (``rest`` as ``RunResult`` names
        them: ``courant``, ``output``, ``blowup``, ``checkpoint``, ``setup_time``, ``compile_time``)."""
        c, first = self.c, {"first_step_time": self.first_time, "first_step": self.first_step}
        counts = {"rhs_evals": c["rhs_evals"], "wall_time": c["wall_time"], "iterations": dict(c["iterations"])}
        loop = c["wall_time"] - self.wall0
        return RunResult(step, diagnostics=history[-1], history=history, loop_time=loop, **counts, **first, **rest)
