"""The adjoint of one coarse step of multirate Adams–Bashforth 3 on element levels
(``steppers.multirate_ab.MultirateAB3``, local time stepping's ``method = "mrab3"``).

The step carries each level's last three tendencies H_k⁰, H_k¹, H_k² (the newest first) from
step to step, so the reverse sweep's states and adjoints hold them after x (the stepper's
``carried_arrays``). What it reads of the step is the stepper's ``local().mrab``
(``steppers.protocol.MrabSteps``). Over the finest sub-steps j = 0 … n−1 (n = 2^K), x_0 = x(n):
at each level k whose step starts at j, H_k ← (f_k(x_j), H_k⁰, H_k¹) (f_k the level's part of
the tendency, ``rhs_part``), then x_(j+1) = x_j + Δt Σ_k Σ_i w[j, k, i] H_kⁱ (``ab3_weights``;
the stepper's sums regrouped by node, ``multirate_ab``'s "The sums", are the same to
round-off), and x(n+1) = H(x_n) (the ∇⁴). Reversed, sub-steps last first, with the adjoints μ
= R Q λ of ``explicit`` (the mass form): H̄_kⁱ += Δt w[j, k, i] x̄; then for each level due at
j, x̄ += f_kᵀ(x_j) H̄_k⁰ (its elements alone, ``TendencyTranspose.transpose(..., runs)``) and
H̄_k ← (H̄_k¹, H̄_k², 0). The first two coarse steps (the start) take n steps of the inner table
at Δt/n, recording f_k(x_j) at each level's step starts: each sub-step reversed by the table's
adjoint (``StepAdjoint.reverse_dynamics``), then the recordings' as above. Each reversed step
takes its sub-steps again from the state (x(n), H) first, holding x_j. With ``parameters``,
g's and Ω's sums at each evaluation and the start's, ν's and hs's as the other adjoints'.
"""

from __future__ import annotations

import numpy as np

from ..model.shallow_water import ShallowWater, element_runs
from .explicit import StepAdjoint


class MrabAdjoint(StepAdjoint):
    """The adjoint of one coarse step of ``stepper`` (an ``Lts`` with ``method = "mrab3"``, its
    levels fixed) of ``model`` at Δt = ``dt`` (s) from model time ``t0`` (s): ``reverse(s, mu,
    k)`` maps the adjoint μ of s(k+1) to that of s(k) in place, s = (x, H_0⁰, H_0¹, H_0², H_1⁰,
    …) (3 + 9·levels, N) (module doc). With ``parameters`` the ∇⁴'s sums as ``StepAdjoint``'s
    (from x_n, the last sub-step taken too), hs's through each level's topography (f̄), g's and
    Ω's each due level's ⟨H̄_k⁰, its f_k of those terms at x_j⟩ (``planet_terms`` with the
    level's part) and the start's inner stages' (folded in). ValueError as ``StepAdjoint``.

    Work arrays (3, N): the n sub-steps' starts x_j, each level's three tendencies, the inner
    table's stages (its ``StepAdjoint``'s and s + 1 more), two for the transposes."""

    def __init__(self, model: ShallowWater, stepper, dt: float, parameters: bool = False, t0: float = 0.0):
        self._setup(model, dt, parameters, t0)
        mrab = self.mrab = stepper.local().mrab
        self.n, self.count, self.history, self.start_steps = mrab.substeps, mrab.levels, mrab.history, mrab.start_steps
        self.w = mrab.weights  # (n, levels, 3) in Δt
        zeros = self._zeros
        self.xs = [zeros(3) for _ in range(self.n)]
        self.H = [[zeros(3) for _ in range(self.history)] for _ in range(self.count)]
        table = mrab.inner
        self.inner = StepAdjoint(model, table, dt / self.n, parameters, t0)  # a start sub-step's stages
        self.a = [[float(v) for v in row] for row in table.A_E]
        self.b = [float(v) for v in table.b_E]
        self.K = [zeros(3) for _ in self.b]
        self.Y, self.tmp, self.last = zeros(3), zeros(3), zeros(3)  # last: x_n, before the ∇⁴
        if mrab.parts == [None]:  # one level: the whole grid's tendency
            self.runs = [None]
        else:
            level = mrab.level[model.topology.elements]
            self.runs = [element_runs(np.flatnonzero(level == k), 0) for k in range(self.count)]
        self._for_dt()

    def _stage_plan(self, zeros) -> None:
        """None: ``reverse`` takes the sub-steps again itself."""

    def _due(self, j: int) -> list:
        """The levels whose step starts at sub-step j."""
        return [k for k in range(self.count) if j % 2 ** (self.count - 1 - k) == 0]

    def _rows(self, a, k: int, i: int):
        """Level k's tendency i's rows of a state or adjoint ``a`` (module doc)."""
        first = 3 + 3 * (self.history * k + i)
        return a[first : first + 3]

    def _recompute(self, s, k: int) -> None:
        """The sub-steps' starts x_j of step k from s (module doc)."""
        n, m, dt = self.n, self.model, self.dt
        x = self.xs[0]
        self.combine(x, [(1.0, s[0:3])])
        if k < self.start_steps:  # the inner table in Butcher form (the stepper's stage form to round-off)
            tau = dt / n
            for j in range(n if self.parameters else n - 1):
                for i, row in enumerate(self.a):
                    self.combine(self.Y, [(1.0, self.xs[j]), *((tau * a, K) for a, K in zip(row[:i], self.K))])
                    m.set_time(self.t0 + (k + (j + float(self.inner.c[i])) / n) * dt)
                    m.rhs(self.Y, self.K[i])
                end = self.xs[j + 1] if j + 1 < n else self.last
                self.combine(end, [(1.0, self.xs[j]), *((tau * b, K) for b, K in zip(self.b, self.K))])
            return
        for lv in range(self.count):
            for i in range(self.history):
                self.combine(self.H[lv][i], [(1.0, self._rows(s, lv, i))])
        for j in range(n):
            x = self.xs[j]
            m.set_time(self.t0 + (k + j / n) * dt)
            for lv in self._due(j):
                h = self.H[lv]
                h.insert(0, h.pop())
                self.mrab.evaluate(lv, x, h[0])
            if j + 1 < n or self.parameters:  # x_(j+1) (x_n: ``last``) gains every level's integral
                terms = [
                    (dt * float(self.w[j, lv, i]), self.H[lv][i])
                    for lv in range(self.count)
                    for i in range(self.history)
                ]
                self.combine(self.xs[j + 1] if j + 1 < n else self.last, [(1.0, x), *terms])

    def before_hyperviscosity(self, out) -> None:
        """out = x_n, the step before its ∇⁴."""
        self.combine(out, [(1.0, self.last)])

    def _record_transpose(self, x, mu, lv: int) -> None:
        """μ_x += f_lvᵀ(x) H̄_lv⁰, then H̄_lv ← (H̄_lv¹, H̄_lv², 0); with ``parameters`` the level's
        share of g's and Ω's sums first."""
        if self.parameters:
            part = self.mrab.parts[lv]
            self.planet_terms(x, [(1.0, self._rows(mu, lv, 0))], None, True, part)
        launches = self._adjoints.get(("record", x.ptr, mu.ptr, lv))
        if launches is None:
            h = [self._rows(mu, lv, i) for i in range(self.history)]
            launches = [
                *self.tendency.transpose(x, [(1.0, h[0])], None, self.runs[lv]),
                *self.model.topology.dss(self.xbar, False, self.tmp),
                self.model.lincomb(mu[0:3], [(1.0, mu[0:3]), (1.0, self.tmp)]),
                self.model.lincomb(h[0], [(1.0, h[1])]),
                self.model.lincomb(h[1], [(1.0, h[2])]),
                self.model.lincomb(h[2], [(0.0, h[2])]),
            ]
            self._adjoints[("record", x.ptr, mu.ptr, lv)] = launches
        for launch in launches:
            launch.launch()

    def reverse(self, s, mu, k: int = 0) -> None:
        """μ of s(k+1) → μ of s(k), in place; s = s(k) (read only), k the step's index."""
        self._recompute(s, k)
        X = slice(0, 3)
        if self.substeps:
            self.hyperviscosity_transpose(mu[X])
        for j in reversed(range(self.n)):
            if k < self.start_steps:
                self.inner.t0 = self.t0 + k * self.dt  # its sub-step j at t(n) + (j + c)·Δt/n
                self.inner.reverse_dynamics(self.xs[j], mu[X], j)
            else:  # H̄_kⁱ += Δt w[j, k, i] x̄
                for lv in range(self.count):
                    for i in range(self.history):
                        h = self._rows(mu, lv, i)
                        self.combine(h, [(1.0, h), (self.dt * float(self.w[j, lv, i]), mu[X])])
            for lv in self._due(j):
                self._record_transpose(self.xs[j], mu, lv)
        if self.parameters and k < self.start_steps:  # the inner stages' sums into this object's
            inner = self.inner
            self.d_planet += inner.d_planet
            inner.d_planet = np.zeros(2)
            self.combine(self.fbar, [(1.0, self.fbar), (1.0, inner.fbar)])
            inner.fbar.zero_()
