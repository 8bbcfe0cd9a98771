"""Explicit steppers that are not a table of the Runge–Kutta engine
(``runge_kutta``): leapfrog (Robert–Asselin), leapfrog-trapezoidal (three
levels: x(n−1) carried between steps) and the forward–backward FB-RK(3,2).

Hyperviscosity is applied after each step, split from the dynamics, as in
HOMME (``advance_hypervis``): forward Euler over the span the step covers.

A stage's linear combinations (x + aΔt F and the like) are written by the DSS
of its RHS (``ShallowWater.rhs_update``) rather than by passes of their own:
F is never stored, and the bits are those of storing F and combining after.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..model.launches import Update
from .base import Stepper, StepStats, gathered_copy, load_entry, work_array
from .capabilities import GraphCapture, TrialSteps


class FBRK32(GraphCapture, TrialSteps, Stepper):
    """Forward–backward Runge–Kutta FB-RK(3,2), the depth advanced first in each of
    three stages (Lilly, Engwirda, Capodaglio, Higdon & Petersen 2023, MWR,
    doi:10.1175/MWR-D-23-0113.1). As in their swe-python ``step_RK32``:
    Wicker–Skamarock stages c = 1/3, 1/2, 1 from x(n), each advancing the depth first, h⁽ⁱ⁾ = h(n) + cᵢΔt F_h(x⁽ⁱ⁻¹⁾), then the wind,
    u⁽ⁱ⁾ = u(n) + cᵢΔt F_u(u⁽ⁱ⁻¹⁾, h̃), with the depth in the momentum tendency
    (in the vector-invariant form it enters only through g∇h) weighted towards
    the new one: h̃ = β h⁽ⁱ⁾ + (1 − β) h(n) in stages 1 and 2, and
    h̃ = β h(n+1) + (1 − 2β) h⁽²⁾ + β h(n) in stage 3 (centred on t + Δt/2,
    which keeps second order for any β). β = (0.531, 0.531, 0.313).

    Each stage evaluates the continuity half (continuity, and the forcing) and
    the momentum half (the other tendency terms) of the RHS, each kernel compiled
    for its terms: together one RHS's arithmetic, plus a second DSS; reported
    as 3 RHS evaluations per step.

    Why it is not a table of the Runge–Kutta engine (``runge_kutta``): a Butcher
    table evaluates the whole F at whole states Y_i = x(n) + Δt Σ a_ij F(Y_j). Here
    F is split into its continuity half F_h (depth rows) and momentum half F_u
    (wind rows), each its own compiled kernel, and F_u's argument (u⁽ⁱ⁻¹⁾, h̃)
    takes its depth from a combination that already holds this stage's F_h and
    its wind from the last stage's: as a table it is an additive (partitioned)
    explicit method of six half-evaluations, two tables A_h, A_u acting on
    different rows. The engine's additive path splits F = N + L with L the
    linear gravity-wave operator, applied by products and Helmholtz solves, not
    into two nonlinear halves evaluated by rows; hosting this needs that
    row-wise fast/slow split, the one split-explicit and multirate methods need."""

    name = "fbrk32"
    explicit = capturable = variable_dt = differentiable = True
    courant_limit = 1.58  # bisection on TC2 (5 days) at ne 8 np 4 only: 1.43 × ssprk3's there
    BETA = (0.531, 0.531, 0.313)
    C = (1.0 / 3.0, 0.5, 1.0)

    def __init__(self, model, dt, options=None):
        super().__init__(model, dt, options)
        self.continuity = tuple(t for t in model.terms if t in ("continuity", "forcing"))
        self.momentum = tuple(
            t for t in model.terms if t in ("momentum_advection", "coriolis", "pressure_gradient", "topography")
        )
        if not self.continuity:
            raise ValueError("fbrk32 advances the depth first: it needs the continuity term (or a forcing)")
        # s: the momentum half's input (u⁽ⁱ⁻¹⁾, v⁽ⁱ⁻¹⁾, h̃); t: x⁽ⁱ⁾ of stages 1 and 2;
        # kh: the continuity half's wind rows (a forcing's; zero without one)
        self.s, self.t, self.kh = work_array(self), work_array(self), work_array(self)
        self._x = None

    def _record(self, x):
        """Per stage: the continuity half's F_h writes h̃ into s and h⁽ⁱ⁾ into t
        (x at the last stage) from its DSS (with a forcing it also stores its wind
        rows in kh); the momentum half's F_u writes u⁽ⁱ⁾ into t (x) and into s, the
        next stage's input; the wind without momentum terms is a combination of
        its own. The same sums, in the same order, as storing F and combining."""
        dt, s, t, kh = self.dt, self.s, self.t, self.kh
        self._x = x
        U, H = slice(0, 2), slice(2, 3)
        forced = "forcing" in self.continuity
        self._stages = []
        for i, (c, beta) in enumerate(zip(self.C, self.BETA)):
            last = i == len(self.C) - 1
            out = x if last else t  # x⁽ⁱ⁾
            if last:  # h̃ = β h(n+1) + (1 − 2β) h⁽²⁾ + β h(n), h(n+1) = h(n) + cΔt F_h
                tilde = ((2 * beta, x), (beta * c * dt, None), (1 - 2 * beta, t))
            else:  # h̃ = β h⁽ⁱ⁾ + (1 − β) h(n)
                tilde = ((1.0, x), (beta * c * dt, None))
            depth = (Update(kh, ((1.0, None),), U),) if forced else ()
            depth += (Update(s, tilde, H), Update(out, ((1.0, x), (c * dt, None)), H))
            wind = ((1.0, x), *(((c * dt, kh),) if forced else ()), (c * dt, None))  # u⁽ⁱ⁾ = u(n) + cΔt (F_u)
            if self.momentum:
                launches = [self.model.lincomb(s[U], ((1.0, x[U]), (0.0, x[U])))] if i == 0 else []  # u⁽⁰⁾ = u(n)
                momentum = (Update(out, wind, U),) + (() if last else (Update(s, wind, U),))
            else:
                launches, momentum = [self.model.lincomb(out[U], ((1.0, x[U]), (c * dt, kh[U])))], None
            self._stages.append((self.C[i - 1] if i else 0.0, x if i == 0 else t, depth, launches, momentum))

    def _dt_changed(self):
        self._x = None  # re-recorded with the new Δt by the next step

    def advance(self, x):
        if self._x is not x:
            self._record(x)
        m = self.model
        for c, arg, depth, launches, momentum in self._stages:
            self._at(c)
            m.rhs_update(arg, depth, self.continuity)
            for launch in launches:
                launch.launch()
            if momentum:
                m.rhs_update(self.s, momentum, self.momentum)
        self._hyperviscosity(x)
        return StepStats(3)


class _LeapfrogFamily(GraphCapture, Stepper):
    """Three-level schemes: keep x(n−1) (``old``; in ``state()`` as "previous");
    the first step (``steps == 0``) is the explicit midpoint rule (second order,
    2 RHS evaluations)."""

    explicit = capturable = differentiable = True
    dense_hyperviscosity = "applies its ∇⁴ to a three-level scheme's new level, x(n+1) over 2Δt"

    def __init__(self, model, dt, options=None):
        super().__init__(model, dt, options)
        self.old, self.new = work_array(self), work_array(self)
        self._x = None

    def graph_key(self):
        return None if self.steps == 0 else super().graph_key()  # the start: once, not worth a graph

    def carried_arrays(self) -> list:
        return [self.old]  # x̃(n−1): the filtered x(n−1), or x(n−1) itself

    def state(self):
        s = super().state()
        if self.steps:
            s["previous"] = gathered_copy(self, self.old)
        return s

    def restore(self, state):
        super().restore(state)
        if self.steps:
            load_entry(self, self.old, state, "previous")

    def _record(self, x):
        """Record the launches on x (once per state array)."""
        dt = self.dt
        self._x = x
        self._start_mid = (Update(self.new, ((1.0, x), (dt / 2, None))),)  # x(n + 1/2), from F(x(n))
        self._start_end = (Update(self.old, ((1.0, x),)), Update(x, ((1.0, x), (dt, None))))  # keep x(n); x(n+1)
        self._start_keep = self.model.lincomb(self.old, ((1.0, x), (0.0, x)))  # the semi-implicit start's
        self._copy_new = self.model.lincomb(x, ((1.0, self.new), (0.0, self.new)))
        self._record_scheme(x)

    def advance(self, x):
        if self._x is not x:
            self._record(x)
        if self.steps == 0:
            m = self.model
            self._at(0.0)
            m.rhs_update(x, self._start_mid)
            self._at(0.5)
            m.rhs_update(self.new, self._start_end)
            m.hyperviscosity(x, self.dt)
            return StepStats(2)
        return self._step(x)


@dataclass(frozen=True)
class LeapfrogOptions:
    """Scene table ``[leapfrog]``: the Robert–Asselin coefficient ε."""

    robert_asselin: float = 0.05

    def __post_init__(self):
        if not 0 <= self.robert_asselin < 0.5:
            raise ValueError(f"robert_asselin must be in [0, 0.5) (got {self.robert_asselin})")


class Leapfrog(_LeapfrogFamily):
    """Leapfrog x(n+1) = x(n−1) + 2Δt F(x(n)) with the Robert–Asselin filter
    x(n) += ε (x(n−1) − 2x(n) + x(n+1)) (Robert 1966; Asselin 1972).
    Hyperviscosity acts on x(n+1) over 2Δt. 1 RHS evaluation per step."""

    name = "leapfrog"
    Options = LeapfrogOptions
    courant_limit = 0.58

    def _record_scheme(self, x):
        eps = self.options.robert_asselin
        self._lf = (Update(self.new, ((1.0, self.old), (2 * self.dt, None))),)
        self._ra = self.model.lincomb(self.old, ((1 - 2 * eps, x), (eps, self.old), (eps, self.new)))

    def _step(self, x):
        m = self.model
        self._at(0.0)
        m.rhs_update(x, self._lf)
        m.hyperviscosity(self.new, 2 * self.dt)
        self._ra.launch()
        self._copy_new.launch()
        return StepStats(1)


class LeapfrogTrapezoidal(_LeapfrogFamily):
    """HOMME's leapfrog-trapezoidal step (LFTfreq = 1; Kurihara 1965): a leapfrog
    predictor x* = x(n−1) + 2Δt F(x(n)) and a trapezoidal corrector
    x(n+1) = x(n) + Δt/2 (F(x(n)) + F(x*)). No filter; the corrector damps
    the computational mode. Hyperviscosity over Δt. 2 RHS evaluations per step."""

    name = "leapfrog_trapezoidal"
    courant_limit = 0.88

    def __init__(self, model, dt, options=None):
        super().__init__(model, dt, options)
        self.half = work_array(self)  # x(n) + Δt/2 F(x(n)), the corrector's first half

    def _record_scheme(self, x):
        dt = self.dt
        self._pred = (
            Update(self.new, ((1.0, self.old), (2 * dt, None))),
            Update(self.half, ((1.0, x), (dt / 2, None))),
        )
        self._corr = (Update(self.old, ((1.0, x),)), Update(x, ((1.0, self.half), (dt / 2, None))))  # keep x(n); x(n+1)

    def _step(self, x):
        m = self.model
        self._at(0.0)
        m.rhs_update(x, self._pred)
        self._at(1.0)  # the predictor x* stands for x(n+1)
        m.rhs_update(self.new, self._corr)
        m.hyperviscosity(x, self.dt)
        return StepStats(2)
