"""Flexible GMRES (Saad 1993, SIAM J. Sci. Comput. 14, 461) over the topology's
vectors, for the JFNK stepper (the Helmholtz CG is compiled:
``kernels.helmholtz``).

It runs on numpy vectors holding this process's part (on the CPU, zero-copy
views of Warp arrays) and take their inner products through ``reduce``, the
sum over processes of an array of partial sums (``Topology.sums``; the
identity on one process), so they run unchanged on any number of MPI ranks.

Right-preconditioned, so the residual it minimises is the true one, and the
preconditioner may change from one iteration to the next (an inexact inner
solve). Why not ``pyamg.krylov.fgmres``: it ends every restart cycle with an
explicit residual b − A x, one more Jacobian-vector product (= one RHS
evaluation) per Newton iteration, ~20 % of JFNK's RHS evaluations at 4–10×
the gravity-wave limit, and allocates its 2·restart·n basis on each call. Here
the basis is allocated once, the residual after a cycle comes from the
least-squares problem, and the Arnoldi vectors are orthogonalised by classical
Gram–Schmidt done twice (two matrix-vector products with the basis; as
accurate as modified Gram–Schmidt, Giraud et al. 2005).
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import solve_triangular


def _identity(values):
    return values


class FGMRES:
    """Solver for A x = b from x = 0 with ``restart``-long cycles and basis
    storage for vectors of length ``n`` (this process's part), inner products
    summed over processes by ``reduce``.

    ``solve(matvec, precond, b, rtol, maxiter)`` → (x, iterations, converged):
    stops when ‖b − A x‖ ≤ rtol ‖b‖ (the Arnoldi estimate) or after
    ``maxiter`` products with A.
    """

    def __init__(self, n: int, restart: int, reduce=_identity):
        self.restart, self.reduce = int(restart), reduce
        self.V = np.empty((self.restart + 1, n))
        self.Z = np.empty((self.restart, n))

    def solve(self, matvec, precond, b, rtol: float, maxiter: int):
        V, Z, m, reduce = self.V, self.Z, self.restart, self.reduce
        x = np.zeros_like(b)
        beta = float(np.sqrt(reduce(b @ b)))  # np.linalg.norm's bits on one process
        if beta == 0.0:
            return x, 0, True
        target = rtol * beta
        r, its = b, 0
        while True:
            H = np.zeros((m + 1, m))
            cs, sn = np.zeros(m), np.zeros(m)
            g = np.zeros(m + 1)
            g[0] = beta
            V[0] = r / beta
            for j in range(m):
                Z[j] = precond(V[j])
                w = matvec(Z[j])
                its += 1
                h = reduce(V[: j + 1] @ w)
                w = w - h @ V[: j + 1]
                h2 = reduce(V[: j + 1] @ w)  # the second pass of classical Gram–Schmidt
                w -= h2 @ V[: j + 1]
                H[: j + 1, j] = h + h2
                H[j + 1, j] = hn = float(np.sqrt(reduce(w @ w)))
                if hn > 0.0:
                    V[j + 1] = w / hn
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
            x += y @ Z[:k]
            beta = abs(g[k])
            if beta <= target or its >= maxiter or hn == 0.0:
                return x, its, beta <= target
            # the residual b − A x = V_{k+1} Qᵀ (0, …, 0, g_k), without a product with A
            e = np.zeros(k + 1)
            e[k] = g[k]
            for i in reversed(range(k)):
                e[i], e[i + 1] = cs[i] * e[i] - sn[i] * e[i + 1], sn[i] * e[i] + cs[i] * e[i + 1]
            r = e @ V[: k + 1]

