"""How an ensemble's held members are stepped (``Simulation(..., members=N, layout=...)``, ``Members.layout``):

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

import numpy as np

from ..cases.scoring import Scorer
from ..cases.tracers import with_tracers
from ..config.parts import partition, scene_stepper
from ..config.resolve import stepper_class
from ..config.scene import Scene
from ..core.arguments import got
from ..core.backend import Backend
from ..core.errors import ArgumentError
from ..core.runtime import run_bytes
from ..grid.cubed_sphere import CubedSphere
from ..grid.topology import Topology
from ..integrator.control import StepControl
from ..integrator.core import Unit
from ..io.initial_state import from_function
from ..model.shallow_water import ShallowWater
from ..steppers.initialization import digital_filter
from .grid import MemberGrid
from .initial import ON_ROOT, Variants

# a blow-up's policies: every member stopped, or the member dropped (no longer stepped, NaN in the
# run file from then on) and the others going on
POLICIES = {"stop": "stop all", "drop": "drop the member and go on"}


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
    causes = [
        ("blow_up 'drop'", own),
        (f"stepper {scene.stepper}", not stepper_class(scene.stepper, scene.stepper_options).explicit),
        ("the tensor ∇⁴", scene.hypervis_scaling is not None),
        ("their own g or ν", isinstance(initial, Variants) and initial.own_model),
    ]
    why = [cause for cause, holds in causes if holds]
    if why and asked == "shared":
        raise ArgumentError(f"layout: these members need a model each ({', '.join(why)}): 'in_turn'")
    default = "shared" if str(device).startswith("cuda") or scene.control is not None else "in_turn"
    return "in_turn" if why else asked or default


def check_memory(scene: Scene, comm, backend: Backend, members: int | None = None) -> None:
    """Refuse (``runtime.ResourceError``, one line, on every rank) a run whose estimated memory
    exceeds what is available on its device (``Backend.check_memory`` over the ranks of ``comm``:
    each holds its elements, or its members). A run of ``members`` (None: a single run) holds a
    run's arrays a member (its copies of the grid, or a model each)."""
    need = run_bytes(scene.ne, scene.np, scene.stepper, nelem=scene.nelem) * (members or 1)
    what = f"{scene.grid_text} with {scene.stepper}"
    if (members or 1) > 1:
        what = f"an ensemble of {members} members of {what}"
    backend.check_memory(need, what, comm)


def element_unit(
    scene: Scene, backend: Backend, comm, start, initial, graphs: str, per_element=None, threads=None
) -> tuple:
    """(the ``Unit`` of a single run, its digital filter's result or None, (case, topology, whole
    grid, whole hs, whole fcor, scorer)): the one member of ``scene`` on this rank's share of the
    elements over ``comm`` (``config.parts.partition``), started from ``start`` (3 + K, nnodes) on
    rank 0 (``ON_ROOT`` on the others: a restart's), or from the function ``initial`` (lat, lon) ->
    (h, u, v), else from the case's state, then the scene's digital filter and its tracers' masses
    (``cases.tracers.with_tracers``). The whole grid, hs and fcor on rank 0 (None elsewhere).
    ``per_element``, ``threads``: the model's kernel layout and CPU threads (None: the backend's)."""
    case = scene.make_case()
    topo = partition(scene, case, comm, backend, threads)
    local = topo.grid
    grid = topo.whole_grid()  # for diagnostics and output: on rank 0 only
    model = ShallowWater.from_scene(
        scene, local, case, device=backend.device, topology=topo, per_element=per_element, threads=topo.threads
    )
    fcor, hs = model.operators.values("fcor"), model.operators.values("hs")  # the case's, as the model holds them
    whole_fcor, whole_hs = topo.gather(fcor), topo.gather(hs)
    stepper = scene_stepper(scene, model)
    scorer = Scorer(case, model, topo, grid, whole_hs, scene.reference_file)
    dfi = None
    if start is None:
        lat, lon = local.lat, local.lon
        start = np.stack(case.initial(lat, lon)) if initial is None else from_function(initial, lat, lon)
        if scene.digital_filter is not None:
            dfi = digital_filter(
                scene.digital_filter, start, grid=local, terms=scene.terms, fcor=fcor, hs=hs, g=model.g, topology=topo
            )
            start = dfi.x
        start = with_tracers(start, scene.tracer_fields(), local.lat, local.lon)
    else:
        start = topo.distribute(None if start is ON_ROOT else start, model.rows, "start state")
    if topo.comm.rank != 0:  # a fallback's warning once, from rank 0
        model.launches.guard.warn = lambda line: None
    unit = Unit.of(model, stepper, start[None], backend, graphs)
    return unit, dfi, (case, topo, grid, whole_hs, whole_fcor, scorer)


def step_control(scene: Scene, unit: Unit, members: int | None, layout: str, comm) -> StepControl | None:
    """The step control of ``scene`` (``integrator.control.StepControl`` of ``unit``, the first; None
    without): ``members`` (None: a single run) with one Δt for every member, in the same launches,
    on one rank (else ``ArgumentError``: laid out ``layout``, over the ranks of ``comm``)."""
    if scene.control is not None and members and (layout != "shared" or comm is not None):
        where = "over MPI ranks" if comm is not None else "each on a model of its own"
        raise ArgumentError(
            f"scene: its dt is controlled (time.control = {scene.control.mode!r}), which an ensemble takes "
            "with its members in the same launches, one rank (an explicit pair, the members' g and ν alike, "
            f"blow_up 'stop'), not {where}"
        )
    return None if scene.control is None else StepControl(scene.control, unit, scene.start_day)


def shared_unit(scene, case, own, grid: CubedSphere, starts, backend, threads: int, options: dict, graphs: str):
    """([the one ``Unit`` of every held member], the ``MemberGrid`` of their copies, one member's
    model or None): one model of ``scene`` and ``case`` over the copies, its ∇⁴'s substeps from
    one member's operator (the one grid's spectral radius, not the copies'); ``own`` the held
    members' (scene, case) (``Variants``), each member's Coriolis parameter its case's (None:
    ``case``'s)."""
    copies = MemberGrid(grid, len(starts))
    topology = Topology(copies, backend, threads, parts=[copies.elements])
    model = ShallowWater.from_scene(scene, copies, case, **options, topology=topology)
    one = None
    if model.hv is not None and model.hv.nu_max > 0 and len(starts) > 1:
        one = ShallowWater.from_scene(scene, grid, case, **options)  # λ of one member's operator
        model.hv.use_biharmonic_radius(one.hv.biharmonic_radius())
    if own is not None:  # in place: the launches read it
        model.operators.set_fcor(np.concatenate([c.fcor(grid.lat, grid.lon) for _, c in own]))
    return [Unit.of(model, scene_stepper(scene, model), starts, backend, graphs)], copies, one


def own_units(scene, case, own, grid: CubedSphere, starts, backend, threads: int, options: dict, graphs: str) -> tuple:
    """(a ``Unit`` a held member (``starts`` their own, in order; ``own`` their (scene, case),
    None: ``scene`` and ``case``), None, the first one's model), as ``shared_unit``'s: each unit
    its single run's model and stepper on one ``Topology`` of the whole grid; the ∇⁴'s spectral
    radius, a property of the grid alone, found once."""
    topology = Topology(grid, backend, threads, parts=[np.arange(grid.nelem)])
    units, radius = [], None
    for (its_scene, its_case), start in zip(own or [(scene, case)] * len(starts), starts):
        model = ShallowWater.from_scene(its_scene, grid, its_case, **options, topology=topology)
        if model.hv is not None and model.hv.nu_max > 0:  # the first one's, then handed on
            radius = radius or model.hv.biharmonic_radius()
            model.hv.use_biharmonic_radius(radius)
        units.append(Unit.of(model, scene_stepper(its_scene, model), start[None], backend, graphs))
    return units, None, units[0].model


def member_step(unit: Unit, j: int, watch: bool):
    """Step j + 1 of a unit's members: a block's watched as a graph where it may be
    (``GraphedSteps``), a checked step's (a block taken again) launched plainly."""
    return unit.graphed.step(unit.stepper, unit.model, unit.x, True) if watch else unit.stepper.step(unit.x)
