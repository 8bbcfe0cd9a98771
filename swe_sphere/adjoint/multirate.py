"""The adjoints of one step of the multirate steppers (``steppers.multirate``): the multirate
infinitesimal tables (``MriAdjoint``: its class doc) and, here, the split-explicit
Wicker–Skamarock RK3 (``SplitExplicitAdjoint``): three stages from x(n), each the slow tendency
of its start held over forward–backward substeps of the gravity waves, then the split ∇⁴.

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
Cᵀ, Gᵀ (the pressure gradient's) and Nᵀ are ``TendencyTranspose.transpose`` with those terms, each
reading only its own rows of k̄, R Q x̄ by the unweighted DSS. Each reversed step recomputes its
stages and substeps from x(n) with the stepper's own substep (``forward_backward``), holding
every substep's wind.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from ..core.errors import ArgumentError
from ..model.shallow_water import ShallowWater, element_runs
from .explicit import StepAdjoint


class _Recomputed(StepAdjoint):
    """A step's adjoint that takes the step's stages again from x(n) itself (``_recompute``),
    then reverses the ∇⁴ and its recorded transposes (``_record``)."""

    def _stage_plan(self, zeros) -> None:
        """None: ``_recompute`` forms the stages."""

    def _recompute(self, x, k: int) -> None:
        raise NotImplementedError

    def _at(self, k: int, c: float) -> None:
        """The model time of step k's abscissa c, t0 + (k + c)·Δt (the stepper's ``_at``: a
        forcing's, which adds to F, not to its Jacobian)."""
        self.model.set_time(self.t0 + (k + c) * self.dt)

    def reverse(self, x, mu, k: int = 0) -> None:
        """μ of x(k+1) → μ of x(k), in place; x = x(k) (read only), k the step's index."""
        self._recompute(x, k)
        if self.substeps:
            self.hyperviscosity_transpose(mu)
        self._replay(mu)


class SplitExplicitAdjoint(_Recomputed):
    """The adjoint of one ``SplitExplicit`` step (``stepper``) of ``model`` at Δt = ``dt`` (s):
    ``reverse(x, mu, k)`` as ``StepAdjoint``'s; with ``parameters`` its ∇⁴ as there, g's terms
    those of the slow topography −g∇hs and of the substeps' −gτ G h̃, Ω's the slow Coriolis
    term's, hs's the topography's (through f̄) and the ∇⁴'s; a forcing (in the slow part) at
    each stage's time. ValueError as ``StepAdjoint``.

    Work arrays (3, N): x(n) in h′, the stages' ends z_0…z_2, S, every substep's (v, h_s)
    (Σ n_i of them; with ``parameters`` its h̃ too), four for the adjoints; (1, N): h̄_old
    and h̄_s."""

    def __init__(self, model: ShallowWater, stepper, dt: float, parameters: bool = False, t0: float = 0.0):
        self._setup(model, dt, parameters, t0)
        self.stepper = stepper  # its ``split_explicit()``, read again once its first step fixed n_fast and H
        zeros = self._zeros
        self.xn, self.S = zeros(3), zeros(3)
        self.Z = [zeros(3) for _ in stepper.split_explicit().c]
        self.winds: list = []  # every substep's W = (v, h_s), made on the first reverse (n_i from H)
        self.tilde: list = []  # with ``parameters``, every substep's h̃ (its h row), which −gτ G reads
        self.state, self.tmp, self.acc, self.sbar = zeros(3), zeros(3), zeros(3), zeros(3)
        self.old, self.hs_bar = zeros(1), zeros(1)
        self._for_dt()

    def _recompute(self, x, k: int) -> None:
        """The stages and substeps of step k from x = x(n) (full depth), as the stepper takes
        them: z_i, and every substep's W in ``winds`` (and h̃ in ``tilde``)."""
        steps, m = self.stepper.split_explicit(), self.model
        assert steps.H != 0.0  # the stepper's first step fixed H (the sweep steps forward before it reverses)
        depth, beta = steps.depth, steps.divergence_damping
        if not self.winds:
            self.winds = [self._zeros(3) for _ in range(sum(steps.n_fast))]
            self.tilde = [self._zeros(3) for _ in self.winds] if self.parameters else []
        self.combine(self.xn, [(1.0, x)])
        self.combine(self.xn[2:3], [(1.0, x[2:3]), (-1.0, depth)])  # h′
        j = 0
        for i, (c, n) in enumerate(zip(steps.c, steps.n_fast)):
            src = self.xn if i == 0 else self.Z[i - 1]
            self._at(k, float(steps.c[i - 1]) if i else 0.0)
            m.rhs(src, self.S, steps.slow_terms)
            self.combine(steps.wind[2:3], [(1.0, src[2:3]), (1.0, depth)])  # h_s
            out, tau = self.Z[i], float(c) * self.dt / n
            for sub in range(n):
                prev = out if sub else self.xn
                if self.tilde:  # the depth the substep's gradient reads (``SplitExplicit.forward_backward``)
                    self.combine(self.tilde[j][2:3], [(1.0, (steps.weighted if sub and beta else prev)[2:3])])
                steps.substep(prev, out, tau, self.S, first=sub == 0)
                wp.copy(self.winds[j], steps.wind)
                j += 1
            self.combine(out[0:2], [(1.0, steps.wind[0:2])])

    def before_hyperviscosity(self, out) -> None:
        """out = z_2 with its full depth, the step before its ∇⁴."""
        self.combine(out, [(1.0, self.Z[-1])])
        self.combine(out[2:3], [(1.0, self.Z[-1][2:3]), (1.0, self.stepper.split_explicit().depth)])

    def _record(self, mu) -> list:
        """The launches of the reverse after the ∇⁴'s transpose (module doc) as segments, those
        that read F_g's and f's arguments with their (Y, k̄, (g_terms, coriolis))."""
        steps, m, dss = self.stepper.split_explicit(), self.model, self.model.topology.dss
        beta = float(steps.divergence_damping)
        V, H = slice(0, 2), slice(2, 3)
        s, tmp, old, acc, sbar, hs_bar = self.state, self.tmp, self.old, self.acc, self.sbar, self.hs_bar
        segments = [(None, None, [m.lincomb(acc, [(0.0, acc)])])]
        zbar, j = mu, len(self.winds)
        for i in reversed(range(len(steps.c))):
            tau = float(steps.c[i]) * self.dt / steps.n_fast[i]
            zero = [m.lincomb(a, [(0.0, a)]) for a in (old, sbar, hs_bar)]
            segments.append((None, None, [m.lincomb(s, [(1.0, zbar)]), *zero]))
            for k in reversed(range(steps.n_fast[i])):
                j -= 1
                first = k == 0 or not beta
                # the depth update: c̄ = τ h̄ through Cᵀ at (v, h_s); h̄ ← h̄ + h̄_old
                depth = [
                    *self.tendency.transpose(self.winds[j], [(tau, s)], ("continuity",)),
                    *dss(self.xbar, False, tmp),
                    m.lincomb(s[V], [(1.0, s[V]), (1.0, tmp[V])]),
                    m.lincomb(hs_bar, [(1.0, hs_bar), (1.0, tmp[H])]),
                    m.lincomb(s[H], [(1.0, s[H]), (1.0, old)]),
                ]
                # the wind update: S̄ += τ v̄; h̃̄ = −gτ Gᵀ v̄ (the pressure gradient's transpose at τ v̄)
                wind = [
                    m.lincomb(sbar[V], [(1.0, sbar[V]), (tau, s[V])]),
                    *self.tendency.transpose(self.xn, [(tau, s)], ("pressure_gradient",)),
                    *dss(self.xbar, False, tmp),
                    m.lincomb(s[H], [(1.0, s[H]), (1.0 if first else 1.0 + beta, tmp[H])]),
                    m.lincomb(old, [(0.0 if first else -beta, tmp[H])]),
                ]
                gradient = (self.tilde[j], [(tau, s)], wind, (("pressure_gradient",), False)) if self.tilde else None
                segments += [(None, None, depth), gradient or (None, None, wind)]
            src = self.xn if i == 0 else self.Z[i - 1]
            slow = [
                m.lincomb(acc, [(1.0, acc), (1.0, s)]),  # x(n) started the substeps
                *self.tendency.transpose(src, [(1.0, sbar)], steps.slow_terms),
                *dss(self.xbar, False, tmp),
                m.lincomb(tmp[H], [(1.0, tmp[H]), (1.0, hs_bar)]),
            ]
            if i == 0:
                slow.append(m.lincomb(acc, [(1.0, acc), (1.0, tmp)]))
            else:  # z_(i−1)'s state is read by this segment's slow transpose only: it holds z̄_(i−1) next
                zbar = self.Z[i - 1]
                slow.append(m.lincomb(zbar, [(1.0, tmp)]))
            segments.append((src, [(1.0, sbar)], slow, (("topography",), True)))
        segments.append((None, None, [m.lincomb(mu, [(1.0, acc)])]))
        return segments


class MriAdjoint(_Recomputed):
    """The adjoint of one ``Mri`` step (``stepper``: its table ``tab``, an explicit Runge–Kutta
    ``inner``) of ``model`` at Δt = ``dt`` (s): ``reverse(x, mu, k)`` as ``StepAdjoint``'s.

    The step in h′ (module doc), Y_1 = x(n), D_j = Y_(j+1) − x(n), for r = 0 … s−1:
    S_r = N(Y_(r+1)) (the RHS without its pressure gradient, at h′), and the solve
    z(0) = x(n) + Σ_j α_rj D_j, dz/dσ = L z + ρ⁰ + (σ/T) ρ¹ over T = d_r Δt in n_r steps of the
    inner table (Z_i = z + τ Σ_j a_ij K_j, K_i = L Z_i + ρ(θ_i), z ← z + τ Σ b_i K_i), ρ⁰ =
    Σ_j (β_rj S_j + γ_rj D_j / Δt) / d_r, ρ¹ = Σ_j β¹_rj S_j / d_r, gives Y_(r+2); x(n+1) =
    H(Y_(s+1)). L is linear (L x = (−g G h′, −H D v)), so the solves reverse without their
    states: K̄_i = τ (b_i z̄ + Σ_l a_li Z̄_l), Z̄_i = Lᵀ K̄_i, ρ̄⁰ += K̄_i, ρ̄¹ += θ_i K̄_i, z̄ += Σ Z̄_i,
    Lᵀ the pressure gradient's and the continuity's transposes at (0, 0, H); then the
    combinations' coefficients carry z̄(0), ρ̄⁰ and ρ̄¹ to x̄(n), the Ȳ_(j+1) and the S̄_j, and
    S̄_r to Ȳ_(r+1) by Nᵀ at Y_(r+1), the stages last first. Each reversed step recomputes its
    stages Y_(r+1) from x(n) (the inner steps by the Butcher form, the stepper's to round-off).
    With ``parameters`` its ∇⁴ as ``StepAdjoint``'s (from Y_(s+1), the last solve taken too),
    g's terms those of the slow topography and of L's −g G h′ at every inner stage (their states
    held), Ω's the slow Coriolis term's, hs's the topography's and the ∇⁴'s; a forcing (in the
    slow part) at each stage's time. ``ArgumentError`` for the fbrk32 inner method, and as
    ``StepAdjoint``.

    Work arrays (3, N): the s stages and slow tendencies, the inner stages' K_i and Z̄_i,
    eight for the solves and the adjoints; with ``parameters`` every inner stage's state."""

    def __init__(self, model: ShallowWater, stepper, dt: float, parameters: bool = False, t0: float = 0.0):
        steps = stepper.multirate()
        if steps.inner is None:
            raise ArgumentError("mri's gradient needs an inner Runge–Kutta table (ssprk3 or rk4)")
        self._setup(model, dt, parameters, t0)
        self.stepper, self.tab = stepper, steps.table  # its ``multirate()``, read again once n_fast is fixed
        inner = steps.inner
        self.a = [[float(v) for v in row] for row in inner.A_E]
        self.b, self.ci = [float(v) for v in inner.b_E], [float(v) for v in inner.c]
        zeros, s = self._zeros, len(self.tab.d)
        self.Y = [zeros(3) for _ in range(s)]  # Y_1 = x(n) … Y_s, in h′
        self.S = [zeros(3) for _ in range(s)]
        self.K = [zeros(3) for _ in self.b]
        self.Z, self.rho0, self.rho1, self.rho = (zeros(3) for _ in range(4))
        self.Ybar, self.Sbar = [zeros(3) for _ in range(s)], [zeros(3) for _ in range(s)]
        self.zbar, self.stage_bar, self.tmp = zeros(3), zeros(3), zeros(3)
        self.at_H = zeros(3)  # (0, 0, H): where the continuity's transpose is L's depth row's
        self.last = zeros(3)  # Y_(s+1): the step before its ∇⁴ (taken where the states are kept)
        self.inner_states: dict = {}  # with ``parameters``: (r, k, i) → Z_i, which L's −g G reads
        self.keep_states = self.parameters
        self.timed_fast = False  # L does not depend on time
        # ``planet_terms``' terms of each part's F: L's −g G h′; the slow topography and Coriolis
        self._fast_planet, self._slow_planet = (("pressure_gradient",), False), (("topography",), True)
        self._for_dt()

    def _solve_terms(self, r: int):
        """Solve r's z(0), ρ⁰ and ρ¹ as (coefficient, array) terms over x(n), the Y_(j+1) and the S_j."""
        t, dt, Y, S = self.tab, self.dt, self.Y, self.S
        d = float(t.d[r])
        alpha = [float(t.alpha[r, j]) for j in range(1, r + 1)]
        gamma = [float(t.gamma[r, j]) / (d * dt) for j in range(1, r + 1)]
        z0 = [(1.0 - sum(alpha), Y[0]), *zip(alpha, Y[1 : r + 1])]
        rho0 = [
            *((float(t.beta[r, j]) / d, S[j]) for j in range(r + 1)),
            (-sum(gamma), Y[0]),
            *zip(gamma, Y[1 : r + 1]),
        ]
        rho1 = [(float(t.beta1[r, j]) / d, S[j]) for j in range(r + 1)]
        return z0, rho0, rho1, bool(t.beta1[r].any())

    def _recompute(self, x, k: int) -> None:
        """Y_1 … Y_s of step k from x = x(n) (full depth), in h′ (class doc); where the inner
        stages' states are kept (``keep_states``: with ``parameters``), every one of them and
        Y_(s+1) (``last``) too."""
        split, s = self.stepper.multirate(), len(self.tab.d)
        self._start(x)
        t = self.tab
        for r in range(s if self.keep_states else s - 1):
            self._at(k, float(t.c[r]))
            split.slow(self.Y[r], self.S[r])
            start = (float(t.c[r + 1]) if r + 1 < s else 1.0) - float(t.d[r])  # the solve's, in Δt
            z0, rho0, rho1, timed = self._solve_terms(r)
            z = self.Y[r + 1] if r + 1 < s else self.last
            self.combine(z, z0)
            self.combine(self.rho0, rho0)
            self.combine(self.rho1, rho1)
            n = split.n_fast[r]
            tau = float(self.tab.d[r]) * self.dt / n
            for sub in range(n):
                for i, row in enumerate(self.a):
                    Z = self.Z
                    if self.keep_states:
                        if (r, sub, i) not in self.inner_states:
                            self.inner_states[r, sub, i] = self._zeros(3)
                        Z = self.inner_states[r, sub, i]
                    self.combine(Z, [(1.0, z), *((tau * a, K) for a, K in zip(row[:i], self.K))])
                    rho = self.rho0
                    theta = (sub + self.ci[i]) / n
                    if timed:
                        rho = self.rho
                        self.combine(rho, [(1.0, self.rho0), (theta, self.rho1)])
                    if self.timed_fast:  # the fast part's forcing at its time in the solve (lts)
                        self._at(k, start + theta * float(t.d[r]))
                    split.fast(Z, self.K[i], rho)
                self.combine(z, [(1.0, z), *((tau * b, K) for b, K in zip(self.b, self.K))])
        if not self.keep_states:  # else the last solve's slow part was evaluated above
            self._at(k, float(t.c[-1]))
            split.slow(self.Y[-1], self.S[-1])

    def _start(self, x) -> None:
        """Y_1 = x(n) in h′ (and (0, 0, H) for Lᵀ)."""
        split = self.stepper.multirate()
        assert split.H != 0.0  # the stepper's first step fixed H (the sweep steps forward before it reverses)
        self.combine(self.Y[0], [(1.0, x)])
        self.combine(self.Y[0][2:3], [(1.0, x[2:3]), (-1.0, split.depth)])
        self.combine(self.at_H[2:3], [(1.0, split.depth)])

    def _fast_transpose(self, state, kb) -> list:
        """x̄ = the fast part's transpose applied to k̄ (``kb``): Lᵀ, at (0, 0, H)."""
        return self.tendency.transpose(self.at_H, [(1.0, kb)], ("pressure_gradient", "continuity"))

    def _slow_transpose(self, Y, sbar) -> list:
        """x̄ = the slow part's transpose at Y applied to S̄ (``sbar``): N's, the RHS without its pressure gradient."""
        return self.tendency.transpose(Y, [(1.0, sbar)], self.stepper.multirate().slow_terms)

    def before_hyperviscosity(self, out) -> None:
        """out = Y_(s+1) with its full depth, the step before its ∇⁴."""
        self.combine(out, [(1.0, self.last)])
        self.combine(out[2:3], [(1.0, self.last[2:3]), (1.0, self.stepper.multirate().depth)])

    def _record(self, mu) -> list:
        """The launches of the reverse after the ∇⁴'s transpose (class doc) as segments, those
        that read F_g's and f's arguments with their (Y, k̄, (g_terms, coriolis))."""
        t, dt, s, dss = self.tab, self.dt, len(self.tab.d), self.model.topology.dss
        Ybar, Sbar, zbar, kb = self.Ybar, self.Sbar, self.zbar, self.stage_bar
        bar = {id(a): b for a, b in zip([*self.Y, *self.S], [*Ybar, *Sbar])}  # each array's adjoint
        segments = [
            (None, None, [launch for a in (*Ybar, *Sbar) for launch in self.combinations.combination(a, [])])
        ]  # Ybar[0]: x̄(n)
        cur, n_fast = mu, self.stepper.multirate().n_fast
        for r in reversed(range(s)):
            n = n_fast[r]
            tau = float(t.d[r]) * dt / n
            z0, rho0, rho1, timed = self._solve_terms(r)
            segments.append(
                (
                    None,
                    None,
                    [
                        *self.combinations.combination(zbar, [(1.0, cur)]),
                        *self.combinations.combination(self.rho0, []),
                        *self.combinations.combination(self.rho1, []),
                    ],
                )
            )
            Zbar = self.K  # the inner stages' Z̄_i (the K_i are not read in the reverse)
            for k in reversed(range(n)):
                for i in reversed(range(len(self.b))):
                    terms = [
                        (tau * self.b[i], zbar),
                        *((tau * self.a[l][i], Zbar[l]) for l in range(i + 1, len(self.b))),
                    ]
                    segments.append((None, None, self.combinations.combination(kb, terms)))
                    launches = [
                        *self._fast_transpose(self.inner_states.get((r, k, i)), kb),
                        *dss(self.xbar, False, Zbar[i]),
                        *self.combinations.combination(self.rho0, [(1.0, self.rho0), (1.0, kb)]),
                        *(
                            self.combinations.combination(self.rho1, [(1.0, self.rho1), ((k + self.ci[i]) / n, kb)])
                            if timed
                            else ()
                        ),
                    ]
                    state = self.inner_states.get((r, k, i))  # the fast part's F read it: g's term, with parameters
                    segments.append((state, [(1.0, kb)], launches, self._fast_planet))
                segments.append(
                    (None, None, self.combinations.combination(zbar, [(1.0, zbar), *((1.0, Z) for Z in Zbar)]))
                )
            combinations = []
            for terms, adjoint in ((z0, zbar), (rho0, self.rho0), (rho1, self.rho1)):
                for c, a in terms:  # a term c·a of the combination: ā += c × its adjoint
                    if c:
                        combinations += self.combinations.combination(bar[id(a)], [(1.0, bar[id(a)]), (c, adjoint)])
            segments.append((None, None, combinations))
            slow = [
                *self._slow_transpose(self.Y[r], Sbar[r]),
                *dss(self.xbar, False, self.tmp),
                *self.combinations.combination(Ybar[r], [(1.0, Ybar[r]), (1.0, self.tmp)]),
            ]
            segments.append((self.Y[r], [(1.0, Sbar[r])], slow, self._slow_planet))
            cur = Ybar[r]
        segments.append((None, None, self.combinations.combination(mu, [(1.0, Ybar[0])])))
        return segments


class LtsAdjoint(MriAdjoint):
    """The adjoint of one ``Lts`` step (``stepper``) with a multirate table on two or more
    element levels: ``MriAdjoint``'s, with the split by level (``steppers.local.LevelSplit``):
    the slow part f_0 the coarsest level's elements' tendency, the fast part f_fine the finer
    levels', nonlinear, so every inner stage's state is held and f_fine's transpose taken there;
    each part's transpose runs over its own elements alone (x̄ zero on the others, then the
    unweighted DSS: f_P = R Q_P W T_P in the mass form), in full depth (no h′). With
    ``parameters`` the ∇⁴'s as ``StepAdjoint``'s, hs's the topography's over each part, g's and
    Ω's each part's f_P of those terms (``planet_terms`` with the part); a forcing at the stages'
    and the inner stages' times. ValueError as ``MriAdjoint``.
    One level is the inner table's global step (``step_adjoint``: a ``StepAdjoint``); MRAB3
    has no adjoint."""

    def __init__(self, model: ShallowWater, stepper, dt: float, parameters: bool = False, t0: float = 0.0):
        super().__init__(model, stepper, dt, parameters, t0)
        self.keep_states = True  # f_fine's transpose reads them
        levels = stepper.multirate()  # each part's F holds every term over its elements
        coarse, finer = levels.parts
        self._fast_planet, self._slow_planet = (None, True, finer), (None, True, coarse)
        self.timed_fast = "forcing" in model.terms  # f_fine holds the forcing on the fine elements
        level = levels.level[model.topology.elements]
        self.runs = {
            part: element_runs(np.flatnonzero(mask), 0) for part, mask in (("slow", level == 0), ("fast", level >= 1))
        }

    def _start(self, x) -> None:
        self.combine(self.Y[0], [(1.0, x)])  # in full depth

    def before_hyperviscosity(self, out) -> None:
        self.combine(out, [(1.0, self.last)])

    def _fast_transpose(self, state, kb) -> list:
        return self.tendency.transpose(state, [(1.0, kb)], None, self.runs["fast"])

    def _slow_transpose(self, Y, sbar) -> list:
        return self.tendency.transpose(Y, [(1.0, sbar)], None, self.runs["slow"])
