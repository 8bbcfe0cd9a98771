"""The gradient of a scalar of a run's final state with respect to its initial state
(``gradient``), by a checkpointed reverse sweep (``revolve.sweep``) of the explicit steps'
adjoints (``explicit.StepAdjoint``)."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import warp as wp

from ..config.scene import Scene
from ..grid.cubed_sphere import CubedSphere
from ..model.shallow_water import ShallowWater
from ..steppers import make_stepper
from ..steppers.runge_kutta import ExplicitRK
from .explicit import StepAdjoint
from .revolve import sweep

f64 = wp.float64


class HeightMisfit:
    """J(x) = ½ Σ spheremp (h − h_obs)² over the element-local nodes (m⁴: the area integral
    ½ ∫ (h − h_obs)² dA of a continuous h), with ``h_obs`` (N,) element-local, m.
    ``__call__(x, spheremp)``: (J, λ) for x (3, N) numpy rows u, v, h; λ = ∂J/∂x (3, N)."""

    def __init__(self, h_obs):
        self.h_obs = np.asarray(h_obs, dtype=float)

    def __call__(self, x, spheremp):
        r = x[2] - self.h_obs
        lam = np.zeros_like(x)
        lam[2] = spheremp * r
        return 0.5 * float(np.sum(spheremp * r * r)), lam


class Gradient(NamedTuple):
    """What ``gradient`` returns: ``cost`` J; ``grad`` (3, N) rows u, v, h, element-local and
    continuous, the gradient in the mass inner product (δJ = Σ spheremp·grad·δx over the
    element-local nodes for a continuous δx; units of J per m² per unit of the row);
    ``final`` (3, N) the final state; ``forward_steps`` the steps taken forward (the cost's
    included), ``reverse_steps`` n. With ``parameters=True``: ``d_nu`` ∂J/∂ν (ν = ν_div, the
    wind's ∇⁴ coefficient; J per m⁴ s⁻¹), ``d_nu_s`` ∂J/∂ν_s (the surface's), ``d_hs`` (N,)
    ∂J/∂hs in the mass inner product as ``grad`` (x0 held fixed); None otherwise."""

    cost: float
    grad: np.ndarray
    final: np.ndarray
    forward_steps: int
    reverse_steps: int
    d_nu: float | None = None
    d_nu_s: float | None = None
    d_hs: np.ndarray | None = None


class _Topography:
    """``case`` with its surface height replaced by ``hs`` (N,) at the grid's nodes."""

    def __init__(self, case, hs):
        self.case, self._hs = case, hs

    def hs(self, lat, lon):
        return self._hs

    def __getattr__(self, name):
        return getattr(self.case, name)


def scene_model(scene: Scene, device: str = "cpu", hs=None):
    """(model, stepper, x0) of ``scene`` on one rank: its ``ShallowWater``, its stepper and
    its case's initial state (3, N) numpy; ``hs`` (N,) m: the surface height instead of the
    case's. ValueError unless the stepper is an explicit table, or for hs of another shape."""
    case = scene.make_case()
    grid = CubedSphere(scene.ne, scene.np, case.planet.a)
    if hs is not None:
        hs = np.asarray(hs, dtype=float)
        if hs.shape != grid.lat.shape:
            raise ValueError(f"hs must have shape {grid.lat.shape} (got {hs.shape})")
    model = ShallowWater.from_scene(scene, grid, case if hs is None else _Topography(case, hs), device=device)
    stepper = make_stepper(scene.stepper, model, scene.dt, **scene.stepper_options)
    if not isinstance(stepper, ExplicitRK):
        raise ValueError(f"gradients need an explicit Runge–Kutta stepper (got {scene.stepper!r})")
    return model, stepper, np.stack(case.initial(grid.lat, grid.lon))


def gradient(
    scene: Scene,
    steps: int,
    cost,
    *,
    x0=None,
    snapshots: int | None = None,
    parameters: bool = False,
    hs=None,
    device="cpu",
) -> Gradient:
    """The cost J(x(n)) of ``scene`` run ``steps`` steps from x0 and its gradient dJ/dx(0)
    (and, with ``parameters``, dJ/dν, dJ/dν_s and dJ/dhs).

    Parameters
    ----------
    scene : a ``config.Scene`` whose stepper is an explicit Runge–Kutta table (ssprk3, rk4,
        kgu35, a tableau), terms without forcing, a ∇⁴ with ν_div = ν and no tensor scaling.
    steps : n ≥ 1 steps of the scene's Δt.
    cost : callable (x, spheremp) → (J, λ), x (3, N) numpy rows u, v, h (m s⁻¹, m s⁻¹, m),
        spheremp (N,) m², λ = ∂J/∂x (3, N) over the element-local entries (e.g. ``HeightMisfit``).
    x0 : (3, N) initial state (None: the case's).
    snapshots : states held at once during the reverse sweep, x(0) included (None: n, every
        state, each step taken forward once); fewer cost ``revolve.forward_steps(n,
        snapshots − 1)`` + 1 forward steps in all (Griewank & Walther 2000), the same bits.
    parameters : also the ∇⁴ coefficients' and the topography's gradients (an extra ∇⁴
        substep a step reversed).
    hs : (N,) surface height (m), element-local and continuous, instead of the case's.
    device : "cpu" (one rank; CUDA and MPI not yet).

    Returns a ``Gradient``. ValueError for steps or snapshots < 1, x0 or hs of another shape,
    or a scene the adjoint cannot serve (``explicit._refusal``, a non-explicit stepper).

    Sources: the adjoints of ``explicit`` (the tendency, the DSS and the ∇⁴ transposed by
    hand), checkpointing by Griewank & Walther (2000), ACM TOMS 26:19.
    """
    steps = int(steps)
    snapshots = steps if snapshots is None else int(snapshots)
    if steps < 1 or snapshots < 1:
        raise ValueError(f"steps and snapshots must be >= 1 (got {steps}, {snapshots})")
    model, stepper, initial = scene_model(scene, device, hs)
    x0 = initial if x0 is None else np.asarray(x0, dtype=float)
    if x0.shape != (3, model.N):
        raise ValueError(f"x0 must have shape (3, {model.N}) (got {x0.shape})")
    adjoint = StepAdjoint(model, stepper.table(), stepper.dt, parameters)
    work = wp.zeros((3, model.N), dtype=f64, device=device)  # the stepper steps this array only
    stepper.prepare(work)

    def advance(x, steps=1):
        wp.copy(work, x)
        for _ in range(steps):
            stepper.advance(work)
        wp.copy(x, work)

    mu = wp.zeros((3, model.N), dtype=f64, device=device)
    found = {}

    def reverse(xk, k):
        if k == steps - 1:  # the sweep's first reversal: x(n) is one step on, J and μ = R Q λ there
            final = wp.clone(xk)
            advance(final)
            found["final"] = final.numpy()
            found["cost"], lam = cost(found["final"], model.grid.spheremp)
            for launch in model.topology.dss(wp.array(lam, dtype=f64, device=device), False, mu):
                launch.launch()
        adjoint.reverse(xk, mu)

    x = wp.array(x0, dtype=f64, device=device)
    taken = 1 + sweep(steps, snapshots, x, advance, reverse, wp.clone)
    extra = {}
    if parameters:
        extra = {"d_nu": adjoint.d_nu[0], "d_nu_s": adjoint.d_nu[1], "d_hs": adjoint.hs_gradient()}
    return Gradient(found["cost"], mu.numpy(), found["final"], taken, steps, **extra)
