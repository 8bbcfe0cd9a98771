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
import math
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
    """``log(line)`` with ``log_line`` every ``schedule`` steps (a ``Callback``; rank 0, the fields
    gathered on every rank), from the diagnostics ``files`` (a ``RunFiles``: its run state and
    diagnostics) recorded at this step when it did; the owner it is called with not read."""

    def call(owner) -> None:
        line = log_line(files.diagnostics, files.history[-1] if is_due(files.schedule, files.run) else None)
        if line is not None:
            log(line)

    return Callback(call, schedule)


def log_line(members, d: dict | None = None) -> str | None:
    """A single run's line on its current step (``members`` its ``members.members.Members``), as
    HOMME prints every ``statefreq`` steps: step, model day, relative changes of mass, total energy
    and potential enstrophy since t = 0 and the largest advective and gravity-wave Courant numbers
    over the nodes. ``d``: the step's ``diagnose`` when the caller has it; else the fields are
    gathered here (the one device synchronisation). Call on every rank; None on the ranks > 0."""
    whole = members.gather_fields() if d is None else None  # on every rank
    if not members.root:
        return None
    d = members.figures(whole) if d is None else d
    names = {"mass_change": "mass", "total_energy_change": "energy", "potential_enstrophy_change": "enstrophy"}
    changes = "".join(f"  {name} {d[k]:+.3e}" for k, name in names.items() if k in d)
    grav = "" if math.isnan(d["courant_gravity"]) else f" gravity-wave {d['courant_gravity']:.3f}"
    run = members.run
    return f"step {run.step} day {run.time:.4f}{changes}  Courant advective {d['courant_advective']:.3f}{grav}"
