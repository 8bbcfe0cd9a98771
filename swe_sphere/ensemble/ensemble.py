"""``Ensemble``, the deprecated name of a ``Simulation`` of members (issue 116: one driver). Its old
names (``step(n)``, ``step_count``, ``day``, ``fields(member)``, ``initial``, ``wall_time``) each
say in one ``DeprecationWarning`` line what the driver calls them; ``run`` returns the run file's
path, and ``from_checkpoint`` continues an ensemble's restart file, as they did."""

from __future__ import annotations

import warnings
from pathlib import Path

from ..core.arguments import integer_argument
from ..core.errors import ArgumentError, SceneError
from ..simulation.simulation import RENAMED, Simulation

__all__ = ["Ensemble"]

# the one line constructing an Ensemble warns
DEPRECATED = "swe_sphere.Ensemble is deprecated: Simulation(scene, members=N, initial=...) is the one driver"


def _renamed(old: str, new: str) -> None:
    """The one-line ``DeprecationWarning`` of an old name of ``Ensemble``."""
    warnings.warn(f"Ensemble.{old} is deprecated: {new}", DeprecationWarning, stacklevel=3)


def _old_name(old: str, new: str, read) -> property:
    """The old name ``old`` of ``Ensemble``, read-only: ``read(ensemble)`` after its ``_renamed`` line."""

    def get(ens):
        _renamed(old, new)
        return read(ens)

    return property(get)


class Ensemble(Simulation):
    """Deprecated: ``Simulation(scene, members=N, initial=…)``, which it is. Constructing it warns
    once in one line; its old names warn where they are used.

    Parameters
    ----------
    scene, members, initial
        As ``Simulation``'s (``members`` and ``initial`` here by position; ``members`` None: the
        scene's [ensemble] ``members``, refused where it has none).
    device, progress
        As ``Simulation``'s (no progress bar by default).
    **kw
        ``Simulation``'s other arguments (``comm``, ``graphs``, ``layout``, ``blow_up``,
        ``per_element``, ``threads``) and the scene's overrides.

    Raises
    ------
    ArgumentError, SceneError
        As ``Simulation``'s.
    """

    _of_members = True

    def __init__(self, scene, members: int | None = None, initial=None, *, device=None, progress=False, **kw):
        warnings.warn(DEPRECATED, DeprecationWarning, stacklevel=2)
        super().__init__(scene, device, members=members, initial=initial, progress=progress, **kw)

    def step(self, n: int = 1) -> None:
        """Deprecated: ``advance(days)`` (``step`` is the steps taken). Advance every member n steps
        at a fixed Δt; ``ArgumentError`` under step control."""
        _renamed("step(n)", "advance(days); step is the steps taken")
        n = integer_argument("n", n, 0)
        if self.control is not None:
            raise ArgumentError("Ensemble.step takes steps of a fixed dt: under step control, advance(days) or run")
        self._advance_to(self.core.step + n)

    def advance(self, days: float) -> None:
        """``Simulation.advance``, returning nothing; ``ArgumentError`` for days not whole steps."""
        try:
            super().advance(days)
        except SceneError as err:  # an interval's, raised as the ArgumentError the old class raised
            raise ArgumentError(str(err)) from None

    def add_callback(self, fn, *, every_steps: int | None = None, every_days: float | None = None) -> None:
        """``Simulation.add_callback``; ``ArgumentError`` for an interval not whole steps."""
        try:
            super().add_callback(fn, every_steps=every_steps, every_days=every_days)
        except SceneError as err:  # as advance's
            raise ArgumentError(str(err)) from None

    step_count = _old_name("step_count", "step", lambda ens: ens.core.step)
    day = _old_name("day", "time", lambda ens: ens.time)
    wall_time = _old_name("wall_time", 'counters["wall_time"]', lambda ens: ens.counters["wall_time"])
    initial = _old_name("initial", "members.initial_states", lambda ens: ens.members.initial_states)
    dt = _old_name("dt", "scene.dt", lambda ens: ens.scene.dt)

    def __getattr__(self, name: str):
        """The members' part's old attributes (``held``, ``layout``, ``units``, ``copies``, …), and
        ``Simulation``'s old names."""
        members = self.__dict__.get("members")
        if members is None or name.startswith("_") or name in RENAMED:
            return super().__getattr__(name)
        _renamed(name, f"members.{name}")
        return getattr(members, name)

    def fields(self, member: int):
        """Deprecated: ``states()[member]``. (u, v, h), each (n,), of ``member``."""
        _renamed("fields(member)", "states()[member]")
        member = integer_argument("member", member, 0)
        if member >= len(self.members):
            raise ArgumentError(f"member must be in 0..{len(self.members) - 1} (got {member})")
        return tuple(self.states()[member].copy())

    def run(self, output=None, *, progress: bool | None = None, **kw):
        """``Simulation.run``; returns the run file's path (``output`` None: the ``RunResult``, the
        driver's ``advance``)."""
        if progress is not None:
            self.progress = progress
        result = super().run(output, **kw)
        return result if output is None else Path(output)

    @classmethod
    def from_checkpoint(cls, path, *, days=None, device=None, per_element=None, threads=None, graphs=None, comm=None):
        """An ensemble's restart file continued (``Simulation.from_checkpoint(..., members=True)``)."""
        kw = {"days": days, "per_element": per_element, "threads": threads, "graphs": graphs, "comm": comm}
        return Simulation.from_checkpoint.__func__(cls, path, device, members=True, progress=False, **kw)
