"""Functions a run calls back every so many steps (Oceananigans' ``add_callback!``)."""

from __future__ import annotations

from dataclasses import dataclass

from .schedules import next_multiple


@dataclass
class Callback:
    """``fn(sim)`` called after every ``steps``-th step (``Simulation.add_callback``)."""

    fn: object
    steps: int


class Callbacks:
    """A simulation's callbacks, called in the order they were added."""

    def __init__(self):
        self._all: list[Callback] = []

    def add(self, fn, steps: int) -> None:
        self._all.append(Callback(fn, steps))

    def __call__(self, sim, step: int) -> None:
        """Call those whose interval divides ``step`` (steps since t = 0)."""
        for callback in self._all:
            if step % callback.steps == 0:
                callback.fn(sim)

    def next_steps(self, step: int) -> list[int]:
        """Each callback's first step after ``step``."""
        return [next_multiple(step, cb.steps) for cb in self._all]
