"""IMEX additive Runge–Kutta (Ascher, Ruuth & Spiteri 1997, Appl. Numer. Math.
25, 151; "ARS"): the linear gravity-wave terms L (``helmholtz.GravityWave``)
implicit, the rest N = F − L explicit, as HOMME-NH and ClimaTimeSteppers split.

With the explicit tableau (Â, b̂) and the implicit one (A, b) of s stages,
A lower triangular (diagonally implicit, a_ii = 0 allowed: an explicit stage),
Â strictly lower triangular, and common abscissae c,

    Y_i = x(n) + Δt Σ_{j<i} (Â_ij N(Y_j) + A_ij L Y_j) + Δt A_ii L Y_i,
    x(n+1) = x(n) + Δt Σ_j (b̂_j N(Y_j) + b_j L Y_j).

Each stage with A_ii ≠ 0 is one solve of (I − A_ii Δt L) Y_i = rhs_i through
the Helmholtz equation, and L Y_i = (Y_i − rhs_i)/(A_ii Δt) follows from it
without another product; an explicit stage takes L Y_i from a product, and
only where the two tableaux weigh it differently (N = F − L). ARS's first
stage is x(n) (A's first row and column zero, A_ii = γ after it) and b̂ = b,
so x(n+1) = x(n) + Δt Σ_j b_j F(Y_j) with F the model's RHS: s RHS
evaluations, s − 1 solves and one product with L a step. Both ARS schemes are
stiffly accurate in A (b = last row), not in Â, so F is evaluated at the last
stage. The same code steps a user's pair (``butcher``, ``stepper = "tableau"``).

* ``ars232``: ARS(2,3,2), §2.5: γ = 1 − 1/√2, δ = −2√2/3; second order.
* ``ars343``: ARS(3,4,3), §2.7: γ the root 0.4358665215… of
  6γ³ − 18γ² + 9γ − 1 = 0 (L-stable SDIRK3), b = (0, β₁, β₂, γ) with
  β₁ = −3γ²/2 + 4γ − 1/4, β₂ = 3γ²/2 − 5γ + 5/4; Â₄₂ = Â₄₃ = 0.55292914803…,
  Â₄₁ = 1 − 2Â₄₂ and Â₃₁, Â₃₂ from the third-order conditions (the paper
  prints them to 10 digits; ClimaTimeSteppers' closed forms); third order.

Mass: every stage keeps ∫h (F_h and L_h integrate to zero; the solve fixes
∫z_h), so x(n+1) has the mass of x(n) to round-off. Hyperviscosity is split
after the step, as for every stepper.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import warp as wp

from ..kernels import blas
from .base import Stepper, StepStats
from .helmholtz import REMOVED_SOLVER_OPTIONS, GravityWave, HelmholtzSteps, check_solve_options

f64 = wp.float64


def _ars232():
    g, d = 1.0 - 1.0 / math.sqrt(2.0), -2.0 * math.sqrt(2.0) / 3.0
    A_exp = np.array([[0, 0, 0], [g, 0, 0], [d, 1 - d, 0]])
    A_imp = np.array([[0, 0, 0], [0, g, 0], [0, 1 - g, g]])
    return A_exp, A_imp, A_imp[-1].copy(), 2


def _ars343():
    g = 0.4358665215084590
    b1, b2 = -1.5 * g * g + 4 * g - 0.25, 1.5 * g * g - 5 * g + 1.25
    a42 = a43 = 0.5529291480359398
    a31 = (1 - 4.5 * g + 1.5 * g * g) * a42 + (2.75 - 10.5 * g + 3.75 * g * g) * a43 - 3.5 + 13 * g - 4.5 * g * g
    a32 = (-1 + 4.5 * g - 1.5 * g * g) * a42 + (-2.75 + 10.5 * g - 3.75 * g * g) * a43 + 4 - 12.5 * g + 4.5 * g * g
    A_exp = np.array([[0, 0, 0, 0], [g, 0, 0, 0], [a31, a32, 0, 0], [1 - 2 * a42, a42, a43, 0]])
    A_imp = np.array([[0, 0, 0, 0], [0, g, 0, 0], [0, (1 - g) / 2, g, 0], [0, b1, b2, g]])
    return A_exp, A_imp, A_imp[-1].copy(), 3


SCHEMES = {"ars232": _ars232, "ars343": _ars343}


def tableau(scheme: str):
    """(Â, A, b, order) of an ARS scheme: explicit and implicit stage matrices
    (s+1)×(s+1) and the weights shared by both (b̂ = b)."""
    return SCHEMES[scheme]()


@dataclass(frozen=True)
class ImexOptions:
    """Scene table ``[imex]`` (see ``Imex``)."""

    scheme: str = "ars343"
    tol: float = 1e-6
    maxiter: int = 500
    mean_depth: float = 0.0
    precision: str = "double"
    guess_history: int = 8

    def __post_init__(self):
        if self.scheme not in SCHEMES:
            raise ValueError(f"scheme must be one of {', '.join(SCHEMES)} (got {self.scheme!r})")
        check_solve_options(self)


class Imex(HelmholtzSteps, Stepper):
    """IMEX Runge–Kutta ARS(2,3,2) / ARS(3,4,3): gravity waves implicit, the rest explicit.

    Options (scene table ``[imex]``): ``scheme`` ("ars343" | "ars232"), ``tol``
    (the Helmholtz CG's relative residual, 1e-6: on TC5 ne16 at 10x the
    gravity-wave limit ARS(3,4,3)'s day-1 error against a converged run is
    2.528e-4 against 2.525e-4 with 1e-10 and 1e-8, with 2.5x fewer
    iterations; 1e-4 gives 3.0e-4), ``maxiter`` (500),
    ``mean_depth`` (H, m; 0 = the initial mean depth), ``precision``
    ("double" | "mixed", as ``semi_implicit``'s). The Helmholtz solve is
    ``helmholtz.GravityWave``'s compiled CG; each stage's solve starts from the
    projection onto past solutions of the stages with its a (all of ARS's),
    ``guess_history`` (0..32, 8) of them (``helmholtz.GuessHistory``; 0: from the last
    one's solution; TC5 ne8 ARS(3,4,3), CG iterations a solve over a day after 6 h at
    2 / 8x the gravity-wave limit: 3.04 / 18.2 from the last solution, 3.84 / 17.8,
    3.33 / 17.7, 2.68 / 16.4, 2.48 / 15.7 with 2, 4, 8, 16). 3 (ARS(2,3,2)) or 4 (ARS(3,4,3)) RHS evaluations and
    one Helmholtz solve fewer a step; reports the Helmholtz iterations (under
    ``Simulation.run`` counted on the device and read once a block, the step a
    graph after the first). Raises ValueError without the continuity and
    pressure-gradient terms.
    """

    name = "imex"
    Options = ImexOptions
    removed_options = REMOVED_SOLVER_OPTIONS
    # ARS(3,4,3) in the 2026-11-23 study (docs/efficiency.md), |v| Δt/Δx at t = 0: stable at
    # 0.88 (TC5 ne16), 1.47 (TC6 ne16), 1.20 (Galewsky ne30); blew up at 1.10 (TC5 ne30,
    # day 2.9, where the flow round the mountain speeds up), 2.21 and above elsewhere
    advective_courant_limit = 1.0

    def __init__(self, model, dt, options=None):
        super().__init__(model, dt, options)
        o = self.options
        self.gw = GravityWave(model, o.mean_depth, o.tol, o.maxiter, warm=True, precision=o.precision, history=o.guess_history)
        A_E, b_E, A_I, b_I, self.c = (np.asarray(t, dtype=float) for t in self.tables())
        stages = len(b_E)
        self.A_E, self.A_I, self.b_E, self.b_I = A_E, A_I, b_E, b_I
        # F(Y_j) is needed where the explicit part weighs it, L Y_j where the two parts weigh it
        # differently (N_j = F_j − L_j enters with A_E, b_E; L Y_j with A_I, b_I)
        self.needs_F = [bool(b_E[j] != 0 or np.any(A_E[j + 1 :, j] != 0)) for j in range(stages)]
        self.needs_L = [bool(b_I[j] != b_E[j] or np.any(A_I[j + 1 :, j] != A_E[j + 1 :, j])) for j in range(stages)]
        self.xn = self._buffer()
        self.F = [self._buffer() for _ in range(stages)]  # F(Y_j)
        self.L = [self._buffer() for _ in range(stages)]  # L Y_j (first the stage's right-hand side)
        self.Y = self._buffer()

    def tables(self):
        """(A_E, b_E, A_I, b_I, c): the explicit and implicit stage matrices (s × s,
        A_E strictly lower triangular, A_I lower triangular), their weights and the
        abscissae; ARS: b_E = b_I, c = Â1."""
        A_exp, A_imp, b, _ = tableau(self.options.scheme)
        return A_exp, b, A_imp, b, A_exp.sum(axis=1)

    def _combine(self, out, base, terms):
        """out = base + Σ c·x over the nonzero (c, x) of ``terms``, two at a time."""
        terms = [(c, x) for c, x in terms if c != 0.0]
        src = base
        for k in range(0, len(terms), 2):
            pair = terms[k : k + 2]
            if len(pair) == 2:
                (c1, x1), (c2, x2) = pair
                self._pointwise(blas.axpbypcz, f64(1.0), src, f64(c1), x1, f64(c2), x2, out)
            else:
                self._pointwise(blas.axpby, f64(1.0), src, f64(pair[0][0]), pair[0][1], out)
            src = out
        if src is base:
            wp.copy(out, base)

    def advance(self, x):
        m, gw, dt = self.model, self.gw, self.dt
        gw.set_depth(x)
        A_E, A_I, F, L = self.A_E, self.A_I, self.F, self.L
        wp.copy(self.xn, x)
        evals = 0
        for i in range(len(F)):
            terms = [(dt * A_E[i, j], F[j]) for j in range(i)]
            terms += [(dt * (A_I[i, j] - A_E[i, j]), L[j]) for j in range(i)]
            a = A_I[i, i] * dt
            if i == 0 and a == 0.0:  # an explicit first stage: Y_0 = x(n)
                Y = x
            elif a == 0.0:  # an explicit later stage
                Y = self.Y
                self._combine(Y, self.xn, terms)
            else:  # (I − aL) Y_i = rhs_i; L Y_i = (Y_i − rhs_i)/a without another product
                Y = self.Y
                self._combine(L[i], self.xn, terms)  # rhs_i, kept to form L Y_i
                gw.solve(L[i], a, Y)
                self._pointwise(blas.axpby, f64(1.0 / a), Y, f64(-1.0 / a), L[i], L[i])
            if a == 0.0 and self.needs_L[i]:
                gw.apply(Y, L[i])
            if self.needs_F[i]:
                self._at(float(self.c[i]))
                m.rhs(Y, F[i])
                evals += 1
        b_E, b_I = self.b_E, self.b_I
        self._combine(x, self.xn, [(dt * b_E[j], F[j]) for j in range(len(F))] + [(dt * (b_I[j] - b_E[j]), L[j]) for j in range(len(F))])
        m.hyperviscosity(x, dt)
        return StepStats(evals, self._device_counts())
