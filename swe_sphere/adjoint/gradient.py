"""The gradient of a scalar of a run's final state, or of a cost summed over observed steps of
the run (``costs``), with respect to its initial state (``gradient``), by a
checkpointed reverse sweep (``revolve.sweep``, or ``revolve.two_level`` with states on a disk:
``disk.DiskTier``) of its steps' adjoints: each step taken again on a tape and the tape reversed
(``reverse.TapeAdjoint``), at the run's Δt or along a controlled run's steps (``StepTimes``)."""

from __future__ import annotations

import sys
from typing import NamedTuple

import numpy as np
import warp as wp

from ..config.parts import partition, scene_stepper
from ..config.scene import Scene
from ..core.arguments import comm_argument, flag_argument, instance_argument, integer_argument, path_argument
from ..core.backend import Backend, pick_device
from ..core.clock import StepTimes
from ..core.constants import DAY
from ..core.errors import ArgumentError, BlowUp, StepFailure
from ..core.mpi import from_root
from ..integrator.core import Integrator, Observer, Unit, trouble_line
from ..model.shallow_water import ShallowWater
from .costs import checked, run_cost
from .disk import DiskTier
from .reverse import TapeAdjoint
from .revolve import sweep, two_level

f64 = wp.float64


class Gradient(NamedTuple):
    """What ``gradient`` returns (N the whole grid's element-local nodes, over MPI ranks too):
    ``cost`` J; ``grad`` (3, N) rows u, v, h, element-local and continuous, the gradient in the
    mass inner product (δJ = Σ spheremp·grad·δx over the element-local nodes for a continuous
    δx; units of J per m² per unit of the row); ``final`` (3, N) the final state;
    ``forward_steps`` the steps taken forward (the cost's included), ``reverse_steps`` n. With
    ``parameters=True``: ``d_nu`` ∂J/∂ν (the wind's ∇⁴ coefficients ν and ν_div moved together;
    J per m⁴ s⁻¹), ``d_nu_s`` ∂J/∂ν_s (the surface's), ``d_hs`` (N,) ∂J/∂hs in the mass inner
    product as ``grad``, ``d_g`` ∂J/∂g (J per m s⁻²) and ``d_omega`` ∂J/∂Ω (J per s⁻¹; f ∝ Ω),
    x0, hs and a case's forcing held fixed (a balanced initial state is not rebalanced); None
    otherwise. ``disk_bytes``: the states' file's size (``disk=``; 0 without it). ``costs``:
    {k: J_k} the terms of J by observed step k (a final-state cost: {n: J}); J is their sum in
    increasing k."""

    cost: float
    grad: np.ndarray
    final: np.ndarray
    forward_steps: int
    reverse_steps: int
    d_nu: float | None = None
    d_nu_s: float | None = None
    d_hs: np.ndarray | None = None
    d_g: float | None = None
    d_omega: float | None = None
    disk_bytes: int = 0
    costs: dict | None = None


class _Topography:
    """``case`` with its surface height replaced by ``hs`` (N,) at the grid's nodes."""

    def __init__(self, case, hs):
        self.case, self._hs = case, hs

    def hs(self, lat, lon):
        return self._hs

    def __getattr__(self, name):
        return getattr(self.case, name)


def scene_model(scene: Scene, device: str = "cpu", hs=None, comm=None):
    """(model, stepper, x0) of ``scene`` on this rank's part of its grid (``comm`` an mpi4py
    communicator; None: one process, the whole grid), as a run makes them (``config.parts``):
    its ``ShallowWater`` (``model.topology`` assembles the ranks' parts), its stepper (at the
    scene's Δt, under no step control) and its case's initial state (3, N) numpy on this rank's
    nodes; ``hs`` (nnodes_total,) m: the whole grid's surface height instead of the case's (read
    on rank 0). Stepped by ``stepper.step(x)`` (x0 as a float64 Warp array on the device) it is the
    scene's run to the bit (``Stepper.advance`` does not count the step, on which the ∇⁴ every k
    steps and the model time depend). ``ArgumentError`` for a scene in float32 (``Scene.precision``: gradients stay
    float64), a stepper without a gradient (not ``differentiable``) or hs of another shape or not
    finite (on every rank); ``SceneError`` for a ν the ∇⁴ cannot step."""
    if scene.precision != "float64":
        raise ArgumentError(
            f"scene.precision = {scene.precision!r}: gradients stay float64 (the adjoint transposes the "
            'float64 tendency); give the scene numerics.precision = "float64"'
        )
    case = scene.make_case()
    topo = partition(scene, case, comm, Backend.of(device))
    if hs is not None:
        case = _Topography(case, topo.distribute(hs if topo.comm.rank == 0 else None, 1, "hs")[0])
    model = ShallowWater.from_scene(scene, topo.grid, case, device=topo.backend.device, topology=topo)
    stepper = scene_stepper(scene, model)
    if not stepper.differentiable:
        raise ArgumentError(
            f"scene.stepper = {scene.stepper!r} has no gradient: gradients need an explicit stepper, one that "
            "solves with L (semi_implicit, an IMEX table), split_explicit, mri or lts"
        )
    return model, stepper, np.stack(case.initial(topo.grid.lat, topo.grid.lon))


def step_adjoint(model: ShallowWater, stepper, parameters: bool = False) -> TapeAdjoint:
    """The adjoint of one step of ``stepper`` (one with a gradient: ``differentiable``) on ``model``,
    its steps from the stepper's ``t0``. ``ArgumentError`` as ``TapeAdjoint``'s."""
    return TapeAdjoint(model, stepper, stepper.dt, parameters, stepper.t0)


def gradient(
    scene: Scene,
    steps: int,
    cost,
    *,
    x0=None,
    snapshots: int | None = None,
    parameters: bool = False,
    hs=None,
    disk=None,
    disk_interval: int | None = None,
    device=None,
    comm=None,
    history=None,
) -> Gradient:
    """The cost J of ``scene`` run ``steps`` steps from x0, J(x(n)) or Σ_k J_k(x(k)) over the
    steps k a cost observes, and its gradient dJ/dx(0) (and, with ``parameters``, dJ/dν,
    dJ/dν_s, dJ/dhs, dJ/dg and dJ/dΩ).

    Parameters
    ----------
    scene : a ``config.Scene`` whose stepper has a gradient (``differentiable``: every explicit
        one, those that solve with L, split_explicit, mri, lts), any terms (a time-dependent
        forcing's stages at their times, from the scene's ``start_day``), any ∇⁴.
    steps : n ≥ 1 steps of the scene's Δt (or of ``history``).
    cost : callable (x, spheremp) → (J, λ) of the final state, x (3, N) numpy rows u, v, h
        (m s⁻¹, m s⁻¹, m), spheremp (N,) m², λ = ∂J/∂x (3, N) over the element-local entries
        (e.g. ``HeightMisfit``); or a cost of the run: an object with ``at_steps`` (the steps
        0 ≤ k ≤ n it observes) called as ``cost(k, x, spheremp)`` → (J_k, λ_k) at x = x(k) (read
        only; e.g. ``HeightObservations``), once a k.
    x0 : (3, N) initial state (None: the case's); with ``comm``, N the whole grid's
        (nnodes_total), read on rank 0.
    snapshots : states held at once during the reverse sweep, x(0) included (None: n, each
        step taken forward once); fewer cost ``revolve.griewank_steps(n, snapshots)`` + 1
        forward steps in all (Griewank & Walther 2000), the same bits (a semi-implicit or IMEX
        step's: to its CG's ``tol``, a recomputed solve starting from later guesses).
    parameters : also the ∇⁴ coefficients', the topography's and g's and Ω's gradients (an extra
        ∇⁴ substep a step reversed, per stage one RHS of the pressure gradient and topography
        and a host-side sum); not with a stepper that solves with L (its L holds g and H).
    hs : (N,) surface height (m), element-local and continuous, instead of the case's (as x0).
    disk : None (every state the sweep holds in memory), True (a second tier: a file in
        ``tempfile.gettempdir()``, on some systems memory) or a folder for it. A first forward
        pass writes x(0), x(K), x(2K), … there (⌈n/K⌉ states of 3·N·8 bytes,
        ``Gradient.disk_bytes``); each segment of K steps, last first, is read back and reversed
        with ``snapshots`` states in memory: ``revolve.two_level_steps(n, snapshots, K)``
        forward steps, 2n − ⌈n/K⌉ where K ≤ snapshots, the same bits. The file has no name in
        the folder and is gone when ``gradient`` returns or raises.
    disk_interval : K ≥ 1, the steps between the states written (None: ``snapshots``).
    device : "cpu", "cuda" or "cuda:N"; None: a ``Simulation``'s default
        (``core.backend.pick_device``).
    history : a run's steps, required for a scene under ``time.control``: that run's
        ``Simulation.control.history``, of which the first n are differentiated with their Δt and
        times held (``StepTimes``): the gradient of the run the controller took, not of its
        choice of Δt (piecewise constant in x(0)).
    comm : an mpi4py communicator (None: one process): the run and its sweep split over its
        ranks as a ``Simulation``'s, every rank calling ``gradient`` alike. The cost is called on
        rank 0 alone, with the whole grid's x and spheremp (N = nnodes_total, in the one-rank
        order), its λ handed back to the ranks; every rank returns the whole-grid ``Gradient``,
        the same bits on any number of ranks. With ``disk``, each rank writes its own part.

    Returns
    -------
    Gradient

    Raises
    ------
    ArgumentError
        (a ValueError; one line naming the argument) for a scene that is not a ``Scene``,
        steps, snapshots or disk_interval not integers ≥ 1, a cost that is not callable, does not
        fit the grid (``check_nodes``), returns other than (J, λ (3, N)) or a non-finite J,
        at_steps outside 0 … n, a controlled scene without a history, a history shorter than n or
        with a bad step, a disk_interval without a disk, a disk that is not an existing folder, a
        scene in float32 (gradients stay float64), x0 or hs of another shape or not finite, x0's
        h ≤ 0 where it is a depth, ``parameters`` not a bool or True with a stepper that solves
        with L, ``comm`` not a communicator, or a scene the adjoint cannot serve
        (``reverse.refusal``; the JFNK implicit, an exponential stepper).
    SceneError
        For another device.
    BlowUp
        Where a state of the run goes bad (non-finite, or h ≤ 0 with a pressure gradient),
        naming its step, model time and place, as a run's.
    OSError
        From the disk.
    StepFailure
        Where a solve, recomputed or transposed, misses its ``tol`` within ``maxiter``.

    Notes
    -----
    Sources: the model's transposes (``model.transposes``) on a tape of each step (``tape``,
    ``reverse``); checkpointing by Griewank & Walther (2000), ACM TOMS 26:19, in two levels by
    Stumm & Walther (2009), SIAM J. Sci. Comput. 31:1946.
    """
    instance_argument("scene", scene, Scene, "a Scene (swe_sphere.load_scene(...))")
    steps = integer_argument("steps", steps, 1)
    snapshots = steps if snapshots is None else integer_argument("snapshots", snapshots, 1)
    cost = run_cost(cost, steps)
    parameters = flag_argument("parameters", parameters)
    disk = None if disk is False else disk
    if disk is not None and disk is not True:
        path_argument("disk", disk, "None, True or an existing folder's path")
    interval = snapshots if disk_interval is None else integer_argument("disk_interval", disk_interval, 1)
    if disk_interval is not None and disk is None:
        raise ArgumentError(f"disk_interval needs a disk (got disk_interval={interval!r}, disk=None)")
    comm_argument("comm", comm)
    if history is None and scene.control is not None:
        raise ArgumentError(
            f"a run under time.control = {scene.control.mode!r} is differentiated along the steps it took: "
            "give history=Simulation(...).control.history of that run"
        )
    clock = StepTimes(scene.start_day * DAY, scene.dt, history)
    if clock.steps is not None and len(clock.steps) < steps:
        raise ArgumentError(f"history holds {len(clock.steps)} steps, fewer than the {steps} asked for")
    model, stepper, initial = scene_model(scene, pick_device(device, comm=comm), hs, comm)
    topo = model.topology
    getattr(cost, "check_nodes", lambda n: None)(topo.nnodes_total)  # h_obs's grid, before the run
    if x0 is not None:
        x0 = topo.distribute(x0 if topo.comm.rank == 0 else None, 3, "x0")
        if "pressure_gradient" in model.terms and (low := -topo.max(-float(x0[2].min()))) <= 0:  # a depth
            raise ArgumentError(f"x0: its depth h is <= 0 somewhere (min {low:.4g} m)")
    work = wp.array(initial if x0 is None else x0, dtype=f64, device=topo.device)  # the stepper steps this array only
    stepper.prepare(work)  # from x(0): lts fixes its levels by its flow
    adjoint = step_adjoint(model, stepper, parameters)
    found, mu, taken, used = _reverse_run(model, stepper, adjoint, clock, work, steps, cost, snapshots, disk, interval)
    extra = {}
    if parameters:
        d_g, d_omega = adjoint.d_planet / [model.g, scene.make_case().planet.omega]  # Ω > 0 (``Planet``)
        extra = dict(d_nu=adjoint.d_nu[0], d_nu_s=adjoint.d_nu[1], d_hs=adjoint.hs_gradient(), d_g=d_g, d_omega=d_omega)
        extra["d_hs"] = topo.bcast(topo.gather(extra["d_hs"]))
    costs = dict(sorted(found["costs"].items()))  # J their sum in increasing k (a final-state cost's: 0 + J)
    final, mu = (topo.bcast(topo.gather(a)) for a in (found["final"], mu))  # the whole grid's, on every rank
    return Gradient(sum(costs.values()), mu, final, taken, steps, disk_bytes=used, costs=costs, **extra)


class _Sweep(Observer):
    """A sweep's advance as one block (the integrator's Δt policy and its observer): each step
    at the run's Δt and model time (``times``, a ``core.clock.StepTimes``: step j's (t0_j, Δt_j)
    and phase j set first), its states checked where not yet (``verified``: the steps checked so
    far; a recomputation's are not checked again), put back by loading its start, the state
    ``x`` it advances, into the stepper's arrays (``pairs(x)``: (array, x's rows)): the sweep
    holds it, so nothing is kept."""

    def __init__(self, times, pairs):
        self.times, self.pairs, self.x, self.verified = times, pairs, None, 0

    def take(self, unit: Unit, j: int, watch: bool) -> None:
        """x(j) to x(j + 1) in the stepper's arrays, watched where not yet checked."""
        self.times.set(unit.stepper, j)
        unit.stepper.set_phase(j)  # its clock, t0_j + (j + c)·Δt_j at each stage as the run's
        unit.stepper.step(unit.x)
        if watch and j >= self.verified:
            unit.model.bad_nodes.watch(unit.x)

    def block_end(self, b: int) -> int:
        return sys.maxsize  # the advance's end (``Integrator.advance``'s stop step)

    def checked(self, b: int, e: int) -> bool:
        return e > self.verified

    def keep(self, active: list, whole: bool) -> None:
        """Nothing: the sweep holds the block's start (``x``)."""

    def put_back(self, active: list, saved: dict) -> None:
        for a, held in self.pairs(self.x):
            wp.copy(a, held)


def _reverse_run(model, stepper, adjoint, clock, work, steps, cost, snapshots, disk, interval):
    """({"costs": {k: J_k}, "final": x(n)}, μ(0) numpy, forward steps, disk bytes) of
    ``gradient``: the run from x0 = ``work`` (3, N), the array the prepared stepper steps, and its
    reverse sweep, in memory or with a disk tier; ``cost`` a cost of the run (``run_cost``),
    called once at each of its steps. Every step, recomputed or reversed, runs at its Δt and
    model time (``clock``: a time-dependent forcing's). A stepper that carries arrays from step
    to step (its ``carried_arrays``: leapfrog's x̃(k−1), MRAB3's histories) has them in its
    states' and adjoints' rows after x's, the cost reading rows 0–2."""
    topo, rows, X = model.topology, 3 * (1 + len(stepper.carried_arrays())), slice(0, 3)

    def pairs(x):  # (the stepper's array, x's rows): x's, then ``carried_arrays``' in their order now
        return [(work, x[X]), *((a, x[3 * i + 3 : 3 * i + 6]) for i, a in enumerate(stepper.carried_arrays()))]

    forward = _Sweep(clock, pairs)  # each step at the run's Δt and model time (``clock``)
    core = Integrator([Unit(model, stepper, work, work, None)], forward, lone=False)

    def advance(x, k, m=1):  # x = x(k) to x(k + m) in place by the integrator (returned): one block, checked once
        core.step, forward.x = k, x
        forward.put_back([], {})  # the stepper's arrays from x's rows
        stop = core.advance(k + m, forward)
        if stop.bad is not None:
            j, trouble, detail = stop.bad
            if trouble == "failure":
                raise StepFailure(detail)
            t0, dt = clock(j - 1)
            raise BlowUp(trouble_line(model, work, stop.bad, (t0 + j * dt) / DAY, " of the gradient's run"))
        forward.verified = max(forward.verified, k + m)
        for a, held in pairs(x):
            wp.copy(held, a)
        return x

    mu = wp.zeros((rows, topo.N), dtype=f64, device=topo.device)
    found, observed = {"costs": {}}, set(cost.at_steps)
    lam = wp.zeros((3, topo.N), dtype=f64, device=topo.device)
    add = topo.dss_update(lam, [(mu[X], ((1.0, mu[X]), (1.0, None)))], weighted=False)  # μ += R Q λ
    spheremp = topo.gather(topo.grid.spheremp)  # the whole grid's on rank 0 (None elsewhere)

    def observe(x, k):  # J_k at x(k) into found, μ += R Q λ_k: the cost on rank 0, the whole grid
        whole = topo.gather(np.array(x.numpy()[X]))
        J, lam_k = from_root(topo.comm, lambda: checked(cost, k, whole, spheremp), ArgumentError) or (None, None)
        found["costs"][k] = topo.bcast(J)
        lam.assign(topo.distribute(None if lam_k is None else np.asarray(lam_k, dtype=float), 3, "the cost's λ"))
        for launch in add:
            launch.launch()

    def finish(x):  # J_n at x(n) and μ = R Q λ_n there (0 where n is not observed)
        found["final"] = x.numpy()[X]
        if steps in observed:
            observe(x, steps)

    def reverse(x, k):
        if "final" not in found:  # in memory alone, x(n) is one step on from the first reversed
            finish(advance(wp.clone(x), k))
        clock.set(adjoint, k)
        adjoint.reverse(x, mu, k)
        if k in observed:  # μ(k) += R Q λ_k, x(k) at hand
            observe(x, k)

    x, used = wp.zeros((rows, topo.N), dtype=f64, device=topo.device), 0
    wp.copy(x[X], work)  # x̃(−1) is not read: the three-level schemes' first step is a midpoint step
    if disk is None:
        taken = 1 + sweep(steps, snapshots, x, advance, reverse, wp.clone)
    else:
        with DiskTier(disk, (rows, topo.N), topo.device) as tier:
            taken = two_level(steps, snapshots, interval, x, advance, reverse, wp.clone, tier, finish)
            used = tier.bytes
    return found, mu.numpy()[X], taken, used
