"""What a run does between its steps, each an activity of one shape (Oceananigans' output
writers and callbacks): a ``schedule`` (``schedules.AtSteps``, ``schedules.EverySteps``, or any
object with ``due(step) -> bool`` and ``next_after(step) -> int | None``; under step control
``schedules.AtDays``, due at days the steps land on) and a call
``activity(sim)``, made after each step the schedule names once the state there is known to be
good (``sim.step`` is that step). A run's own activities (``writers.RunFiles``,
``writers.Checkpointer``, ``log_activity``) read the run state and parts they were made with, not ``sim``.

``Simulation.activities`` holds them by name, called in order: during ``run`` the run file and its
streams (``"run_file"``, ``writers.RunFiles``), the restart file (``"checkpointer"``,
``writers.Checkpointer``), then those the user added (``Simulation.add_callback``, or an output
writer of one's own set as ``sim.activities[name] = writer``), then the log (``"log"``, ``log_activity``).
Blocks of steps end at every step some activity is due (``guard.RunObserver.block_end``), so an
activity always sees the state of its own step.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable
from dataclasses import dataclass

from .schedules import EverySteps, is_due
from .writers import RunFiles


def add_callback(activities: dict, fn: Callable, schedule: EverySteps, name: str | None = None) -> None:
    """``fn(owner)`` at the steps of ``schedule`` (a ``Callback``) in ``activities`` under ``name``
    (None: the first free "callback N"): ``Simulation.add_callback``'s."""
    if name is None:
        name = next(f"callback {k}" for k in itertools.count(1) if f"callback {k}" not in activities)
    activities[name] = Callback(fn, schedule)


@dataclass
class Callback:
    """``fn(sim)`` at the steps of ``schedule`` (``Simulation.add_callback``)."""

    fn: Callable
    schedule: EverySteps

    def __call__(self, sim) -> None:
        self.fn(sim)


def log_activity(log: Callable, schedule: EverySteps, files: RunFiles) -> Callback:
    """``log(line)`` with ``Members.log_line`` every ``schedule`` steps (a ``Callback``;
    rank 0, the fields gathered on every rank), from the diagnostics ``files`` (a ``RunFiles``: its
    run state and diagnostics) recorded at this step when it did; the owner it is called with not
    read."""

    def call(owner) -> None:
        line = files.diagnostics.log_line(files.history[-1] if is_due(files.schedule, files.run) else None)
        if line is not None:
            log(line)

    return Callback(call, schedule)
