"""Semi-implicit leapfrog (HOMME ``advance_si_nonstag``; Robert, Henderson & Turnbull 1972).

The linear gravity-wave terms about a mean depth H — the pressure gradient
−g∇h and −H∇·v — are averaged over levels n−1 and n+1; everything else
(S = F − L) is leapfrogged at level n. Eliminating v(n+1) leaves a Helmholtz
equation for the height, solved by the shared gravity-wave operator
(``helmholtz.HelmholtzSolver`` of ``model.gravity_wave.GravityWaveOperator``: L is built from the DSS'd operators of the
explicit RHS, so the elimination is exact and mass is kept to round-off):

    (I − Δt L) x(n+1) = x(n−1) + 2Δt F(x(n)) + Δt L (x(n−1) − 2x(n)).

Dissipation: HOMME disallows hyperviscosity with SI; here the scene's ∇⁴
hyperviscosity is applied after the step as for the explicit leapfrog (split,
forward Euler over 2Δt, subcycled to stay stable at long steps), and the
Robert–Asselin filter (``robert_asselin``, default 0.05) damps the leapfrog
computational mode. The first step is a semi-implicit half step from
x(−1) = x(0).
"""

from __future__ import annotations

from dataclasses import dataclass

import warp as wp

from ..kernels import blas
from ..model.helmholtz import HelmholtzOptions
from .base import StepStats, device_counts, work_array
from .explicit import Leapfrog, LeapfrogOptions
from .helmholtz_steps import REMOVED_SOLVER_OPTIONS, HelmholtzSteps

f64 = wp.float64


@dataclass(frozen=True)
class SemiImplicitOptions(HelmholtzOptions, LeapfrogOptions):
    """Scene table ``[semi_implicit]`` (see ``SemiImplicit``): the leapfrog's and the
    Helmholtz solve's options, a tighter ``tol`` by default."""

    tol: float = 1e-7

    def __post_init__(self):
        LeapfrogOptions.__post_init__(self)
        HelmholtzOptions.__post_init__(self)


class SemiImplicit(HelmholtzSteps, Leapfrog):
    """Semi-implicit leapfrog: 1 RHS evaluation and one Helmholtz solve per step.

    Options (scene table ``[semi_implicit]``): ``robert_asselin`` (0.05),
    ``tol`` (the Helmholtz CG's relative residual, 1e-7: where a tighter one no longer
    changes the sweep's temporal errors; the earlier benchmarks notebook (benchmarks/README.md before the suite), "Measurements behind the
    code"), ``maxiter`` (500),
    ``mean_depth`` (H in m; 0 = the initial state's mean depth). The
    Helmholtz solve is ``helmholtz.HelmholtzSolver``'s compiled CG; each solve
    starts from the projection of its right-hand side onto past solutions,
    ``guess_history`` (0..32, 8) of them (``helmholtz.GuessHistory``; 0: from the
    last solution). ``precision`` ("float64" | "float32", as [numerics] precision; the old "double" and
    "mixed" deprecated: float32 CG passes refined in float64 to the same ``tol``; "float64" is the
    default because the float32 product is no faster on the CPU, the earlier benchmarks notebook (benchmarks/README.md before the suite)).
    Reports the Helmholtz iterations per step (under ``Simulation.run`` counted on
    the device and read once a block, the step a graph after the first). Raises
    ValueError without the continuity and pressure-gradient terms.
    """

    name = "semi_implicit"
    Options = SemiImplicitOptions
    explicit = False
    courant_limit = None
    removed_options = REMOVED_SOLVER_OPTIONS

    def __init__(self, model, dt, options=None):
        super().__init__(model, dt, options)
        self.F, self.W, self.LW = work_array(self), work_array(self), work_array(self)

    @property
    def H(self) -> float:
        """The mean depth H (m) of the linear gravity-wave terms."""
        return self.linear.H

    def _si(self, old, cur, new, dt):
        """new = semi-implicit leapfrog from old over 2dt, explicit terms at cur (the solve's
        iterations counted on the device, ``HelmholtzSolver.iterations``)."""
        m = self.model
        self.linear.set_depth(cur)
        self._at(0.0)  # cur is x(n)
        m.rhs(cur, self.F)
        self.model.pointwise(blas.axpby, f64(1.0), old, f64(-2.0), cur, self.W)
        self.linear.apply(self.W, self.LW)
        self.model.pointwise(blas.axpbypcz, f64(1.0), old, f64(2.0 * dt), self.F, f64(dt), self.LW, new)
        self.helmholtz.solve(new, dt, new)

    def advance(self, x):
        m = self.model
        if self._x is not x:
            self._record(x)
        if self.steps == 0:
            self._start_keep.launch()  # x(−1) = x(0)
            self._si(self.old, x, self.new, self.dt / 2)
            self._copy_new.launch()
            m.hyperviscosity(x, self.dt)
            return StepStats(1, device_counts(self))
        self._si(self.old, x, self.new, self.dt)
        m.hyperviscosity(self.new, 2 * self.dt)
        self._ra.launch()
        self._copy_new.launch()
        return StepStats(1, device_counts(self))
