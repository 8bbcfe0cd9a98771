"""IMEX additive Runge–Kutta steppers of the table engine (``runge_kutta``): the explicit part of
a pair ``butcher.Table`` stepped as ``runge_kutta.ExplicitRK`` steps its table, the implicit part's
stages each one Helmholtz solve (``helmholtz_steps.HelmholtzSteps``); the built-in pairs ``imex``
(ARS(2,3,2) / ARS(3,4,3)) and the embedded ``ark324``, ``ark436`` (``tables.IMEX``, ``IMEX_PAIRS``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import warp as wp

from ..core.constants import DAY
from ..kernels import blas
from ..model.helmholtz import HelmholtzOptions
from ..model.launches import Update
from .base import Stepper, StepStats, device_counts, work_array
from .butcher import TABLES, Table
from .capabilities import ErrorEstimates, GraphCapture, TrialSteps
from .helmholtz_steps import REMOVED_SOLVER_OPTIONS, HelmholtzSteps
from .tables import IMEX, IMEX_ADVECTIVE_LIMITS, IMEX_PAIRS

f64 = wp.float64


# the IMEX pairs' Helmholtz CG residual under error control, per rtol (``ImexRK.follow_tolerance``):
# SUNDIALS' 0.1 for an inner solve's error against the step's, and 0.1 more because the CG's
# relative residual understates the solution's error at these steps (TC5 and TC2 ne8, 5 days,
# rtol 1e-5 and 1e-6: at 0.1 rtol the noise still shrank the steps, ark436 303 and 366 where
# 0.01 takes 226 and 196 in less CPU; 0.001 changes nothing more: docs/explanation/efficiency/error_control.md)
CG_PER_RTOL = 0.01


class ImexRK(HelmholtzSteps, GraphCapture, ErrorEstimates, TrialSteps, Stepper):
    """An IMEX additive Runge–Kutta step of the pair ``table()`` (a ``butcher.Table``):
    gravity waves through A_I (one Helmholtz solve a stage with a_ii ≠ 0), the rest
    through A_E. Options: the Helmholtz solve's ``tol``, ``maxiter``,
    ``mean_depth``, ``precision``, ``guess_history``; each stage's solve starts from
    the projection onto past solutions of the stages with its a_ii
    (``helmholtz.GuessHistory``; ``guess_history`` 0: from the last one's solution). Raises ValueError without the continuity and pressure-gradient terms.

    IMEX additive pairs (Ascher, Ruuth & Spiteri 1997, Appl. Numer.
    Math. 25, 151; Kennedy & Carpenter 2003): the linear gravity-wave terms L
    (``model.gravity_wave.GravityWaveOperator``) implicit, the rest S = F − L explicit, as HOMME-NH
    and ClimaTimeSteppers split. With the explicit table (A_E, b_E), the implicit
    one (A_I, b_I) of s stages, A_I lower triangular (diagonally implicit,
    a_ii = 0 allowed: an explicit stage), A_E strictly lower triangular, and
    common abscissae c,

        Y_i = x(n) + Δt Σ_{j<i} (A_E,ij S(Y_j) + A_I,ij L Y_j) + Δt A_I,ii L Y_i,
        x(n+1) = x(n) + Δt Σ_j (b_E,j S(Y_j) + b_I,j L Y_j).

    Each stage with a_ii ≠ 0 is one solve of (I − a_ii Δt L) Y_i = rhs_i through
    the Helmholtz equation, and L Y_i = (Y_i − rhs_i)/(a_ii Δt) follows from it
    without another product, written by the solve's back-substitution
    (``HelmholtzSolver.solve``'s ``implicit``) in rhs_i's own array; an explicit stage
    takes L Y_i from a product, and only where the two tables weigh it differently
    (S = F − L). Each combination
    (rhs_i, and x(n+1)) is summed from x itself (x(n) until the last writes it) in
    passes of two terms, as ``blas.axpbypcz``; the pass holding the F that the
    stage before has just evaluated is written by that RHS's DSS
    (``ShallowWater.rhs_update``, as the explicit tables' stages), and that F is
    stored only where a later combination needs it: the same passes in the same
    order, so the bits of storing F and combining after, with fewer passes (TC5
    ne 2, a step's own launches outside the solves and the ∇⁴, with the L Y_i in
    the back-substitution: ARS(3,4,3) 26 → 18, ARS(2,3,2) 19 → 13,
    ``tests/steppers/test_imex.py``). ARS's pairs
    (b_E = b_I, the first stage x(n)) cost s RHS evaluations, s − 1 solves and
    one product with L a step. Mass: every stage keeps ∫h (F_h and L_h integrate
    to zero; the solve fixes ∫z_h), so x(n+1) has the mass of x(n) to round-off.
    """

    variable_dt = True  # the combinations read Δt every step
    fused = True
    """Whether a combination's pass holding F(Y_i) is written by that RHS's DSS (``rhs_update``;
    the class docstring). False: every F stored by a plain ``rhs`` and combined after, the
    reference whose bits the fused passes keep (``tests/steppers/test_tableau.py``)."""

    def table(self) -> Table:
        """The checked pair this stepper steps."""
        raise NotImplementedError

    def follow_tolerance(self, atol: float, rtol: float = 0.0, per_unit_step: bool = False) -> None:
        """Under error control at the relative tolerance ``rtol`` > 0: the Helmholtz CG's relative
        residual at most ``CG_PER_RTOL`` rtol (not below ``model.helmholtz.TIGHTEST``): a solve's
        error enters the stages' L Y_j, and through them the estimate, as is, so a CG looser than
        the step made the estimate its noise (TC5 ne8 over 5 days at the CG's 1e-6: ``ark436`` at
        rtol 1e-7 rejected 3435 tries for 2818 steps). ``per_unit_step`` (rtol a day's): times
        the first step's share Δt / 1 day, set once (a new CG tolerance drops the solve graphs).
        ``atol`` alone (rtol 0) changes nothing."""
        if rtol > 0:
            self.helmholtz.tighten(CG_PER_RTOL * rtol * (min(self.dt / DAY, 1.0) if per_unit_step else 1.0))

    def __init__(self, model, dt, options=None):
        super().__init__(model, dt, options)
        A_E, b_E, A_I, b_I, self.c = self.table().floats()
        stages = len(b_E)
        self.A_E, self.A_I, self.b_E, self.b_I = A_E, A_I, b_E, b_I
        # F(Y_j) is needed where the explicit part weighs it, L Y_j where the two parts weigh it
        # differently (N_j = F_j − L_j enters with A_E, b_E; L Y_j with A_I, b_I)
        # and the estimate's weights d = b − b̂ (exact, then rounded; zero without a b̂)
        estimate = self.table().estimate
        self.d_E, self.d_I = (b_E * 0, b_I * 0) if estimate is None else (np.array(d, dtype=float) for d in estimate)
        self.needs_F = [bool(b_E[j] != 0 or self.d_E[j] != 0 or (A_E[j + 1 :, j] != 0).any()) for j in range(stages)]
        self.needs_L = [
            bool(b_I[j] != b_E[j] or self.d_I[j] != self.d_E[j] or (A_I[j + 1 :, j] != A_E[j + 1 :, j]).any())
            for j in range(stages)
        ]
        self.F = [
            work_array(self) for _ in range(stages)
        ]  # F(Y_j), where a combination not written by its DSS needs it
        self.L = [work_array(self) for _ in range(stages)]  # L Y_j (first the stage's right-hand side)
        self.Y = work_array(self)
        # an embedded pair's error estimate of the last step, e = Δt Σ_j (d_E,j S(Y_j) + d_I,j L Y_j)
        # (3, N; as ``ExplicitRK.error_estimate``), summed after x(n+1) from the stored F_j and L Y_j
        self.error_estimate = None if estimate is None else work_array(self)

    @staticmethod
    def _passes(terms) -> list:
        """The nonzero (c, a) of ``terms`` two at a time: the passes of a combination, in order."""
        terms = [(c, a) for c, a in terms if c != 0.0]
        return [terms[k : k + 2] for k in range(0, len(terms), 2)]

    def _combine(self, out, src, passes) -> None:
        """out = src + Σ c·a over ``passes``, one ``blas.axpbypcz``/``axpby`` a pass, each after the first from out."""
        for pair in passes:
            args = [a for c, x in pair for a in (f64(c), x)]
            self.model.pointwise(blas.axpbypcz if len(pair) == 2 else blas.axpby, f64(1.0), src, *args, out)
            src = out

    def advance(self, x):
        dt = self.dt
        self.linear.set_depth(x)
        A_E, A_I, b_E, b_I, F, L = self.A_E, self.A_I, self.b_E, self.b_I, self.F, self.L
        s = len(F)
        # combination k: stage k's right-hand side (or, a_kk = 0, Y_k) for k < s, x(n+1) for k = s; each is
        # x(n) + Σ c·a in passes from x itself, which holds x(n) until the last combination writes it
        combos = [
            self._passes(
                [(dt * A_E[k, j], F[j]) for j in range(k)] + [(dt * (A_I[k, j] - A_E[k, j]), L[j]) for j in range(k)]
            )
            for k in range(s)
        ]
        for wE, wI in ((b_E, b_I), (self.d_E, self.d_I)):  # x(n+1), then the estimate's (from zero)
            combos.append(
                self._passes([(dt * wE[j], F[j]) for j in range(s)] + [(dt * (wI[j] - wE[j]), L[j]) for j in range(s)])
            )
        outs = [L[k] if A_I[k, k] != 0.0 else self.Y for k in range(s)] + [x]
        done = [False] * (s + 1)  # a combination written with the RHS of the stage before (``_rhs``)
        evals = 0
        for i in range(s):
            a = A_I[i, i] * dt
            r = outs[i] if combos[i] else x  # no terms: x(n) itself (stage 0)
            if combos[i] and not done[i]:
                self._combine(r, x, combos[i])
            if a == 0.0:
                Y = r
                if self.needs_L[i]:
                    self.linear.apply(Y, L[i])
            else:  # (I − aL) Y_i = rhs_i, and L Y_i = (Y_i − rhs_i)/a in its back-substitution
                Y = self.Y
                self.helmholtz.solve(r, a, Y, implicit=L[i])
            if self.needs_F[i]:
                self._at(float(self.c[i]))
                done[i + 1] = self._rhs(i, Y, combos, outs, x)
                evals += 1
        if not done[s]:
            self._combine(x, x, combos[s])
        if self.error_estimate is not None:  # e = the first pass, then the others added
            e, (first, *rest) = self.error_estimate, combos[s + 1]
            (c1, a1), (c2, a2) = first if len(first) == 2 else (*first, (0.0, first[0][1]))
            self.model.pointwise(blas.axpby, f64(c1), a1, f64(c2), a2, e)
            self._combine(e, e, rest)
        self._hyperviscosity(x)
        return StepStats(evals, device_counts(self))

    def _rhs(self, i, Y, combos, outs, x) -> bool:
        """F_i = F(Y), and the next combination's pass that F_i enters written by its DSS
        (``ShallowWater.rhs_update``; the passes before it first, those after it next: the
        same passes in the same order, so the same bits); F_i stored only if another
        combination needs it. False, F_i stored, where the next combination lacks F_i, or
        its earlier passes would write Y before the RHS reads it."""
        F, k = self.F, i + 1
        passes = combos[k]
        p = next((n for n, pair in enumerate(passes) if any(arr is F[i] for _, arr in pair)), None)
        if not self.fused or p is None or (p > 0 and outs[k] is Y):
            self.model.rhs(Y, F[i])
            return False
        out = outs[k]
        self._combine(out, x, passes[:p])
        stored = any(arr is F[i] for combo in combos[k + 1 :] for pair in combo for _, arr in pair)
        fused = Update(out, ((1.0, out if p else x), *((c, None if arr is F[i] else arr) for c, arr in passes[p])))
        self.model.rhs_update(Y, [Update(F[i], ((1.0, None),)), fused] if stored else [fused])
        self._combine(out, out, passes[p + 1 :])
        return True


class ImexPair(ImexRK):
    """A built-in embedded IMEX pair of ``tables.IMEX_PAIRS`` as a stepper of its own
    (``imex_pair_steppers``); options the Helmholtz solve's, as ``imex``'s."""

    Options = HelmholtzOptions
    removed_options = REMOVED_SOLVER_OPTIONS

    def table(self) -> Table:
        return TABLES[self.name]


def imex_pair_steppers() -> tuple[type[Stepper], ...]:
    """A registered stepper class per built-in IMEX pair with an embedding (``ark324``, ``ark436``)."""
    return tuple(
        type(
            key.upper(),
            (ImexPair,),
            {
                "name": key,
                "order": t["order"],
                "embedded_order": t.get("embedded_order", 0),
                "advective_courant_limit": IMEX_ADVECTIVE_LIMITS[key],
                "__doc__": t["description"],
            },
        )
        for key, t in IMEX_PAIRS.items()
    )


@dataclass(frozen=True)
class ImexOptions(HelmholtzOptions):
    """Scene table ``[imex]`` (see ``Imex``): the pair and the Helmholtz solve's options."""

    scheme: str = "ars343"

    def __post_init__(self):
        if self.scheme not in IMEX:
            raise ValueError(f"scheme must be one of {', '.join(IMEX)} (got {self.scheme!r})")
        super().__post_init__()


class Imex(ImexRK):
    """IMEX Runge–Kutta ARS(2,3,2) / ARS(3,4,3): gravity waves implicit, the rest explicit.

    Options (scene table ``[imex]``): ``scheme`` ("ars343" | "ars232", the pairs of
    ``tables.IMEX``), ``tol`` (the Helmholtz CG's relative residual, 1e-6),
    ``maxiter`` (500), ``mean_depth``
    (H, m; 0 = the initial mean depth), ``precision`` ("float64" | "float32", as
    ``semi_implicit``'s). The Helmholtz solve is ``helmholtz.HelmholtzSolver``'s
    compiled CG; each stage's solve starts from the projection onto past solutions
    of the stages with its a (all of ARS's), ``guess_history`` (0..32, 8) of them
    (``helmholtz.GuessHistory``; 0: from the last one's solution). Why these defaults:
    docs/explanation/defaults.md. 3 (ARS(2,3,2)) or 4 (ARS(3,4,3)) RHS evaluations and one Helmholtz solve fewer
    a step; reports the Helmholtz iterations (under ``Simulation.run`` counted on
    the device and read once a block, the step a graph after the first). Both ARS
    pairs are stiffly accurate in A_I (b = its last row), not in A_E, so F is
    evaluated at the last stage. Raises ValueError without the continuity and
    pressure-gradient terms.
    """

    name = "imex"
    Options = ImexOptions
    removed_options = REMOVED_SOLVER_OPTIONS
    # |v| Δt/Δx at t = 0: below what ARS(3,4,3) ran stably on every case of the efficiency
    # study, above none it blew up at (docs/explanation/defaults.md)
    advective_courant_limit = 1.0

    def table(self):
        return TABLES[self.options.scheme]
