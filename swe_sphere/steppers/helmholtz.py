"""The gravity-wave Helmholtz solve shared by the semi-implicit stepper and the
physics-based JFNK preconditioner.

Solves (I − c DG) δ = c DG r for δ, element-local, where G = DSS∘grad and
D = DSS∘div are the model's own strong operators and c = (βΔt)²gH. M·DG is
symmetric negative semi-definite (M the assembled mass; Taylor & Fournier
2010), so the system is solved on unique nodes as M(I − cDG) y = b by
preconditioned CG (``warp.optim.linear.cg``, CPU and CUDA) with the inverse
mass as diagonal preconditioner. The right-hand side c DG r has zero area
integral and CG keeps its iterates there, so h = r + δ has the mass of r to
round-off (HOMME ``advance_si_nonstag`` solves the same equation for h directly).

Two CG implementations, chosen by ``backend``: ``"warp"``
(``warp.optim.linear.cg``, on the device; the CUDA default) and ``"scipy"``
(``scipy.sparse.linalg.cg`` on zero-copy host views; the CPU default, because
Warp's CPU reductions cost milliseconds per dot product).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse.linalg as spla
import warp as wp
import warp.optim.linear as wpl

from ..kernels import blas
from ..kernels import semi_implicit as si
from ..model import ShallowWater
from .base import StepFailure

f64 = wp.float64


class Helmholtz:
    """CG solver for (I − c DG) h = r on the model's grid; buffers allocated once.

    ``solve(r, row, c, out, out_row)``: r[row] (element-local, continuous) →
    out[out_row] = h. Returns the CG iterations. Raises ``StepFailure`` when CG
    does not reach ``tol`` (relative) within ``maxiter``; ``ValueError`` for an
    unknown backend or "scipy" on a CUDA device.
    """

    def __init__(self, model: ShallowWater, tol: float, maxiter: int, backend: str | None = None):
        self.model, self.tol, self.maxiter = model, float(tol), int(maxiter)
        dev, N, nu = model.device, model.N, model.topology.nunique
        self.backend = backend or ("scipy" if wp.get_device(dev).is_cpu else "warp")
        if self.backend not in ("scipy", "warp"):
            raise ValueError(f"unknown linear solver backend {self.backend!r} (scipy, warp)")
        if self.backend == "scipy" and not wp.get_device(dev).is_cpu:
            raise ValueError("the scipy linear solver runs on the CPU only; use backend 'warp' on CUDA")
        self.Y = wp.zeros((3, N), dtype=f64, device=dev)
        self.GY = wp.zeros((2, N), dtype=f64, device=dev)
        self.DGY = wp.zeros((1, N), dtype=f64, device=dev)
        self.b, self.y, self.tmp = (wp.zeros(nu, dtype=f64, device=dev) for _ in range(3))
        self.minv = wp.array(1.0 / model.topology.area, dtype=f64, device=dev)
        self.c = 0.0
        if self.backend == "warp":
            self.A = wpl.LinearOperator((nu, nu), f64, wp.get_device(dev), self._matvec)
            self.cg = wpl.cg(
                self.A, self.b, self.y, tol=self.tol, atol=0.0, maxiter=self.maxiter, M=self.minv, run=False, check_every=1,
                use_cuda_graph=False,
            )
        else:
            y_np, tmp_np, minv_np = self.y.numpy(), self.tmp.numpy(), self.minv.numpy()

            def apply(v):
                y_np[:] = v
                self._apply(self.y, self.tmp)
                return tmp_np.copy()

            self.A = spla.LinearOperator((nu, nu), matvec=apply, dtype=np.float64)
            self.M = spla.LinearOperator((nu, nu), matvec=lambda v: minv_np * v, dtype=np.float64)

    def DG(self, x, row):
        """DGY[0] = D G x[row] (GY holds G x[row])."""
        self.model.gradient(x, row, self.GY)
        self.model.divergence(self.GY, self.DGY)

    def _apply(self, x, out):
        """out = M(I − c DG) x on unique nodes."""
        m = self.model
        m.scatter(x, self.Y, 2)
        self.DG(self.Y, 2)
        wp.launch(si.helmholtz, m.N, [self.Y, f64(self.c), self.DGY], device=m.device)
        m.assemble(self.DGY, 0, out)

    def _matvec(self, x, y, z, alpha, beta):
        """warp.optim.linear interface: z = alpha·A x + beta·y."""
        self._apply(x, self.tmp)
        wp.launch(blas.axpby1d, x.shape[0], [f64(alpha), self.tmp, f64(beta), y, z], device=self.model.device)

    def _run_cg(self) -> int:
        if self.backend == "warp":
            iterations, residual, atol = self.cg()
            converged = float(residual) <= float(atol)
            detail = f"residual {float(residual):.3e} > {float(atol):.3e}"
        else:
            count = [0]
            b = self.b.numpy()
            if not np.any(b):
                self.y.zero_()
                return 0
            y, info = spla.cg(self.A, b, rtol=self.tol, maxiter=self.maxiter, M=self.M, callback=lambda _: count.__setitem__(0, count[0] + 1))
            self.y.numpy()[:] = y
            iterations, converged, detail = count[0], info == 0, f"scipy cg info {info}"
        if not converged:
            raise StepFailure(f"Helmholtz CG did not converge after {int(iterations)} iterations ({detail})")
        return int(iterations)

    def solve(self, r, row, c, out, out_row) -> int:
        m, dev = self.model, self.model.device
        self.c = float(c)
        self.DG(r, row)
        m.assemble(self.DGY, 0, self.b)
        wp.launch(blas.axpby1d, self.b.shape[0], [f64(c), self.b, f64(0.0), self.b, self.b], device=dev)
        self.y.zero_()
        iterations = self._run_cg()
        m.scatter(self.y, out, out_row)  # δ
        wp.launch(blas.add_row, m.N, [r, row, out, out_row], device=dev)  # h = r + δ
        return iterations
