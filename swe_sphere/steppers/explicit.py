"""Explicit steppers: leapfrog (Robert–Asselin), leapfrog-trapezoidal, and the
Runge–Kutta family from one table (SSP-RK3, RK4, HOMME's KGU35), and the
forward–backward FB-RK(3,2).

Hyperviscosity is applied after each step, split from the dynamics, as in
HOMME (``advance_hypervis``): forward Euler over the span the step covers.
"""

from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction

from .base import Stepper, StepStats


@dataclass(frozen=True)
class RKScheme:
    """An explicit Runge–Kutta scheme as the launches it records.

    ``stages``: per stage (c, arg, updates): the abscissa c, the buffer whose RHS
    goes into ``k``, then the combinations written after it, each
    (out, terms) with out = Σ a·src over two or three (a, src) terms; src
    "k" takes a ``Fraction`` q of Δt (the RHS times qΔt). Buffers are "x" (the
    state, overwritten by the last update) and the scheme's ``buffers``.
    ``courant_limit``: the measured one (``Stepper.courant_limit``)."""

    name: str
    doc: str
    buffers: tuple[str, ...]
    stages: tuple
    courant_limit: float


def _dt_times(q: Fraction, dt: float) -> float:
    """qΔt, rounded as Δt/d for q = 1/d (an exact reciprocal is not representable)."""
    return dt / q.denominator if q.numerator == 1 else float(q) * dt


F = Fraction
RK_SCHEMES = (
    RKScheme(
        "ssprk3",
        """Three-stage, third-order strong-stability-preserving Runge–Kutta in
        Shu–Osher form (Shu & Osher 1988, eq. 2.18). 3 RHS evaluations per step.""",
        ("s1", "s2"),
        (
            (0.0, "x", (("s1", ((1.0, "x"), (F(1), "k"))),)),
            (1.0, "s1", (("s2", ((0.75, "x"), (0.25, "s1"), (F(1, 4), "k"))),)),
            (0.5, "s2", (("x", ((1.0 / 3.0, "x"), (2.0 / 3.0, "s2"), (F(2, 3), "k"))),)),
        ),
        1.11,
    ),
    RKScheme(
        "rk4",
        "Classical fourth-order Runge–Kutta. 4 RHS evaluations per step.",
        ("s", "acc"),
        (
            (0.0, "x", (("s", ((1.0, "x"), (F(1, 2), "k"))), ("acc", ((1.0, "x"), (F(1, 6), "k"))))),
            (0.5, "s", (("acc", ((1.0, "acc"), (F(1, 3), "k"))), ("s", ((1.0, "x"), (F(1, 2), "k"))))),
            (0.5, "s", (("acc", ((1.0, "acc"), (F(1, 3), "k"))), ("s", ((1.0, "x"), (F(1), "k"))))),
            (1.0, "s", (("x", ((1.0, "acc"), (F(1, 6), "k"))),)),
        ),
        1.73,
    ),
    RKScheme(
        "kgu35",
        """HOMME's ``tstep_type = 5`` (E3SM ``prim_advance_mod``; Kinnmark & Gray 1984
        in Ullrich's five-stage third-order form): u1 = u0 + Δt/5 f(u0),
        u2 = u0 + Δt/5 f(u1), u3 = u0 + Δt/3 f(u2), u4 = u0 + 2Δt/3 f(u3),
        u5 = (5u1 − u0)/4 + 3Δt/4 f(u4). Third order (measured 3 on TC6),
        imaginary-axis limit √15 ≈ 3.87 against RK4's 2.83. 5 RHS evaluations per step.""",
        ("s1", "s"),
        (
            (0.0, "x", (("s1", ((1.0, "x"), (F(1, 5), "k"))),)),
            (0.2, "s1", (("s", ((1.0, "x"), (F(1, 5), "k"))),)),
            (0.2, "s", (("s", ((1.0, "x"), (F(1, 3), "k"))),)),
            (1.0 / 3.0, "s", (("s", ((1.0, "x"), (F(2, 3), "k"))),)),
            (2.0 / 3.0, "s", (("x", ((1.25, "s1"), (-0.25, "x"), (F(3, 4), "k"))),)),
        ),
        2.32,  # bisection on TC2 (5 days) at ne 8 np 4 only: 1.34 × rk4's there
    ),
)


class ExplicitRK(Stepper):
    """An explicit Runge–Kutta step recorded from its ``scheme`` (an ``RKScheme``);
    one subclass per scheme is made from the table (``rk_steppers``)."""

    explicit = True
    scheme: RKScheme

    def __init__(self, model, dt, options=None):
        super().__init__(model, dt, options)
        self.k = self._buffer()
        self._buffers = {name: self._buffer() for name in self.scheme.buffers}
        self._x = None

    def _record(self, x):
        arrays = {"x": x, "k": self.k, **self._buffers}
        self._x = x
        self._stages = [
            (c, arrays[arg], [
                self._lincomb(arrays[out], *((_dt_times(a, self.dt) if src == "k" else a, arrays[src]) for a, src in terms))
                for out, terms in updates
            ])
            for c, arg, updates in self.scheme.stages
        ]

    def advance(self, x):
        if self._x is not x:
            self._record(x)
        for c, arg, launches in self._stages:
            self._at(c)
            self.model.rhs(arg, self.k)
            for launch in launches:
                launch.launch()
        self.model.hyperviscosity(x, self.dt)
        return StepStats(len(self._stages))


def rk_steppers() -> tuple[type[Stepper], ...]:
    """A registered stepper class per scheme of ``RK_SCHEMES``."""
    return tuple(
        type(s.name.upper(), (ExplicitRK,), {"name": s.name, "scheme": s, "courant_limit": s.courant_limit, "__doc__": s.doc})
        for s in RK_SCHEMES
    )


class FBRK32(Stepper):
    """Forward–backward Runge–Kutta FB-RK(3,2) (Lilly, Engwirda, Capodaglio, Higdon
    & Petersen 2023, MWR, doi:10.1175/MWR-D-23-0113.1, as in their swe-python
    ``step_RK32``): Wicker–Skamarock stages c = 1/3, 1/2, 1 from x(n), each
    advancing the depth first, h⁽ⁱ⁾ = h(n) + cᵢΔt F_h(x⁽ⁱ⁻¹⁾), then the wind,
    u⁽ⁱ⁾ = u(n) + cᵢΔt F_u(u⁽ⁱ⁻¹⁾, h̃), with the depth in the momentum tendency
    (in the vector-invariant form it enters only through g∇h) weighted towards
    the new one: h̃ = β h⁽ⁱ⁾ + (1 − β) h(n) in stages 1 and 2, and
    h̃ = β h(n+1) + (1 − 2β) h⁽²⁾ + β h(n) in stage 3 (centred on t + Δt/2,
    which keeps second order for any β). β = (0.531, 0.531, 0.313).

    Each stage evaluates the continuity half (continuity, and the forcing) and
    the momentum half (the other tendency terms) of the RHS, each kernel compiled
    for its terms: together one RHS's arithmetic, plus a second DSS; reported
    as 3 RHS evaluations per step."""

    name = "fbrk32"
    explicit = True
    courant_limit = 1.58  # bisection on TC2 (5 days) at ne 8 np 4 only: 1.43 × ssprk3's there
    BETA = (0.531, 0.531, 0.313)
    C = (1.0 / 3.0, 0.5, 1.0)

    def __init__(self, model, dt, options=None):
        super().__init__(model, dt, options)
        self.kh, self.km, self.s = self._buffer(), self._buffer(), self._buffer()
        self.continuity = tuple(t for t in model.terms if t in ("continuity", "forcing"))
        self.momentum = tuple(t for t in model.terms if t in ("momentum_advection", "coriolis", "pressure_gradient", "topography"))
        self._x = None

    def _record(self, x):
        dt, kh, km, s = self.dt, self.kh, self.km, self.s
        self._x = x
        U, H = slice(0, 2), slice(2, 3)
        b1, b2, b3 = self.BETA
        c1, c2, c3 = self.C
        weighted = (  # s = (u⁽ⁱ⁻¹⁾, v⁽ⁱ⁻¹⁾, h̃); before it, kh = F(x⁽ⁱ⁻¹⁾)'s continuity half
            [self._lincomb(s[U], (1.0, x[U]), (0.0, x[U])), self._lincomb(s[H], (1.0, x[H]), (b1 * c1 * dt, kh[H]))],
            [self._lincomb(s[H], (1.0, x[H]), (b2 * c2 * dt, kh[H]))],
            [self._lincomb(s[H], (2 * b3, x[H]), (b3 * c3 * dt, kh[H]), (1 - 2 * b3, s[H]))],
        )
        self._stages = []
        for i, c in enumerate(self.C):
            out = x if i == len(self.C) - 1 else s
            terms = [(1.0, x), (c * dt, kh)] + ([(c * dt, km)] if self.momentum else [])
            self._stages.append((self.C[i - 1] if i else 0.0, x if i == 0 else s, weighted[i], self._lincomb(out, *terms)))

    def advance(self, x):
        if self._x is not x:
            self._record(x)
        m = self.model
        for c, arg, weighted, update in self._stages:
            self._at(c)
            if self.continuity:
                m.rhs(arg, self.kh, self.continuity)
            for launch in weighted:
                launch.launch()
            if self.momentum:
                m.rhs(self.s, self.km, self.momentum)
            update.launch()
        m.hyperviscosity(x, self.dt)
        return StepStats(3)


class _LeapfrogFamily(Stepper):
    """Three-level schemes: keep x(n−1) (``old``; in ``state()`` as "previous");
    the first step (``steps == 0``) is the explicit midpoint rule (second order,
    2 RHS evaluations)."""

    explicit = True

    def __init__(self, model, dt, options=None):
        super().__init__(model, dt, options)
        self.old, self.k, self.new = self._buffer(), self._buffer(), self._buffer()
        self._x = None

    def state(self):
        s = super().state()
        if self.steps:
            s["previous"] = self._save(self.old)
        return s

    def restore(self, state):
        super().restore(state)
        if self.steps:
            self._load(self.old, state, "previous")

    def _record(self, x):
        """Record the launches on x (once per state array)."""
        dt = self.dt
        self._x = x
        self._start_mid = self._lincomb(self.new, (1.0, x), (dt / 2, self.k))
        self._start_keep = self._lincomb(self.old, (1.0, x), (0.0, x))
        self._start_end = self._lincomb(x, (1.0, x), (dt, self.k))
        self._copy_new = self._lincomb(x, (1.0, self.new), (0.0, self.new))
        self._record_scheme(x)

    def advance(self, x):
        if self._x is not x:
            self._record(x)
        if self.steps == 0:
            m = self.model
            self._at(0.0)
            m.rhs(x, self.k)
            self._start_mid.launch()
            self._at(0.5)
            m.rhs(self.new, self.k)
            self._start_keep.launch()
            self._start_end.launch()
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
        self._lf = self._lincomb(self.new, (1.0, self.old), (2 * self.dt, self.k))
        self._ra = self._lincomb(self.old, (1 - 2 * eps, x), (eps, self.old), (eps, self.new))

    def _step(self, x):
        m = self.model
        self._at(0.0)
        m.rhs(x, self.k)
        self._lf.launch()
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
        self.k2 = self._buffer()

    def _record_scheme(self, x):
        dt = self.dt
        self._pred = self._lincomb(self.new, (1.0, self.old), (2 * dt, self.k))
        self._keep = self._lincomb(self.old, (1.0, x), (0.0, x))
        self._corr = self._lincomb(x, (1.0, x), (dt / 2, self.k), (dt / 2, self.k2))

    def _step(self, x):
        m = self.model
        self._at(0.0)
        m.rhs(x, self.k)
        self._pred.launch()
        self._at(1.0)  # the predictor x* stands for x(n+1)
        m.rhs(self.new, self.k2)
        self._keep.launch()
        self._corr.launch()
        m.hyperviscosity(x, self.dt)
        return StepStats(2)
