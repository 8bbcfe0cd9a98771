"""What a scene makes of itself on a rank: the part of its grid (``partition``), its model
(``ShallowWater.from_scene``) and its stepper (``scene_stepper``, after ``check_hyperviscosity``).
One path for a run (``members.units.element_unit``) and a gradient (``adjoint.gradient.scene_model``), so a
gradient is taken of the model and stepper a run steps."""

from __future__ import annotations

from ..core.backend import Backend
from ..core.constants import DAY
from ..core.errors import SceneError
from ..grid.cubed_sphere import CubedSphere
from ..grid.topology import Topology, on_ranks
from ..model.shallow_water import ShallowWater
from ..steppers import STEPPERS, make_stepper
from ..steppers.butcher import real_axis_limit
from .resolve import refuse_precision
from .scene import Scene

MAX_HYPERVIS_EVALUATIONS = 10_000  # ∇⁴ evaluations a step; beyond, ν is ~10⁷ times its explicit bound or more


def check_hyperviscosity(model: ShallowWater, scene: Scene) -> None:
    """Refuse (``SceneError``, before the run) a ν whose ∇⁴ sub-stepping
    (``hypervis.Hyperviscosity.plan``) would take more than
    ``MAX_HYPERVIS_EVALUATIONS`` evaluations a step: such a step runs for hours
    and is a mistyped coefficient, not a setting."""
    if model.hv is None or model.hv.nu_max == 0.0:
        return
    hv = model.hv
    evals, _ = hv.plan(scene.dt)
    if evals > MAX_HYPERVIS_EVALUATIONS:
        bound = 1.5 / (scene.dt * hv.biharmonic_radius())
        raise SceneError(
            f"hyperviscosity nu = {hv.nu_max:.3g} m^4/s is {hv.nu_max / bound:.2g}x its explicit bound "
            f"({bound:.3g} m^4/s at dt = {scene.dt:g} s): {evals:.3g} ∇⁴ evaluations a step (at most "
            f"{MAX_HYPERVIS_EVALUATIONS}); lower hyperviscosity.nu"
        )


def check_stage_hyperviscosity(model: ShallowWater, stepper, dt: float) -> None:
    """Refuse (``SceneError``, before the run) ν_s in the stages (``tracers.stage_hyperviscosity``)
    past ``stepper``'s stability on the negative real axis: there its stages step −ν_s ∇⁴
    explicitly, at ν_s Δt λ (λ ``biharmonic_radius``), which ``butcher.real_axis_limit`` of its table
    bounds (the split ∇⁴ would take substeps instead). Only an explicit Runge–Kutta stepper carries
    tracers (``tracers_refusal``): ``stepper.table()``."""
    if not model.stage_hyperviscosity or model.nu_s == 0.0:
        return
    table = stepper.table()
    limit = real_axis_limit(table.A_E, table.b_E)
    stiffness = model.nu_s * dt * model.hv.biharmonic_radius()
    if stiffness > limit:
        raise SceneError(
            f"tracers.stage_hyperviscosity = true: nu_s dt λ = {stiffness:.3g} (nu_s = {model.nu_s:.3g} m^4/s on this grid, "
            f"dt = {dt:g} s) is past {stepper.name}'s stable {limit:.3g} on the negative real axis; "
            "lower hyperviscosity.nu_s or dt, or set it false (the ∇⁴ split after each step)"
        )


def scene_stepper(scene: Scene, model: ShallowWater):
    """The scene's stepper on ``model`` at the scene's Δt, its clock at the scene's start
    day (not yet ``prepare``d); ``SceneError`` first for a stepper that cannot step the scene's
    precision (``refuse_precision``: a ``Scene`` changed by ``dataclasses.replace`` too), a
    ν the ∇⁴ cannot step (``check_hyperviscosity``) and ν_s in the stages past the stepper's
    stability (``check_stage_hyperviscosity``)."""
    refuse_precision(scene.precision, scene.stepper, scene.stepper_options)
    check_hyperviscosity(model, scene)
    stepper = make_stepper(scene.stepper, model, scene.dt, **scene.stepper_options)
    check_stage_hyperviscosity(model, stepper, scene.dt)
    stepper.t0 = scene.start_day * DAY
    return stepper


def partition(scene: Scene, case, comm, backend: Backend, threads: int | None = None) -> Topology:
    """This rank's part of the scene's grid, assembled over ``comm``'s ranks (None: one
    process): the elements of ``topology.rank_parts``, by the stepper's element levels where
    its work goes by levels (lts; decided on rank 0 from the whole grid and broadcast), its
    launches split over ``threads`` CPU threads (None: ``Backend.threads``)."""
    size, rank = (1, 0) if comm is None else (comm.size, comm.rank)
    mesh = scene.make_mesh()  # None: the equiangular cube
    level = None
    if size > 1:
        whole = lambda: CubedSphere(scene.ne, scene.np, case.planet.a, mesh=mesh)  # noqa: E731
        mine = STEPPERS[scene.stepper].partition_levels(whole, scene.stepper_options) if rank == 0 else None
        level = comm.bcast(mine, root=0)
    # the halos carry a state's rows, a tracer's mass each among them
    rows = 3 + len(scene.tracers)
    return on_ranks(scene.ne, scene.np, case.planet.a, comm, backend, mesh, level, rows=rows, threads=threads)
