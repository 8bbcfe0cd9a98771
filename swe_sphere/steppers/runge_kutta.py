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
from fractions import Fraction

import warp as wp

from ..model.launches import Update
from .base import Stepper, StepStats, work_array
from .butcher import (
    PARTS,
    TABLES,
    Table,
    TableauOptions,
    imaginary_axis_limit,
    parse,
)
from .capabilities import ErrorEstimates, GraphCapture, TrialSteps
from .imex_rk import ImexRK
from .stage_plan import stage_form
from .tables import COURANT_LIMITS, EXPLICIT

f64 = wp.float64


def _dt_times(q: Fraction, dt: float) -> float:
    """qΔt, rounded as Δt/d for q = 1/d (an exact reciprocal is not representable)."""
    return dt / q.denominator if q.numerator == 1 else float(q) * dt


class ExplicitRK(GraphCapture, ErrorEstimates, TrialSteps, Stepper):
    """An explicit Runge–Kutta step of the table ``table()`` (a ``butcher.Table``),
    recorded once from its ``stage_form``: s RHS evaluations a step.

    x(n+1) = x(n) + Δt Σ b_j K_j, K_i = F(Y_i),
    Y_i = x(n) + Δt Σ_j a_ij K_j, written as ``stage_plan.stage_form``'s
    combinations, each written by the DSS of its stage's RHS
    (``ShallowWater.rhs_update``) rather than by a pass of its own: F is never
    stored, and the bits are those of storing F and combining after (ssprk3's and
    kgu35's combinations are their Shu–Osher forms; RK4's take one buffer and one
    combination fewer than its accumulator form).

    Under the model's ``precision = "float32_state"`` the stages run on a float32 state y (u, v,
    h − H₀) in float32 buffers, each chained combination's partial sums holding the whole of the
    state (``stage_plan.stage_form``'s ``whole_partials``: a constant state kept to the bit). Where
    the run keeps the float32 state between steps (``ShallowWater.held``, the default), x is y:
    the stages step it in place, the ∇⁴ acts on it on its steps (``ShallowWater.hyperviscosity``)
    and the mass fixer puts back the mass taken as the run's state was set
    (``ShallowWater.restore_mass``). Compensated (a float64 x between steps), y is
    ``ShallowWater.to_step_state`` of x at the step's start, which takes x's mass, and the step's
    end adds y's increment back to x (``ShallowWater.from_step_state``) before the ∇⁴, which acts
    on x as under "float32", and the fixer.
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
        dtype = model.state_dtype
        # a float32 state's chained combinations hold their whole x(n) part in each partial sum
        d, whole = None if estimate is None else estimate[0], dtype is not f64
        buffers, self._form = stage_form(table.A_E, table.b_E, table.c, d, whole_partials=whole)
        self._buffers = {name: work_array(self, dtype) for name in buffers}
        # the float32 state the stages step (None: they step x itself, float64 or the float32 state
        # the run keeps: ``model.held``)
        self._y = None if model.held.dtype is dtype else work_array(self, dtype)
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
        if not self.fsal() or "forcing" in self.model.terms or self.model.state_dtype is not f64:
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

    def _float32_state(self):
        """The float32 state the stages step for a float64 x (a run that keeps the float32 state
        makes it here, on first use, for a float64 one stepped apart from the run)."""
        if self._y is None:
            self._y = work_array(self, self.model.state_dtype)
        return self._y

    def _dt_changed(self):
        self._x = None  # the stages' coefficients made again with the new Δt (the model's launches take them in place)

    def advance(self, x):
        y = x if x.dtype is self.model.state_dtype else self._float32_state()  # the state the stages step
        if self._x is not y:
            self._record(y)
        limiter = self.model.limiter  # the tracers' (a scene's tracers.limiter): the step's start's bounds
        if limiter is not None:
            limiter.bound(x)
        if self._carried is None:
            departed = self.model.state_dtype is not f64  # y is x where the run keeps it
            if departed:
                self.model.to_step_state(x, y)
            for (c, arg, updates), limit in zip(self._stages, self._limited, strict=True):
                self._at(c)
                if limit:  # the stage's tracers limited before their DSS (a model with a limiter)
                    self.model.rhs_update(arg, updates, limit=True)
                else:
                    self.model.rhs_update(arg, updates)
            if departed:
                self.model.from_step_state(y, x)
            self._hyperviscosity(x)
            if departed:
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
