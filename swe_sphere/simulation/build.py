"""A simulation's build: the checks before it, the partition of the grid over the ranks,
the model and stepper of the scene and the start state (the case's, a function's, a digital
filter's or one handed in): ``build``, which returns them to ``Simulation.__init__``."""

from __future__ import annotations

import numpy as np

from ..cases.scoring import Scorer
from ..cases.tracers import with_tracers
from ..config.parts import partition, scene_stepper
from ..config.scene import Scene
from ..core.backend import Backend
from ..core.errors import ResourceError
from ..core.runtime import run_bytes
from ..io.initial_state import from_function
from ..model.shallow_water import ShallowWater
from ..steppers.initialization import digital_filter
from .checkpoint import ON_ROOT


def check_memory(scene: Scene, comm, backend: Backend, members: int = 1) -> None:
    """Refuse (``runtime.ResourceError``, one line, on every rank) a run whose
    estimated memory exceeds what is available on its device (a GPU's free memory,
    else the host's): the whole run on one process; over MPI ranks, the share of
    the ranks on each node, or on CUDA on each GPU (each holds its elements, or an
    ensemble's members; ``Backend.sharing``). An
    ensemble of ``members`` holds a run's arrays a member (its copies of the grid, or a
    model each)."""
    need = run_bytes(scene.ne, scene.np, scene.stepper, nelem=scene.nelem) * members
    what = f"{scene.grid_text} with {scene.stepper}"
    if members > 1:
        what = f"an ensemble of {members} members of {what}"
    if comm is None or comm.size == 1:
        return backend.check_memory(need, what)
    local, where = backend.sharing(comm)  # the ranks whose arrays share this rank's memory
    try:
        backend.check_memory(need * local // comm.size, f"{what} over {comm.size} MPI ranks ({local} {where})")
        error = None
    except ResourceError as err:
        error = str(err)
    errors = [e for e in comm.allgather(error) if e is not None]  # every rank refuses if one node must
    if errors:
        err = ResourceError(errors[0])
        err.on_every_rank = True  # the console script says it once (rank 0), without MPI_Abort
        raise err


def build(scene: Scene, backend: Backend, progress: bool, comm, start, initial) -> tuple:
    """The scene's topology, grid, case, model, stepper, scorer and start state; the arguments as
    ``Simulation``'s. Raises as ``Simulation``.

    Returns what ``Simulation.__init__`` takes as its attributes of the same names (beside its
    scene and backend, and what follows from them), in this order: the case, this rank's part
    of the grid (``topology``), ``root`` (the rank that diagnoses, writes files and shows
    progress), ``progress``, the whole grid on rank 0 (``grid``; None elsewhere), the model, the
    case's fcor and hs gathered (rank 0), the scorer, ``dfi`` (the digital filter's result where
    it ran, else None), the stepper and the start state ``start`` (3 + K, N) on this rank's nodes
    (u, v in m s⁻¹, h in m, the K tracers' masses hq in m: the scene's [tracers]; the integrator's ``Unit.of`` makes it the device state and prepares
    the stepper on it)."""
    check_memory(scene, comm, backend)
    case = scene.make_case()
    topo = partition(scene, case, comm, backend)
    local = topo.grid
    root = topo.comm.rank == 0
    # the whole grid and fields for diagnostics and output: on rank 0 only (None elsewhere)
    grid = topo.whole_grid()
    model = ShallowWater.from_scene(scene, local, case, device=backend.device, topology=topo)
    fcor, hs = model.operators.fcor.numpy(), model.operators.hs.numpy()  # the case's, as the model holds them
    whole_fcor, whole_hs = topo.gather(fcor), topo.gather(hs)
    stepper = scene_stepper(scene, model)
    scorer = Scorer(case, model, topo, grid, whole_hs, scene.reference_file)
    dfi = None
    if start is None:
        if initial is None:
            start = np.stack(case.initial(local.lat, local.lon))
        else:
            start = from_function(initial, local.lat, local.lon)
        if scene.digital_filter is not None:
            dfi = digital_filter(
                scene.digital_filter, start, grid=local, terms=scene.terms, fcor=fcor, hs=hs, g=model.g, topology=topo
            )
            start = dfi.x
        start = with_tracers(start, scene.tracers, local.lat, local.lon)
    else:
        start = topo.distribute(None if start is ON_ROOT else start, model.rows, "start state")
    if not root:  # a fallback's warning once, from rank 0
        model.launches.guard.warn = lambda line: None
    return case, topo, root, progress and root, grid, model, whole_fcor, whole_hs, scorer, dfi, stepper, start
