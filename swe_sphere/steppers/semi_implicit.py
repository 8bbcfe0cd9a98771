"""Semi-implicit leapfrog (HOMME ``advance_si_nonstag``; Robert, Henderson & Turnbull 1972).

The linear gravity-wave terms about a mean depth H — the pressure gradient
−g∇h and −H∇·v — are averaged over levels n−1 and n+1; everything else
(N = F − L) is leapfrogged at level n. Eliminating v(n+1) leaves a Helmholtz
equation for the height (``helmholtz.Helmholtz``: CG on the DSS'd operators
of the explicit RHS, so the elimination is exact and mass is kept to round-off):

    (I − Δt² gH DG) h(n+1) = R,    v(n+1) = v(n−1) + 2Δt N_v − Δt g G(h(n+1) + h(n−1)).

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

from ..kernels import semi_implicit as si
from .base import StepStats
from .explicit import Leapfrog, LeapfrogOptions
from .helmholtz import Helmholtz

f64 = wp.float64


@dataclass(frozen=True)
class SemiImplicitOptions(LeapfrogOptions):
    """Scene table ``[semi_implicit]`` (see ``SemiImplicit``)."""

    tol: float = 1e-10
    maxiter: int = 500
    mean_depth: float = 0.0
    linear_solver: str = ""

    def __post_init__(self):
        super().__post_init__()
        if self.linear_solver not in ("", "scipy", "warp"):
            raise ValueError(f"linear_solver must be 'scipy' or 'warp' (got {self.linear_solver!r})")
        if not 0 < self.tol < 1:
            raise ValueError(f"tol must be in (0, 1) (got {self.tol})")
        if self.maxiter < 1:
            raise ValueError(f"maxiter must be >= 1 (got {self.maxiter})")
        if self.mean_depth < 0:
            raise ValueError(f"mean_depth must be >= 0 (got {self.mean_depth})")


class SemiImplicit(Leapfrog):
    """Semi-implicit leapfrog: 1 RHS evaluation and one CG solve per step.

    Options (scene table ``[semi_implicit]``): ``robert_asselin`` (0.05),
    ``tol`` (CG relative residual, 1e-10), ``maxiter`` (500), ``mean_depth``
    (H in m; 0 = the initial state's mean depth), ``linear_solver`` ("scipy" on
    CPU, "warp" on CUDA by default). Reports CG iterations per step.
    Raises ValueError without the continuity and pressure-gradient terms.
    """

    name = "semi_implicit"
    Options = SemiImplicitOptions
    explicit = False
    courant_limit = None
    solvers = ("cg",)

    def __init__(self, model, dt, options=None):
        super().__init__(model, dt, options)
        for term in ("continuity", "pressure_gradient"):
            if term not in model.terms:
                raise ValueError(f"semi_implicit needs the {term} term")
        o = self.options
        self.H = o.mean_depth
        dev, N = model.device, self.N

        def z(rows):
            return wp.zeros((rows, N), dtype=f64, device=dev)

        self.F, self.W = z(3), z(3)
        self.Gh, self.Gh_old, self.Gh_new = z(2), z(2), z(2)
        self.Dv, self.Dw, self.DGh = z(1), z(1), z(1)
        self.R = z(1)
        self.Dv1, self.Dw1, self.DGh1 = self.Dv.flatten(), self.Dw.flatten(), self.DGh.flatten()
        self.helmholtz = Helmholtz(model, o.tol, o.maxiter, o.linear_solver or None)

    def _si(self, old, cur, new, dt):
        """new = semi-implicit leapfrog from old over 2dt, explicit terms at cur. Returns CG iterations."""
        m, dev, N, g = self.model, self.model.device, self.N, self.model.g
        if self.H == 0.0:
            self.H = m.topology.mean(cur.numpy()[2])  # mean depth
        c = dt * dt * g * self.H
        m.rhs(cur, self.F)
        m.gradient(cur, 2, self.Gh)
        m.divergence(cur, self.Dv)
        wp.launch(si.half_wind, N, [old, self.F, f64(g), self.Gh, f64(dt), self.W], device=dev)
        m.divergence(self.W, self.Dw)
        m.gradient(old, 2, self.Gh_old)
        m.divergence(self.Gh_old, self.DGh)
        wp.launch(si.height_rhs, N, [old, self.F, f64(self.H), self.Dv1, self.Dw1, f64(c), self.DGh1, f64(dt), self.R], device=dev)
        iterations = self.helmholtz.solve(self.R, 0, c, new, 2)
        m.gradient(new, 2, self.Gh_new)
        wp.launch(si.new_wind, N, [old, self.F, f64(g), self.Gh, self.Gh_new, self.Gh_old, f64(dt), new], device=dev)
        return iterations

    def state(self):
        return {**super().state(), "mean_depth": self.H}  # H = 0 until fixed by the first step

    def restore(self, state):
        super().restore(state)
        self.H = float(self._entry(state, "mean_depth"))

    def advance(self, x):
        m = self.model
        if self._x is not x:
            self._record(x)
        if self.steps == 0:
            self._start_keep.launch()  # x(−1) = x(0)
            it = self._si(self.old, x, self.new, self.dt / 2)
            self._copy_new.launch()
            m.hyperviscosity(x, self.dt)
            return StepStats(1, {"cg": it})
        it = self._si(self.old, x, self.new, self.dt)
        m.hyperviscosity(self.new, 2 * self.dt)
        self._ra.launch()
        self._copy_new.launch()
        return StepStats(1, {"cg": it})
