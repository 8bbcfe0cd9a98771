"""Exponential steppers: the exponential Rosenbrock–Euler method (``epi2``) and
Tokman's EPI3 (``epi3``), their φ-function products by KIOPS (``kiops.Kiops``)
on the JFNK stepper's finite-difference Jacobian–vector product
(``jacobian.FiniteDifferenceJacobian``).

With F the model's DSS'd RHS, J = F'(x(n)) (by forward differences, about x(n),
at t(n)) and the nonlinear remainder R(y) = F(y) − F(x(n)) − J (y − x(n)):

  epi2   x(n+1) = x(n) + Δt φ₁(ΔtJ) F(x(n))
         (Hochbruck, Lubich & Selhofer 1998, SIAM J. Sci. Comput. 19, 1552;
         second order; exact for linear F: the gravity waves about a state at
         rest are propagated, neither damped nor slowed);
  epi3   x(n+1) = x(n) + Δt φ₁(ΔtJ) F(x(n)) + ⅔ Δt φ₂(ΔtJ) R(x(n−1))
         (Tokman 2006, J. Comput. Phys. 213, 748, EPI3; the form of ECCC's
         GEF/WxFactory ``integrators/epi.py``, Gaudreault & Pudykiewicz 2016,
         J. Comput. Phys. 322, 827; third order: R vanishes to second order at
         x(n), so R(x(t(n) + s)) ≈ (s/Δt)² R(x(n−1)), whose integral against
         e^((Δt−s)J) is 2Δt φ₃(ΔtJ) R(x(n−1)), equal to ⅔ Δt φ₂(ΔtJ) R(x(n−1))
         up to O(Δt² J R) = O(Δt⁴)); the first step is an epi2 step (its O(Δt³)
         error, once, keeps the global third order).

Both are one KIOPS call a step (φ₁ and φ₂ together for epi3), with τ = 1,
A = ΔtJ and the vectors scaled by 1/‖F(x(n))‖, so ``tol`` bounds the Krylov
error of the step relative to ‖ΔtF(x(n))‖ (Euclidean norm of the unique-node
vectors, as FGMRES's); the forward differences' own error, ~1e-8 of each J·v
(a φ-product 2e-7–6e-7 from the exact one at 6 Δt_g on TC5 ne2, where KIOPS with
the exact J·v is within tol), bounds what a smaller tol buys. Cost a step: one F, one F a Krylov vector (the first,
of the zero vector, is free), for epi3 one more for J (x(n−1) − x(n)), with a
forcing two more.
F(x(n−1)) is kept from the last step. A time-dependent forcing: the step is that
of the autonomous system in (x, t), whose Jacobian has the column ∂F/∂t, which
adds Δt² φ₂(ΔtJ) ∂F/∂t to both steps and Δt ∂F/∂t to epi3's R (exactly, as
φ_k of a block-triangular matrix); ∂F/∂t by a centred difference in time (two
more RHS evaluations a step). Without it TC4 ran at order 1.0 with both.

Mass: F's and every J·v's depth integrate to zero, so every Krylov vector's
does, and so does the step's increment, but only to the round-off of a forward
difference (eps_mach/ε ~ 1e-8 of a J·v's own size: −1.7e-12 of the mass after 4
steps at 20 Δt_g on TC5 ne8); the increment's depth is set to integrate to zero
exactly (one inner product), as the exact one does, and the step keeps the mass
to round-off (not with a forcing, which may add mass).

Hyperviscosity is applied after the step, split from the dynamics, as for the
other steppers.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import warp as wp

from ..kernels import blas
from ..solvers.jacobian import FLOAT32_REFUSAL, FiniteDifferenceJacobian
from ..solvers.kiops import Kiops
from .base import Stepper, StepStats, entry, gathered_copy, load_entry

f64 = wp.float64


@dataclass(frozen=True)
class ExponentialOptions:
    """Scene tables ``[epi2]`` and ``[epi3]`` (see ``Epi2``)."""

    tol: float = 1e-7
    m_min: int = 10
    m_max: int = 64
    iop: int = 2

    def __post_init__(self):
        if not 0 < self.tol < 1:
            raise ValueError(f"tol must be in (0, 1) (got {self.tol})")
        if self.m_min < 3:  # the augmented start vector and φ₂'s take 3 (on m = 1 KIOPS's substeps shrink to nothing)
            raise ValueError(f"m_min must be >= 3 (got {self.m_min})")
        if self.m_max < self.m_min:
            raise ValueError(f"m_max must be >= m_min = {self.m_min} (got {self.m_max})")
        if not self.m_max <= 256:
            raise ValueError(f"m_max must be <= 256 (got {self.m_max})")
        if self.iop < 1:
            raise ValueError(f"iop must be >= 1 (got {self.iop})")


class _Exponential(Stepper):
    """An EPI step (module docstring); ``p`` φ-functions beyond φ₀ per call, ``multistep``:
    whether it reads x(n−1)."""

    Options = ExponentialOptions
    solvers = ("krylov", "substeps", "rejected")
    float32_refusal = FLOAT32_REFUSAL
    multistep = False

    def __init__(self, model, dt, options=None):
        super().__init__(model, dt, options)
        o = self.options
        dev, N = model.topology.device, self.N
        self.topology = topo = model.topology
        n3 = 3 * topo.nunique
        self.forced = "forcing" in model.terms
        self.p = 2 if self.multistep or self.forced else 1  # φ₂ carries R(x(n−1)) and Δt ∂F/∂t
        self.jacobian = FiniteDifferenceJacobian(model, self._F)
        self.kiops = Kiops(n3, self.p, o.m_max, topo, o.iop)
        self.m = o.m_min  # the Krylov size the next step starts with (KIOPS's last)
        self.Fx, self.work = wp.zeros((3, N), dtype=f64, device=dev), wp.zeros((3, N), dtype=f64, device=dev)
        # unique-node rows: F(x(n)), F(x(n−1)), J (x(n−1) − x(n)), x(n−1) − x(n), x(n), Δt ∂F/∂t
        self.T = wp.zeros((6, n3), dtype=f64, device=dev)
        self.rows_T = [self.T[k] for k in range(6)]
        if self.forced:  # F at t(n) ± Δt/64
            self.Fa, self.Fb = wp.zeros((3, N), dtype=f64, device=dev), wp.zeros((3, N), dtype=f64, device=dev)
        self.u = wp.zeros((self.p, n3), dtype=f64, device=dev)  # the scaled φ_k vectors
        self.rows_u = [self.u[k] for k in range(self.p)]
        self.w = wp.zeros(n3, dtype=f64, device=dev)
        # the depth's mass and the unit depth, as unique-node vectors: ∫ of w's depth is M[0]·w
        mass = np.zeros((2, 3, topo.nunique))
        mass[0, 2], mass[1, 2] = topo.area, 1.0
        self.M = wp.array(mass.reshape(2, n3), dtype=f64, device=dev)
        if self.multistep:
            self.xprev, self.Fprev = wp.zeros((3, N), dtype=f64, device=dev), wp.zeros((3, N), dtype=f64, device=dev)
        self._none = np.zeros(0)

    def _F(self, x, out):
        self.model.rhs(x, out)
        self.rhs_evals += 1

    # -- what carries over between steps -------------------------------------------
    def _uses_previous(self) -> bool:
        return self.multistep and self.steps > 0

    def state(self):
        s = super().state()
        s["krylov_size"] = self.m
        if self._uses_previous():
            s["previous"] = gathered_copy(self, self.xprev)
            s["previous_rhs"] = gathered_copy(self, self.Fprev)
        return s

    def restore(self, state):
        super().restore(state)
        self.m = int(entry(self, state, "krylov_size"))
        if self._uses_previous():
            load_entry(self, self.xprev, state, "previous")
            load_entry(self, self.Fprev, state, "previous_rhs")

    # -- the step ----------------------------------------------------------------------
    def _forcing_rate(self, x, out) -> None:
        """Unique-node out = Δt ∂F/∂t at t(n): (F(x, t(n) + δ) − F(x, t(n) − δ)) Δt / 2δ,
        δ = Δt/64 (error δ²/6 ∂³F/∂t³, below the third order's; two RHS evaluations: the
        model's RHS of the forcing alone adds it to a stale tendency); the model time
        is left at t(n)."""
        q = 1.0 / 64.0
        self._at(q)
        self._F(x, self.Fa)
        self._at(-q)
        self._F(x, self.Fb)
        self._at(0.0)
        self.model.pointwise(blas.axpby, f64(0.5 / q), self.Fa, f64(-0.5 / q), self.Fb, self.work)
        self.jacobian.gather(1.0, self.work, out)

    def advance(self, x):
        o, jac, T, lin = self.options, self.jacobian, self.rows_T, self.kiops.basis.lincomb
        self.rhs_evals = 0
        self._at(0.0)
        self._F(x, self.Fx)
        jac.gather(1.0, self.Fx, T[0])
        jac.gather(1.0, x, T[4])
        fnorm, xnorm = jac.norm(T[0]), jac.point_norm(T[4])
        stats = None
        if fnorm > 0.0:  # else x is a steady state of the dynamics
            lin(self.T, self._none, 1.0 / fnorm, T[0], self.rows_u[0])
            c = np.zeros(6)  # the φ₂ vector from the rows of T
            if self._uses_previous():  # ⅔ R(x(n−1)) / ‖F‖
                self.model.pointwise(blas.axpby, f64(1.0), self.xprev, f64(-1.0), x, self.work)
                jac.gather(1.0, self.work, T[3])
                jac.gather(1.0, self.Fprev, T[1])
                jac.apply(x, self.Fx, xnorm, T[3], T[2])
                c[:3] = np.array([-1.0, 1.0, -1.0]) * (2.0 / 3.0 / fnorm)
            if self.forced:  # Δt ∂F/∂t / ‖F‖ in φ₁'s part, and in R's for epi3
                self._forcing_rate(x, T[5])
                c[5] = (5.0 / 3.0 if self._uses_previous() else 1.0) / fnorm
            if self.p > 1:
                lin(self.T, c, 0.0, T[0], self.rows_u[1])

            def matvec(v, out):  # out = Δt J v
                jac.apply(x, self.Fx, xnorm, v, out, 0.0, self.dt)

            stats = self.kiops.apply(matvec, None, self.rows_u, self.w, 1.0, o.tol, self.m, o.m_min)
            self.m = stats.m
            if not self.forced:  # (a forcing may add mass)
                mass = self.kiops.basis.project_dots(self.M, self.w, 0, None, 1)[0]
                lin(self.M[1:], np.array([-mass / self.topology.total_area]), 1.0, self.w, self.w)
        if self.multistep:
            wp.copy(self.xprev, x)
            wp.copy(self.Fprev, self.Fx)
        if stats is not None:
            jac.scatter(self.w, self.work)
            self.model.pointwise(blas.axpby, f64(1.0), x, f64(self.dt * fnorm), self.work, x)
        self._hyperviscosity(x)
        counts = (stats.krylov, stats.substeps, stats.rejected) if stats else (0, 0, 0)
        return StepStats(self.rhs_evals, dict(zip(self.solvers, counts)))


class Epi2(_Exponential):
    """Exponential Rosenbrock–Euler x(n+1) = x(n) + Δt φ₁(ΔtJ) F(x(n)) (Hochbruck, Lubich
    & Selhofer 1998), second order, φ₁ by KIOPS (Gaudreault, Rainwater & Tokman 2018) on
    finite-difference J·v.

    Options (scene table ``[epi2]``): ``tol`` (1e-7: the Krylov error of a step relative to
    ‖ΔtF‖), ``m_min`` (10), ``m_max`` (64: Krylov sizes KIOPS chooses between; the
    last one starts the next step), ``iop`` (2: vectors each new Krylov vector is
    orthogonalised against). Reports per step the Krylov vectors, KIOPS substeps and
    rejected substeps; RHS evaluations a step: the Krylov vectors (the first, of a zero
    vector, costs none; F(x(n)) one), two more with a forcing (∂F/∂t).
    """

    name = "epi2"


class Epi3(_Exponential):
    """Tokman's (2006) EPI3 x(n+1) = x(n) + Δt φ₁(ΔtJ) F(x(n)) + ⅔ Δt φ₂(ΔtJ) R(x(n−1)),
    R the remainder of F's linearisation about x(n), third order, one KIOPS call a step;
    an epi2 first step. Options (``[epi3]``) and reports as ``epi2``'s; one more RHS
    evaluation a step (J (x(n−1) − x(n))).
    """

    name = "epi3"
    multistep = True
