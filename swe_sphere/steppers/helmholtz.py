"""The linear gravity-wave operator shared by the semi-implicit stepper, the
JFNK preconditioner and the IMEX stepper.

About a mean depth H, the gravity-wave part of the shallow-water RHS is

    L_v = −g G h,    L_h = −H D v,

with G = DSS∘grad and D = DSS∘div the model's own strong operators (so the
split F = (F − L) + L of the model's RHS is exact). ``GravityWave.solve``
inverts (I − aL) for any a through its Schur complement, the Helmholtz
equation for the height (HOMME ``advance_si_nonstag``; Lott, Woodward &
Evans 2015 for its use as a preconditioner):

    (I − a²gH DG) z_h = r_h − aH D r_v,    z_v = r_v − a g G z_h.

On unique nodes, multiplied by the assembled mass M, the Helmholtz operator
is M + c K with K = −M D G (c = a²gH): K is symmetric positive
semi-definite (the SE divergence and gradient are adjoint under the GLL
quadrature; Taylor & Fournier 2010), K·1 = 0, so M + cK is SPD.
``helmholtz_matrix`` assembles K once per grid as a scipy sparse matrix by
probing the model's element kernels (it is the matrix-free operator, to
round-off), and the solve is, by name (``SOLVERS``):

* ``"cg"``: CG on the assembled matrix with the inverse mass as (Jacobi)
  preconditioner, to the relative tolerance ``tol`` (scipy, CPU);
* ``"amg"``: CG preconditioned by one pyamg smoothed-aggregation V-cycle
  (Vaněk, Mandel & Brezina 1996), to ``tol`` (CPU);
* ``"chebyshev"``: ``maxiter`` steps of mass-preconditioned Chebyshev
  iteration (Saad 2003, Alg. 12.1) on the eigenvalue interval [1, 1 + cμ],
  μ = λmax(M⁻¹K): a fixed polynomial, hence a fixed linear approximate
  inverse for a preconditioner, with no inner products (CPU);
* ``"vcycle"``: one AMG V-cycle, a fixed approximate inverse (CPU);
* ``"warp_cg"``: matrix-free mass-preconditioned CG with the model's
  operators on the device (``warp.optim.linear.cg``; the CUDA default, as
  scipy and pyamg run on the host only);
* ``"mf_cg"``: the same matrix-free mass-preconditioned CG on the host
  (``krylov.cg``) with the inner products summed over MPI ranks: the solver
  for runs on several ranks (their default), where the others cannot go —
  the assembled matrix and the AMG hierarchy are the whole grid's, and
  warp.optim's inner products are the process's own. The operator's bits do
  not depend on the rank count (the DSS's do not), so a run on N ranks
  differs from one on one rank only by the order of the inner products' sums.

Measured (TC5 ne16, 2 busy cores): one pyamg V-cycle costs 15–28 sparse
products with K (its Python overhead per level dominates at 14k unknowns),
so AMG-CG needs fewer iterations than Jacobi-CG (13 / 30 / 59 against
84 / ~200 / 472 to 1e-10 at 4 / 10 / 30× the gravity-wave limit) but more
time (≈ 370 / 830 / 1400 against 84 / 200 / 472 products).

The height's area integral is set to that of the right-hand side after the
solve (the exact solution has it, since ∫D v = 0), so a loose solve still
keeps mass to round-off.
"""

from __future__ import annotations

import numpy as np
import pyamg
import scipy.sparse as sp
import scipy.sparse.linalg as spla
import warp as wp
import warp.optim.linear as wpl

from ..kernels import blas
from ..kernels import gravity_wave as gk
from ..model import ShallowWater
from .base import StepFailure
from .krylov import cg

f64 = wp.float64
SOLVERS = ("cg", "amg", "chebyshev", "vcycle", "warp_cg", "mf_cg")
_HOST_SOLVERS = ("cg", "amg", "chebyshev", "vcycle", "mf_cg")
_DISTRIBUTED_SOLVERS = ("mf_cg",)
# Two symmetric Gauss–Seidel sweeps before and after each coarse correction: TC5
# ne16, random right-hand side to 1e-10, CG iterations at 4x / 30x the gravity-wave
# limit 13 / 59 against 18 / 84 with pyamg's default one sweep (Jacobi-CG: 84 / 472).
_SMOOTHER = ("block_gauss_seidel", {"sweep": "symmetric", "iterations": 2})


def default_solver(model: ShallowWater) -> str:
    """The measured default: Jacobi-CG on the assembled matrix on the CPU (the
    cheapest per step as an accurate solve and, loose, as a preconditioner;
    ``benchmarks/implicit_cost.py``), the matrix-free Warp CG on CUDA; over
    several MPI ranks the matrix-free host CG with distributed inner products."""
    if model.topology.distributed:
        return "mf_cg"
    return "cg" if wp.get_device(model.device).is_cpu else "warp_cg"


def check_solve_options(o) -> None:
    """The checks of a stepper's accurate-solve options ``helmholtz_solver``, ``tol``,
    ``maxiter``, ``mean_depth`` (semi-implicit, IMEX): ValueError '<option> must ...'."""
    if o.helmholtz_solver not in ("", "cg", "amg", "warp_cg", "mf_cg"):
        raise ValueError(f"helmholtz_solver must be 'cg', 'amg', 'warp_cg' or 'mf_cg' (got {o.helmholtz_solver!r})")
    if not 0 < o.tol < 1:
        raise ValueError(f"tol must be in (0, 1) (got {o.tol})")
    if o.maxiter < 1:
        raise ValueError(f"maxiter must be >= 1 (got {o.maxiter})")
    if o.mean_depth < 0:
        raise ValueError(f"mean_depth must be >= 0 (got {o.mean_depth})")


def helmholtz_matrix(model: ShallowWater) -> sp.csr_matrix:
    """K = −M D G (nunique × nunique, dimensionless: M in m², D G in m⁻²) on unique nodes, symmetrised (its asymmetry is round-off, ~1e-15 relative).

    Built from the model's own element kernels: ``model.gradient`` and
    ``model.divergence`` leave the element-local (pre-DSS) result in
    ``model.vec_work`` / ``model.scalar``, so np² (gradient) and 2np²
    (divergence) probes with a unit value at one local node of every element
    give the element matrices Ĝ, D̂ exactly; with P the scatter (unique →
    element-local), W = diag(spheremp) and the DSS S = P M⁻¹ Pᵀ W,
    K = −Pᵀ W D̂ S Ĝ P. The whole grid on one process (the host solvers').
    """
    grid, N = model.grid, model.N
    npp, nu = grid.np**2, grid.nunique
    base = np.arange(grid.nelem) * npp
    x = wp.zeros((3, N), dtype=f64, device=model.device)
    G2, D1 = wp.zeros((2, N), dtype=f64, device=model.device), wp.zeros((1, N), dtype=f64, device=model.device)
    nodes = np.arange(N)  # element-major: the rows of element e are e·np² … (e+1)·np² − 1
    grow, gcol, gval, drow, dcol, dval = [], [], [], [], [], []
    unit = np.zeros((3, N))
    for k in range(npp):
        col = np.repeat(base + k, npp)  # the probed column of each row's element
        unit[:] = 0.0
        unit[2, base + k] = 1.0
        x.assign(unit)
        model.gradient(x, 2, G2)
        g = model.vec_work.numpy()
        for c in range(2):
            grow.append(c * N + nodes), gcol.append(col), gval.append(g[c].copy())
        for c in range(2):
            unit[:] = 0.0
            unit[c, base + k] = 1.0
            x.assign(unit)
            model.divergence(x, D1)
            drow.append(nodes), dcol.append(c * N + col), dval.append(model.scalar.numpy()[0].copy())
    G_hat = sp.csr_matrix((np.concatenate(gval), (np.concatenate(grow), np.concatenate(gcol))), shape=(2 * N, N))
    D_hat = sp.csr_matrix((np.concatenate(dval), (np.concatenate(drow), np.concatenate(dcol))), shape=(N, 2 * N))
    G_hat.eliminate_zeros()
    D_hat.eliminate_zeros()
    P = sp.csr_matrix((np.ones(N), (nodes, grid.gid)), shape=(N, nu))
    PtW = (P.T @ sp.diags(grid.spheremp)).tocsr()
    inv_area = sp.diags(np.tile(1.0 / grid.area, 2))
    G = inv_area @ sp.block_diag((PtW, PtW)) @ G_hat @ P  # (2 nunique, nunique): DSS'd gradient on unique nodes
    K = -(PtW @ D_hat @ sp.block_diag((P, P)) @ G)
    K = ((K + K.T) * 0.5).tocsr()
    K.eliminate_zeros()
    return K


class GravityWave:
    """The linear gravity-wave operator L and solves of (I − aL) z = s·r.

    Parameters: the model; ``mean_depth`` H (m; 0 = the mean depth of the first
    state passed to ``set_depth``); ``solver`` (one of ``SOLVERS``; None = the
    CPU/CUDA default for an accurate solve), ``tol`` (relative residual of the
    CG solvers) and ``maxiter``; ``warm``: start each CG from the last
    solution (for a sequence of similar solves, as the semi-implicit steps).
    Over several MPI ranks only ``"mf_cg"`` runs (the default there).

    ``apply(x, out)``: out = L x (states (3, N), element-local). ``solve(r, a,
    z, scale)``: z = (I − aL)⁻¹ (scale·r); returns the Helmholtz iterations
    (CG iterations; 1 for a V-cycle). Raises ``StepFailure`` when CG does not
    reach ``tol`` within ``maxiter``; ``ValueError`` for an unknown solver, a
    host solver on CUDA, a solver other than "mf_cg" over several MPI ranks,
    or a model without continuity and pressure gradient.
    """

    def __init__(self, model: ShallowWater, mean_depth=0.0, solver=None, tol=1e-10, maxiter=500, warm=False):
        for term in ("continuity", "pressure_gradient"):
            if term not in model.terms:
                raise ValueError(f"the gravity-wave operator needs the {term} term")
        solver = solver or default_solver(model)
        if solver not in SOLVERS:
            raise ValueError(f"unknown Helmholtz solver {solver!r} (known: {', '.join(SOLVERS)})")
        if solver in _HOST_SOLVERS and not wp.get_device(model.device).is_cpu:
            raise ValueError(f"the Helmholtz solver {solver!r} runs on the CPU only; use 'warp_cg' on CUDA")
        if model.topology.distributed and solver not in _DISTRIBUTED_SOLVERS:
            raise ValueError(f"the Helmholtz solver {solver!r} runs on one MPI rank only; use 'mf_cg' over several ranks")
        self.model, self.H, self.solver = model, float(mean_depth), solver
        self.tol, self.maxiter, self.warm = float(tol), int(maxiter), bool(warm)
        dev, N, nu = model.device, model.N, model.topology.nunique
        self.Gh, self.Dv = wp.zeros((2, N), dtype=f64, device=dev), wp.zeros((1, N), dtype=f64, device=dev)
        self.b, self.y = wp.zeros(nu, dtype=f64, device=dev), wp.zeros(nu, dtype=f64, device=dev)
        self.area = model.topology.area
        self.c = None
        if solver in ("warp_cg", "mf_cg"):
            self._matrix_free(model)
        else:
            self.K = helmholtz_matrix(model)
            self._amg: dict[float, object] = {}
            self._A: dict[float, sp.csr_matrix] = {}
            self._mu = None

    # -- what carries over between solves (for bitwise restarts) ----------------------
    def state(self) -> dict:
        """The mean depth (0 until fixed) and, with ``warm``, the last solution: a
        height, stored element-local in row 2 of a (3, N) array like a state."""
        s = {"mean_depth": self.H}
        if self.warm:  # whole-grid, gathered from every rank on rank 0 (call on all)
            topo = self.model.topology
            guess = wp.zeros((3, self.model.N), dtype=f64, device=self.model.device)
            for launch in topo.scatter(self.y, guess, 2):
                launch.launch()
            s["helmholtz_guess"] = topo.gather(guess.numpy())
        return s

    def restore(self, state: dict, entry) -> None:
        """Set what ``state()`` returned; ``entry(state, key)`` raises ValueError for a missing key."""
        self.H = float(entry(state, "mean_depth"))
        if self.warm:
            topo = self.model.topology
            guess = topo.distribute(entry(state, "helmholtz_guess"), 3, "stepper state 'helmholtz_guess'")  # on rank 0 only when several ranks
            self.y.assign(guess[2][topo.first.numpy()])

    # -- L and the Schur complement (element-local) ---------------------------------
    def set_depth(self, x) -> None:
        """Take H as the area mean of x's depth if no mean depth was given."""
        if self.H == 0.0:
            self.H = self.model.topology.mean(x.numpy()[2])

    def apply(self, x, out) -> None:
        """out = L x = (−g G h, −H D v)."""
        m = self.model
        m.gradient(x, 2, self.Gh)
        m.divergence(x, self.Dv)
        m.pointwise(gk.apply, self.Gh, self.Dv, f64(m.g), f64(self.H), out)

    def solve(self, r, a: float, z, scale: float = 1.0) -> int:
        """z = (I − aL)⁻¹ (scale·r) through the Helmholtz equation; z may alias r."""
        m = self.model
        m.divergence(r, self.Dv)
        m.pointwise(gk.schur_height, r, self.Dv, f64(scale), f64(a * self.H), z)
        m.assemble(z, 2, self.b)
        iterations = self._helmholtz(a * a * m.g * self.H)
        m.scatter(self.y, z, 2)
        m.gradient(z, 2, self.Gh)
        m.pointwise(gk.schur_wind, r, self.Gh, f64(scale), f64(a * m.g), z)
        return iterations

    # -- the Helmholtz solve on unique nodes: (M + cK) y = b --------------------------
    def _helmholtz(self, c: float) -> int:
        if self.solver == "warp_cg":
            return self._device(c)
        b, y, topo = self.b.numpy(), self.y.numpy(), self.model.topology
        if not self.warm:
            y[:] = 0.0
        iterations = self._host(c, b, y)
        y += (topo.sum(b.sum()) - topo.sum(self.area @ y)) / topo.total_area  # ∫z_h = ∫(right-hand side)
        return iterations

    def matrix(self, c: float) -> sp.csr_matrix:
        """M + cK (cached for the last few c: a stepper uses one or two)."""
        A = self._A.get(c)
        if A is None:
            if len(self._A) >= 4:
                self._A.pop(next(iter(self._A)))
            A = self._A[c] = (sp.diags(self.area) + c * self.K).tocsr()
        return A

    def hierarchy(self, c: float):
        """The pyamg smoothed-aggregation hierarchy for M + cK (built once per c)."""
        ml = self._amg.get(c)
        if ml is None:
            if len(self._amg) >= 4:
                self._amg.pop(next(iter(self._amg)))
            ml = self._amg[c] = pyamg.smoothed_aggregation_solver(self.matrix(c), symmetry="symmetric", presmoother=_SMOOTHER, postsmoother=_SMOOTHER)
            ml.vcycle = ml.aspreconditioner(cycle="V")
        return ml

    def _host(self, c, b, y) -> int:
        if self.solver == "vcycle":
            y[:] = self.hierarchy(c).vcycle @ b
            return 1
        if self.solver == "chebyshev":
            y[:] = self._chebyshev(c, b)
            return self.maxiter
        if self.solver == "mf_cg":
            return self._mf_cg(c, b, y)
        A = self.matrix(c)
        if self.solver == "amg":
            M = self.hierarchy(c).vcycle
        else:
            inv_area = 1.0 / self.area
            M = spla.LinearOperator(A.shape, matvec=lambda v: inv_area * v, dtype=np.float64)
        count = [0]
        x, info = spla.cg(A, b, x0=y.copy(), rtol=self.tol, atol=0.0, maxiter=self.maxiter, M=M,
                          callback=lambda _: count.__setitem__(0, count[0] + 1))
        if info != 0:
            raise StepFailure(f"Helmholtz {self.solver} did not converge in {count[0]} iterations (scipy cg info {info})")
        y[:] = x
        return count[0]

    def _chebyshev(self, c, b):
        """``maxiter`` Chebyshev steps from 0 for (M + cK) y = b, preconditioned by M,
        on the interval [1, 1 + cμ] that holds the spectrum of I + cM⁻¹K."""
        if self._mu is None:  # λmax(M⁻¹K) = λmax(M^-½ K M^-½), 5 % margin
            s = 1.0 / np.sqrt(self.area)
            S = sp.diags(s) @ self.K @ sp.diags(s)
            self._mu = 1.05 * float(spla.eigsh(S, k=1, which="LA", tol=1e-3, return_eigenvectors=False)[0])
        A, inv_area = self.matrix(c), 1.0 / self.area
        lo, hi = 1.0, 1.0 + c * self._mu
        theta, delta = 0.5 * (hi + lo), 0.5 * (hi - lo)
        sigma = theta / delta
        rho = 1.0 / sigma
        r = b.copy()
        d = inv_area * r / theta
        y = np.zeros_like(b)
        for k in range(self.maxiter):
            y += d
            if k == self.maxiter - 1:
                break
            r -= A @ d
            rho_new = 1.0 / (2.0 * sigma - rho)
            d = rho_new * rho * d + (2.0 * rho_new / delta) * (inv_area * r)
            rho = rho_new
        return y

    # -- matrix-free CG: on the device ("warp_cg") or over MPI ranks ("mf_cg") -------------
    def _matrix_free(self, model):
        dev, N, nu = model.device, model.N, model.topology.nunique
        self.Y = wp.zeros((3, N), dtype=f64, device=dev)
        self.GY = wp.zeros((2, N), dtype=f64, device=dev)
        self.DGY = wp.zeros((1, N), dtype=f64, device=dev)
        self.tmp = wp.zeros(nu, dtype=f64, device=dev)
        if self.solver == "mf_cg":
            self.p = wp.zeros(nu, dtype=f64, device=dev)
            return
        self.minv = wp.array(1.0 / self.area, dtype=f64, device=dev)
        self.area_wp = wp.array(self.area, dtype=f64, device=dev)
        self.ones = wp.ones(nu, dtype=f64, device=dev)
        self.A = wpl.LinearOperator((nu, nu), f64, wp.get_device(dev), self._warp_matvec)
        self.cg = wpl.cg(self.A, self.b, self.y, tol=self.tol, atol=0.0, maxiter=self.maxiter, M=self.minv, run=False,
                         check_every=1, use_cuda_graph=False)

    def _apply_matrix_free(self, y, out):
        """out = (M + cK) y = M (I − c DG) y with the model's operators."""
        m = self.model
        m.scatter(y, self.Y, 2)
        m.gradient(self.Y, 2, self.GY)
        m.divergence(self.GY, self.DGY)
        wp.launch(gk.helmholtz, m.N, [self.Y, f64(self.c), self.DGY], device=m.device)
        m.assemble(self.DGY, 0, out)

    def _mf_cg(self, c, b, y) -> int:
        """(M + cK) y = b by ``krylov.cg`` with the matrix-free operator, M⁻¹ as preconditioner."""
        self.c = c
        p, Ap, inv_area = self.p.numpy(), self.tmp.numpy(), 1.0 / self.area

        def matvec(v):
            p[:] = v
            self._apply_matrix_free(self.p, self.tmp)
            return Ap

        iterations, converged = cg(matvec, lambda r: inv_area * r, b, y, self.tol, self.maxiter, self.model.topology.sums)
        if not converged:
            raise StepFailure(f"Helmholtz mf_cg did not converge in {iterations} iterations")
        return iterations

    def _warp_matvec(self, x, y, z, alpha, beta):
        """warp.optim.linear interface: z = alpha·A x + beta·y."""
        self._apply_matrix_free(x, self.tmp)
        wp.launch(blas.axpby1d, x.shape[0], [f64(alpha), self.tmp, f64(beta), y, z], device=self.model.device)

    def _device(self, c) -> int:
        self.c = c
        if not self.warm:
            self.y.zero_()
        iterations, residual, atol = self.cg()
        if float(residual) > float(atol):
            raise StepFailure(f"Helmholtz warp_cg did not converge in {int(iterations)} iterations "
                              f"(residual {float(residual):.3e} > {float(atol):.3e})")
        u, topo = wp.utils, self.model.topology
        shift = (topo.sum(float(u.array_sum(self.b))) - topo.sum(float(u.array_inner(self.area_wp, self.y)))) / topo.total_area
        wp.launch(blas.axpby1d, self.y.shape[0], [f64(1.0), self.y, f64(shift), self.ones, self.y], device=self.model.device)
        return int(iterations)
