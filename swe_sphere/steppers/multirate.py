"""Gravity waves on their own clock: the fast/slow split of the RHS (``GravitySplit``) and
the steppers that take many cheap fast substeps a slow step without a global solve,
``split_explicit`` (``SplitExplicit``) and ``mri`` (``Mri``); both apply ∇⁴ once a step
after it, as every stepper here. Their scene options and the check of a multirate table are
in ``multirate_options``."""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import warp as wp

from ..model.launches import Update
from .base import Stepper, StepStats, entry, work_array
from .butcher import built_in_table
from .capabilities import GraphCapture
from .explicit import FBRK32
from .multirate_options import MriOptions, SplitExplicitOptions, parse_mri, substeps_label
from .stage_plan import stage_form, stage_terms

f64 = wp.float64

FBRK32_STAGES = tuple(zip(FBRK32.C, FBRK32.BETA))  # c, β of ``explicit.FBRK32``


class GravitySplit:
    """The fast/slow split of the model's RHS about a reference depth H (m; 0: the
    rounded area-mean depth of the first state given to ``set_depth``, the
    ``GravityWaveOperator``'s rule).

    The fast part is the linear gravity-wave operator ``model.gravity_wave.GravityWaveOperator``,
    L x = (−g G h, −H D v) (G = DSS∘grad, D = DSS∘div); the slow part S = F − L is the rest:
    −(ζ + f) k×v − ∇(½|v|²), the mountain's −g∇hs, −∇·(h′v) with h′ = h − H, and the forcing.
    The steppers carry the depth as h′ through a step (h − H is exact for H/2 ≤ h ≤ 2H,
    Sterbenz), so S is the model's own RHS without its pressure-gradient term evaluated at
    (u, v, h′): one tendency pass and one DSS, compiled for those terms (``ShallowWater.rhs``
    with ``terms``), not F − L by two evaluations. A fast evaluation L z + ρ is one element
    pass of the gradient of h′ and the divergence of v (``kernels.gravity_wave.linear_element``)
    and one DSS of its three rows into the combination that uses it
    (``GravityWaveOperator.update``): 2 launches moving 0.86× the bytes of the RHS's 2
    (``tally.Tally``), with far less arithmetic than the flux-form tendency. Mass: both parts'
    depth rows are DSS'd divergences, whose area integral is zero, so every stage keeps ∫h to
    round-off.

    States are (3, N) element-local with the depth as h′ = h − H (``to_perturbation``,
    ``from_perturbation``). ``slow(x, out)``: out = S(x) = F(u, v, h) − L x, the model's
    RHS without its pressure gradient at h′ (one tendency pass and its DSS); ``fast(x,
    out)``: out = L x (``linear``, the ``GravityWaveOperator``; a forward–backward substep
    takes its halves apart, through ``ShallowWater.gradient_update`` and
    ``divergence_update``). ValueError for a model without the continuity and
    pressure-gradient terms."""

    def __init__(self, model, mean_depth: float = 0.0):
        self.linear = model.implicit_terms(mean_depth)
        self.model = model
        self.slow_terms = tuple(t for t in model.terms if t not in ("pressure_gradient", "hyperviscosity"))
        self.depth = wp.zeros((1, model.topology.N), dtype=f64, device=model.topology.device)  # H at every node
        self._shifts: dict[tuple, tuple] = {}
        self.set_depth_value(mean_depth)

    @property
    def H(self) -> float:
        """The reference depth H (m; 0 until fixed), the operator's."""
        return self.linear.H

    def set_depth_value(self, H: float) -> None:
        """Set H (m; 0: not yet fixed) and, fixed, the depth array the shifts subtract."""
        self.linear.H = float(H)
        if self.linear.H:
            self.depth.fill_(self.linear.H)

    def set_depth(self, x) -> None:
        """Fix H from x (a state with the full depth) unless given or fixed before."""
        self.linear.set_depth(x)
        self.depth.fill_(self.H)

    def to_perturbation(self, x) -> None:
        """h ← h − H in place."""
        self._shift(x, -1.0)

    def from_perturbation(self, x) -> None:
        """h ← h′ + H in place."""
        self._shift(x, 1.0)

    def _shift(self, x, sign) -> None:
        key = (x.ptr, sign)
        if key not in self._shifts:  # recorded once per state array (the view held with it)
            self._shifts[key] = (self.model.lincomb(x[2:3], ((1.0, x[2:3]), (sign, self.depth))), x)
        self._shifts[key][0].launch()

    def slow(self, x, out) -> None:
        """out (3, N) = N(x), x with the depth as h′ (its rows that no slow term writes stay zero)."""
        self.model.rhs(x, out, self.slow_terms)

    def fast(self, x, out, forcing=None) -> None:
        """out (3, N) = L x = (−g G h′, −H D v) (+ forcing, a (3, N) array), both halves in
        one element pass and one DSS (``GravityWaveOperator.apply``)."""
        self.linear.apply(x, out, forcing)


class _Multirate(GraphCapture, Stepper):
    """What both steppers share: the split, H in ``state()``, the step in h′, cached combinations."""

    capturable = differentiable = True
    removed_options: dict = {}
    fewest_auto_substeps = 1  # "auto"'s least n
    # the fast evaluations (L z a substep; ~0.9 of an RHS's bytes) reported beside the slow
    # RHS evaluations, as a solver's iterations are: run summaries and sweep tables show both
    solvers = ("fast",)

    def __init__(self, model, dt, options=None):
        super().__init__(model, dt, options)
        self.split = self._make_split()
        self._combs: dict[tuple, object] = {}
        self.n_fast = None  # the fast steps of each stage (or solve), from H at the first step

    def _make_split(self):
        """The fast/slow split the engine steps: the gravity waves' (``GravitySplit``)."""
        return GravitySplit(self.model, self.options.mean_depth)

    def substeps(self) -> int:
        """n, the fast steps a slow step: the ``substeps`` option, or with "auto" the fewest
        (at least ``fewest_auto_substeps``) whose gravity-wave Courant number sqrt(g H) Δt /
        (n Δx) about the split's depth H is at most ``fast_courant`` (Δx the smallest
        distance between GLL nodes on the sphere, the same on every rank)."""
        o = self.options
        if o.substeps != "auto":
            return o.substeps
        dx = -self.model.topology.max(-float(self.model.topology.grid.dx.min()))
        n = math.ceil(math.sqrt(self.model.g * self.split.H) * self.dt / (o.fast_courant * dx) - 1e-9)
        return max(self.fewest_auto_substeps, n)

    def state(self):
        return {**super().state(), "mean_depth": self.split.H}

    def restore(self, state):
        super().restore(state)
        self.split.set_depth_value(entry(self, state, "mean_depth"))
        self.n_fast = None

    def graph_key(self):
        return None if self.split.H == 0.0 else super().graph_key()  # the first step reads the mean depth

    def _comb(self, out, *terms) -> None:
        """out = Σ c·x over one to three (c, x) terms, recorded once per arrays and coefficients."""
        key = (out.ptr, out.shape, tuple((c, x.ptr, x.shape) for c, x in terms))
        launch = self._combs.get(key)
        if launch is None:
            launch = self._combs[key] = (self.model.lincomb(out, terms), out, terms)  # holds the views
        launch[0].launch()

    def _combine(self, out, terms) -> None:
        """out = Σ c·x over the nonzero (c, x) of ``terms`` (at least one; none of them out):
        three in the first pass, two more in each next."""
        terms = [(c, x) for c, x in terms if c != 0.0]
        self._comb(out, *terms[:3])
        for k in range(3, len(terms), 2):
            self._comb(out, (1.0, out), *terms[k : k + 2])

    def advance(self, x):
        split = self.split
        if split.H == 0.0:
            split.set_depth(x)
        if self.n_fast is None:
            self.n_fast = self._fast_steps(self.substeps())
        split.to_perturbation(x)
        evals = self._advance(x)
        split.from_perturbation(x)
        self._hyperviscosity(x)
        return StepStats(evals, {"fast": self.fast_evaluations()})


class SplitExplicit(_Multirate):
    """Split-explicit Wicker–Skamarock RK3: the gravity waves in forward–backward substeps (MPAS).

    Wicker & Skamarock (2002, MWR 130, 2088) RK3 for the slow part, the stages of Δt/3,
    Δt/2, Δt each from x(n) with the slow tendency of the last stage held fixed over
    forward–backward substeps of the fast part (Klemp, Skamarock & Dudhia 2007, MWR 135,
    2897, §2; MPAS-Atmosphere's ``atm_srk3``): n/3, n/2 and n substeps (rounded up; each
    stage's substep its span over its count), the wind first, v ← v + τ(S_v − g G h̃), then
    the depth with the new wind, h ← h − τ D(h_s v), with h̃ = h + β(h − h_old)
    forward-weighted as MPAS damps the divergence (without it, a weak instability of the
    split like those Baldauf 2010, MWR 138, 4475, found in RK3 time splitting). Its fast
    part is linear about the depth h_s of the stage whose slow tendency it carries, not about
    H, as MPAS linearises its acoustic substeps about the stage's state: the whole mass flux
    is the substeps' (``tendency`` compiled for the continuity alone, on the new wind and
    h_s), the slow part the momentum's terms without the pressure gradient (about H, the slow
    −∇·(h′v) held fixed over a step is unstable over a mountain). A substep: element gradient
    and its DSS-update into the wind, continuity tendency and its DSS-update into the depth
    (4 launches).

    Options (scene table ``[split_explicit]``): ``substeps`` n, the fast substeps of the
    last stage (the stages take ⌈n/3⌉, ⌈n/2⌉, n), or "auto" (the default): the fewest,
    and at least 2, whose Courant number about the mean depth is ≤ ``fast_courant``
    (default 0.6; ``_Multirate.substeps``). ``divergence_damping`` β (the
    forward weighting of the depth in the substeps' pressure gradient, h̃ = h′ + β(h′ −
    h′_old), which damps the fast divergent modes as divergence damping does: Klemp,
    Skamarock & Ha 2018, MWR 146, 1911, §3; MPAS's smdiv = 0.1; default 0.1). A stage's
    first substep has no last one, so with one substep a stage nothing is damped: hence
    "auto"'s 2. ``mean_depth``
    H (m; 0: the area-mean depth of the initial state, rounded to 6 digits: the step carries
    the depth as h′ = h − H, and "auto" takes the Courant number about it). 3 slow evaluations a step
    (reported as RHS evaluations) and ⌈n/3⌉ + ⌈n/2⌉ + n fast ones. Slow order 2 (Wicker &
    Skamarock 2002: third order for linear problems). Raises ValueError without the
    continuity and pressure-gradient terms."""

    name = "split_explicit"
    Options = SplitExplicitOptions
    # the gravity waves in substeps of their own: the slow step is limited by advection. TC5 ne8,
    # 12 days, 12 substeps: stable at |v|Δt/Δx = 0.58 (7.1 Δt_g), blew up on day 7.8 at 0.78 (9.5 Δt_g;
    # with 24 substeps too). Without divergence damping it blew up on day 9.8 at 0.64 (7.8 Δt_g).
    advective_courant_limit = 0.6
    C = (Fraction(1, 3), Fraction(1, 2), Fraction(1))
    fewest_auto_substeps = 2  # the divergence damping needs a second substep (the docstring)

    def __init__(self, model, dt, options=None):
        super().__init__(model, dt, options)
        self.xn, self.z, self.S = work_array(self), work_array(self), work_array(self)
        self.w = work_array(self)  # row 2: the next substep's forward-weighted depth h̃
        self.W = work_array(self)  # rows 0, 1: the substeps' wind; row 2: the stage's full depth h
        # the continuity is the substeps' (about the stage's depth): its slow part is zero
        self.slow_terms = tuple(t for t in self.split.slow_terms if t != "continuity")

    @classmethod
    def label(cls, options: dict) -> str:
        return f"{cls.name} {substeps_label(cls.make_options(**options))}"

    def _fast_steps(self, n: int) -> tuple:
        return tuple(math.ceil(c * n) for c in self.C)

    def fast_evaluations(self) -> int:
        """Fast evaluations (L z) a step."""
        return sum(self.n_fast)

    def _advance(self, x):
        self._comb(self.xn, (1.0, x))  # a combination, not a copy: a verb a gradient's tape reads
        src = self.xn
        for i, (c, n) in enumerate(zip(self.C, self.n_fast)):
            self._at(float(self.C[i - 1]) if i else 0.0)
            if self.slow_terms:
                self.model.rhs(src, self.S, self.slow_terms)
            self._comb(self.W[2:3], (1.0, src[2:3]), (1.0, self.split.depth))
            out = x if i == len(self.C) - 1 else self.z
            tau = float(c) * self.dt / n
            for k in range(n):
                self.forward_backward(out if k else self.xn, out, tau, self.S, first=k == 0)
            self._comb(out[0:2], (1.0, self.W[0:2]))
            src = self.z
        return len(self.C)

    def forward_backward(self, prev, out, tau: float, forcing, first: bool = False) -> None:
        """One forward–backward substep of τ (s) of the fast system, 4 launches (``prev``, ``out``,
        ``forcing``: (3, N) arrays, wind in m s⁻¹ and depth h′ in m, ρ in those per s): from
        prev's depth h′ (and wind, when ``first``; else the last substep's, in W) into W's
        wind and out's depth (may be prev):
        v ← v + τ(ρ_v − g G h̃), then h′ ← h′ + τ(ρ_h − D(h_s v)) with the new wind, h_s the
        stage's full depth (W's row 2), ρ = ``forcing``. h̃ = h′ + β(h′ − h′_old), h′_old the
        last substep's depth, is written by the last substep's depth update as
        h′_old + (1 + β)τ(ρ_h − D(h_s v)) beside h′ (its DSS serves both); ``first`` (a
        stage's first substep, which has no last one): h̃ = h′."""
        g, W, w, beta = self.model.g, self.W, self.w, self.options.divergence_damping
        self.model.operators.gradient_update(
            w if not first and beta else prev,
            2,
            [Update(W[0:2], ((1.0, (prev if first else W)[0:2]), (tau, forcing[0:2]), (-g * tau, None)))],
        )
        weighted = (
            [Update(w, ((1.0, prev), ((1.0 + beta) * tau, forcing), ((1.0 + beta) * tau, None)), slice(2, 3))]
            if beta
            else []
        )
        self.model.rhs_update(
            W, [*weighted, Update(out, ((1.0, prev), (tau, forcing), (tau, None)), slice(2, 3))], ("continuity",)
        )


class Mri(_Multirate):
    """Multirate MIS / MRI-GARK tables (or [mri]'s): the gravity waves by an inner method in substeps.

    From a table (``tables.MULTIRATE``, or the scene's ``[mri]``): the r-th of s inner solves
    starts from z(0) = x(n) + Σ_j α_rj (Y_{j+1} − x(n)) and integrates dz/dσ = L z + ρ_r(σ/T_r)
    over σ ∈ [0, T_r], T_r = d_r Δt, d_r = Σ_j β_rj, with the slow forcing
    ρ_r(θ) = (1/d_r) Σ_j ((β_rj + θ β¹_rj) S(Y_{j+1}) + γ_rj (Y_{j+1} − x(n))/Δt),
    giving Y_{r+2}; x(n+1) = Y_{s+1}. With α, β, γ the MIS coefficients (Wensch, Knoth &
    Galant 2009, eq. 2.3; Knoth & Wensch 2014) this is MIS; with α = I, γ = 0,
    β = Γ⁰, β¹ = Γ¹ it is explicit MRI-GARK (Sandu 2019, Definition 2.2, σ there
    scaled by Δc_r). The inner ODE is integrated by ``inner`` with ``substeps`` fast steps a
    slow step (each solve ⌈d_r n⌉ of them): ``fbrk32`` (the forward–backward FB-RK(3,2) of
    ``explicit.FBRK32`` on the fast system), or ``ssprk3``/``rk4``, the engine's own tables
    stepped through its ``stage_plan.stage_form``.

    Options (scene table ``[mri]``): ``method`` ("mis2", "mis3c", "mis4a",
    "mri_gark_erk33a": ``tables.MULTIRATE``; default "mis4a", third order) or a table of one's own
    (``MriOptions``); ``inner`` ("fbrk32" | "ssprk3" | "rk4", the fast integrator;
    default "ssprk3"); ``substeps`` n (fast steps a slow step, ⌈d_r n⌉ a solve) or "auto"
    (the default): the fewest whose Courant number about the mean depth is ≤
    ``fast_courant`` (default 1.0; ``_Multirate.substeps``); ``mean_depth`` H (m; 0: the
    area-mean initial depth, rounded to 6 digits).
    s slow evaluations a step (reported as RHS evaluations). The run file's attributes
    ``mri`` and ``mri_order`` name the table."""

    name = "mri"
    Options = MriOptions
    # TC5 ne8, 12 days, 8 substeps: MIS3C and MIS4a stable at |v|Δt/Δx = 0.78 (9.5 Δt_g), blew up at
    # 0.88; MIS2 with fbrk32 at 0.64, not 0.78 (TC6 ne8, 28 days: MIS4a stable at 1.54, MIS3C at
    # 0.78, not 0.93). MRI-GARK-ERK33a blows up on TC5 from 3.9 Δt_g (0.32) with any substeps
    # (stable at 3 Δt_g): its limit is the coupling's, not advection's.
    advective_courant_limit = 0.75

    def __init__(self, model, dt, options=None):
        super().__init__(model, dt, options)
        o = self.options
        self.tab = parse_mri(o)
        s = len(self.tab.d)
        self.xn, self.z, self.rho0, self.rho1, self.rho = (work_array(self) for _ in range(5))
        self.S = [work_array(self) for _ in range(s)]
        # Y_{j+1} − x(n), kept where a later solve that does not simply restart reads it
        used = ((self.tab.alpha != 0) | (self.tab.gamma != 0)) & ~np.array([[self._restarts(r)] for r in range(s)])
        self.D = {j: work_array(self) for j in range(1, s) if used[j:, j].any()}
        self.inner = None  # the inner explicit table (None: fbrk32)
        if o.inner == "fbrk32":
            self.t, self.s = work_array(self), work_array(self)
        else:
            table = self.inner = built_in_table(o.inner)
            names, self._form = stage_form(table.A_E, table.b_E, table.c)
            self._rk = {name: work_array(self) for name in names}
            self.K = work_array(self)

    def _restarts(self, r: int) -> bool:
        """Whether solve r starts from Y_{r+1} with nothing else of the earlier stages (MRI-GARK)."""
        a, g = self.tab.alpha[r], self.tab.gamma[r]
        return a[r] == 1.0 and not np.delete(a, r).any() and not g.any()

    @classmethod
    def label(cls, options: dict) -> str:
        o = cls.make_options(**options)
        return f"{cls.name} {o.table()['name']} {o.inner} {substeps_label(o)}"

    def _fast_steps(self, n: int) -> tuple:
        return tuple(max(1, math.ceil(d * n - 1e-9)) for d in self.tab.d)

    def attrs(self):
        t = self.options.table()
        return {"mri": t["name"], "mri_order": int(t["order"]), "mri_inner": self.options.inner}

    def fast_evaluations(self) -> int:
        """Fast evaluations (L z) a step."""
        per = 3 if self.options.inner == "fbrk32" else len(self._form)
        return per * sum(self.n_fast)

    def _advance(self, x):
        tab, dt, xn, z = self.tab, self.dt, self.xn, self.z
        s = len(tab.d)
        self._comb(xn, (1.0, x))  # a combination, not a copy: a verb a gradient's tape reads
        for r in range(s):
            stage = xn if r == 0 else z  # Y_{r+1}
            self._at(tab.c[r])
            self.split.slow(stage, self.S[r])
            if r in self.D:
                self._comb(self.D[r], (1.0, z), (-1.0, xn))
            out = x if r == s - 1 else z
            if r == 0 or not self._restarts(r):  # z(0) = x(n) + Σ_j α_rj (Y_{j+1} − x(n))
                self._combine(out, [(1.0, xn), *((tab.alpha[r, j], self.D.get(j)) for j in range(1, r + 1))])
            elif out is not z:
                self._comb(out, (1.0, z))
            d = tab.d[r]
            self._combine(
                self.rho0,
                [
                    *((tab.beta[r, j] / d, self.S[j]) for j in range(r + 1)),
                    *((tab.gamma[r, j] / (d * dt), self.D.get(j)) for j in range(1, r + 1)),
                ],
            )
            timed = bool(tab.beta1[r].any())
            if timed:
                self._combine(self.rho1, [(tab.beta1[r, j] / d, self.S[j]) for j in range(r + 1)])
            self._solve = ((tab.c[r + 1] if r + 1 < s else 1.0) - d, d)  # its start and span, in Δt
            self._inner(out, d * dt, self.n_fast[r], timed)
        return s

    def _fast_at(self, theta: float) -> None:
        """Set the model time for a fast evaluation at the fraction θ of the current solve:
        nothing here (the gravity-wave operator L does not depend on time)."""

    def _forcing(self, theta: float, timed: bool):
        """ρ(θ) = ρ⁰ + θ ρ¹ (ρ⁰ itself when constant)."""
        if not timed:
            return self.rho0
        self._comb(self.rho, (1.0, self.rho0), (theta, self.rho1))
        return self.rho

    def _inner(self, z, span, n, timed) -> None:
        """Integrate dz/dσ = L z + ρ(σ/span) over [0, span] in n steps of ``inner``, in place."""
        tau = span / n
        for k in range(n):
            if self.options.inner == "fbrk32":
                self._fbrk32(z, tau, k, n, timed)
            else:
                self._rk_step(z, tau, k, n, timed)

    def _rk_step(self, z, tau, k, n, timed) -> None:
        """One step of the inner explicit table through the engine's stage form: K = L Y + ρ
        stored, each update a combination of at most three arrays."""
        arrays = {"x": z, **self._rk}
        for c, arg, updates in self._form:
            rho = self._forcing((k + c) / n, timed)
            self._fast_at((k + c) / n)
            self.split.fast(arrays[arg], self.K, rho)
            for out, terms in updates:
                self._comb(arrays[out], *stage_terms(terms, arrays[out], arrays, self.K, tau))

    def _fbrk32(self, z, tau, k, n, timed) -> None:
        """One FB-RK(3,2) step (``explicit.FBRK32``: the depth first, the wind with h̃) of the
        fast system from z in place: t holds stage i's state, s's depth row h̃ or h(n+1)."""
        g, H, t, s = self.model.g, self.split.H, self.t, self.s
        c_prev = 0.0
        for i, (c, beta) in enumerate(FBRK32_STAGES):
            rho = self._forcing((k + c_prev) / n, timed)
            last = i == len(FBRK32_STAGES) - 1
            prev = z if i == 0 else t
            ct = c * tau
            if last:  # h(n+1) into s, then h̃ = β h(n+1) + (1 − 2β) h⁽²⁾ + β h(n) into t, h(n+1) into z
                self.model.operators.divergence_update(
                    prev, [Update(s[2:3], ((1.0, z[2:3]), (ct, rho[2:3]), (-H * ct, None)))]
                )
                self._comb(t[2:3], (beta, s[2:3]), (1.0 - 2.0 * beta, t[2:3]), (beta, z[2:3]))
                self._comb(z[2:3], (1.0, s[2:3]))
                self.model.operators.gradient_update(
                    t, 2, [Update(z[0:2], ((1.0, z[0:2]), (ct, rho[0:2]), (-g * ct, None)))]
                )
            else:  # h̃ = β h⁽ⁱ⁾ + (1 − β) h(n) into s, h⁽ⁱ⁾ into t
                self.model.operators.divergence_update(
                    prev,
                    [
                        Update(s[2:3], ((1.0, z[2:3]), (beta * ct, rho[2:3]), (-H * beta * ct, None))),
                        Update(t[2:3], ((1.0, z[2:3]), (ct, rho[2:3]), (-H * ct, None))),
                    ],
                )
                self.model.operators.gradient_update(
                    s, 2, [Update(t[0:2], ((1.0, z[0:2]), (ct, rho[0:2]), (-g * ct, None)))]
                )
            c_prev = c
