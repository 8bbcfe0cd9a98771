"""Flexible GMRES (Saad 1993, SIAM J. Sci. Comput. 14, 461) on Warp arrays, for
the JFNK stepper (the Helmholtz CG is ``kernels.helmholtz``'s), and the Krylov
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
MPI ranks, and an Arnoldi step synchronises with the host twice (its two sets of
inner products) besides what the operator and the preconditioner need. The new
vector's norm is ‖w₁‖² − ‖h₂‖² (w₁ after the first pass, h₂ the second pass's
coefficients: Pythagoras, exact for an orthonormal basis), not a third pass.

Right-preconditioned, so the residual it minimises is the true one, and the
preconditioner may change from one iteration to the next (an inexact inner
solve). Why not ``pyamg.krylov.fgmres`` or ``warp.optim.linear.gmres``: the
first works on host vectors and ends every restart cycle with an explicit
residual b − A x (one more Jacobian-vector product, i.e. RHS evaluation, per
Newton iteration, ~20 % of JFNK's RHS evaluations at 4–10× the gravity-wave
limit); the second is not flexible (measured on an H100, TC5 ne30 at 4× Δt:
64 GMRES iterations a step against FGMRES's 4, and a state 1e-5 away).
Here the residual after a cycle comes from the least-squares problem.
"""

from __future__ import annotations

import numpy as np
import warp as wp
from scipy.linalg import solve_triangular

from ..kernels import krylov as kk
from ..parallel import record, reduction_chunk

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
    inner products as per-chunk partial sums (``parallel.reduction_chunk``) added
    by ``Topology.partial_sums``."""

    def __init__(self, basis: "KrylovBasis"):
        n, rows, topo = basis.n, basis.V.shape[0], basis.topology
        self.n, self.topology = n, topo
        self.coef, self._coef = wp.zeros(rows, dtype=f64, device=topo.device), np.zeros(rows)
        self.chunk = chunk = reduction_chunk(n, topo.device)
        self.partial = wp.zeros((rows + 1, (n + chunk - 1) // chunk), dtype=f64, device=topo.device)
        self._launches: dict[tuple, object] = {}

    def _launch(self, kernel, dim, inputs, nodes_per_index=1, **params):
        """Launch ``kernel`` on ``inputs``, recorded once per set of arrays (their
        addresses), with the scalar ``params`` set by name for this call."""
        key = (kernel.key, *(a.ptr for a in inputs if isinstance(a, wp.array)))
        launch = self._launches.get(key)
        if launch is None:
            topo = self.topology
            launch = self._launches[key] = record(kernel, dim, inputs, device=topo.device, threads=topo.threads,
                                                  nodes_per_index=nodes_per_index)
        for name, value in params.items():
            launch.set_param_by_name(name, value)
        launch.launch()

    def _set_coef(self, c) -> None:
        """The first len(c) coefficients on the device (the kernels read no more)."""
        self._coef[: len(c)] = c
        self.coef.assign(self._coef)

    def project_dots(self, B, w, k_sub, h, k_dot):
        if k_sub:
            self._set_coef(h)
        self._launch(kk.project_dots, self.partial.shape[1], [B, 0, self.coef, w, 0, self.partial, self.chunk],
                     nodes_per_index=self.chunk, k_sub=k_sub, k_dot=k_dot)
        return self.topology.partial_sums(self.partial, k_dot + 1)  # the rows it wrote: less to copy from a GPU

    def lincomb(self, B, c, a, x, out):
        if len(c):
            self._set_coef(c)
        self._launch(kk.lincomb, self.n, [B, 0, self.coef, f64(0.0), x, out], k=len(c), a=f64(a))


class HostVectors:
    """A ``KrylovBasis``'s vector work in numpy and BLAS on zero-copy views of the
    Warp arrays (the backend on a CPU device). Warp's CPU kernels run a pass over
    a vector at ~5 ns an entry, where BLAS runs one at ~0.2–0.7 ns: with the kernels,
    the Gram–Schmidt and combination passes cost more than the J·v of a Krylov
    vector at ne16 (``benchmarks/implicit_cost.py --krylov``). The passes are
    single-threaded: the vectors are short (in cache at ne30) and a BLAS thread
    pool spinning beside the model's threads made a norm cost 10 ms (``Simulation``
    runs with one BLAS thread, as ``Topology.dot``'s inner products assume). An
    inner product is BLAS's dot over this process's entries, then summed over
    processes in rank order by ``Topology.sums``: the bits do not depend on the
    model's threads (SWE_SPHERE_THREADS), which never touch these passes."""

    def __init__(self, basis: "KrylovBasis"):
        self.topology = basis.topology
        self.tmp = np.zeros(basis.n)
        self._np = NumpyViews()

    def project_dots(self, B, w, k_sub, h, k_dot):
        B, w = self._np(B), self._np(w)
        if k_sub:
            np.dot(np.asarray(h, dtype=np.float64), B[:k_sub], out=self.tmp)  # BLAS gemv: one pass over B's rows
            np.subtract(w, self.tmp, out=w)
        d = np.empty(k_dot + 1)
        if k_dot:
            np.dot(B[:k_dot], w, out=d[:k_dot])
        d[k_dot] = w @ w
        return self.topology.sums(d)

    def lincomb(self, B, c, a, x, out):
        x, out = self._np(x), self._np(out)
        k = len(c)
        if k:
            np.dot(np.asarray(c, dtype=np.float64), self._np(B)[:k], out=self.tmp)
        if a != 1.0 or out is not x:  # a·x first: out may alias x (an update in place skips the pass)
            np.multiply(x, a, out=out)
        if k:
            np.add(out, self.tmp, out=out)


class KrylovBasis:
    """A Krylov basis of ``rows`` vectors of length ``n`` (this process's part of a
    unique-node vector) on ``topology``'s device, the rows of ``V``, with the vector
    work Gram–Schmidt and the combinations need on any 2-D array of such vectors (a
    row range of ``V``, FGMRES's preconditioned vectors), its inner products summed
    over the topology's processes. Shared by ``FGMRES`` and ``kiops.Kiops``.

    ``vectors``: the backend of that work, chosen once here: ``HostVectors``
    (numpy/BLAS on views of the arrays) on a CPU device, ``KernelVectors``
    (``kernels.krylov``) elsewhere; either may be given (the tests check the two
    agree to round-off)."""

    def __init__(self, n: int, rows: int, topology, vectors=None):
        n, rows = int(n), int(rows)
        self.n, self.topology = n, topology
        dev = topology.device
        self.V = wp.zeros((rows, n), dtype=f64, device=dev)
        self.rows_V = [self.V[j] for j in range(rows)]  # row views: their addresses key the recorded launches
        self.w = wp.zeros(n, dtype=f64, device=dev)
        if vectors is None:
            vectors = HostVectors if wp.get_device(dev).is_cpu else KernelVectors
        self.vectors = vectors(self)

    def project_dots(self, B, w, k_sub: int, h: np.ndarray | None, k_dot: int) -> np.ndarray:
        """w −= Σ_{i<k_sub} h_i B_i; returns (B_i·w for i < k_dot, w·w) over all processes
        (B a 2-D array of vectors, w a vector)."""
        return self.vectors.project_dots(B, w, k_sub, h, k_dot)

    def lincomb(self, B, c: np.ndarray, a: float, x, out) -> None:
        """out = a·x + Σ c_i B_i (out may alias x; not B's rows i < len(c))."""
        self.vectors.lincomb(B, c, a, x, out)


class FGMRES(KrylovBasis):
    """Solver for A x = b from x = 0 with ``restart``-long cycles, for vectors of
    length ``n`` (this process's part) on ``topology``'s device, inner products
    summed over its processes.

    ``solve(matvec, precond, b, x, rtol, maxiter)`` → (iterations, converged):
    ``matvec(v, out)`` and ``precond(v, out)`` write A v and P⁻¹ v into ``out``
    (Warp arrays of length n); x (a Warp array, overwritten) gets the solution;
    stops when ‖b − A x‖ ≤ rtol ‖b‖ (the Arnoldi estimate) or after
    ``maxiter`` products with A.
    """

    def __init__(self, n: int, restart: int, topology):
        m = self.restart = int(restart)
        super().__init__(n, m + 1, topology)
        self.Z = wp.zeros((m, self.n), dtype=f64, device=topology.device)
        self.rows_Z = [self.Z[j] for j in range(m)]
        self.r = wp.zeros(self.n, dtype=f64, device=topology.device)

    def _project_dots(self, k_sub: int, h: np.ndarray | None, k_dot: int) -> np.ndarray:
        """w −= Σ_{i<k_sub} h_i V_i; returns (V_i·w for i < k_dot, w·w) over all processes."""
        return self.project_dots(self.V, self.w, k_sub, h, k_dot)

    def solve(self, matvec, precond, b, x, rtol: float, maxiter: int):
        m, V, Z, w = self.restart, self.rows_V, self.rows_Z, self.w
        x.zero_()
        wp.copy(w, b)
        beta = float(np.sqrt(self._project_dots(0, None, 0)[0]))
        if beta == 0.0:
            return 0, True
        target = rtol * beta
        r, its = b, 0
        while True:
            H = np.zeros((m + 1, m))
            cs, sn = np.zeros(m), np.zeros(m)
            g = np.zeros(m + 1)
            g[0] = beta
            self.lincomb(self.V, np.zeros(0), 1.0 / beta, r, V[0])
            for j in range(m):
                precond(V[j], Z[j])
                matvec(Z[j], w)
                its += 1
                h = self._project_dots(0, None, j + 1)[:-1]
                *h2, ww = self._project_dots(j + 1, h, j + 1)  # the second pass of classical Gram–Schmidt
                h2 = np.array(h2)
                H[: j + 1, j] = h + h2
                H[j + 1, j] = hn = float(np.sqrt(max(ww - h2 @ h2, 0.0)))
                if hn > 0.0:
                    self.lincomb(self.V, -h2 / hn, 1.0 / hn, w, V[j + 1])
                for i in range(j):  # earlier Givens rotations on the new column
                    H[i, j], H[i + 1, j] = cs[i] * H[i, j] + sn[i] * H[i + 1, j], -sn[i] * H[i, j] + cs[i] * H[i + 1, j]
                d = np.hypot(H[j, j], H[j + 1, j])
                cs[j], sn[j] = H[j, j] / d, H[j + 1, j] / d
                H[j, j], H[j + 1, j] = d, 0.0
                g[j], g[j + 1] = cs[j] * g[j], -sn[j] * g[j]
                if abs(g[j + 1]) <= target or its >= maxiter or hn == 0.0:
                    break
            k = j + 1
            y = solve_triangular(H[:k, :k], g[:k])
            self.lincomb(self.Z, y, 1.0, x, x)
            beta = abs(g[k])
            if beta <= target or its >= maxiter or hn == 0.0:
                return its, beta <= target
            # the residual b − A x = V_{k+1} Qᵀ (0, …, 0, g_k), without a product with A
            e = np.zeros(k + 1)
            e[k] = g[k]
            for i in reversed(range(k)):
                e[i], e[i + 1] = cs[i] * e[i] - sn[i] * e[i + 1], sn[i] * e[i] + cs[i] * e[i + 1]
            self.lincomb(self.V, e, 0.0, self.r, self.r)
            r = self.r
