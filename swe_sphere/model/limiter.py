"""The tracers' shape-preserving limiter of a ``ShallowWater`` model (a scene's ``tracers.limiter``):
Guba, Taylor & St-Cyr (2014)'s optimisation-based limiter as HOMME applies it
(``limiter_optim_iter_full``, ``limiter_option = 8``): on each explicit stage's element-local
values before their DSS (HOMME's ``euler_step``), the tracers' ∇⁴ substeps and stages included
(the kernels: ``kernels.limiter``)."""

from __future__ import annotations

import warp as wp

from ..kernels import limiter

f64 = wp.float64

LIMITERS = ("none", "optimization")  # a scene's tracers.limiter


class TracerLimiter:
    """The limiter of ``model``'s tracers (``model.tracers`` > 0): ``bound`` takes each element's
    bounds from a state (its q's and its neighbours' extremes: the start of a step), ``stage``
    limits a stage's element-local tracer values into them before their DSS, keeping each
    element's tracer mass (``ShallowWater.rhs_update``'s ``limit``: the DSS of the limited values
    is a convex combination of them at each node, no new extremum, the integral kept); the
    tracers' ∇⁴ limits its own (``model.hyperviscosity.Hyperviscosity.build_tracers``), so a
    step's end holds nothing more to limit (a pass over it there changed the transport test's
    extremes by round-off alone: ne4 np4, 1.5 days). Element-local, the neighbours' bounds exchanged as a min and a max: the same bits on any
    ranks. Mass is kept to round-off and the bounds met exactly: the passes go on until one clips
    nothing, at most np² + 1 (``kernels.limiter.limited``; HOMME's np² − 1 stop at a tolerance).

    The bounds can be met only where an element's mean lies within them, which a stage that is a
    forward-Euler step of the element-local update ensures while no node's outflow over the step
    exceeds its own mass (a corner's, whose GLL weight is the least, first). SSPRK(4,3)'s stages
    are Euler steps of Δt/2, as HOMME's tracer stages are (``euler_step`` with dt/2), and keep
    the transport test within its initial range to round-off at the study's Δt; SSP-RK3's are of
    Δt, and there an element's mean may leave its bounds (the limiter then keeps the mass: 4e-9
    of the range on ne4 np4 at 1800 s, round-off at 900 s; tests/model/test_tracers.py)."""

    def __init__(self, model):
        self.model = m = model
        self.npp = npp = m.grid.np**2
        nelem, K, N, device = m.N // npp, m.tracers, m.N, m.device
        self.own = wp.zeros((2 * K, N), dtype=f64, device=device)  # each element's own: 2k least, 2k + 1 most
        self.near = wp.zeros((2 * K, nelem), dtype=f64, device=device)  # over the neighbours too: 2k least, 2k + 1 most
        self.work = wp.zeros((K, N), dtype=f64, device=device)

    def bound(self, x: wp.array2d) -> None:
        """Each element's bounds of each tracer's q from state x (rows, N): the least and greatest
        over it and the elements that share a node with it, on this rank or another."""
        m = self.model
        topo = m.topology
        columns, ghosts = topo.table.shape[1], bool(len(topo.neighbours))

        def build():
            rows = m.operators.as_rows
            kernel = limiter.neighbour_bounds(m.tracers, columns, ghosts)
            return [
                m.launches.elements(limiter.element_bounds(m.grid.np), [rows(x), rows(self.own)]),
                *topo.exchange(self.own),
                m.launches.elements(kernel, [self.own, topo.dss_copies, self.npp, self.near]),
            ]

        m.launches.replay(("limiter_bounds", x.ptr), (x,), build)

    def _limits(self) -> list:
        """The limiting kernels' common arguments after the sources: mass, spheremp (as rows), the
        bounds, the passes (np² + 1: enough to reach one that clips nothing), the output (as rows)."""
        rows = self.model.operators.as_rows
        m = self.model
        return [
            rows(m.tendency_arrays.mass),
            rows(m.spheremp[: m.N]),
            self.near,
            self.npp + 1,
            rows(self.work),
        ]

    def stage(self, update, tend, weighted: bool, first: int = 0, rkl: bool = False, assemble: bool = True) -> list:
        """Launches of ``update``'s tracer rows (an ``Update`` out = Σ a·src + a_F·F of at most two
        arrays and F once, F from the element-local ``tend``, spheremp·F where ``weighted``, its
        rows the state's from ``first``: 0, the tendency; 2, the ∇⁴'s of h and the tracers): its
        element-local values limited (``kernels.limiter.limit_stage``) and assembled by the
        mass-weighted DSS into out[3:], of the values less s₀ (the first source, an assembled state),
        which the DSS update adds back: a mass-weighted DSS of whole values biases the mass by
        rspheremp's rounding, the same at every DSS (−0.035 ε a DSS at ne4 np4), of an increment by
        that of the increment alone. The caller runs the first launch before any other writes
        the update's arrays' rows it reads, and the others after it. ``rkl``: the terms (1, s₀),
        (ν, s₁), (coef, F) formed as an RKL1 stage (``kernels.dss.rkl_stage``'s arithmetic).
        ``assemble`` False (``first`` 0): the limiting launch alone, writing over tend's tracer
        rows the terms of their weighted DSS (spheremp·h·q̃ where ``weighted``, whose DSS is
        then unweighted, else h·q̃), for the caller's DSS pass of the stage's rows to assemble
        (``Topology.dss_update``'s ``assembled``: the same bits, the tracers' indices read with
        the dynamics'; TC5 ne16 one tracer, one thread: a 1-row pass of 0.07 ms a stage saved)."""
        m = self.model
        arrays = [(a, src) for a, src in update.terms if src is not None]
        a = [a for a, _ in arrays] + [0.0] * (2 - len(arrays))
        srcs = [src for _, src in arrays] + [update.out] * (2 - len(arrays))
        flux = [a for a, src in update.terms if src is None]
        kernel = limiter.limit_stage(
            weighted, first, m.grid.np, rkl, weigh=weighted and not assemble, relative=bool(arrays)
        )
        rows = m.operators.as_rows
        args = [wp.vec3d(*a, *flux), *map(rows, (*srcs, tend)), *self._limits()]
        if not assemble:
            args[-1] = rows(tend[3 - first :])
            return [m.launches.elements(kernel, args)]
        assembled = [(1.0, srcs[0][3:])] if arrays else []
        return [
            m.launches.elements(kernel, args),
            *m.topology.dss_update(self.work, [(update.out[3:], [*assembled, (1.0, None)])]),
        ]
