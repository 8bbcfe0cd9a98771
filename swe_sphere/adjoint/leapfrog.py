"""The adjoint of one step of the three-level schemes (``steppers.explicit``): leapfrog with the
Robert–Asselin filter and HOMME's leapfrog-trapezoidal. Their state is two levels,
s(n) = (x(n), x̃(n−1)) (x̃ the array the stepper carries, ``carried_arrays``: the filtered x(n−1), or x(n−1) itself), so the
reverse sweep's states and adjoints are (6, N): rows 0–2 x(n)'s, rows 3–5 x̃(n−1)'s.

Leapfrog, n ≥ 1 (F at t(n)):
    Φ = x̃ + 2Δt F(x),  N = H_2Δt(Φ),  x(n+1) = N,  x̃(n) = (1 − 2ε) x + ε x̃ + ε N;
reversed with μ' = (μ_x', μ_x̃') given: μ_N = μ_x' + ε μ_x̃', μ_Φ = H_2Δtᵀ μ_N,
    μ_x = (1 − 2ε) μ_x̃' + Fᵀ(x) 2Δt μ_Φ,  μ_x̃ = ε μ_x̃' + μ_Φ.
Leapfrog-trapezoidal, n ≥ 1 (F(x) at t(n), F(x*) at t(n+1)):
    x* = x̃ + 2Δt F(x),  Φ = x + Δt/2 F(x) + Δt/2 F(x*),  x(n+1) = H_Δt(Φ),  x̃(n) = x;
    μ_Φ = H_Δtᵀ μ_x',  μ_* = Fᵀ(x*) Δt/2 μ_Φ,
    μ_x = μ_x̃' + μ_Φ + Fᵀ(x) (2Δt μ_* + Δt/2 μ_Φ),  μ_x̃ = μ_*.
The first step (n = 0) of both is the explicit midpoint rule, x̃(0) = x(0): its table's adjoint
(``StepAdjoint``) plus μ_x̃', and x̃(−1) is never read (its adjoint 0). Fᵀ in the mass form as
``explicit``'s: x̄ = Tᵀ(Y) W k̄, R Q x̄ by the unweighted DSS; H the split ∇⁴ over the step's span
(``StepAdjoint.hyperviscosity_transpose``, this object's ``dt`` being that span); the parameters
(``parameters=True``) as there, the start's sums folded into this object's once it is reversed.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from ..model.launches import Update
from ..model.shallow_water import ShallowWater
from .explicit import StepAdjoint


class LeapfrogAdjoint(StepAdjoint):
    """The adjoint of one step of ``stepper`` (a ``Leapfrog`` or ``LeapfrogTrapezoidal``) on
    ``model`` at Δt = ``dt`` (s), its steps from model time ``t0`` (s): ``reverse(s, mu, k)``
    maps the adjoint μ (6, N) of s(k+1) to that of s(k) in place, s = s(k) (6, N) (module doc);
    ``parameters`` as ``StepAdjoint``'s (∂J/∂ν, ν_s, hs, g and Ω). ``dt`` (the attribute) is
    the ∇⁴'s span, 2Δt for leapfrog, Δt for leapfrog-trapezoidal; ``step_dt`` Δt. ValueError
    as ``StepAdjoint``, and from ``set_dt`` for another Δt (these schemes keep one).

    Work arrays (3, N): x, x̃, μ_Φ, x̄ (and with the trapezoid x*, μ_*), the start's
    ``StepAdjoint`` (two stages)."""

    def __init__(self, model: ShallowWater, stepper, dt: float, parameters: bool = False, t0: float = 0.0):
        steps = stepper.leapfrog()
        self.trapezoidal, self.start_table = steps.trapezoidal, steps.start
        self.step_dt = float(dt)
        self._setup(model, dt if self.trapezoidal else 2 * dt, parameters, t0)
        self.eps = steps.robert_asselin
        zeros = self._zeros
        self.x, self.old, self.mphi, self.held = zeros(3), zeros(3), zeros(3), zeros(3)
        if self.trapezoidal:
            self.star, self.mstar = zeros(3), zeros(3)
        self._for_dt()
        self.start = self._first_step(model, stepper, dt, parameters, t0)

    def _first_step(self, model, stepper, dt: float, parameters: bool, t0: float):
        """The first step's adjoint (``_reverse_start`` reverses it): its table's (the midpoint rule)."""
        return StepAdjoint(model, self.start_table, dt, parameters, t0)

    def _stage_plan(self, zeros) -> None:
        """None: ``reverse`` forms the step's states itself."""

    def set_dt(self, dt: float) -> None:
        if float(dt) != self.step_dt:
            raise ValueError(f"a three-level scheme's adjoint keeps its dt {self.step_dt!r} s (got {dt!r})")

    def before_hyperviscosity(self, out) -> None:
        """out = Φ, the step before its ∇⁴ (module doc), at the step's times."""
        m, dt, t = self.model, self.step_dt, self.t_n
        m.set_time(t)
        if not self.trapezoidal:
            m.rhs_update(self.x, (Update(out, ((1.0, self.old), (2 * dt, None))),))
            return
        m.rhs_update(self.x, (Update(out, ((1.0, self.x), (dt / 2, None))),))
        m.set_time(t + dt)
        m.rhs_update(self.star, (Update(out, ((1.0, out), (dt / 2, None))),))

    def _record(self, mu) -> list:
        """The launches of a step's reverse after μ_Φ (``reverse``), as (Y, k̄'s terms, launches)
        segments: the parameters' sums read each F's (Y, k̄)."""
        m, topo, dt, eps = self.model, self.model.topology, self.step_dt, self.eps
        X, O = mu[0:3], mu[3:6]
        add = ((1.0, X), (1.0, None))
        if not self.trapezoidal:
            kbar = [(2 * dt, self.mphi)]
            return [
                (None, None, [m.lincomb(X, [(1 - 2 * eps, O)]), m.lincomb(O, [(eps, O), (1.0, self.mphi)])]),
                (
                    self.x,
                    kbar,
                    [*self.tendency.transpose(self.x, kbar), *topo.dss_update(self.xbar, [(X, add)], False)],
                ),
            ]
        star = [(dt / 2, self.mphi)]
        kbar = [(2 * dt, self.mstar), (dt / 2, self.mphi)]
        return [
            (self.star, star, [*self.tendency.transpose(self.star, star), *topo.dss(self.xbar, False, self.mstar)]),
            (None, None, [m.lincomb(X, [(1.0, O), (1.0, self.mphi)]), m.lincomb(O, [(1.0, self.mstar)])]),
            (self.x, kbar, [*self.tendency.transpose(self.x, kbar), *topo.dss_update(self.xbar, [(X, add)], False)]),
        ]

    def reverse(self, x, mu, k: int = 0) -> None:
        """μ of s(k+1) → μ of s(k), in place; x = s(k) (6, N) (read only), k the step's index."""
        X, O = slice(0, 3), slice(3, 6)
        if k == 0 and self.start is not None:  # (a first step's own adjoint has no start)
            self._reverse_start(x, mu)
            return
        m, dt = self.model, self.step_dt
        wp.copy(self.x, x[X])
        wp.copy(self.old, x[O])
        self.t_n = self.t0 + k * dt  # the stepper's ``_at(0)`` at step k
        if self.trapezoidal:  # x* = x̃ + 2Δt F(x), which F(x*)'s transpose reads
            m.set_time(self.t_n)
            m.rhs_update(self.x, (Update(self.star, ((1.0, self.old), (2 * dt, None))),))
        self.combine(self.mphi, [(1.0, mu[X]), (self.eps, mu[O])])  # μ_N
        self._phi_adjoint()
        self._replay(mu)

    def _phi_adjoint(self) -> None:
        """μ_N → μ_Φ in ``mphi``, in place: the ∇⁴'s transpose (``semi_implicit`` adds its solve's)."""
        if self.substeps:
            self.hyperviscosity_transpose(self.mphi)

    def _reverse_start(self, x, mu) -> None:
        """The first step's reverse: the midpoint rule's adjoint on μ_x', plus μ_x̃' (x̃(0) = x(0));
        the start's parameter sums folded into this object's."""
        X, O = slice(0, 3), slice(3, 6)
        start = self.start
        wp.copy(self.held, mu[O])
        start.t0 = self.t0
        start.reverse(x[X], mu[X], 0)
        self.combine(mu[X], [(1.0, mu[X]), (1.0, self.held)])  # μ's rows 3–5 left: x̃(−1) is not read
        if self.parameters:
            self.d_nu += start.d_nu
            self.d_planet += start.d_planet
            start.d_nu, start.d_planet = np.zeros(2), np.zeros(2)
            for mine, theirs in ((self.d_hs, start.d_hs), (self.fbar, start.fbar)):
                self.combine(mine, [(1.0, mine), (1.0, theirs)])
                theirs.zero_()
