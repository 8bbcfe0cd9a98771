"""The compiled matrix-free CG of the Helmholtz solve, (M + cK) y = b on unique nodes
(``HelmholtzCG``): Chronopoulos–Gear, one reduction an iteration, mass preconditioner, in
float64 or float32, vectors in Warp arrays, the operator in three element launches split over
the CPU threads (per node on CUDA); the same code on CPU, CUDA and any number of MPI ranks,
the whole solve on the device with no host read (its scalar recurrences, convergence test and
loop, ``wp.capture_while``). The operator's bits depend on neither threads nor ranks (its DSS
is a gather in the global order), so a run on N ranks differs from one on one rank only by the
order of the inner products' sums."""

from __future__ import annotations

import warp as wp

from ..kernels import helmholtz as hk
from ..kernels import helmholtz_cg as cgk
from ..kernels import operators
from .precision import rounded

f64 = wp.float64


# the float32 CG's reach: a tolerance at or above SINGLE_TOL is solved in float32 alone;
# below it, refinement passes each reduce the float64 residual by SINGLE_FLOOR at most
# (float32's unit round-off 6e-8 times the growth of CG's recurrences)
SINGLE_TOL = 1e-3
SINGLE_FLOOR = 1e-4


class HelmholtzCG:
    """(M + cK) y = b on unique nodes (``nunique``,) by Chronopoulos–Gear CG (1989, J.
    Comput. Appl. Math. 25, 153) preconditioned by M⁻¹, matrix-free, in ``dtype``
    (float64, or float32 for the inner solves of ``HelmholtzSolver``'s "float32"
    precision); inner products summed in float64 in a fixed order on any device,
    threads and ranks. ``b``, ``y``: the right-hand side and solution vectors
    (float64 ones may be given, shared with the caller); ``stats``: the float64
    device counters (``kernels.helmholtz_cg.ITERATIONS``, ``FAILURES``, ``RESIDUAL``)
    the solve adds to, shared with the caller's other solves (its own if None).

    The whole solve runs on the device: the inner products' partial sums are added
    there (``Topology.device_sums``), the recurrences' scalars α, β, γ, δ, ‖r‖² and
    the convergence test are computed by one-thread kernels (``cg_check`` after an
    update, ``cg_alpha`` after a product) into device arrays the vector update reads,
    and on one rank the test between the two spares the converged iteration's product
    (k iterations cost k products, k + 1 from a warm start; over ranks k + 1 and one
    reduction an iteration, as Chronopoulos–Gear's order). The loop is
    ``wp.capture_while`` on a device flag: a host loop on the CPU (it reads the flag
    in place, no copy), a conditional node inside a CUDA graph (``HelmholtzSolver``
    captures the solve) — the same kernels, so the same bits on CPU threads and to
    round-off on CUDA. Over several MPI ranks the per-rank sums go through the host
    between the two (``Topology.allreduce``: one read an iteration); on one rank no
    value comes back to the host during a solve.

    ``apply(y, out, c)``: out = (M + cK) y. ``one_reduction``: Chronopoulos–Gear's order,
    one reduction an iteration and the converged iteration's product (True over ranks, else
    False; either gives the same iterations and bits). ``solve(c, tol, maxiter, warm)``: y to the
    relative residual tol from y (``warm``) or from zero; adds its iterations to
    ``stats`` and, past ``maxiter``, a failure (nothing is read back: the caller reads
    ``stats``, ``HelmholtzSolver.iterations``). ``residual(c)``: r = b − Ay and r·r into
    ``sums[2]``, b·b into ``sums[1]`` (refinement's)."""

    def __init__(self, model, dtype=f64, b=None, y=None, stats=None):
        topo, dev, N, nu = model.topology, model.topology.device, model.topology.N, model.topology.nunique
        self.model, self.dtype = model, dtype
        z = lambda *shape: wp.zeros(shape, dtype=dtype, device=dev)  # noqa: E731
        self.b = z(nu) if b is None else b
        self.y = z(nu) if y is None else y
        self.wg, self.z = z(2, N), z(1, N)
        self.r, self.u, self.w, self.p, self.s = (z(nu) for _ in range(5))
        # the metric in the solve's type (``precision.rounded``): the model's own arrays in float64,
        # float32 copies rounded once else; the local copies' masses (the ghosts' follow on a rank)
        self.Dinv, self.metdet = model.operators.rounded("Dinv", dtype), model.operators.rounded("metdet", dtype)
        self.spheremp, self.rspheremp = rounded(topo.spheremp[: topo.N], dtype), rounded(topo.rspheremp, dtype)
        self.dvv = (
            model.operators.dvv_rows if dtype is f64 else operators.dvv_matrix(model.topology.grid.rule.dvv, dtype)
        )
        self.minv = wp.array(1.0 / topo.area, dtype=dtype, device=dev)
        self.area, self.ones = wp.array(topo.area, dtype=dtype, device=dev), wp.ones(nu, dtype=dtype, device=dev)
        self.chunk = chunk = topo.backend.reduction_chunk(nu)
        self.partial = wp.zeros((3, (nu + chunk - 1) // chunk), dtype=f64, device=dev)
        # the device scalars: the inner products' totals, the recurrences' (cgk.GAMMA …), the flag and counts (cgk.GO …)
        self.sums = wp.zeros(3, dtype=f64, device=dev)
        self.cs = wp.zeros(8, dtype=f64, device=dev)
        self.ic = wp.zeros(3, dtype=wp.int32, device=dev)
        # the loop's flag alone, a view of ic[GO]: uncaptured on CUDA, ``wp.capture_while`` copies its
        # whole condition array into a one-int host buffer (Warp 1.19), which refuses all of ic
        self.go = self.ic[cgk.GO : cgk.GO + 1]
        self.stats = wp.zeros(3, dtype=f64, device=dev) if stats is None else stats
        self._totals = topo.device_sums(self.partial, 3, self.sums)
        self._ops: dict[tuple, list] = {}
        self._div: dict[tuple, list] = {}  # each operator's divergence launch and the c it has
        self._inner = {}
        rec, nchunks = model.launches.record, self.partial.shape[1]
        update = [self.p, self.s, self.y, self.r, self.u, self.w, self.minv, self.partial, chunk]
        self._update = rec(cgk.cg_update(dtype), nchunks, [self.cs, 0, *update], nodes_per_index=chunk)
        self._restart = rec(cgk.cg_update(dtype), nchunks, [self.cs, 1, *update], nodes_per_index=chunk)
        self._first, self._check = (
            wp.launch(
                cgk.cg_check,
                1,
                [self.sums, first, f64(0.0), 0, self.cs, self.ic, self.stats],
                device=dev,
                record_cmd=True,
            )
            for first in (1, 0)
        )
        self._alpha = wp.launch(cgk.cg_alpha, 1, [self.sums, self.cs, self.ic], device=dev, record_cmd=True)
        # over ranks an iteration keeps Chronopoulos–Gear's one reduction (an allreduce costs more there
        # than the converged iteration's product, a 1/P share); on one rank the sums stay on the device
        self.one_reduction = topo.distributed

    @property
    def parts(self) -> int:
        """The CPU threads each of the CG's vector passes runs on (``core.parallel.SplitLaunch``'s
        ranges; 1: one launch, as on CUDA or for a grid too small to split)."""
        return len(getattr(self._update, "parts", (self._update,)))

    def _operator(self, y, out) -> list:
        """Launches for out = (M + cK) y (unique-node vectors; c set by ``apply``), recorded once per pair."""
        key = (y.ptr, out.ptr)
        launches = self._ops.get(key)
        if launches is None:
            m, topo, dt = self.model, self.model.topology, self.dtype
            halo = topo.owned.recv_buffer
            y2 = y.reshape((1, topo.nunique))
            div = self.model.launches.record(
                hk.helmholtz_divergence(m.topology.grid.np, topo.table.shape[1], dt),
                m.topology.grid.nelem,
                [
                    self.wg,
                    topo.ghost,
                    topo.N,
                    topo.table,
                    self.rspheremp,
                    y,
                    halo,
                    topo.gid,
                    self.model.operators.as_rows(self.Dinv),
                    self.model.operators.as_rows(self.metdet),
                    self.model.operators.as_rows(self.spheremp),
                    self.dvv,
                    dt(0.0),
                    self.model.operators.as_rows(self.z),
                ],
                nodes_per_index=m.topology.grid.np**2,
            )
            grad = self.model.launches.record(
                hk.helmholtz_gradient(m.topology.grid.np, dt),
                m.topology.grid.nelem,
                [
                    y,
                    halo,
                    topo.gid,
                    self.model.operators.as_rows(self.Dinv),
                    self.model.operators.as_rows(self.spheremp),
                    self.dvv,
                    self.model.operators.as_rows(self.wg),
                ],
                nodes_per_index=m.topology.grid.np**2,
            )
            assemble = self.model.launches.record(
                hk.helmholtz_assemble(topo.table.shape[1], dt),
                self.partial.shape[1],
                [self.z, topo.ghost, topo.N, topo.table, topo.first, y, out, self.partial, self.chunk],
                nodes_per_index=self.chunk,
            )
            launches = self._ops[key] = [
                *topo.exchange(y2, unique=True),
                grad,
                *topo.exchange(self.wg),
                div,
                *topo.exchange(self.z),
                assemble,
            ]
            self._div[key] = [div, None]
        return launches

    def _per_node(self, y, out) -> list:
        """The last launch of out = (M + cK) y in the per-node layout (CUDA's), recorded once
        per pair; ``apply`` runs the model's operators before it."""
        key = (y.ptr, out.ptr)
        launches = self._ops.get(key)
        if launches is None:
            topo = self.model.topology
            combine = self.model.launches.record(
                hk.helmholtz_combine,
                self.partial.shape[1],
                [self.z, topo.first, y, self.area, f64(0.0), out, self.partial, self.chunk],
                nodes_per_index=self.chunk,
            )
            launches = self._ops[key] = [combine]
            self._div[key] = [combine, None]
        return launches

    def apply(self, y, out, c: float) -> None:
        """out = (M + cK) y on unique nodes; partial[1] = out·y. Per element (the CPU's
        layout, and float32 on any device): the three fused element kernels. Per node
        (CUDA's, float64): the model's per-node gradient and divergence with their DSS,
        then ``helmholtz_combine`` — the element kernels run a thread per element, whose
        strided reads are slow on a GPU (the benchmarks notebook (git show 5fa9286:benchmarks/README.md), "Measurements behind the code")."""
        m = self.model
        if m.operators.per_element or self.dtype is not f64:
            launches = self._operator(y, out)
        else:
            launches = self._per_node(y, out)
            m.operators.scatter(y, self.z, 0)
            m.operators.gradient(self.z, 0, self.wg)
            m.operators.divergence(self.wg, self.z)
        div = self._div[(y.ptr, out.ptr)]
        if div[1] != c:
            div[0].set_param_by_name("c", self.dtype(c))
            div[1] = c
        for launch in launches:
            launch.launch()

    def dots(self, a0, b0, a1, b1, a2, b2) -> None:
        """sums = (a0·b0, a1·b1, a2·b2) over all ranks, on the device (``totals``)."""
        key = tuple(a.ptr for a in (a0, b0, a1, b1, a2, b2))
        launch = self._inner.get(key)
        if launch is None:
            launch = self._inner[key] = self.model.launches.record(
                cgk.inner3(self.dtype),
                self.partial.shape[1],
                [a0, b0, a1, b1, a2, b2, self.partial, self.chunk],
                nodes_per_index=self.chunk,
            )
        launch.launch()
        self.totals()

    def totals(self) -> None:
        """sums = the totals of ``partial``'s three rows over all ranks: added on the device in
        index order, then over ranks (``Topology.allreduce``; a host read only on several ranks)."""
        for launch in self._totals:
            launch.launch()
        self.model.topology.allreduce(self.sums)

    def residual(self, c: float) -> None:
        """r = b − Ay, u = M⁻¹r; sums = (r·u, b·b, r·r) over all ranks: one product (refinement's)."""
        self.apply(self.y, self.w, c)
        self._residual_update()
        self.totals()

    def _residual_update(self) -> None:
        """From w = Ay: r = b − w, u = M⁻¹ r, partial sums r·u, b·b and r·r (an update from r = b, u = 0)."""
        wp.copy(self.r, self.b)
        self.u.zero_()
        self._restart.launch()

    def solve(self, c: float, tol: float, maxiter: int, warm: bool, guessed: bool = False) -> None:
        """y = (M + cK)⁻¹ b to the relative residual ``tol``, from y (``warm``: one product
        more), from y with w = A y already set (``guessed``: a projected start,
        ``GuessHistory``) or from zero; tol ≤ 0 and maxiter ≤ 0: those ``refine_check``
        left on the device. k iterations cost k products on one rank (the test between an
        update and the next product), k + 1 over ranks (one reduction an iteration)."""
        if guessed:
            pass
        elif warm:
            self.apply(self.y, self.w, c)
        else:
            self.y.zero_()
            self.w.zero_()
        self._residual_update()  # r = b − Ay, u = M⁻¹r; r·u, b·b, r·r
        self.totals()
        self._first.set_param_by_name("tol2", f64(tol * tol if tol > 0 else 0.0))
        self._first.set_param_by_name("maxiter", int(maxiter))
        self._first.launch()  # the bound; go?
        if self.one_reduction:  # the first product and α ahead of the loop
            self._product(c)
        wp.capture_while(self.go, self._iteration, c=c)

    def _product(self, c: float) -> None:
        """w = Au, δ = w·u over all ranks, α."""
        self.apply(self.u, self.w, c)
        self.totals()
        self._alpha.launch()

    def _iteration(self, c: float) -> None:
        """One CG iteration: the product, α, the update with the device's α and β, the test
        (over ranks: the update, the product, then the test and α on one reduction)."""
        if not self.one_reduction:
            self._product(c)
        self._update.launch()  # p, s, y, r, u; r·u, r·r
        if self.one_reduction:
            self.apply(self.u, self.w, c)  # and w·u, summed with them
        self.totals()
        self._check.launch()  # β; go?
        if self.one_reduction:
            self._alpha.launch()
