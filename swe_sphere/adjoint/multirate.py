"""The adjoint of one step of the split-explicit Wicker–Skamarock RK3 (``steppers.multirate.
SplitExplicit``): three stages from x(n), each the slow tendency of its start held over
forward–backward substeps of the gravity waves, then the split ∇⁴.

The step in h′ = h − H (a constant shift: its adjoint is the identity), stage i from its
start s_i (s_0 = x(n), s_i = z_(i−1)) with τ = c_i Δt / n_i, S = N(s_i) (the slow wind terms),
h_s = s_i's depth + H, and from (v, h) = x(n):
    h̃ = h + β (h − h_old)  (the first substep: h̃ = h),
    v ← v + τ S − g τ G h̃,   h_old ← h,   h ← h + τ C(v, h_s),
C(v, h_s) = −D(h_s v) (the continuity's tendency at the substep's new wind), z_i = (v, h) after
n_i substeps; x(n+1) = H(z_2). Reversed with the adjoints μ = R Q λ of ``explicit`` (the mass
form), the substeps last first, (v̄, h̄, h̄_old) of the state after each:
    c̄ = τ h̄:  v̄ += Cᵀ_v c̄,  h̄_s += Cᵀ_h c̄;   h̄ ← h̄ + h̄_old;
    S̄ += τ v̄;  h̃̄ = −g τ Gᵀ v̄;  h̄ += (1 + β) h̃̄,  h̄_old = −β h̃̄ (the first: h̄ += h̃̄),
then x̄(n) += (v̄, h̄) and s̄_i = Nᵀ S̄ + (0, 0, h̄_s): x̄(n)'s where i = 0, z̄_(i−1) otherwise.
Cᵀ, Gᵀ (the pressure gradient's) and Nᵀ are ``StepAdjoint._transpose`` with those terms, each
reading only its own rows of k̄, R Q x̄ by the unweighted DSS. Each reversed step recomputes its
stages and substeps from x(n) with the stepper's own substep (``forward_backward``), holding
every substep's wind.
"""

from __future__ import annotations

import warp as wp

from ..model.shallow_water import ShallowWater
from .explicit import StepAdjoint


class SplitExplicitAdjoint(StepAdjoint):
    """The adjoint of one ``SplitExplicit`` step (``stepper``) of ``model`` at Δt = ``dt`` (s):
    ``reverse(x, mu, k)`` as ``StepAdjoint``'s. ValueError for ``parameters`` (the substeps'
    g and the slow part's hs are not summed yet), a model with a forcing, and as ``StepAdjoint``.

    Work arrays (3, N): x(n) in h′, the stages' ends z_0…z_2, S, every substep's (v, h_s)
    (Σ n_i of them), four for the adjoints; (1, N): h̄_old and h̄_s."""

    def __init__(self, model: ShallowWater, stepper, dt: float, parameters: bool = False, t0: float = 0.0):
        if parameters or "forcing" in model.terms:
            raise ValueError("split_explicit's gradient is of the initial state alone and takes no forcing yet")
        self._setup(model, dt, parameters, t0)
        self.stepper = stepper
        zeros = self._zeros
        self.xn, self.S = zeros(3), zeros(3)
        self.Z = [zeros(3) for _ in stepper.C]
        self.winds: list = []  # every substep's W = (v, h_s), made on the first reverse (n_i from H)
        self.state, self.tmp, self.acc, self.sbar = zeros(3), zeros(3), zeros(3), zeros(3)
        self.old, self.hs_bar = zeros(1), zeros(1)
        self._for_dt()

    def _stage_plan(self, zeros) -> None:
        """None: ``reverse`` recomputes the stages with the stepper's substeps."""

    def _substeps(self, x) -> None:
        """The stages and substeps of the step from x = x(n) (full depth), as the stepper takes
        them: z_i, and every substep's W in ``winds``."""
        st, m = self.stepper, self.model
        assert st.split.H != 0.0  # the stepper's first step fixed H (the sweep steps forward before it reverses)
        depth = st.split.depth
        if not self.winds:
            self.winds = [self._zeros(3) for _ in range(sum(st.n_fast))]
        self.combine(self.xn, [(1.0, x)])
        self.combine(self.xn[2:3], [(1.0, x[2:3]), (-1.0, depth)])  # h′
        j = 0
        for i, (c, n) in enumerate(zip(st.C, st.n_fast)):
            src = self.xn if i == 0 else self.Z[i - 1]
            m.rhs(src, self.S, st.slow_terms)
            self.combine(st.W[2:3], [(1.0, src[2:3]), (1.0, depth)])  # h_s
            out, tau = self.Z[i], float(c) * self.dt / n
            for k in range(n):
                st.forward_backward(out if k else self.xn, out, tau, self.S, first=k == 0)
                wp.copy(self.winds[j], st.W)
                j += 1
            self.combine(out[0:2], [(1.0, st.W[0:2])])

    def _record(self, mu) -> list:
        """The launches of the reverse after the ∇⁴'s transpose (module doc), as one segment."""
        st, m, dss = self.stepper, self.model, self.model.topology.dss
        beta = float(st.options.divergence_damping)
        V, H = slice(0, 2), slice(2, 3)
        s, tmp, old, acc, sbar, hs_bar = self.state, self.tmp, self.old, self.acc, self.sbar, self.hs_bar
        out = [m.lincomb(acc, [(0.0, acc)])]
        zbar, j = mu, len(self.winds)
        for i in reversed(range(len(st.C))):
            tau = float(st.C[i]) * self.dt / st.n_fast[i]
            out += [m.lincomb(s, [(1.0, zbar)]), *(m.lincomb(a, [(0.0, a)]) for a in (old, sbar, hs_bar))]
            for k in reversed(range(st.n_fast[i])):
                j -= 1
                first = k == 0 or not beta
                out += [
                    # the depth update: c̄ = τ h̄ through Cᵀ at (v, h_s); h̄ ← h̄ + h̄_old
                    *self._transpose(self.winds[j], [(tau, s)], ("continuity",)),
                    *dss(self.xbar, False, tmp),
                    m.lincomb(s[V], [(1.0, s[V]), (1.0, tmp[V])]),
                    m.lincomb(hs_bar, [(1.0, hs_bar), (1.0, tmp[H])]),
                    m.lincomb(s[H], [(1.0, s[H]), (1.0, old)]),
                    # the wind update: S̄ += τ v̄; h̃̄ = −gτ Gᵀ v̄ (the pressure gradient's transpose at τ v̄)
                    m.lincomb(sbar[V], [(1.0, sbar[V]), (tau, s[V])]),
                    *self._transpose(self.xn, [(tau, s)], ("pressure_gradient",)),
                    *dss(self.xbar, False, tmp),
                    m.lincomb(s[H], [(1.0, s[H]), (1.0 if first else 1.0 + beta, tmp[H])]),
                    m.lincomb(old, [(0.0 if first else -beta, tmp[H])]),
                ]
            src = self.xn if i == 0 else self.Z[i - 1]
            out += [
                m.lincomb(acc, [(1.0, acc), (1.0, s)]),  # x(n) started the substeps
                *self._transpose(src, [(1.0, sbar)], st.slow_terms),
                *dss(self.xbar, False, tmp),
                m.lincomb(tmp[H], [(1.0, tmp[H]), (1.0, hs_bar)]),
            ]
            if i == 0:
                out.append(m.lincomb(acc, [(1.0, acc), (1.0, tmp)]))
            else:  # z_(i−1)'s state is read by its stage's slow transpose above only: it holds z̄_(i−1) now
                zbar = self.Z[i - 1]
                out.append(m.lincomb(zbar, [(1.0, tmp)]))
        out.append(m.lincomb(mu, [(1.0, acc)]))
        return [(None, None, out)]

    def reverse(self, x, mu, k: int = 0) -> None:
        """μ of x(k+1) → μ of x(k), in place; x = x(k) (read only)."""
        self._substeps(x)
        if self.substeps:
            self.hyperviscosity_transpose(mu)
        self._replay(mu)
