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
Lᵀ and A_δ⁻ᵀ are the model's (``model.transposes.GravityTranspose``, from the stepper's
``linear.transpose``): Lᵀ μ = R Q Tᵀ(x_H) W μ, the pressure gradient's and continuity's transposes
at x_H = (0, 0, H); A_δ⁻ᵀ μ = S Z A_δ⁻¹ Z S⁻¹ μ, S = diag(1, 1, g/H), Z = diag(1, 1, −1): the
forward's Helmholtz solve at a = δ between two scalings of the h row. The solve is the scene's CG to its
``tol``, as the forward's: the step is linear in its solve to that tolerance, and so is this
transpose (a Taylor test sets ``tol`` near round-off). H is the stepper's (fixed from x(0) by
its first step and rounded: piecewise constant, held). The parameters' gradients
(``parameters=True``) are not served: L holds g and H.
"""

from __future__ import annotations

from ..core.errors import ArgumentError
from ..model.shallow_water import ShallowWater
from ..model.transposes import GravityTranspose
from ..solvers.helmholtz import HelmholtzSolver
from .leapfrog import LeapfrogAdjoint


class GravityTransposes:
    """What the adjoints of the steps that solve with the gravity-wave operator L share (put
    before ``StepAdjoint``; ``semi_implicit``'s and ``imex``'s): ``gravity``, the transposes of L
    and of its solve (``model.transposes.GravityTranspose``), made by the stepper's ``linear``
    with a ``HelmholtzSolver`` of the adjoint's own about it (the stepper's guesses untouched),
    and that ``solver``."""

    def _gravity(self, stepper, gravity=None) -> None:
        """``linear``, ``gravity`` and ``solver`` (``gravity``: shared with another adjoint)."""
        self.linear = stepper.linear
        self.gravity = gravity or self.linear.transpose(HelmholtzSolver(self.linear, stepper.options, warm=True))
        self.solver = self.gravity.solver

    def solve_transpose(self, mu, a: float) -> None:
        """μ ← A_a⁻ᵀ μ in place, A_a = I − aL, a (s) > 0, μ (3, N) continuous (mass form):
        ``GravityTranspose.solve``. ``StepFailure`` where the CG misses ``tol`` within ``maxiter``."""
        self.gravity.solve(mu, a)


class SemiImplicitAdjoint(GravityTransposes, LeapfrogAdjoint):
    """The adjoint of one step of ``stepper`` (a ``SemiImplicit``) on ``model`` at Δt = ``dt``
    (s), its steps from model time ``t0`` (s): ``reverse(s, mu, k)`` as ``LeapfrogAdjoint``'s
    (module doc). ``first``: the adjoint of the first step alone (δ = Δt/2, any k reversed as
    step 0), which the run's adjoint holds as its ``start``, sharing its ``gravity``.
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
        gravity: GravityTranspose | None = None,
    ):
        if parameters:
            raise ArgumentError(
                "parameters must be False with semi_implicit (got True): its gradient is the initial "
                "state's alone (its gravity-wave operator L holds g and H)"
            )
        self.first = first
        self._gravity(stepper, gravity)
        super().__init__(model, stepper, dt / 2 if first else dt, parameters, t0)
        self.eps = 0.0 if first else self.eps

    def _first_step(self, model, stepper, dt: float, parameters: bool, t0: float):
        if not self.first:
            return SemiImplicitAdjoint(model, stepper, dt, parameters, t0, first=True, gravity=self.gravity)
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
            *self.gravity.transpose(self.tendency, [(1.0, self.mphi)]),
            *topo.dss_update(self.xbar, [(X, ((1.0, X), (-2 * d, None))), (O, ((1.0, O), (d, None)))], False),
        ]
        fold = [self.model.lincomb(X, [(1.0, X), (1.0, O)])] if self.first else []
        return [*super()._record(mu), (None, None, gravity + fold)]
