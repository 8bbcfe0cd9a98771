"""The gradient of a scalar of a run's final state, or of a cost summed over observed steps of
the run (``observations``), with respect to its initial state (``gradient``), by a
checkpointed reverse sweep (``revolve.sweep``, or ``revolve.two_level`` with states on a disk:
``disk.DiskTier``) of its steps' adjoints: each step taken again on a tape and the tape reversed
(``reverse.TapeAdjoint``), at the run's Δt or along a controlled run's
steps (``StepTimes``)."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import warp as wp

from ..config.parts import partition, scene_stepper
from ..config.scene import Scene
from ..core.arguments import (
    array_argument,
    callable_argument,
    comm_argument,
    flag_argument,
    instance_argument,
    integer_argument,
    path_argument,
)
from ..core.backend import Backend, pick_device
from ..core.constants import DAY
from ..core.errors import ArgumentError
from ..model.shallow_water import ShallowWater
from .disk import DiskTier
from .reverse import TapeAdjoint
from .revolve import sweep, two_level
from .sums import refusal

f64 = wp.float64


class HeightMisfit:
    """J(x) = ½ Σ spheremp (h − h_obs)² over the element-local nodes (m⁴: the area integral
    ½ ∫ (h − h_obs)² dA of a continuous h), with ``h_obs`` a number or (N,) element-local, m
    (N the whole grid's element-local nodes, ``gradient``'s). ``__call__(x, spheremp)``: (J, λ)
    for x (3, N) numpy rows u, v, h; λ = ∂J/∂x (3, N). ``ArgumentError`` naming ``h_obs`` for
    anything but finite numbers of those shapes (``gradient`` checks N before it runs:
    ``check_nodes``)."""

    def __init__(self, h_obs):
        self.h_obs = array_argument("h_obs", h_obs, unit="m")
        if self.h_obs.ndim > 1:
            raise ArgumentError(f"h_obs must be a number or have shape (N,) (got {self.h_obs.shape})")

    def check_nodes(self, n: int) -> None:
        """Refuse (``ArgumentError``) an ``h_obs`` of another length than the grid's ``n`` nodes."""
        if self.h_obs.ndim == 1 and self.h_obs.shape != (n,):
            raise ArgumentError(
                f"h_obs must be a number or have shape ({n},), the grid's element-local nodes (got {self.h_obs.shape})"
            )

    def __call__(self, x, spheremp):
        self.check_nodes(np.shape(x)[-1])
        r = x[2] - self.h_obs
        lam = np.zeros_like(x)
        lam[2] = spheremp * r
        return 0.5 * float(np.sum(spheremp * r * r)), lam


class Gradient(NamedTuple):
    """What ``gradient`` returns (N the whole grid's element-local nodes, over MPI ranks too):
    ``cost`` J; ``grad`` (3, N) rows u, v, h, element-local and
    continuous, the gradient in the mass inner product (δJ = Σ spheremp·grad·δx over the
    element-local nodes for a continuous δx; units of J per m² per unit of the row);
    ``final`` (3, N) the final state; ``forward_steps`` the steps taken forward (the cost's
    included), ``reverse_steps`` n. With ``parameters=True``: ``d_nu`` ∂J/∂ν (the wind's
    ∇⁴ coefficients ν and ν_div moved together; J per m⁴ s⁻¹), ``d_nu_s`` ∂J/∂ν_s (the surface's), ``d_hs`` (N,)
    ∂J/∂hs in the mass inner product as ``grad`` (x0 held fixed), ``d_g`` ∂J/∂g (J per m s⁻²) and
    ``d_omega`` ∂J/∂Ω (J per s⁻¹; the Coriolis parameter f ∝ Ω), x0, hs and a case's forcing
    held fixed (a balanced initial state is not rebalanced); None otherwise.
    ``disk_bytes``: the size of the states' file on the disk (``disk=``; 0 without it).
    ``costs``: {k: J_k} the terms of J by observed step k (a cost with ``at_steps``; a final-state
    cost: {n: J}); J is their sum in increasing k."""

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


class _FinalCost:
    """A final-state cost (x, spheremp) → (J, λ) as a cost of the run observed at step n alone."""

    def __init__(self, cost, n: int):
        self.cost, self.at_steps = cost, (n,)

    def check_nodes(self, n: int) -> None:
        if hasattr(self.cost, "check_nodes"):
            self.cost.check_nodes(n)

    def __call__(self, k, x, spheremp):
        return self.cost(x, spheremp)


def run_cost(cost, steps: int):
    """``cost`` as a cost of the run: one with ``at_steps`` as it is (its steps checked), any
    other callable as that of the final state x(n). ``ArgumentError`` for a cost that is neither,
    no steps, or one outside 0 … ``steps`` or not an integer."""
    if not hasattr(cost, "at_steps"):
        return _FinalCost(callable_argument("cost", cost, _COST), steps)
    callable_argument("cost", cost, _COST)
    try:
        at = list(cost.at_steps)
    except TypeError:
        at = None
    if not at or any(isinstance(k, bool) or not isinstance(k, (int, np.integer)) or not 0 <= k <= steps for k in at):
        raise ArgumentError(
            f"cost.at_steps must be integers in 0 … {steps} (got {at if at is not None else cost.at_steps!r})"
        )
    return cost


_COST = "a callable (x, spheremp) -> (J, λ), or a cost of the run with at_steps (HeightObservations)"


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
    communicator; None: one process, the whole grid): its ``ShallowWater`` (``model.topology``
    assembles the ranks' parts), its stepper (at the scene's Δt, under no step control) and its
    case's initial state (3, N) numpy on this rank's nodes; ``hs`` (nnodes_total,) m: the whole
    grid's surface height instead of the case's (read on rank 0). ``ArgumentError`` unless the
    stepper has an adjoint (``step_adjoint``: not the JFNK ``implicit`` nor an exponential stepper), or
    for hs of another shape (on every rank);
    ``SceneError`` for a ν the ∇⁴ cannot step (``config.parts.scene_stepper``, as a run)."""
    case = scene.make_case()
    topo = partition(scene, case, comm, Backend.of(device))  # as a run's (``simulation.build``)
    grid = topo.grid
    if hs is not None:
        hs = _distributed(topo, hs, 1, "hs")[0]
    case = case if hs is None else _Topography(case, hs)
    # the model's arrays on the device its topology launches on (issue 83: they were the CPU's)
    model = ShallowWater.from_scene(scene, grid, case, device=topo.backend.device, topology=topo)
    stepper = scene_stepper(scene, model)
    if not has_gradient(stepper):
        raise ArgumentError(
            f"gradients need an explicit stepper (a Runge–Kutta table built in or a tableau, fbrk32, leapfrog, "
            f"leapfrog_trapezoidal), one that solves with L (semi_implicit, an IMEX table: imex, ark324, ark436, "
            f"a tableau) or one of {', '.join(sorted(TAPED))} "
            f"(got scene.stepper = {scene.stepper!r})"
        )
    return model, stepper, np.stack(case.initial(grid.lat, grid.lon))


class StepTimes:
    """The steps' Δt and model times: step k (from x(k)) takes Δt_k, its stages at
    t0_k + (k + c)·Δt_k (a stepper's ``_at`` with ``t0`` and ``steps`` = k), as the run took them.
    Fixed (``history`` None): Δt_k = ``dt``, t0_k = ``start`` (s). Otherwise ``history`` a
    controlled run's accepted steps from ``start`` (``StepControl.history``: (time reached (s),
    Δt (s), error norm) each): Δt_k its k-th Δt, t0_k = t_k − k·Δt_k with t_k the time step k
    started at (``StepControl.step`` sets the stepper's clock so). ``ArgumentError`` for rows
    that are not numbers, a Δt that is not a positive finite number or times that do not
    increase, naming the step."""

    def __init__(self, start: float, dt: float, history=None):
        self.start, self.dt, self.steps = float(start), float(dt), None
        if history is None:
            return
        try:
            rows = [tuple(map(float, row[:2])) for row in history]
        except (TypeError, ValueError, IndexError):
            raise ArgumentError(
                f"history must be rows (time reached (s), dt (s), ...), a run's control.history (got {history!r:.60})"
            ) from None
        if any(len(row) < 2 for row in rows):
            raise ArgumentError("history must be rows (time reached (s), dt (s), ...), a run's control.history")
        t = self.start
        for k, (reached, step) in enumerate(rows):
            if not (np.isfinite(step) and step > 0 and np.isfinite(reached) and reached > t):
                raise ArgumentError(
                    f"history step {k}: dt {step!r} s must be > 0 and its time {reached!r} s after {t!r}"
                )
            t = reached
        starts = [self.start, *(reached for reached, _ in rows[:-1])]
        self.steps = [(t - k * step, step) for k, (t, (_, step)) in enumerate(zip(starts, rows))]

    def __call__(self, k: int) -> tuple[float, float]:
        """(t0_k, Δt_k) of step k."""
        return (self.start, self.dt) if self.steps is None else self.steps[k]

    def set(self, stepper, k: int) -> None:
        """``stepper`` (or an adjoint: ``set_dt``, ``t0``) at step k's Δt and clock."""
        t0, dt = self(k)
        if dt != stepper.dt:  # a three-level stepper keeps one Δt; a controlled run's change step to step
            stepper.set_dt(dt)
        stepper.t0 = t0


# the steppers, besides the explicit ones and those that solve with L, whose steps the tape reads
# (``reverse.TapeAdjoint``), by their registered names (``steppers.STEPPERS``)
TAPED = ("split_explicit", "mri", "lts")


def has_gradient(stepper) -> bool:
    """Whether ``stepper``'s steps have an adjoint (``reverse.TapeAdjoint``): every explicit stepper
    (every explicit Runge–Kutta table built in or a ``tableau``, fbrk32, leapfrog,
    leapfrog_trapezoidal), any that solves with L (semi_implicit, imex, ark324, ark436, an IMEX
    ``tableau``) and ``TAPED``'s; not the JFNK ``implicit`` nor an exponential stepper."""
    return stepper.explicit or getattr(stepper, "linear", None) is not None or stepper.name in TAPED


def step_adjoint(model: ShallowWater, stepper, parameters: bool = False) -> TapeAdjoint:
    """The adjoint of one step of ``stepper`` (one with a gradient: ``has_gradient``) on ``model``,
    its steps from the stepper's ``t0``. ``ArgumentError`` as ``TapeAdjoint``'s."""
    return TapeAdjoint(model, stepper, stepper.dt, parameters, stepper.t0)


def _on_root(topo, check):
    """``check()`` on rank 0, its ``ArgumentError`` raised on every rank (the others wait for it)."""
    refusal, value = None, None
    if topo.comm.rank == 0:
        try:
            value = check()
        except ArgumentError as err:
            refusal = str(err)
    refusal = topo.bcast(refusal)
    if refusal is not None:
        raise ArgumentError(refusal)
    return value


def _distributed(topo, whole, rows: int, name: str) -> np.ndarray:
    """This rank's part (rows, N) of the whole-grid field ``whole`` ((nnodes_total,) where
    rows is 1, else (rows, nnodes_total); read on rank 0). ``ArgumentError`` on every rank for
    another shape ("<name> must have shape S (got T)") or a NaN or an infinity."""
    want = (topo.nnodes_total,) if rows == 1 else (rows, topo.nnodes_total)
    whole = _on_root(topo, lambda: array_argument(name, whole, want))
    return topo.distribute(None if whole is None else np.reshape(whole, (rows, -1)), rows, name)


def _whole(topo, a: np.ndarray) -> np.ndarray:
    """The whole-grid field of every rank's part ``a`` (…, N), on every rank (``a`` itself on one)."""
    return topo.bcast(topo.gather(a))


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
    scene : a ``config.Scene`` whose stepper is an explicit Runge–Kutta table (ssprk3, rk4,
        kgu35, the pairs, a tableau), fbrk32, leapfrog, leapfrog_trapezoidal, split_explicit,
        mri, lts (a multirate table or MRAB3), semi_implicit, imex, ark324, ark436 or an IMEX
        tableau (``step_adjoint``), any terms (a time-dependent
        forcing's stages at their times, from the scene's ``start_day``), a ∇⁴ constant or
        tensor, ν_div = ν or not.
    steps : n ≥ 1 steps of the scene's Δt (or of ``history``).
    cost : callable (x, spheremp) → (J, λ) of the final state, x (3, N) numpy rows u, v, h
        (m s⁻¹, m s⁻¹, m), spheremp (N,) m², λ = ∂J/∂x (3, N) over the element-local entries
        (e.g. ``HeightMisfit``); or a cost of the run: an object with ``at_steps`` (the step
        indices k, 0 ≤ k ≤ n, it observes) called as ``cost(k, x, spheremp)`` → (J_k, λ_k) at
        x = x(k) (read only; e.g. ``HeightObservations``), once a k in any mode (the reverse
        sweep's, x(k) at hand: R Q λ_k added to the adjoint once step k is reversed).
    x0 : (3, N) initial state (None: the case's); with ``comm``, N the whole grid's
        (nnodes_total), read on rank 0.
    snapshots : states held at once during the reverse sweep, x(0) included (None: n, every
        state, each step taken forward once); fewer cost ``revolve.forward_steps(n,
        snapshots − 1)`` + 1 forward steps in all (Griewank & Walther 2000), the same bits
        (semi_implicit's and the IMEX pairs': the same to their CG's ``tol``, a recomputed step's CG starting from
        the stepper's later guesses).
    parameters : also the ∇⁴ coefficients', the topography's and the planet's gravity and
        rotation rate's gradients (an extra ∇⁴ substep a step reversed, and per stage one RHS of
        the pressure gradient and topography and a host-side sum); not with semi_implicit nor
        the IMEX pairs (their L holds g and H).
    hs : (N,) surface height (m), element-local and continuous, instead of the case's (as x0).
    disk : None (every state the sweep holds in memory), True (a second tier: a file in
        ``tempfile.gettempdir()``, on some systems tmpfs, i.e. memory) or a folder (str or path) for it. A first forward pass
        writes x(0), x(K), x(2K), … there, ⌈n/K⌉ states of 3·N·8 bytes (``Gradient.disk_bytes``:
        the tier grows as n/K while memory stays at ``snapshots`` states); each segment of K
        steps, last first, is then read back and reversed as above with ``snapshots`` states
        in memory: ``revolve.two_level_steps(n, snapshots, K)`` forward steps in all, 2n −
        ⌈n/K⌉ where K ≤ snapshots (each step taken forward about twice), the same bits. The
        file has no name in the folder and is gone when ``gradient`` returns or raises.
    disk_interval : K ≥ 1, the steps between the states written (None: ``snapshots``, the
        most that reverses a segment with every state held; 1: every state on the disk, each
        step taken forward once).
    device : "cpu", "cuda" or "cuda:N"; None: a ``Simulation``'s default (``SWE_SPHERE_DEVICE``
        where set, else CUDA when present, else the CPU: ``core.backend.pick_device``). Its
        per-node transposes are checked against the CPU's element kernels on the CPU; the whole on
        a GPU by ``tests/adjoint``'s CUDA test.
    history : a run's steps (required for a scene under ``time.control``, whose steps its
        controller chose): that run's ``Simulation.control.history`` (``StepControl.history``:
        (time reached (s), Δt (s), error norm) per accepted step, from the scene's start), of
        which the first n are differentiated with their Δt and times held (``StepTimes``): the
        gradient of the run the controller took, not of the controller's choice of Δt (piecewise
        constant in x(0)). The scene's stepper, without the control, takes each step.
    comm : an mpi4py communicator (None: one process): the run and its reverse sweep split
        over its ranks as a ``Simulation``'s (``config.parts.partition``), every rank calling
        ``gradient`` alike. The cost is called on rank 0 alone, with the whole grid's x and
        spheremp (N = nnodes_total, the element-local nodes in the one-rank order), its λ
        handed back to the ranks; every rank returns the whole-grid ``Gradient``, the same
        bits on any number of ranks (the forward's DSS sums its copies in one global order;
        ∂J/∂ν's sum runs on rank 0 in the one-rank order). With ``disk``, each rank writes
        its own part.

    Returns a ``Gradient``. ``ArgumentError`` (a ValueError; one line naming the argument) for a
    scene that is not a ``Scene``, steps, snapshots or disk_interval not integers >= 1, a cost
    that is not callable (or whose h_obs does not fit the grid: ``check_nodes``), returns other
    than (J, λ (3, N)) or a non-finite J, at_steps outside 0 … n, a controlled scene without a
    history, a history shorter than n or with a bad step (``StepTimes``), a disk_interval without a
    disk, a disk that is not an existing folder, x0 or hs of another shape or not finite,
    ``parameters`` not a bool or True with semi_implicit or an IMEX pair, ``comm`` not a communicator, or a scene
    the adjoint cannot serve (``sums.refusal``; the JFNK implicit, an exponential stepper);
    ``SceneError`` for another device than "cpu", "cuda" or "cuda:N"; OSError from the disk
    (full, unwritable); ``StepFailure`` where a semi-implicit or IMEX step's solve, recomputed or
    transposed, misses its ``tol`` within ``maxiter``.

    Sources: the model's transposes (``model.transposes``: the tendency, the DSS and the ∇⁴
    transposed by hand; the Helmholtz solve by its symmetry) on a tape of each step
    (``tape``, ``reverse``), checkpointing by Griewank & Walther (2000), ACM TOMS 26:19, in two
    levels by Stumm & Walther (2009), SIAM J. Sci. Comput. 31:1946.
    """
    instance_argument("scene", scene, Scene, "a Scene (swe_sphere.load_scene(...))")
    steps = integer_argument("steps", steps, 1)
    snapshots = steps if snapshots is None else integer_argument("snapshots", snapshots, 1)
    cost = run_cost(cost, steps)
    parameters = flag_argument("parameters", parameters)
    disk = None if disk is False else disk
    if disk is not None and disk is not True:
        path_argument("disk", disk, "None, True or an existing folder's path")
    if disk_interval is not None:
        integer_argument("disk_interval", disk_interval, 1)
        if disk is None:
            raise ArgumentError(f"disk_interval needs a disk (got disk_interval={disk_interval!r}, disk=None)")
    comm_argument("comm", comm)
    device = pick_device(device)
    clock = _clock(scene, steps, history)
    model, stepper, initial = scene_model(scene, device, hs, comm)
    if hasattr(cost, "check_nodes"):  # h_obs, the observation operator's grid: before the run
        cost.check_nodes(model.topology.nnodes_total)
    for dt in {clock(k)[1] for k in range(steps)}:  # every Δt served before a step is taken
        if (why := refusal(model, dt)) is not None:
            raise ArgumentError(why)
    topo = model.topology
    x0 = initial if x0 is None else _distributed(topo, x0, 3, "x0")
    work = wp.array(x0, dtype=f64, device=model.topology.device)  # the stepper steps this array only
    stepper.prepare(work)  # from x(0): lts fixes its levels by its flow
    adjoint = step_adjoint(model, stepper, parameters)
    interval = snapshots if disk_interval is None else int(disk_interval)
    found, mu, taken, used = _reverse_run(model, stepper, adjoint, clock, work, steps, cost, snapshots, disk, interval)
    extra = {}
    if parameters:
        d_hs = _whole(topo, adjoint.hs_gradient())
        d_g, d_omega = adjoint.d_planet / [model.g, scene.make_case().planet.omega]  # Ω > 0 (``Planet``)
        extra = {"d_nu": adjoint.d_nu[0], "d_nu_s": adjoint.d_nu[1], "d_hs": d_hs, "d_g": d_g, "d_omega": d_omega}
    costs = dict(sorted(found["costs"].items()))
    total = sum(costs.values())  # in increasing k; a final-state cost's J exactly (0 + J)
    final = _whole(topo, found["final"])
    return Gradient(total, _whole(topo, mu), final, taken, steps, disk_bytes=used, costs=costs, **extra)


def _clock(scene: Scene, steps: int, history) -> StepTimes:
    """The ``StepTimes`` of ``gradient``'s run of ``scene``: its Δt from its start day, or
    ``history``'s steps. ``ArgumentError`` for a controlled scene without a history (its steps
    are its controller's) or a history shorter than ``steps``."""
    if history is None and scene.control is not None:
        raise ArgumentError(
            f"a run under time.control = {scene.control.mode!r} is differentiated along the steps it took: "
            "give history=Simulation(...).control.history of that run"
        )
    clock = StepTimes(scene.start_day * DAY, scene.dt, history)
    if clock.steps is not None and len(clock.steps) < steps:
        raise ArgumentError(f"history holds {len(clock.steps)} steps, fewer than the {steps} asked for")
    return clock


def _checked_cost(cost, k: int, x, spheremp) -> tuple[float, np.ndarray]:
    """(J_k, λ_k) of ``cost`` at x = x(k) (3, N), checked: ``ArgumentError`` naming the cost
    unless it returns a finite number J and λ of x's shape, finite."""
    out = cost(k, x, spheremp)
    if not (isinstance(out, tuple) and len(out) == 2):
        raise ArgumentError(f"cost must return (J, λ) (got {out!r:.60} at step {k})")
    J = out[0]
    if isinstance(J, bool) or not isinstance(J, (int, float, np.number)) or not np.isfinite(J):
        raise ArgumentError(f"cost's J must be a finite number (got {J!r:.60} at step {k})")
    return float(J), array_argument("cost's λ", out[1], np.shape(x))


class _At:
    """A state x (3, N) of the run and its step index k (its model time t0 + k·Δt)."""

    def __init__(self, x, k: int):
        self.x, self.k = x, k


class _IndexedTier:
    """A ``DiskTier`` of ``_At`` states: x(jK) saved and loaded with its index jK."""

    def __init__(self, tier, interval: int):
        self.tier, self.interval = tier, interval

    def save(self, j: int, state: _At) -> None:
        self.tier.save(j, state.x)

    def load(self, j: int) -> _At:
        return _At(self.tier.load(j), j * self.interval)


def _reverse_run(model, stepper, adjoint, clock, work, steps, cost, snapshots, disk, interval):
    """({"costs": {k: J_k}, "final": x(n)}, μ(0) numpy, forward steps, disk bytes) of
    ``gradient``: the run from x0 = ``work`` (3, N), the array the prepared stepper steps, and its reverse sweep, in memory or with a disk
    tier; ``cost`` a cost of the run (``run_cost``), called once at each of its steps. The
    sweep's states carry their step index (``_At``), so that every step, recomputed or
    reversed, runs at its Δt and model time (``clock``: a time-dependent forcing's). A
    stepper that carries arrays from step to step (its ``carried_arrays``: leapfrog's x̃(k−1),
    MRAB3's histories) has them in its states' and adjoints' rows after x's, the cost reading
    rows 0–2."""
    device, rows = model.topology.device, 3 * (1 + len(stepper.carried_arrays()))
    X = slice(0, 3)

    def carried(x):  # (the stepper's array, the state's rows) pairs, in ``carried_arrays``' order now
        return [(a, x[3 * i + 3 : 3 * i + 6]) for i, a in enumerate(stepper.carried_arrays())]

    def advance(state, steps=1):
        wp.copy(work, state.x[X])
        for a, held in carried(state.x):
            wp.copy(a, held)
        for k in range(state.k, state.k + steps):
            clock.set(stepper, k)
            stepper.set_phase(k)  # its clock, t0_k + (k + c)·Δt_k at each stage as the run's, and start
            stepper.step(work)
        wp.copy(state.x[X], work)
        for a, held in carried(state.x):
            wp.copy(held, a)
        state.k += steps

    def copy(state):
        return _At(wp.clone(state.x), state.k)

    mu = wp.zeros((rows, model.topology.N), dtype=f64, device=device)
    found, observed = {"costs": {}}, set(cost.at_steps)
    lam = wp.zeros((3, model.topology.N), dtype=f64, device=device)
    add = model.topology.dss_update(lam, [(mu[X], ((1.0, mu[X]), (1.0, None)))], weighted=False)  # μ += R Q λ
    topo = model.topology
    spheremp = topo.gather(model.topology.grid.spheremp)  # the whole grid's on rank 0 (None elsewhere)

    def observe(x, k):  # J_k at x(k) into found, λ_k into ``lam``: the cost on rank 0, the whole grid
        whole = topo.gather(np.array(x.numpy()[X]))
        J, lam_k = _on_root(topo, lambda: _checked_cost(cost, k, whole, spheremp)) or (None, None)
        found["costs"][k] = topo.bcast(J)
        lam.assign(topo.distribute(None if lam_k is None else np.asarray(lam_k, dtype=float), 3, "the cost's λ"))

    def finish(state):  # J_n at x(n) and μ = R Q λ_n there (0 where n is not observed)
        found["final"] = state.x.numpy()[X]
        if steps in observed:
            observe(state.x, steps)
            for launch in model.topology.dss(lam, False, mu[X]):
                launch.launch()

    def reverse(state, k):
        if "final" not in found:  # in memory alone, x(n) is one step on from the first reversed
            final = copy(state)
            advance(final)
            finish(final)
        clock.set(adjoint, k)
        adjoint.reverse(state.x, mu, k)
        if k in observed:  # μ(k) += R Q λ_k, x(k) at hand
            observe(state.x, k)
            for launch in add:
                launch.launch()

    start = np.zeros((rows, model.topology.N))
    start[X] = work.numpy()  # x̃(−1) is not read: the three-level schemes' first step is a midpoint step
    x, used = _At(wp.array(start, dtype=f64, device=device), 0), 0
    if disk is None:
        taken = 1 + sweep(steps, snapshots, x, advance, reverse, copy)
    else:
        with DiskTier(disk, (rows, model.topology.N), device) as tier:
            indexed = _IndexedTier(tier, interval)
            taken = two_level(steps, snapshots, interval, x, advance, reverse, copy, indexed, finish)
            used = tier.bytes
    return found, mu.numpy()[X], taken, used
