"""One engine for Runge–Kutta methods given by their tables (``butcher.Table``): the built-in
``ssprk3``, ``rk4``, ``kgu35``, the embedded pairs and ``imex`` (their tables in ``tables``) and a
user's ``tableau`` (its table in the scene) are the same code: explicit tables (``ExplicitRK``)
and IMEX additive pairs (``ImexRK``), each class's docstring saying how it steps; the ∇⁴ applied
after each step, split from the dynamics, as in HOMME (``advance_hypervis``: forward Euler over
the span the step covers). A stepper of this engine is a subclass that says which table it steps
(``table()``); a method of another shape (a multirate outer table driving a fast inner
integrator) is another engine class beside these two; FB-RK(3,2) (``explicit.FBRK32``) is not a
table of this engine.
"""

from __future__ import annotations

import json
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from fractions import Fraction

import numpy as np
import warp as wp

from ..core.constants import DAY
from ..kernels import blas
from ..model.helmholtz import HelmholtzOptions
from ..model.launches import Update
from .base import Stepper, StepStats, device_counts, work_array
from .butcher import BUILT_IN, PARTS, Table, TableauOptions, built_in_table, imaginary_axis_limit, parse, stage_form
from .capabilities import ErrorEstimates, GraphCapture, TrialSteps
from .helmholtz_steps import REMOVED_SOLVER_OPTIONS, HelmholtzSteps
from .tables import COURANT_LIMITS, EXPLICIT, IMEX, IMEX_ADVECTIVE_LIMITS, IMEX_PAIRS

f64 = wp.float64


class _Tables(Mapping):
    """The built-in tables by key (``butcher.built_in_table``: each checked when first read, not
    at import)."""

    def __getitem__(self, key: str) -> Table:
        return built_in_table(key)

    def __iter__(self) -> Iterator[str]:
        return iter(BUILT_IN)

    def __len__(self) -> int:
        return len(BUILT_IN)


TABLES = _Tables()


# the IMEX pairs' Helmholtz CG residual under error control, per rtol (``ImexRK.follow_tolerance``):
# SUNDIALS' 0.1 for an inner solve's error against the step's, and 0.1 more because the CG's
# relative residual understates the solution's error at these steps (TC5 and TC2 ne8, 5 days,
# rtol 1e-5 and 1e-6: at 0.1 rtol the noise still shrank the steps, ark436 303 and 366 where
# 0.01 takes 226 and 196 in less CPU; 0.001 changes nothing more: docs/explanation/efficiency/error_control.md)
CG_PER_RTOL = 0.01


def _dt_times(q: Fraction, dt: float) -> float:
    """qΔt, rounded as Δt/d for q = 1/d (an exact reciprocal is not representable)."""
    return dt / q.denominator if q.numerator == 1 else float(q) * dt


class ExplicitRK(GraphCapture, ErrorEstimates, TrialSteps, Stepper):
    """An explicit Runge–Kutta step of the table ``table()`` (a ``butcher.Table``),
    recorded once from its ``stage_form``: s RHS evaluations a step.

    x(n+1) = x(n) + Δt Σ b_j K_j, K_i = F(Y_i),
    Y_i = x(n) + Δt Σ_j a_ij K_j, written as ``butcher.stage_form``'s
    combinations, each written by the DSS of its stage's RHS
    (``ShallowWater.rhs_update``) rather than by a pass of its own: F is never
    stored, and the bits are those of storing F and combining after (ssprk3's and
    kgu35's combinations are their Shu–Osher forms; RK4's take one buffer and one
    combination fewer than its accumulator form).

    Under the model's ``precision = "float32_state"`` the stages run on a float32 state y
    (u, v, h − H₀: ``ShallowWater.to_step_state`` of x at the step's start) in float32
    buffers, and the step's end gives y back to x (``ShallowWater.from_step_state``: compensated
    or rounded) before the ∇⁴, which acts on x as under "float32"; after it the mass fixer puts
    back the mass x held at the start (``ShallowWater.restore_mass``).
    """

    explicit = capturable = variable_dt = differentiable = True
    tracers_refusal = None  # its stages combine whole states: the tracers' rows ride them
    float32_state_refusal = None  # its stages are the model's combinations, of any float type

    def table(self) -> Table:
        """The checked table this stepper steps: a built-in's, its ``name``'s (``explicit_steppers``)."""
        return TABLES[self.name]

    def __init__(self, model, dt, options=None):
        super().__init__(model, dt, options)
        table = self.table()
        estimate = table.estimate
        buffers, self._form = stage_form(table.A_E, table.b_E, table.c, None if estimate is None else estimate[0])
        dtype = model.state_dtype
        self._buffers = {name: work_array(self, dtype) for name in buffers}
        # the float32 state the stages step (None: they step x itself)
        self._y = None if dtype is f64 else work_array(self, dtype)
        self._x = None
        self._carried = None  # ``carry_last_stage``: the FSAL stage's weight d_s in the estimate
        self._ahead = None  # the Δt whose first stage the last step's FSAL evaluation wrote (None: not written)

    @property
    def error_estimate(self) -> wp.array2d | None:
        """An embedded pair's local error estimate of the last step, e = Δt Σ (b − b̂)_j K_j
        (3, N), in x's units (m s⁻¹ for u, v, m for h); written by the step's last stage, no
        RHS of its own, without the ∇⁴ step (with it, its FSAL stage F(x(n+1)) evaluated
        after the ∇⁴, where ``carry_last_stage``). None for a table without b̂."""
        return self._buffers.get("e")

    def fsal(self) -> bool:
        """Whether the table is an embedded pair whose last stage is F(x(n+1)) (first same as
        last: A's last row b, b's last weight 0, c 1), the next step's first stage."""
        t = self.table()
        b, last = t.b_E, t.A_E[-1]
        return t.estimate is not None and t.c[-1] == 1 and b[-1] == 0 and tuple(last[:-1]) == tuple(b[:-1])

    def carry_last_stage(self) -> bool:
        """Step an FSAL pair (``fsal``) with its last stage carried over as the next step's
        first, s − 1 RHS evaluations a step instead of s (error control, where the estimate is
        read every step: ``integrator.control.StepControl``): after the ∇⁴ step, F(x(n+1)) is
        evaluated once, and its DSS writes the estimate's last term (weight d_s = b_s − b̂_s)
        and the next step's first combinations at this step's Δt, ahead (``rhs_update``: the
        bits of evaluating them at the next step). A next step at another Δt, or after
        ``restore`` (a rejected step's, a restart's), evaluates its first stage itself, s RHS:
        under control Δt changes in about 2 % of the steps (TC5 ne30, ``rk43`` at rtol 1e-6).
        x(n+1) is the same (b_s = 0); the estimate's last term is F after the ∇⁴ rather than
        before, so it holds the ∇⁴ step's effect on F too. Returns whether it does: not for a
        table that is not FSAL, nor with a time-dependent forcing (the FSAL evaluation's time
        would be t(n) + Δt(n) rather than the next step's rebased t0 + steps·Δt, another
        rounding), nor on a float32 state (its step's end is the conversion back to x)."""
        if self._carried is not None:
            return True
        if not self.fsal() or "forcing" in self.model.terms or self._y is not None:
            return False
        t = self.table()
        s, d = len(t.b_E), t.estimate[0]
        cut = [row[: s - 1] for row in t.A_E[: s - 1]]
        buffers, self._form = stage_form(cut, t.b_E[: s - 1], t.c[: s - 1], d[: s - 1])
        self._buffers = {name: work_array(self) for name in buffers}
        self._carried, self._ahead, self._x = d[s - 1], None, None
        return True

    def restore(self, state: dict) -> None:
        super().restore(state)
        self._ahead = None  # x is put back: the first stage written ahead is of another state

    def device_arrays(self) -> list:
        return list(self._buffers.values()) if self._carried is not None else []  # the first stage written ahead

    def carried(self):
        return self._ahead

    def resume(self, carried) -> None:
        self._ahead = carried

    def graph_key(self):
        key = super().graph_key()
        # a carried pair's step evaluates its first stage only where not written ahead at this Δt
        return key if key is None or self._carried is None else (*key, self._ahead == self.dt)

    def graph_family(self):
        key = self.graph_key()
        return None if key is None else key[:1] + key[2:]  # Δt enters as the combinations' coefficients

    def replayed(self, stats: StepStats) -> StepStats:
        if self._carried is not None:
            self._ahead = self.dt  # as ``advance`` leaves it
        return super().replayed(stats)

    def _record(self, x):
        """The stages on x: (c, the RHS's argument, its updates), Δt folded into F's coefficients."""
        arrays = {"x": x, "k": None, **self._buffers}  # None: F itself (``rhs_update``)
        self._x = x
        self._stages = [
            (
                c,
                arrays[arg],
                tuple(
                    Update(
                        arrays[out],
                        tuple((_dt_times(a, self.dt) if src == "k" else a, arrays[src]) for a, src in terms),
                    )
                    for out, terms in updates
                ),
            )
            for c, arg, updates in self._form
        ]
        # with the tracers' limiter, the stages whose last update writes the next stage's state (x at
        # the last) from F: their tracers limited before the DSS (HOMME's euler_step), the others' not
        # (a chained combination's partial sums are no state: ssprk3, rk4, kgu35 limit every stage)
        states = [arg for _, arg, _ in self._stages[1:]] + [x]
        self._limited = [
            self.model.limiter is not None
            and updates[-1].out is state
            and sum(src is None for _, src in updates[-1].terms) == 1
            for (_, _, updates), state in zip(self._stages, states, strict=True)
        ]

    def _dt_changed(self):
        self._x = None  # the stages' coefficients made again with the new Δt (the model's launches take them in place)

    def advance(self, x):
        y = x if self._y is None else self._y  # the state the stages step
        if self._x is not y:
            self._record(y)
        limiter = self.model.limiter  # the tracers' (a scene's tracers.limiter): the step's start's bounds
        if limiter is not None:
            limiter.bound(x)
        if self._carried is None:
            if y is not x:
                self.model.to_step_state(x, y)
            for (c, arg, updates), limit in zip(self._stages, self._limited, strict=True):
                self._at(c)
                if limit:  # the stage's tracers limited before their DSS (a model with a limiter)
                    self.model.rhs_update(arg, updates, limit=True)
                else:
                    self.model.rhs_update(arg, updates)
            if y is not x:
                self.model.from_step_state(y, x)
            self._hyperviscosity(x)
            if y is not x:
                self.model.restore_mass(x)
            return StepStats(len(self._stages))
        evals = len(self._stages)  # s − 1 stages; the FSAL evaluation after the ∇⁴ stands for the first
        (c0, arg0, first), *rest = self._stages
        if self._ahead != self.dt:  # not written ahead at this Δt
            self._at(c0)
            self.model.rhs_update(arg0, first)
            evals += 1
        for c, arg, updates in rest:
            self._at(c)
            self.model.rhs_update(arg, updates)
        self._hyperviscosity(x)
        self._at(1.0)
        e = self._buffers["e"]
        self.model.rhs_update(x, (Update(e, ((1.0, e), (_dt_times(self._carried, self.dt), None))), *first))
        self._ahead = self.dt
        return StepStats(evals)


def explicit_steppers() -> tuple[type[Stepper], ...]:
    """A registered stepper class per built-in explicit table (``tables.EXPLICIT``): its
    measured Courant limit (``tables.COURANT_LIMITS``), or where none was measured its
    stability polynomial's estimate (as a ``tableau``'s, ``TableauRK.courant_limit``)."""
    classes = []
    for key, t in EXPLICIT.items():
        limit = {"courant_limit": COURANT_LIMITS.get(key)}
        if limit["courant_limit"] is None:
            axis = imaginary_axis_limit(TABLES[key].A_E, TABLES[key].b_E)
            limit = {
                "courant_limit": axis * COURANT_PER_AXIS_LIMIT,
                "courant_limit_source": f"its stability polynomial's imaginary-axis limit {axis:.3g} "
                f"x {COURANT_PER_AXIS_LIMIT:.3g}, as rk4's measured limit is its own",
            }
        # the orders as declared (those the parsed table holds), the table parsed when first stepped
        attrs = {"name": key, "order": t["order"], "embedded_order": t.get("embedded_order", 0)}
        classes.append(type(key.upper(), (ExplicitRK,), {**attrs, **limit, "__doc__": t["description"]}))
    return tuple(classes)


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


# A table's Courant limit from its stability polynomial: rk4's measured limit over rk4's
# imaginary-axis limit 2√2 (0.61; the same rule puts ssprk3 at 1.06 and kgu35 at 2.37,
# measured 1.11 and 2.32: the semi-discrete operator's largest wave number is nearly the same)
COURANT_PER_AXIS_LIMIT = COURANT_LIMITS["rk4"] / imaginary_axis_limit(EXPLICIT["rk4"]["A"], EXPLICIT["rk4"]["b"])


class Tableau(Stepper):
    """A Runge–Kutta or IMEX Runge–Kutta stepper from a Butcher tableau in the scene (scene table ``[tableau]``).

    An explicit table (A, b, c) steps as the built-in explicit Runge–Kutta
    steppers do (``ExplicitRK``: s RHS evaluations a step, the same cost per
    RHS); an IMEX pair (A_E, b_E, A_I, b_I, c) as ``imex`` (``ImexRK``: the
    gravity-wave terms through A_I, one Helmholtz solve per stage with
    a_ii ≠ 0, reported as helmholtz iterations). Hyperviscosity after the step,
    as for every stepper. Options and checks: ``butcher.TableauOptions`` and
    ``butcher.parse``; the run file's attributes ``tableau``,
    ``tableau_description``, ``tableau_order`` and ``tableau_table`` (JSON, the
    entries as written) say which table ran, as the run's header does. An explicit
    table's Courant limit (and warning) comes from its stability polynomial
    (``TableauRK.courant_limit``); an IMEX pair has none: no Courant warning.
    """

    name = "tableau"
    Options = TableauOptions
    explicit = False  # depends on the table: an instance of an explicit one is (``TableauRK``)
    variable_dt = differentiable = True  # either engine
    courant_limit = None
    advective_courant_limit = None
    removed_options: dict = {}

    def __new__(cls, model=None, dt=None, options=None):
        return super().__new__(cls.picked(TableauOptions() if options is None else options))

    @classmethod
    def picked(cls, options) -> type:
        """The engine the kind of table picks: ``TableauRK`` for an explicit table, ``TableauARK``
        for an IMEX pair (``options``: a dict of ``[tableau]`` or ``TableauOptions``)."""
        if cls is not Tableau:
            return cls
        table = parse(options if isinstance(options, TableauOptions) else cls.make_options(**options))
        return TableauARK if table.imex else TableauRK

    @classmethod
    def label(cls, options: dict) -> str:
        return f"{cls.name} {cls.make_options(**options).name}"

    @classmethod
    def has_estimate(cls, options: dict) -> bool:
        return parse(cls.make_options(**options)).estimate is not None

    def table(self) -> Table:
        return parse(self.options)

    @property
    def order(self) -> int:
        """The table's order."""
        return self.table().order

    @property
    def embedded_order(self) -> int:
        """Its embedded solution's order (0: no b̂ row)."""
        return self.table().embedded_order

    def attrs(self) -> dict:
        o = self.options
        table = {key: getattr(o, key) for key in PARTS if getattr(o, key)}
        return {
            "tableau": o.name,
            "tableau_description": o.description,
            "tableau_order": o.order,
            "tableau_table": json.dumps(table),
        }


class TableauRK(Tableau, ExplicitRK):
    """An explicit table, through ``ExplicitRK``; its Courant limit from its stability
    polynomial (``courant_limit``)."""

    explicit = True
    solvers = ()

    @property
    def courant_limit(self) -> float:
        """``axis_limit`` × ``COURANT_PER_AXIS_LIMIT``; 0 for a table whose stability
        region holds no stretch of the imaginary axis (Heun's second-order one)."""
        return self.axis_limit * COURANT_PER_AXIS_LIMIT

    @property
    def axis_limit(self) -> float:
        """The table's imaginary-axis stability limit (``butcher.imaginary_axis_limit``)."""
        table = self.table()
        return imaginary_axis_limit(table.A_E, table.b_E)

    @property
    def courant_limit_source(self) -> str:
        return (
            f"its stability polynomial's imaginary-axis limit {self.axis_limit:.3g} x {COURANT_PER_AXIS_LIMIT:.3g}, "
            "as rk4's measured limit is its own"
        )


class TableauARK(Tableau, ImexRK):
    """An IMEX pair, through ``ImexRK``."""

    solvers = ("helmholtz",)
