"""How an ensemble's held members are stepped (``Ensemble.layout``):

- "shared": every held member in the same launches, one ``ShallowWater`` and stepper over their
  copies of the grid (``members.MemberGrid``): the launches' start-up and the loop's Python paid
  once. For an explicit stepper whose members share g and ν; the default on CUDA.
- "in_turn": each member a ``ShallowWater`` and stepper of its own on the one grid, stepped one
  after the other a block of steps at a time: for a stepper that reduces over the grid (the
  solves, mean depth and Krylov bases of semi_implicit, the IMEX pairs, implicit, the
  exponential steppers, split_explicit's and the multirate ones' checks are a member's own),
  members whose g or ν differ (``Variants.own_model``), or the tensor ∇⁴ (its reference Δx is
  the grid's); the default on a CPU (``layout``).

Either way member k's steps are its single run's launches on its own numbers: the same bits.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import warp as wp

from ..config.parts import scene_stepper
from ..core.arguments import got
from ..core.errors import ArgumentError
from ..core.graphs import GraphedSteps
from ..grid.cubed_sphere import CubedSphere
from ..grid.topology import Topology
from ..model.shallow_water import ShallowWater
from ..steppers import STEPPERS
from .initial import Variants
from .members import MemberGrid


@dataclasses.dataclass
class Unit:
    """Held members stepped together: their ``model`` and ``stepper``, their states side by side
    ``x`` (3, members·n), a block's first state ``start`` (to re-run it step by step after a
    blow-up) and the graphs of their steps ``graphed``."""

    model: ShallowWater
    stepper: object
    x: wp.array
    start: wp.array
    graphed: GraphedSteps
    members: int

    @classmethod
    def of(cls, model: ShallowWater, stepper, starts: np.ndarray, backend, graphs: str) -> Unit:
        """The unit of ``model`` and ``stepper`` from ``starts`` (members, 3, n), prepared."""
        x = model.new_state(*np.concatenate(list(starts), axis=1))
        stepper.prepare(x)
        return cls(model, stepper, x, wp.clone(x), GraphedSteps(backend, model.launches.guard, graphs), len(starts))


def checked_scene(scene) -> None:
    """``ArgumentError`` naming ``scene`` where the ensemble cannot give each member the single
    run's bits yet: a controlled Δt or a digital-filter start; or whose output it does not write
    yet (``[[output.streams]]``)."""
    why = None
    if scene.control is not None:
        why = "its dt is controlled (ensembles take a fixed dt)"
    elif scene.digital_filter is not None:
        why = "it starts from a digital filter (not yet with ensembles)"
    elif scene.output_streams:
        why = "it names [[output.streams]] (an ensemble writes one run file, not yet its streams)"
    if why is not None:
        raise ArgumentError(f"scene: {why}")


def layout(scene, initial, asked: str | None, device, own: bool = False) -> str:
    """The layout of ``scene``'s members started from ``initial`` on ``device`` (module doc):
    "in_turn" where they need a model each, else ``asked``; None: "shared" on CUDA (its time a step
    is its launches': 32 Galewsky members 17× one member's step on an H100, 31× in turn), "in_turn"
    on a CPU (its time is the nodes', and a member's arrays stay in the cache through its block of
    steps: 8 members 7.9× one member's run on one thread, 10.1× shared). ``ArgumentError`` naming
    ``layout`` for another value, or "shared" asked where the members need a model each (``own``:
    they do, whatever the stepper: a blow-up policy that drops a member)."""
    if asked not in (None, "shared", "in_turn"):
        raise ArgumentError(f"layout must be None, 'shared' or 'in_turn' (got {got(asked)})")
    own = own or not STEPPERS[scene.stepper].explicit or scene.hypervis_scaling is not None
    if own or (isinstance(initial, Variants) and initial.own_model):
        if asked == "shared":
            raise ArgumentError(
                f"layout: these members need a model each (stepper {scene.stepper}, its tensor ∇⁴, their g or ν, "
                "or blow_up 'drop'): 'in_turn'"
            )
        return "in_turn"
    return asked or ("shared" if str(device).startswith("cuda") else "in_turn")


def shared_unit(scene, grid: CubedSphere, case, starts, fcor, backend, threads: int, options: dict, graphs: str):
    """(the one ``Unit`` of every held member, the ``MemberGrid`` of their copies, one member's
    model or None): one model over the copies, its ∇⁴'s substeps from one member's operator (the
    one grid's spectral radius, not the copies'); ``fcor`` (held, n) each member's Coriolis
    parameter (None: the case's)."""
    copies = MemberGrid(grid, len(starts))
    topology = Topology(copies, backend, threads, parts=[copies.elements])
    model = ShallowWater.from_scene(scene, copies, case, **options, topology=topology)
    one = None
    if model.hv is not None and model.hv.nu_max > 0 and len(starts) > 1:
        one = ShallowWater.from_scene(scene, grid, case, **options)  # λ of one member's operator
        model.hv.use_biharmonic_radius(one.hv.biharmonic_radius())
    if fcor is not None:  # in place: the launches read it
        model.operators.fcor.assign(np.concatenate(list(fcor)))
    return Unit.of(model, scene_stepper(scene, model), starts, backend, graphs), copies, one


def own_units(scenes, grid: CubedSphere, cases, starts, backend, threads: int, options: dict, graphs: str) -> list:
    """A ``Unit`` a held member (``scenes``, ``cases`` and ``starts`` its own, in order), each its
    single run's model and stepper on one ``Topology`` of the whole grid; the ∇⁴'s spectral
    radius, a property of the grid alone, found once."""
    topology = Topology(grid, backend, threads, parts=[np.arange(grid.nelem)])
    units, radius = [], None
    for scene, case, start in zip(scenes, cases, starts):
        model = ShallowWater.from_scene(scene, grid, case, **options, topology=topology)
        if model.hv is not None and model.hv.nu_max > 0:
            if radius is None:
                radius = model.hv.biharmonic_radius()
            else:
                model.hv.use_biharmonic_radius(radius)
        units.append(Unit.of(model, scene_stepper(scene, model), start[None], backend, graphs))
    return units


def stepper_state(units: list, layout: str, held) -> dict:
    """The stepper state of a rank's ``units`` (its members ``held``) as a restart file keeps it:
    the shared stepper's; in turn, the members' arrays (3, n) side by side (a member without one
    of them zeros there) and each member's scalars under ``member<k>_`` (k its index)."""
    if layout == "shared":
        return units[0].stepper.state()
    states = [u.stepper.state() for u in units]
    n = units[0].model.topology.N
    arrays = {k for st in states for k, v in st.items() if isinstance(v, np.ndarray)}
    out = {k: np.concatenate([st.get(k, np.zeros((3, n))) for st in states], axis=-1) for k in sorted(arrays)}
    for k, st in zip(held, states):
        out |= {f"member{k}_{key}": v for key, v in st.items() if key not in arrays}
    return out


def held_state(state: dict, nodes, prefix: str | None) -> dict:
    """A unit's stepper state from a restart file's ``state`` (``stepper_state``): its members'
    columns ``nodes`` of the arrays; the scalars as they are (``prefix`` None) or those under
    ``prefix``, without it."""
    arrays = {k: v[..., nodes] for k, v in state.items() if isinstance(v, np.ndarray)}
    if prefix is None:
        return {**state, **arrays}
    return {**arrays, **{k[len(prefix) :]: v for k, v in state.items() if k.startswith(prefix)}}


def step_block(active: list, block: int, anywhere, drop: bool) -> tuple[list, bool]:
    """Step the (index, unit) ``active`` ``block`` steps, a unit's block and then the next's (its
    arrays in the cache), the bad-state check read once at the end (``anywhere(flag)``: whether
    it holds on any rank). Where a state went bad (a non-finite value, or h ≤ 0 where h is a
    depth) the block is taken again step by step from its start to find the step. Returns
    (events, stopped): each event (k, bad), the (index, unit, first bad node) ``bad`` at step k
    (1 … block) of the block; ``stopped``: the last event stops every unit there (not ``drop``,
    or none left going). Where ``drop``, an event's units go back to their last good state (their
    steppers to the block's start) and are not stepped again, the others going on."""
    saved = {i: u.stepper.state() for i, u in active}
    for _, u in active:
        wp.copy(u.start, u.x)
        for _ in range(block):
            u.graphed.step(u.stepper, u.model, u.x, True)
    if not anywhere(any(u.model.bad_nodes.watched_bad() for _, u in active)):
        return [], False
    for i, u in active:
        wp.copy(u.x, u.start)
        u.stepper.restore(saved[i])
    events = []
    for k in range(1, block + 1):
        for _, u in active:
            if drop:
                wp.copy(u.start, u.x)  # its last good state
            u.stepper.step(u.x)
        bad = [(i, u, node) for i, u in active if (node := u.model.bad_nodes.first(u.x)) is not None]
        if anywhere(bool(bad)):
            events.append((k, bad))
            if not drop or not anywhere(len(bad) < len(active)):
                return events, True
            for i, u, _ in bad:
                wp.copy(u.x, u.start)
                u.stepper.restore(saved[i])
            active = [(i, u) for i, u in active if all(i != j for j, _, _ in bad)]
    return events, False


def unit_members(layout: str, held) -> list:
    """The members (indices) of each unit of a rank holding ``held``, in order: all in one unit
    ("shared"), or one a unit ("in_turn")."""
    return [held] if layout == "shared" else list(held[:, None])
