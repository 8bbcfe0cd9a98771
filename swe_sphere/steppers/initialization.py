"""Digital-filter initialisation: a balanced start (Lynch & Huang 1992, MWR 120, 1019).

The case's initial state x0 is integrated forward and backward in time over
± span/2 with the adiabatic, non-dissipative dynamics (the scene's terms less
hyperviscosity, which is anti-diffusive backwards and would blow up), by the
model's RK4 at a small step, and the states x(n Δt), n = −N..N, are summed with
Lanczos low-pass weights (``timefilter.lanczos_weights``, the sigma window
reaching zero at ± span/2): oscillations faster than the cutoff period — the
gravity waves an unbalanced start excites (on TC5 periods of 8–33 h) — are
removed and the slow, balanced flow is kept. The weights sum to 1, so the mass
of the filtered state is that of x0 to round-off.

Backward in time is forward in the time-reversed equations: without dissipation
the shallow-water equations are invariant under t → −t, v → −v, f → −f. The
discrete right-hand side has the same symmetry exactly (its terms are linear or
quadratic in v, and ζ(−v) = −ζ(v) bit for bit), so x(−t) = P x̃(t) with
P = diag(−1, −1, 1) and x̃ integrated forward from P x0 on a model with −f: RK4
there is RK4 with −Δt here, and no stepper needs a negative step.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from ..model.diagnostics import max_signal_rate
from ..model.shallow_water import ShallowWater
from . import make_stepper
from .timefilter import lanczos_weights

METHODS = ("none", "dfi")
# RK4's step in the filter: (|v| + sqrt(g h)) Δt / Δx ≤ 0.5 on x0, well inside
# RK4's stability limit (1.73), so the fast waves the filter removes are
# integrated accurately enough to be removed (RK4's amplitude error there ≲ 1e-4)
COURANT = 0.5


@dataclass(frozen=True)
class DigitalFilter:
    """The filter: ``cutoff_hours`` the half-power period, ``span_hours`` the whole
    window (−span/2 … span/2). Defaults, chosen on TC5 ne16 (README "A balanced
    start"): a 24 h cutoff over a 48 h span removes the impulsive start's gravity
    waves (response −5e-4 at 8 h, −4.7e-3 at 12 h, 0.048 at 16 h, 0.50 at 24 h,
    0.79 at 33 h), so that Crank–Nicolson's difference to RK4 at 7× the
    gravity-wave limit drops 70× in h + hs, and keeps slow motions (0.94 at 48 h,
    0.987 at 3 days, no overshoot). Longer cutoffs remove a little more but damp
    the balanced flow near the mountain, which moves past a point in 1–3 days
    (the day-5 vorticity changes 5.4e-3 at 24 h, 1.7e-2 at 36 h, 2.8e-2 at 48 h
    against a spatial error of 2.2e-2). The span must be at least twice the cutoff
    period; shorter windows leave periods of half the cutoff in (Lynch & Huang's
    6 h span for a 6 h cutoff passes 4 h waves at 0.24). Raises ``ValueError``
    naming the offending value."""

    span_hours: float = 48.0
    cutoff_hours: float = 24.0

    def __post_init__(self):
        for name in ("span_hours", "cutoff_hours"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ValueError(f"dfi.{name} must be > 0 (got {value!r})")
        if self.span_hours < 2 * self.cutoff_hours:
            raise ValueError(
                f"dfi.span_hours = {self.span_hours:g} is too short for a cutoff of {self.cutoff_hours:g} h "
                f"(needs >= 2 x dfi.cutoff_hours = {2 * self.cutoff_hours:g})"
            )

    def steps(self, rate: float) -> tuple[float, int]:
        """(Δt in s, n): the RK4 step and the steps each way to span/2, Δt ≤ COURANT / ``rate``
        (``rate`` = ``max (|v| + sqrt(g h)) / Δx`` of x0, s⁻¹) dividing span/2."""
        half = self.span_hours * 1800.0
        n = max(2, math.ceil(half * rate / COURANT - 1e-9))
        return half / n, n

    def weights(self, dt: float, n: int) -> np.ndarray:
        """The 2n + 1 weights w_{−n..n} (w_{±n} = 0) of the states at n Δt."""
        return lanczos_weights(dt / (self.cutoff_hours * 3600.0), n)


@dataclass(frozen=True)
class FilterResult:
    """A digital-filter start: the filtered state and what it cost and changed."""

    x: np.ndarray  # (3, N) element-local u, v (m s⁻¹), h (m) of this rank's part
    dt: float  # s, RK4 step of the filter
    steps: int  # RK4 steps each way (n − 1: the states at ± n Δt weigh 0)
    rhs_evals: int
    wall_time: float  # s
    dhdt_rms: tuple  # area-RMS of ∂h/∂t (m s⁻¹) of x0 and of the filtered state
    mass_change: float  # relative, filtered against x0

    def attrs(self, f: DigitalFilter) -> dict:
        """The run file's global attributes (prefix dfi_)."""
        return {
            "dfi_span_hours": f.span_hours,
            "dfi_cutoff_hours": f.cutoff_hours,
            "dfi_dt": self.dt,
            "dfi_steps": self.steps,
            "dfi_rhs_evals": self.rhs_evals,
            "dfi_wall_time": self.wall_time,
            "dfi_dhdt_rms_before": self.dhdt_rms[0],
            "dfi_dhdt_rms_after": self.dhdt_rms[1],
            "dfi_mass_change": self.mass_change,
        }

    def describe(self, f: DigitalFilter) -> str:
        """One line for the run's header."""
        return (
            f"digital filter (Lynch & Huang 1992): cutoff {f.cutoff_hours:g} h, span +-{f.span_hours / 2:g} h, RK4 dt "
            f"{self.dt:.4g} s x {self.steps} steps each way, {self.wall_time:.2f} s; rms dh/dt {self.dhdt_rms[0]:.3e} -> "
            f"{self.dhdt_rms[1]:.3e} m/s, mass change {self.mass_change:+.1e}"
        )


def digital_filter(f: DigitalFilter, x0: np.ndarray, *, grid, terms, fcor, hs, g, topology) -> FilterResult:
    """Filter the state ``x0`` ((3, N) element-local numpy, this rank's part) with
    ``f`` (see the module docstring). ``grid``, ``fcor``, ``hs`` (N,), ``topology``:
    this rank's part as for ``model.ShallowWater`` (the topology's device); ``terms`` the scene's (the
    hyperviscosity is left out; ``forcing``, not time-reversible, is not expected:
    the forced case TC4 has an exact solution, so its scenes refuse a filter). Collective over the topology's ranks. Raises
    ``ValueError`` if either integration ends with a non-finite value or a depth
    h ≤ 0 (the span is too long for the state)."""
    t0 = time.perf_counter()
    terms = tuple(t for t in terms if t != "hyperviscosity")
    reverse = np.array([-1.0, -1.0, 1.0])[:, None]  # P: v → −v
    dt, n = f.steps(topology.max(max_signal_rate(grid, *x0, g)))
    w = f.weights(dt, n)
    acc = w[n] * x0
    models = {}
    for sign in (1, -1):
        model = models[sign] = ShallowWater(
            grid, terms, sign * fcor, hs, g=g, device=topology.device, topology=topology
        )
        x = model.new_state(*(x0 if sign > 0 else reverse * x0))
        stepper = make_stepper("rk4", model, dt)
        for k in range(1, n):  # w[0] = w[2n] = 0: the states at ± n Δt are not needed
            stepper.step(x)
            acc += w[n + sign * k] * (x.numpy() if sign > 0 else reverse * x.numpy())
        if model.bad_nodes.first(x) is not None:
            raise ValueError(
                f"the digital filter's {'forward' if sign > 0 else 'backward'} integration over {f.span_hours / 2:g} h "
                f"(RK4, dt = {dt:.4g} s) went non-finite or dry; try a shorter dfi.span_hours"
            )

    def dhdt_rms(state):  # L&H's measure of noise: the tendency of the free surface
        x, tend = models[1].new_state(*state), models[1].new_state()
        models[1].rhs(x, tend)
        return math.sqrt(topology.mean(tend.numpy()[2] ** 2))

    mass0 = topology.integrate(x0[2])
    return FilterResult(
        x=acc,
        dt=dt,
        steps=n - 1,
        rhs_evals=8 * (n - 1),
        wall_time=time.perf_counter() - t0,
        dhdt_rms=(dhdt_rms(x0), dhdt_rms(acc)),
        mass_change=(topology.integrate(acc[2]) - mass0) / mass0,
    )
