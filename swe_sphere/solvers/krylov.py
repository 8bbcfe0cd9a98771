"""Flexible GMRES (Saad 1993, SIAM J. Sci. Comput. 14, 461) on Warp arrays, for
the JFNK stepper (the Helmholtz CG is ``kernels.helmholtz_cg``'s), and the Krylov
basis it is built on (``KrylovBasis``), which the exponential steppers' KIOPS
(``kiops.Kiops``) shares.

The vectors are Warp arrays on the model's device, each this process's part of
a unique-node vector; the basis is two 2-D arrays allocated once. The vector
work: classical Gram–Schmidt done twice (as accurate as modified Gram–Schmidt,
Giraud et al. 2005, Numer. Math. 101, 87), each projection fused with the inner
products of the next pass, which are summed over processes by
``Topology.sums``; on CUDA in ``kernels.krylov``'s kernels, on a CPU in
numpy/BLAS on views of the same arrays (``HostVectors``: Warp's CPU kernels are
7–15× slower at such passes). So the solver is the same on CPU threads, CUDA and
MPI ranks. FGMRES keeps its Arnoldi coefficients on the device (``kernels.krylov``'s
one-thread kernels) and reads one set of scalars back a restart cycle; KIOPS reads
its inner products back (``project_dots``). The new
vector's norm is ‖w₁‖² − ‖h₂‖² (w₁ after the first pass, h₂ the second pass's
coefficients: Pythagoras, exact for an orthonormal basis), not a third pass.

Right-preconditioned, so the residual it minimises is the true one, and the
preconditioner may change from one iteration to the next (an inexact inner
solve). Why not ``pyamg.krylov.fgmres`` or ``warp.optim.linear.gmres``: the
first works on host vectors and ends every restart cycle with an explicit
residual b − A x (one more Jacobian-vector product, i.e. RHS evaluation, per
Newton iteration, ~20 % of JFNK's RHS evaluations at 4–10× the gravity-wave
limit); the second is not flexible, so a preconditioner that is itself an inexact
solve costs it many times FGMRES's iterations (the benchmarks notebook (git show 5fa9286:benchmarks/README.md), "Measurements
behind the code").
Here the residual after a cycle comes from the least-squares problem.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from ..core.graphs import captured
from ..core.parallel import record
from ..kernels import krylov as kk

f64 = wp.float64


class NumpyViews:
    """numpy views of CPU Warp arrays: ``views(a)``, zero-copy, cached per address, shape
    and strides (making one costs as much as a numpy pass over an ne16 vector; a cached
    view keeps its array alive, so the address stays its own)."""

    def __init__(self):
        self._views: dict[tuple, np.ndarray] = {}

    def __call__(self, a) -> np.ndarray:
        key = (a.ptr, a.shape, a.strides)
        view = self._views.get(key)
        if view is None:
            view = self._views[key] = a.numpy()
        return view


class KernelVectors:
    """A ``KrylovBasis``'s vector work in ``kernels.krylov``'s Warp kernels (the
    backend on CUDA): each operation one launch, recorded once per set of arrays;
    inner products as per-chunk partial sums (``Backend.reduction_chunk``) added
    on the device in index order (``Topology.device_sums``), over ranks through the
    host (``Topology.allreduce``; nothing comes back on one rank)."""

    def __init__(self, basis: KrylovBasis):
        n, rows, topo = basis.n, basis.V.shape[0], basis.topology
        self.n, self.topology = n, topo
        self.chunk = chunk = topo.backend.reduction_chunk(n)
        self.partial = wp.zeros((rows + 1, (n + chunk - 1) // chunk), dtype=f64, device=topo.device)
        self._launches: dict[tuple, object] = {}
        self._totals: dict[tuple, tuple] = {}
        self._host: dict[int, np.ndarray] = {}

    def _launch(self, kernel, dim, inputs, nodes_per_index=1, **params):
        """Launch ``kernel`` on ``inputs``, recorded once per set of arrays (their
        addresses), with the scalar ``params`` set by name for this call."""
        key = (kernel.key, *(a.ptr for a in inputs if isinstance(a, wp.array)))
        launch = self._launches.get(key)
        if launch is None:
            topo = self.topology
            launch = self._launches[key] = record(
                kernel, dim, inputs, device=topo.backend, threads=topo.threads, nodes_per_index=nodes_per_index
            )
        for name, value in params.items():
            launch.set_param_by_name(name, value)
        launch.launch()

    def dots(self, B, w, k_sub, h, k_dot, out):
        self._launch(
            kk.project_dots,
            self.partial.shape[1],
            [B, 0, h, w, 0, self.partial, self.chunk],
            nodes_per_index=self.chunk,
            k_sub=k_sub,
            k_dot=k_dot,
        )
        rows = k_dot + 1  # the rows it wrote
        key = (out.ptr, rows)
        totals = self._totals.get(key)
        if totals is None:
            head = out[:rows]
            totals = self._totals[key] = (self.topology.device_sums(self.partial, rows, head), head)
        for launch in totals[0]:
            launch.launch()
        self.topology.allreduce(totals[1])

    def combine(self, B, c, k, x, out):
        self._launch(kk.lincomb, self.n, [B, 0, c, x, out], k=k)

    def put(self, a, values) -> None:
        host = self._host.get(a.ptr)
        if host is None:
            host = self._host[a.ptr] = np.zeros(a.shape[0])
        host[: len(values)] = values
        a.assign(host)  # a copy to the device, not a read

    def get(self, a, k: int) -> np.ndarray:
        return a.numpy()[:k]


class HostVectors:
    """A ``KrylovBasis``'s vector work in numpy and BLAS on zero-copy views of the
    Warp arrays (the backend on a CPU device). Warp's CPU kernels run a pass over
    a vector at ~5 ns an entry, where BLAS runs one at ~0.2–0.7 ns: with the kernels,
    the Gram–Schmidt and combination passes cost more than the J·v of a Krylov
    vector at ne16 (``benchmarks/studies/implicit_cost.py --krylov``). The passes are
    single-threaded: the vectors are short (in cache at ne30) and a BLAS thread
    pool spinning beside the model's threads made a norm cost 10 ms (``Simulation``
    runs with one BLAS thread, as ``Topology.dot``'s inner products assume). An
    inner product is BLAS's dot over this process's entries, then summed over
    processes in rank order by ``Topology.sums``: the bits do not depend on the
    model's threads (SWE_SPHERE_THREADS), which never touch these passes. The
    coefficient arrays are read and written in place (CPU memory: no copy)."""

    def __init__(self, basis: KrylovBasis):
        self.topology = basis.topology
        self.tmp = np.zeros(basis.n)
        self._np = NumpyViews()

    def dots(self, B, w, k_sub, h, k_dot, out):
        B, w = self._np(B), self._np(w)
        if k_sub:
            np.dot(self._np(h)[:k_sub], B[:k_sub], out=self.tmp)  # BLAS gemv: one pass over B's rows
            np.subtract(w, self.tmp, out=w)
        d = np.empty(k_dot + 1)
        if k_dot:
            np.dot(B[:k_dot], w, out=d[:k_dot])
        d[k_dot] = w @ w
        self._np(out)[: k_dot + 1] = self.topology.sums(d)

    def combine(self, B, c, k, x, out):
        x, out, c = self._np(x), self._np(out), self._np(c)
        a = c[k]
        if k:
            np.dot(c[:k], self._np(B)[:k], out=self.tmp)
        if a != 1.0 or out is not x:  # a·x first: out may alias x (an update in place skips the pass)
            np.multiply(x, a, out=out)
        if k:
            np.add(out, self.tmp, out=out)

    def put(self, a, values) -> None:
        self._np(a)[: len(values)] = values

    def get(self, a, k: int) -> np.ndarray:
        return self._np(a)[:k].copy()


class KrylovBasis:
    """A Krylov basis of ``rows`` vectors of length ``n`` (this process's part of a
    unique-node vector) on ``topology``'s device, the rows of ``V``, with the vector
    work Gram–Schmidt and the combinations need on any 2-D array of such vectors (a
    row range of ``V``, FGMRES's preconditioned vectors), its inner products summed
    over the topology's processes. Shared by ``FGMRES`` and ``kiops.Kiops``.

    ``vectors``: the implementation of that work, chosen by the topology's backend
    (``Backend.choose``): ``HostVectors`` (numpy/BLAS on views of the arrays) on a CPU
    device, ``KernelVectors`` (``kernels.krylov``) elsewhere; either may be given (the tests check the two
    agree to round-off). A backend's operations take their coefficients from and
    put their inner products into device arrays (float64, (rows + 1,) at most):
    ``dots(B, w, k_sub, h, k_dot, out)``: w −= Σ_{i<k_sub} h[i] B_i, out[:k_dot + 1] =
    (B_i·w for i < k_dot, w·w) over all processes; ``combine(B, c, k, x, out)``: out =
    c[k]·x + Σ_{i<k} c[i] B_i; ``put(a, values)``, ``get(a, k)``: host values into a
    device array and its first k back (a host read on a GPU). ``project_dots`` and
    ``lincomb`` are the same with host coefficients (KIOPS's)."""

    def __init__(self, n: int, rows: int, topology, vectors=None):
        n, rows = int(n), int(rows)
        self.n, self.topology = n, topology
        dev = topology.device
        self.V = wp.zeros((rows, n), dtype=f64, device=dev)
        self.rows_V = [self.V[j] for j in range(rows)]  # row views: their addresses key the recorded launches
        self.w = wp.zeros(n, dtype=f64, device=dev)
        self.coef = wp.zeros(rows + 1, dtype=f64, device=dev)  # host coefficients, on the device
        self.sums = wp.zeros(rows + 1, dtype=f64, device=dev)  # inner products
        self.vectors = (vectors or topology.backend.choose(HostVectors, KernelVectors))(self)

    def project_dots(self, B, w, k_sub: int, h: np.ndarray | None, k_dot: int) -> np.ndarray:
        """w −= Σ_{i<k_sub} h_i B_i; returns (B_i·w for i < k_dot, w·w) over all processes
        (B a 2-D array of vectors, w a vector; one host read on a GPU)."""
        if k_sub:
            self.vectors.put(self.coef, h[:k_sub])
        self.vectors.dots(B, w, k_sub, self.coef, k_dot, self.sums)
        return self.vectors.get(self.sums, k_dot + 1)

    def lincomb(self, B, c: np.ndarray, a: float, x, out) -> None:
        """out = a·x + Σ c_i B_i (out may alias x; not B's rows i < len(c))."""
        k = len(c)
        self.vectors.put(self.coef, np.append(c, a))
        self.vectors.combine(B, self.coef, k, x, out)


class FGMRES(KrylovBasis):
    """Solver for A x = b from x = 0 with ``restart``-long cycles, for vectors of
    length ``n`` (this process's part) on ``topology``'s device, inner products
    summed over its processes.

    ``solve(matvec, precond, b, x, rtol, maxiter, graph_key=None, guard=None)`` → (iterations,
    converged): ``matvec(v, out)`` and ``precond(v, out)`` write A v and P⁻¹ v into
    ``out`` (Warp arrays of length n); x (a Warp array, overwritten) gets the
    solution; stops when ‖b − A x‖ ≤ rtol ‖b‖ (the Arnoldi estimate) or after
    ``maxiter`` products with A. With a ``graph_key``, a cycle's Arnoldi steps are
    captured once per key as a graph (a CUDA graph with conditional nodes; Warp's
    CPU graph on a CPU) and replayed: the caller vouches that matvec and precond
    read nothing back, that their launches with the parameters they bake in are the
    same for every solve under that key, that the backends are Warp kernels and the
    launches on one thread of one rank; their Python side effects happen only while
    capturing (count products by the iterations returned). ``guard`` (a
    ``graphs.GraphGuard``): a capture or replay that raises turns it off with one
    line and the cycle runs inline (without, it raises).

    One algorithm on every backend and device: the vector passes are the basis's
    backend's, the small dense work (the Hessenberg column, Givens rotations, the
    residual estimate, the triangular solve) ``kernels.krylov``'s one-thread
    kernels on device arrays, so no coefficient comes back to the host inside a
    cycle. A cycle's Arnoldi steps run under ``wp.capture_if`` on a device flag
    that the last step clears (converged, products spent, breakdown): on a CPU the
    host tests the flag in place (no copy), on CUDA a step is skipped by a 4-byte
    flag copy or, inside a captured graph, by a conditional node. Then one read a
    cycle (``info``: the residual estimate, products, steps) decides the update's
    length and whether to restart. Over several ranks the inner products go
    through the host (``Topology.allreduce``), twice a step.
    """

    def __init__(self, n: int, restart: int, topology, vectors=None):
        m = self.restart = int(restart)
        super().__init__(n, m + 1, topology, vectors)
        dev = topology.device
        self.Z = wp.zeros((m, self.n), dtype=f64, device=dev)
        self.rows_Z = [self.Z[j] for j in range(m)]
        self.r = wp.zeros(self.n, dtype=f64, device=dev)
        zeros = lambda *shape: wp.zeros(shape, dtype=f64, device=dev)  # noqa: E731
        self.H, self.cs, self.sn, self.g = zeros(m + 1, m), zeros(m), zeros(m), zeros(m + 1)
        self.h1, self.h2, self.cv, self.y, self.e = (zeros(m + 2) for _ in range(5))  # passes' sums, V_{j+1}'s, y, r's
        self.info = zeros(kk.INFO_SIZE)
        self.go = wp.zeros(1, dtype=wp.int32, device=dev)
        rec = lambda kernel, inputs: wp.launch(kernel, 1, inputs, device=dev, record_cmd=True)  # noqa: E731
        self._start = rec(kk.fgmres_start, [self.h1, f64(0.0), 0, self.info])
        self._cycle = rec(kk.fgmres_cycle, [self.info, self.g, self.coef, self.go])
        self._column = rec(
            kk.arnoldi_column, [0, self.h1, self.h2, self.H, self.cs, self.sn, self.g, self.cv, self.info, self.go]
        )
        self._end = rec(kk.fgmres_end, [self.H, self.cs, self.sn, self.g, self.info, self.y, self.e])
        self._graphs: dict = {}

    @property
    def graph_count(self) -> int:
        """The cycle graphs this solver holds: one per ``graph_key`` captured (0 without)."""
        return len(self._graphs)

    def _arnoldi(self, j: int, matvec, precond) -> None:
        """Arnoldi step j: Z_j = P⁻¹ V_j, w = A Z_j, classical Gram–Schmidt twice (as
        accurate as modified Gram–Schmidt, Giraud et al. 2005, Numer. Math. 101, 87),
        H's column, its rotation and the test on the device, V_{j+1}."""
        vec = self.vectors
        precond(self.rows_V[j], self.rows_Z[j])
        matvec(self.rows_Z[j], self.w)
        vec.dots(self.V, self.w, 0, self.coef, j + 1, self.h1)
        vec.dots(self.V, self.w, j + 1, self.h1, j + 1, self.h2)  # the second pass, with the first's coefficients
        self._column.set_param_by_name("j", j)
        self._column.launch()
        vec.combine(self.V, self.cv, j + 1, self.w, self.rows_V[j + 1])

    def _steps(self, matvec, precond) -> None:
        """A cycle's Arnoldi steps, each run while the device flag ``go`` is set."""
        for j in range(self.restart):
            wp.capture_if(self.go, self._arnoldi, j=j, matvec=matvec, precond=precond)

    def _replay_steps(self, key, matvec, precond, guard) -> None:
        """``_steps`` as the graph captured under ``key`` on its first use (``graphs.captured``:
        a failure turns ``guard`` off with one line and runs them inline)."""
        captured(
            self._graphs, key, lambda: self._steps(matvec, precond), self.topology.device, guard, "an FGMRES cycle"
        )

    def solve(self, matvec, precond, b, x, rtol: float, maxiter: int, graph_key=None, guard=None):
        vec = self.vectors
        x.zero_()
        vec.dots(self.V, b, 0, self.coef, 0, self.h1)  # b·b
        self._start.set_param_by_name("rtol", f64(rtol))
        self._start.set_param_by_name("maxiter", int(maxiter))
        self._start.launch()
        r = b
        while True:
            self._cycle.launch()  # g = β e₁, V₀ = r/β, go
            vec.combine(self.V, self.coef, 0, r, self.rows_V[0])
            if graph_key is None:
                self._steps(matvec, precond)
            else:
                self._replay_steps(graph_key, matvec, precond, guard)
            self._end.launch()  # y, and the residual's combination e
            residual, target, its, k, breakdown = vec.get(self.info, 5)  # the cycle's one read
            its, k = int(its), int(k)
            if k:
                vec.combine(self.Z, self.y, k, x, x)
            if residual <= target or its >= maxiter or breakdown or k == 0:
                return its, bool(residual <= target)
            vec.combine(self.V, self.e, k + 1, self.r, self.r)  # b − A x = V_{k+1} Qᵀ (0, …, 0, g_k)
            r = self.r
