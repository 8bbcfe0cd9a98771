"""How a ``Simulation``'s public names read its members (``members.members.Members``, issue 124:
one run of any size): the one squeeze rule of their answers (``squeeze``), a method of the
members squeezed or handed on, and a property of the one member that N > 1 members refuse."""

from __future__ import annotations

import functools
from operator import attrgetter

from ..core.errors import ArgumentError


def squeeze(n: int, each):
    """The one squeeze rule of a simulation's answers of its ``n`` members, given with the member
    axis first (a list of N dicts or values, an (N, ...) array, or a tuple of them, None off rank
    0): N = 1 the one member's (a dict, a value, an (n,) array: a single run's shapes), N > 1 as
    given."""
    if n > 1 or each is None:
        return each
    return tuple(squeeze(n, a) for a in each) if isinstance(each, tuple) else each[0]


def delegated(method, owner):
    """A simulation's method that is its ``owner(sim)``'s method of ``method``'s name (its
    intervals'), whose doc it has."""
    return functools.wraps(method)(lambda sim, *args, **kw: getattr(owner(sim), method.__name__)(*args, **kw))


def squeezed(method):
    """A simulation's method that is its members' (``Members``) method of ``method``'s name, its
    answer squeezed (``squeeze``), whose doc it has."""
    call = delegated(method, attrgetter("members"))
    return functools.wraps(method)(lambda sim, *a, **kw: squeeze(len(sim.members), call(sim, *a, **kw)))


def of_one(name: str, attr: str, doc: str, units: bool = False) -> property:
    """A simulation's ``name``: its one member's unit's ``attr`` (``integrator.core.Unit``); for N > 1
    an ``ArgumentError`` naming ``states()``, which holds every member's (``units``: the one unit's, of
    every member "shared"; for members each on a unit of their own an ``ArgumentError`` naming
    ``members.units``, which holds them)."""

    def get(sim):
        if units and len(sim.core.units) > 1:
            raise ArgumentError(
                f"Simulation.{name}: {len(sim.core.units)} members each step on a model and {name} of their own "
                "(layout 'in_turn'); members.units holds them"
            )
        if not units and len(sim.members) > 1:
            raise ArgumentError(
                f"Simulation.{name}: a run of {len(sim.members)} members has a state a member; states() gives them "
                "(N, 3, n) and set_states(states) sets them"
            )
        return getattr(sim.core.units[0], attr)

    return property(get, doc=doc)
