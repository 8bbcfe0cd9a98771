"""The tracers' shape-preserving limiter of a ``ShallowWater`` model (a scene's ``tracers.limiter``):
Guba, Taylor & St-Cyr (2014)'s optimisation-based limiter as HOMME applies it
(``limiter_optim_iter_full``, ``limiter_option = 8``), on each element, then a DSS of the tracer
masses (the kernels: ``kernels.limiter``)."""

from __future__ import annotations

import warp as wp

from ..core.errors import ArgumentError
from ..kernels import limiter

f64 = wp.float64

LIMITERS = ("none", "optimization")  # a scene's tracers.limiter


class TracerLimiter:
    """The limiter of ``model``'s tracers (``model.tracers`` > 0): ``bound`` takes each element's
    bounds from a state (its q's and its neighbours' extremes: the start of a step), ``apply``
    limits a state's tracer masses into them, element by element keeping each element's tracer
    mass, and assembles them by the mass-weighted DSS (a convex combination of the elements'
    limited values: no new extremum; the integral kept). On one rank only (the neighbours' bounds
    are not exchanged): ``ArgumentError`` (a ValueError) on several. Mass is kept to round-off, the bounds met to
    ``tol`` of an element's mass after at most np² − 1 passes (HOMME's)."""

    tol = 1e-14

    def __init__(self, model):
        if model.topology.distributed:
            raise ArgumentError("tracers.limiter runs on one MPI rank (its neighbours' bounds are not exchanged)")
        self.model = m = model
        self.npp = npp = m.grid.np**2
        nelem, K = m.N // npp, m.tracers
        self.bounds = wp.zeros((2 * K, nelem), dtype=f64, device=m.device)
        self.near = wp.zeros((2 * K, nelem), dtype=f64, device=m.device)  # over the neighbours too
        self.work = wp.zeros((K, m.N), dtype=f64, device=m.device)

    def bound(self, x: wp.array2d) -> None:
        """Each element's bounds of each tracer's q from state x (rows, N): the least and greatest
        over it and the elements that share a node with it."""
        m = self.model

        def build():
            return [
                m.launches.elements(limiter.element_bounds, [x, self.npp, self.bounds]),
                m.launches.elements(limiter.neighbour_bounds, [self.bounds, m.topology.table, self.npp, self.near]),
            ]

        m.launches.replay(("limiter_bounds", x.ptr), (x,), build)

    def apply(self, x: wp.array2d) -> None:
        """Limit x's tracer masses (rows 3..) in place into the bounds ``bound`` took last."""
        m = self.model

        def build():
            args = [x, m.spheremp, self.near, self.npp, self.npp - 1, f64(self.tol), self.work]
            return [m.launches.elements(limiter.limit_element, args), *m.topology.dss(self.work, True, x[3:])]

        m.launches.replay(("limiter", x.ptr), (x,), build)
