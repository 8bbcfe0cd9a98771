"""Explicit steppers: leapfrog (Robert–Asselin), leapfrog-trapezoidal, SSP-RK3, RK4.

Hyperviscosity is applied after each step, split from the dynamics, as in
HOMME (``advance_hypervis``): forward Euler over the span the step covers.
"""

from __future__ import annotations

from dataclasses import dataclass

from .base import Stepper, StepStats


class SSPRK3(Stepper):
    """Three-stage, third-order strong-stability-preserving Runge–Kutta
    (Shu & Osher 1988, eq. 2.18). 3 RHS evaluations per step."""

    name = "ssprk3"
    explicit = True
    courant_limit = 1.11

    def __init__(self, model, dt, options=None):
        super().__init__(model, dt, options)
        self.k, self.s1, self.s2 = self._buffer(), self._buffer(), self._buffer()
        self._x = None

    def _record(self, x):
        dt, k, s1, s2 = self.dt, self.k, self.s1, self.s2
        self._x = x
        self._l1 = self._lincomb(s1, (1.0, x), (dt, k))
        self._l2 = self._lincomb(s2, (0.75, x), (0.25, s1), (0.25 * dt, k))
        self._l3 = self._lincomb(x, (1.0 / 3.0, x), (2.0 / 3.0, s2), (2.0 / 3.0 * dt, k))

    def advance(self, x):
        if self._x is not x:
            self._record(x)
        m = self.model
        self._at(0.0)
        m.rhs(x, self.k)
        self._l1.launch()
        self._at(1.0)
        m.rhs(self.s1, self.k)
        self._l2.launch()
        self._at(0.5)
        m.rhs(self.s2, self.k)
        self._l3.launch()
        m.hyperviscosity(x, self.dt)
        return StepStats(3)


class RK4(Stepper):
    """Classical fourth-order Runge–Kutta. 4 RHS evaluations per step."""

    name = "rk4"
    explicit = True
    courant_limit = 1.73

    def __init__(self, model, dt, options=None):
        super().__init__(model, dt, options)
        self.k, self.s, self.acc = self._buffer(), self._buffer(), self._buffer()
        self._x = None

    def _record(self, x):
        dt, k, s, acc = self.dt, self.k, self.s, self.acc
        self._x = x
        self._stages = [  # (stage abscissa, argument, launches after its RHS)
            (0.0, x, [self._lincomb(s, (1.0, x), (dt / 2, k)), self._lincomb(acc, (1.0, x), (dt / 6, k))]),
            (0.5, s, [self._lincomb(acc, (1.0, acc), (dt / 3, k)), self._lincomb(s, (1.0, x), (dt / 2, k))]),
            (0.5, s, [self._lincomb(acc, (1.0, acc), (dt / 3, k)), self._lincomb(s, (1.0, x), (dt, k))]),
            (1.0, s, [self._lincomb(x, (1.0, acc), (dt / 6, k))]),
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
        return StepStats(4)


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
