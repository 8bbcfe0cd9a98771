"""The adjoint of one step of an IMEX additive Runge–Kutta pair (``steppers.runge_kutta.ImexRK``):
``imex``'s ARS(2,3,2) and ARS(3,4,3) (Ascher, Ruuth & Spiteri 1997, Appl. Numer. Math. 25:151,
§2.5 and §2.7), ``ark324``'s and ``ark436``'s ARK3(2)4L[2]SA and ARK4(3)6L[2]SA (Kennedy &
Carpenter 2003, Appl. Numer. Math. 44:139, tables in ``steppers.tables``).

The step (the stepper's ``advance``), with F the model's RHS, L the linear gravity-wave operator
about the stepper's mean depth H (``semi_implicit``'s), S = F − L, s stages and A_i = I − Δt a^I_ii L:
    r_i = x + Δt Σ_{j<i} (a^E_ij F(Y_j) + (a^I_ij − a^E_ij) L Y_j),  Y_i = A_i⁻¹ r_i,
    Φ = x + Δt Σ_j (b^E_j F(Y_j) + (b^I_j − b^E_j) L Y_j),  x(n+1) = H_Δt(Φ)
(A_i = I where a^I_ii = 0: an explicit stage). Reversed with μ' the adjoint of x(n+1):
    μ_Φ = H_Δtᵀ μ', and for i = s − 1 … 0
    k̄_i = Δt (b^E_i μ_Φ + Σ_{k>i} a^E_ki r̄_k),  l̄_i = Δt ((b^I_i − b^E_i) μ_Φ + Σ_{k>i} (a^I_ki − a^E_ki) r̄_k),
    r̄_i = A_i⁻ᵀ (Fᵀ(Y_i) k̄_i + Lᵀ l̄_i);   μ = μ_Φ + Σ_i r̄_i.
Fᵀ and H_Δtᵀ are ``explicit``'s (mass form, μ = R Q λ), Lᵀ and A_i⁻ᵀ the model's
(``model.transposes.GravityTranspose``: Lᵀ the pressure gradient's and continuity's transposes at (0, 0, H);
A_a⁻ᵀ the forward's Helmholtz solve at a = Δt a^I_ii between two scalings of the h row). The
stages Y_i are recomputed from x(n) by the same combinations and solves (each F at its stage's
time), one solve a stage with a^I_ii ≠ 0, and one transposed solve each: 2(s − 1) solves a step
reversed for these pairs. The solves are the scene's CG to its ``tol``: the step is linear in
them to that tolerance (a Taylor test sets ``tol`` near round-off). An embedded pair's estimate
does not enter x(n+1), nor its gradient. The parameters' gradients (``parameters=True``) are not
served: L holds g and H.
"""

from __future__ import annotations

import warp as wp

from ..core.errors import ArgumentError
from ..model.shallow_water import ShallowWater
from .explicit import StepAdjoint
from .semi_implicit import GravityTransposes


class ImexAdjoint(GravityTransposes, StepAdjoint):
    """The adjoint of one step of ``stepper`` (an ``ImexRK``: ``imex``, ``ark324``, ``ark436``)
    on ``model`` at Δt = ``dt`` (s), its steps from model time ``t0`` (s): ``reverse(x, mu, k)``
    maps the continuous adjoint μ (3, N) of x(k+1) to that of x(k) in place, x = x(k) (3, N)
    (module doc); ``set_dt`` as ``StepAdjoint``'s (a controlled run's steps). ``ArgumentError``
    with ``parameters`` (not served) and as ``StepAdjoint``; ``StepFailure`` (from ``reverse``)
    where a solve, forward or transposed, misses the stepper's ``tol`` within ``maxiter``.

    Work arrays (3, N): x, the s stages Y_i and r̄_i, F(Y_j) and L Y_j where a combination reads
    them; a ``HelmholtzSolver`` of its own about the stepper's L (its guesses untouched)."""

    def __init__(self, model: ShallowWater, stepper, dt: float, parameters: bool = False, t0: float = 0.0):
        if parameters:
            raise ArgumentError(
                f"parameters must be False with {stepper.name} (got True): its gradient is the initial "
                "state's alone (its gravity-wave operator L holds g and H)"
            )
        A_E, b_E, A_I, b_I, c = stepper.table().floats()
        self.A_E, self.A_I, self.b_E, self.b_I = (t.tolist() for t in (A_E, A_I, b_E, b_I))
        self.c = tuple(c)  # the stages' abscissae, as the stepper's ``_at`` takes them
        self._gravity(stepper)
        self._setup(model, dt, parameters, t0)
        s, zeros = len(self.b_E), self._zeros
        # F(Y_j) where the explicit part weighs it, L Y_j where the two parts weigh it differently
        # or its solve writes it (as the stepper's ``needs_F``, ``needs_L``, the estimate left out)
        self.F = [zeros(3) if b_E[j] or A_E[j + 1 :, j].any() else None for j in range(s)]
        weighs_L = [b_I[j] != b_E[j] or (A_I[j + 1 :, j] != A_E[j + 1 :, j]).any() for j in range(s)]
        self.L = [zeros(3) if A_I[j, j] or weighs_L[j] else None for j in range(s)]
        self.x, self.Y, self.rbar = zeros(3), [zeros(3) for _ in range(s)], [zeros(3) for _ in range(s)]
        self._for_dt()

    def _stage_plan(self, zeros) -> None:
        """None: ``stages`` forms the stages itself (their solves between the combinations)."""

    def stages(self, k: int = 0) -> None:
        """Y_i of step k from x (module doc), F(Y_i) and L Y_i where kept, as the stepper forms
        them: r_i into L Y_i's array, the solve into Y_i with L Y_i = (Y_i − r_i)/(Δt a^I_ii) from
        its back-substitution; each F at t0 + (k + c_i)·Δt."""
        m, dt, A_E, A_I = self.model, self.dt, self.A_E, self.A_I
        for i, (Y, F, L) in enumerate(zip(self.Y, self.F, self.L)):
            terms = [(dt * A_E[i][j], self.F[j]) for j in range(i) if A_E[i][j]]
            terms += [(dt * (A_I[i][j] - A_E[i][j]), self.L[j]) for j in range(i) if A_I[i][j] != A_E[i][j]]
            a = dt * A_I[i][i]
            if a:
                self.combine(L, [(1.0, self.x), *terms])
                self.solver.solve(L, a, Y, implicit=L)
            else:
                self.combine(Y, [(1.0, self.x), *terms])
                if L is not None:
                    self.linear.apply(Y, L)
            if F is not None:
                m.set_time(self.t0 + (k + self.c[i]) * dt)
                m.rhs(Y, F)
        self.solver.iterations()

    def _record(self, mu) -> list:
        """(i, launches) a stage, last first: r̄_i = Fᵀ(Y_i) k̄_i + Lᵀ l̄_i, each transpose's x̄ added
        by its unweighted DSS (``reverse`` then solves r̄_i ← A_i⁻ᵀ r̄_i); then (None, μ += Σ r̄_i)
        over the stages with a transpose."""
        dt, s, A_E, A_I, b_E, b_I = self.dt, len(self.b_E), self.A_E, self.A_I, self.b_E, self.b_I
        topo, segments, active = self.model.topology, [], []
        for i in reversed(range(s)):
            kbar = [(dt * c, a) for c, a in [(b_E[i], mu), *((A_E[k][i], self.rbar[k]) for k in active)] if c]
            lbar = [(b_I[i] - b_E[i], mu), *((A_I[k][i] - A_E[k][i], self.rbar[k]) for k in active)]
            lbar = [(dt * c, a) for c, a in lbar if c]
            launches, r = [], self.rbar[i]
            for terms, transpose in ((kbar, self.tendency.transpose), (lbar, None)):
                if terms:
                    add = ((1.0, r), (1.0, None)) if launches else ((1.0, None),)  # the first writes r̄_i
                    launches += (
                        transpose(self.Y[i], terms) if transpose else self.gravity.transpose(self.tendency, terms)
                    )
                    launches += topo.dss_update(self.xbar, [(r, add)], False)
            if launches:
                active.append(i)
                segments.append((i, launches))
        total = self.combinations.combination(mu, [(1.0, mu), *((1.0, self.rbar[i]) for i in active)])
        return [*segments, (None, total)]

    def reverse(self, x, mu, k: int = 0) -> None:
        """μ of x(k+1) → μ of x(k), in place; x = x(k) (read only), k the step's index."""
        wp.copy(self.x, x)
        self.stages(k)
        if self.substeps:
            self.hyperviscosity_transpose(mu)
        recorded = self._adjoints.get(mu.ptr)
        if recorded is None:
            recorded = self._adjoints[mu.ptr] = (mu, self._record(mu))
        for i, launches in recorded[1]:
            for launch in launches:
                launch.launch()
            if i is not None and self.A_I[i][i]:
                self.solve_transpose(self.rbar[i], self.dt * self.A_I[i][i])
