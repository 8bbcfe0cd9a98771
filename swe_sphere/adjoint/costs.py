"""The costs of a run that ``gradient`` differentiates: a final state's misfit (``HeightMisfit``)
or a cost of the run against observations of it at several steps (such as
``io.observations.HeightObservations``), and how ``gradient`` takes any of them (``run_cost``,
``checked``); a cost's λ, element-local, is gathered to the continuous adjoint (R Q λ) there."""

from __future__ import annotations

import numpy as np

from ..core.arguments import array_argument, callable_argument
from ..core.errors import ArgumentError

_RADIANS = "radians: degrees times π/180"


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


class _FinalCost:
    """A final-state cost (x, spheremp) → (J, λ) as a cost of the run observed at step n alone."""

    def __init__(self, cost, n: int):
        self.cost, self.at_steps = cost, (n,)
        self.check_nodes = getattr(cost, "check_nodes", lambda n: None)

    def __call__(self, k, x, spheremp):
        return self.cost(x, spheremp)


def run_cost(cost, steps: int):
    """``cost`` as a cost of the run: one with ``at_steps`` as it is (its steps checked), any
    other callable as that of the final state x(n). ``ArgumentError`` for a cost that is neither,
    no steps, or one outside 0 … ``steps`` or not an integer."""
    callable_argument("cost", cost, "a callable (x, spheremp) -> (J, λ), or a cost of the run with at_steps")
    if not hasattr(cost, "at_steps"):
        return _FinalCost(cost, steps)
    try:
        at = [*cost.at_steps]
    except TypeError:
        at = None
    if not at or any(isinstance(k, bool) or not isinstance(k, (int, np.integer)) or not 0 <= k <= steps for k in at):
        raise ArgumentError(f"cost.at_steps must be integers in 0 … {steps} (got {cost.at_steps!r})")
    return cost


def checked(cost, k: int, x, spheremp) -> tuple[float, np.ndarray]:
    """(J_k, λ_k) of ``cost`` at x = x(k) (3, N), checked: ``ArgumentError`` naming the cost
    unless it returns a finite number J and λ of x's shape, finite."""
    out = cost(k, x, spheremp)
    if not (isinstance(out, tuple) and len(out) == 2):
        raise ArgumentError(f"cost must return (J, λ) (got {out!r:.60} at step {k})")
    J = out[0]
    if isinstance(J, bool) or not isinstance(J, (int, float, np.number)) or not np.isfinite(J):
        raise ArgumentError(f"cost's J must be a finite number (got {J!r:.60} at step {k})")
    return float(J), array_argument("cost's λ", out[1], np.shape(x))
