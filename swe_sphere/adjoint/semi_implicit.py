"""The adjoint of one step of the semi-implicit leapfrog (``steppers.semi_implicit``, HOMME's
``advance_si_nonstag``): ``leapfrog``'s three-level adjoint with the gravity waves' trapezoid and
their Helmholtz solve. States and adjoints (6, N) as ``leapfrog``'s: s(n) = (x(n), x̃(n−1)).

The step, with δ its half span and A_δ = I − δL (L x = (−g G h, −H D v), the linear
gravity-wave operator about the mean depth H, ``model.gravity_wave``):
    Φ = x̃ + 2δ F(x) + δ L (x̃ − 2x),  P = A_δ⁻¹ Φ,  N = H_2δ(P),
    x(n+1) = N,  x̃(n) = (1 − 2ε) x + ε x̃ + ε N;
n ≥ 1: δ = Δt; n = 0: δ = Δt/2 from x̃ = x(0), ε = 0 (so x̃(0) = x(0)). Reversed with
μ' = (μ_x', μ_x̃') given:
    μ_N = μ_x' + ε μ_x̃',  μ_P = H_2δᵀ μ_N,  μ_Φ = A_δ⁻ᵀ μ_P,
    μ_x = (1 − 2ε) μ_x̃' + 2δ Fᵀ(x) μ_Φ − 2δ Lᵀ μ_Φ,  μ_x̃ = ε μ_x̃' + μ_Φ + δ Lᵀ μ_Φ,
and at n = 0, x̃ being x(0), μ_x(0) = μ_x + μ_x̃ (x̃(−1) is not read). Fᵀ and H_2δᵀ are
``explicit``'s (mass form: μ = R Q λ, ⟨a, b⟩ = Σ spheremp·a·b over the element-local nodes).
L is the Jacobian of F's pressure gradient and continuity at x_H = (0, 0, H), so
Lᵀ μ = R Q Tᵀ(x_H) W μ, those two terms' transpose as any F's (``TendencyTranspose.transpose``).
A_δ⁻ᵀ: GLL differentiation sums by parts (W D + Dᵀ W = B along each direction, applied to
metdet c^i h, c the contravariant wind), and the element-edge terms cancel between neighbours
for continuous v and h, so in the mass form D and −G are each other's transposes
(⟨D v, h⟩ = −⟨v, G h⟩) and Lᵀ (v, h) = (H G h, g D v) = −S L S⁻¹, S = diag(1, 1, g/H). With
Z = diag(1, 1, −1) (Z L Z = −L): A_δᵀ = I + δ S L S⁻¹ = S Z A_δ Z S⁻¹, hence
    A_δ⁻ᵀ μ = S Z A_δ⁻¹ Z S⁻¹ μ:
the h row times −H/g, the forward's Helmholtz solve at a = δ (its operator M + δ²gH K is
symmetric: ``solvers.helmholtz``), the h row times −g/H. The solve is the scene's CG to its
``tol``, as the forward's: the step is linear in its solve to that tolerance, and so is this
transpose (a Taylor test sets ``tol`` near round-off). H is the stepper's (fixed from x(0) by
its first step and rounded: piecewise constant, held). The parameters' gradients
(``parameters=True``) are not served: L holds g and H.
"""

from __future__ import annotations

import numpy as np

from ..core.errors import ArgumentError
from ..model.shallow_water import ShallowWater
from ..solvers.helmholtz import HelmholtzSolver
from .leapfrog import LeapfrogAdjoint

GRAVITY = ("continuity", "pressure_gradient")  # the terms whose Jacobian at (0, 0, H) is L


class GravityTransposes:
    """What the adjoints of the steps that solve with the gravity-wave operator L share (put
    before ``StepAdjoint``; ``semi_implicit``'s and ``imex``'s): ``gravity_transpose``, the
    launches of Lᵀ's element part, and ``solve_transpose``, A_a⁻ᵀ = (I − aL)⁻ᵀ (module doc), with
    ``linear`` the stepper's L, ``solver`` a ``HelmholtzSolver`` of the adjoint's own about it (the
    stepper's guesses untouched), ``depth`` x_H = (0, 0, H) (3, N) once H is fixed."""

    def _gravity(self, stepper, solver: HelmholtzSolver | None = None) -> None:
        """``linear`` and ``solver`` (``solver``: shared with another adjoint); before ``_setup``."""
        self.linear = stepper.linear
        self.solver = solver or HelmholtzSolver(self.linear, stepper.options, warm=True)
        self.depth, self.H = None, 0.0

    def fix_depth(self) -> None:
        """x_H's depth row from the stepper's H (fixed by its first step, before any reverse)."""
        if self.depth is None or self.linear.H != self.H:
            self.H, N = self.linear.H, self.model.topology.N
            self.depth = self._zeros(3) if self.depth is None else self.depth
            self.depth.assign(np.stack([np.zeros(N), np.zeros(N), np.full(N, self.H)]))

    def gravity_transpose(self, kbar) -> list:
        """Launches of x̄ = Tᵀ(x_H) W k̄ (element-local, into ``xbar``), k̄ = Σ c·a over (c, a)
        ``kbar``: Lᵀ k̄ = R Q x̄ by the unweighted DSS that follows."""
        self.fix_depth()
        return self.tendency.transpose(self.depth, kbar, GRAVITY)

    def solve_transpose(self, mu, a: float) -> None:
        """μ ← A_a⁻ᵀ μ in place, A_a = I − aL, a (s) > 0, μ (3, N) continuous (mass form; module
        doc): its h row times −H/g, the Helmholtz solve at a to the stepper's ``tol``, the h row
        times −g/H. ``StepFailure`` where the CG misses ``tol`` within ``maxiter``."""
        self.fix_depth()
        H, g, h = self.H, self.model.g, mu[2:3]
        self.combine(h, [(-H / g, h)])
        self.solver.solve(mu, a, mu)
        self.combine(h, [(-g / H, h)])
        self.solver.iterations()


class SemiImplicitAdjoint(GravityTransposes, LeapfrogAdjoint):
    """The adjoint of one step of ``stepper`` (a ``SemiImplicit``) on ``model`` at Δt = ``dt``
    (s), its steps from model time ``t0`` (s): ``reverse(s, mu, k)`` as ``LeapfrogAdjoint``'s
    (module doc). ``first``: the adjoint of the first step alone (δ = Δt/2, any k reversed as
    step 0), which the run's adjoint holds as its ``start``, sharing its ``solver``.
    ``ArgumentError`` with ``parameters`` (not served) and as ``StepAdjoint``; ``StepFailure``
    (from ``reverse``) where the transposed solve does not reach the stepper's ``tol``.

    Work arrays (3, N): ``leapfrog``'s and x_H; a ``HelmholtzSolver`` of its own (the stepper's
    guesses untouched) about the stepper's ``linear`` operator."""

    def __init__(
        self,
        model: ShallowWater,
        stepper,
        dt: float,
        parameters: bool = False,
        t0: float = 0.0,
        *,
        first: bool = False,
        solver: HelmholtzSolver | None = None,
    ):
        if parameters:
            raise ArgumentError(
                "parameters must be False with semi_implicit (got True): its gradient is the initial "
                "state's alone (its gravity-wave operator L holds g and H)"
            )
        self.first = first
        self._gravity(stepper, solver)
        super().__init__(model, stepper, dt / 2 if first else dt, parameters, t0)
        self.eps = 0.0 if first else self.eps

    def _first_step(self, model, stepper, dt: float, parameters: bool, t0: float):
        if not self.first:
            return SemiImplicitAdjoint(model, stepper, dt, parameters, t0, first=True, solver=self.solver)
        return None

    def _reverse_start(self, x, mu) -> None:
        self.start.t0 = self.t0
        self.start.reverse(x, mu, 0)

    def _phi_adjoint(self) -> None:
        """μ_N → μ_Φ: the ∇⁴'s transpose, then A_δ⁻ᵀ."""
        super()._phi_adjoint()
        self.solve_transpose(self.mphi, self.step_dt)

    def _record(self, mu) -> list:
        """``leapfrog``'s segments (μ_x = (1 − 2ε) μ_x̃' + 2δ Fᵀ μ_Φ, μ_x̃ = ε μ_x̃' + μ_Φ), then
        Lᵀ μ_Φ added to both (−2δ, δ) by its DSS, and at the first step μ_x += μ_x̃."""
        X, O, d, topo = mu[0:3], mu[3:6], self.step_dt, self.model.topology
        gravity = [
            *self.gravity_transpose([(1.0, self.mphi)]),
            *topo.dss_update(self.xbar, [(X, ((1.0, X), (-2 * d, None))), (O, ((1.0, O), (d, None)))], False),
        ]
        fold = [self.model.lincomb(X, [(1.0, X), (1.0, O)])] if self.first else []
        return [*super()._record(mu), (None, None, gravity + fold)]
