"""Fully implicit Jacobian-free Newton–Krylov stepper (Evans, Taylor & Drake 2010,
Mon. Wea. Rev. 138, 3333; HOMME ``implicit_mod`` / ``residual``).

Each step solves R(x) = 0 on the DSS'd state, with F the model's DSS'd RHS:

  θ-method (``method = "theta"``; θ = 0.5 Crank–Nicolson, 1 backward Euler):
      R(x) = (x − x(n))/Δt − θ F(x) − (1−θ) F(x(n))
  BDF2 (``method = "bdf2"``; backward Euler on the first step):
      R(x) = (x − 4/3 x(n) + 1/3 x(n−1))/Δt − 2/3 F(x)

both written R(x) = (x − b)/Δt − β F(x) with b fixed during the step. (HOMME
multiplies by the mass matrix M; F here is already M⁻¹-weighted by the DSS.)

Newton: δ from J δ = −R by GMRES (``krylov = "scipy"``, the CPU default, or
``"warp"``: ``warp.optim.linear.gmres`` on the device), J v by a forward
difference of F with ε = sqrt(ε_mach)(1 + ‖x‖)/‖v‖; forcing terms by
Eisenstat & Walker (1996) choice 2 (γ = 0.9, α = 2, safeguarded, η ≤ 0.9,
η ≥ ``gmres_tol``); a backtracking line search (Armijo, halving up to 8 times)
when the residual does not fall. Converged when the RMS of R is ≤ ``atol``
(default 1e-10, HOMME's) or ≤ ``rtol`` × its first value; at most ``maxiter``
(30) iterations, else the step fails (``StepFailure``).

Preconditioner (``preconditioner = "helmholtz"``; Lott, Woodward & Evans 2015):
the linearised gravity-wave block I/Δt − β L (L_v = −g∇h, L_h = −H∇·v),
inverted exactly through its Schur complement — the semi-implicit Helmholtz
equation (I − (βΔt)²gH DG) z_h = Δt(r_h − βΔtH D r_v), then
z_v = Δt(r_v − βg G z_h) — applied on the right, so GMRES sees the true residual.

Hyperviscosity is applied after the step, split from the implicit dynamics
(forward Euler over Δt, subcycled as needed), as for the other steppers: inside
the residual its ∇⁴ spectrum would dominate the Newton–Krylov iteration for
a term that only damps the grid scale.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
import scipy.sparse.linalg as spla
import warp as wp
import warp.optim.linear as wpl

from ..kernels import blas
from ..kernels import implicit as ik
from .base import StepFailure, Stepper, StepStats
from .helmholtz import Helmholtz

f64 = wp.float64
_SQRT_EPS = math.sqrt(np.finfo(float).eps)


@dataclass(frozen=True)
class ImplicitOptions:
    """Scene table ``[implicit]`` (see ``Implicit``)."""

    method: str = "theta"
    theta: float = 0.5
    atol: float = 1e-10
    rtol: float = 0.0
    maxiter: int = 30
    gmres_tol: float = 1e-11
    gmres_restart: int = 30
    gmres_maxiter: int = 300
    krylov: str = ""
    preconditioner: str = "none"
    cg_tol: float = 1e-8
    mean_depth: float = 0.0

    def __post_init__(self):
        if self.method not in ("theta", "bdf2"):
            raise ValueError(f"method must be 'theta' or 'bdf2' (got {self.method!r})")
        if not 0.5 <= self.theta <= 1.0:
            raise ValueError(f"theta must be in [0.5, 1] (got {self.theta})")
        if self.atol < 0 or self.rtol < 0 or (self.atol == 0 and self.rtol == 0):
            raise ValueError(f"atol and rtol must be >= 0, one of them > 0 (got {self.atol}, {self.rtol})")
        for name in ("maxiter", "gmres_restart", "gmres_maxiter"):
            if getattr(self, name) < 1:
                raise ValueError(f"{name} must be >= 1 (got {getattr(self, name)})")
        for name in ("gmres_tol", "cg_tol"):
            if not 0 < getattr(self, name) < 1:
                raise ValueError(f"{name} must be in (0, 1) (got {getattr(self, name)})")
        if self.krylov not in ("", "scipy", "warp"):
            raise ValueError(f"krylov must be 'scipy' or 'warp' (got {self.krylov!r})")
        if self.preconditioner not in ("none", "helmholtz"):
            raise ValueError(f"preconditioner must be 'none' or 'helmholtz' (got {self.preconditioner!r})")
        if self.mean_depth < 0:
            raise ValueError(f"mean_depth must be >= 0 (got {self.mean_depth})")


class Implicit(Stepper):
    """Fully implicit θ-method / BDF2 stepper by Jacobian-free Newton–Krylov.

    Options (scene table ``[implicit]``): ``method`` ("theta" | "bdf2"),
    ``theta`` (0.5), ``atol`` (1e-10), ``rtol`` (0: off), ``maxiter`` (30),
    ``gmres_tol`` (1e-11, the floor of the forcing term), ``gmres_restart``
    (30), ``gmres_maxiter`` (300 inner iterations), ``krylov`` ("scipy" on CPU,
    "warp" on CUDA), ``preconditioner`` ("none" | "helmholtz"), ``cg_tol``
    (1e-8, the preconditioner's CG; GMRES assumes a fixed preconditioner: at
    1e-3, TC5 at gravity-wave Courant 10.7 needed more GMRES iterations than
    with no preconditioner), ``mean_depth`` (H, m; 0 = initial mean).
    Reports Newton, GMRES (and preconditioner CG) iterations per step; keeps
    the last step's residual history in ``residual_history``.
    """

    name = "implicit"
    Options = ImplicitOptions
    solvers = ("newton", "gmres", "cg")

    def __init__(self, model, dt, options=None):
        super().__init__(model, dt, options)
        o = self.o = dataclasses.asdict(self.options)
        dev, N = model.device, self.N
        self.krylov = o["krylov"] or ("scipy" if wp.get_device(dev).is_cpu else "warp")
        if self.krylov == "scipy" and not wp.get_device(dev).is_cpu:
            raise ValueError("krylov 'scipy' runs on the CPU only; use 'warp' on CUDA")
        if o["preconditioner"] == "helmholtz":
            for term in ("continuity", "pressure_gradient"):
                if term not in model.terms:
                    raise ValueError(f"the helmholtz preconditioner needs the {term} term")
            self.helmholtz = Helmholtz(model, o["cg_tol"], 1000, "scipy" if self.krylov == "scipy" else "warp")
        self.H = o["mean_depth"]
        for name in ("xn", "xprev", "b", "Fx", "R", "delta", "trial", "Ft", "Rt", "v", "xp", "Fp", "z"):
            setattr(self, name, wp.zeros((3, N), dtype=f64, device=dev))
        self.hrhs, self.Dr, self.Gz = (wp.zeros((k, N), dtype=f64, device=dev) for k in (1, 1, 2))
        # Krylov vectors live on unique nodes (3·nunique: 0.56× the element-local length at np = 4)
        self.topology = topo = model.topology
        self.nu = topo.nunique
        n3 = 3 * self.nu
        for name in ("w", "w_in", "minus_R", "zu", "Jv", "xu"):
            setattr(self, name, wp.zeros(n3, dtype=f64, device=dev))
        self.residual_history: list[float] = []
        self._cg_its = 0
        if self.krylov == "scipy":
            self.op = spla.LinearOperator((n3, n3), matvec=self._host_matvec, dtype=np.float64)
        else:
            self.op = wpl.LinearOperator((n3, n3), f64, wp.get_device(dev), self._device_matvec)
            self.gmres = wpl.gmres(
                self.op, self.minus_R, self.w, tol=o["gmres_tol"], atol=0.0, restart=o["gmres_restart"],
                maxiter=o["gmres_maxiter"], run=False, check_every=o["gmres_restart"], use_cuda_graph=False,
            )

    # -- vector helpers ----------------------------------------------------------
    def _norm(self, a) -> float:
        """Euclidean norm of an array (3, N) or (3·nunique,)."""
        return self.topology.norm(a)

    def _rms(self, a) -> float:
        """RMS over the element-local nodes of the whole grid of a (3, N) array."""
        return self._norm(a) / math.sqrt(3 * self.topology.npts_total)

    def _axpby(self, a, x, b, y, out):
        self._pointwise(blas.axpby, f64(a), x, f64(b), y, out)

    def _F(self, x, out):
        self.model.rhs(x, out)
        self.rhs_evals += 1

    def _residual(self, x, F, R):
        self._pointwise(ik.residual, x, self.b, F, f64(1.0 / self.dt), f64(self.beta), R)

    # -- the linear operator: J P⁻¹ ----------------------------------------------
    def _precondition(self, r, z):
        """z = P⁻¹ r with P = I/Δt − β L (see the module docstring)."""
        m, dt, beta = self.model, self.dt, self.beta
        m.divergence(r, self.Dr)
        wp.launch(ik.precond_height, self.N, [r, self.Dr, f64(dt), f64(beta * dt * self.H), self.hrhs], device=m.device)
        self._cg_its += self.helmholtz.solve(self.hrhs, 0, (beta * dt) ** 2 * m.g * self.H, z, 2)
        m.gradient(z, 2, self.Gz)
        wp.launch(ik.precond_wind, self.N, [r, self.Gz, f64(dt), f64(beta * m.g), z], device=m.device)

    def _scatter(self, u, out):
        """Element-local out (3, N) from the unique-node vector u."""
        nu = self.nu
        for r in range(3):
            self.model.scatter(u[r * nu : (r + 1) * nu], out, r)

    def _gather(self, a, v, out):
        """Unique-node out = a·v from a continuous (3, N) v."""
        self._pointwise(ik.gather, f64(a), v, self.topology.first, self.nu, out, unique=True)

    def _jv(self, w, out):
        """out = J w (unique-node vectors) by a forward difference of F about the current iterate x."""
        wnorm = self._norm(w)
        if wnorm == 0.0:
            out.zero_()
            return
        eps = _SQRT_EPS * (1.0 + self.xnorm) / wnorm
        self._pointwise(ik.scatter_perturb, self.x, f64(eps), w, self.topology.gid, self.nu, self.xp)
        self._F(self.xp, self.Fp)
        self._pointwise(ik.jacobian_vector, w, self.Fx, self.Fp, self.topology.first, self.nu, f64(1.0 / self.dt), f64(self.beta / eps), out, unique=True)

    def _apply(self, w, out):
        """out = J P⁻¹ w (unique-node vectors)."""
        if self.o["preconditioner"] == "none":
            self._jv(w, out)
            return
        self._scatter(w, self.v)
        self._precondition(self.v, self.z)
        self._gather(1.0, self.z, self.zu)
        self._jv(self.zu, out)

    def _host_matvec(self, w):
        self.w_in.numpy()[:] = w
        self._apply(self.w_in, self.Jv)
        return self.Jv.numpy()  # scipy copies it into its basis before the next product overwrites it

    def _device_matvec(self, x, y, z, alpha, beta):
        self._apply(x, self.Jv)
        wp.launch(blas.axpby1d, x.shape[0], [f64(alpha), self.Jv, f64(beta), y, z], device=self.model.device)

    def _gmres(self, eta) -> int:
        """Solve J P⁻¹ w = −R (on unique nodes) to relative tolerance eta; delta = P⁻¹ w. Returns iterations."""
        o = self.o
        self._gather(-1.0, self.R, self.minus_R)
        if self.krylov == "scipy":
            count = [0]
            w, info = spla.gmres(
                self.op, self.minus_R.numpy(), rtol=eta, atol=0.0, restart=o["gmres_restart"],
                maxiter=max(1, o["gmres_maxiter"] // o["gmres_restart"]), callback=lambda _: count.__setitem__(0, count[0] + 1),
                callback_type="pr_norm",
            )
            self.w.numpy()[:] = w
            iterations = count[0]
        else:
            self.w.zero_()
            self.gmres._tol = eta  # the functor reads its tolerance at each run; no setter exists
            iterations, _, _ = self.gmres()
            iterations = int(iterations)
        if self.o["preconditioner"] == "none":
            self._scatter(self.w, self.delta)
        else:
            self._scatter(self.w, self.v)
            self._precondition(self.v, self.delta)
        return iterations

    # -- Newton ------------------------------------------------------------------------
    def _eta(self, k, rnorm, rprev, eta_prev):
        """Eisenstat–Walker (1996) choice 2 forcing term, safeguarded."""
        gamma, alpha, o = 0.9, 2.0, self.o
        if k == 0:
            eta = 0.1
        else:
            eta = gamma * (rnorm / rprev) ** alpha
            safe = gamma * eta_prev**alpha
            if safe > 0.1:
                eta = max(eta, safe)
        eta = min(eta, 0.9)
        eta = max(eta, 0.5 * o["atol"] / max(rnorm, 1e-300))  # do not oversolve the last iteration
        return max(eta, o["gmres_tol"])

    def _newton(self, x, Fx_known=False):
        """Solve R(x) = 0 in place from the initial guess in x (F(x) already in Fx if Fx_known)."""
        o = self.o
        self.x = x
        if not Fx_known:
            self._F(x, self.Fx)
        self._residual(x, self.Fx, self.R)
        rnorm = r0 = self._rms(self.R)
        history = [rnorm]
        newton = gmres = 0
        eta = rprev = None
        while not (rnorm <= o["atol"] or rnorm <= o["rtol"] * r0):
            if newton == o["maxiter"]:
                raise StepFailure(f"Newton did not converge in {newton} iterations (residual RMS {rnorm:.3e} > {o['atol']:.1e})")
            if not math.isfinite(rnorm):
                raise StepFailure("Newton residual is not finite")
            eta = self._eta(newton, rnorm, rprev, eta)
            self._gather(1.0, x, self.xu)
            self.xnorm = self._norm(self.xu)
            gmres += self._gmres(eta)
            lam = 1.0
            for _ in range(9):
                self._axpby(1.0, x, lam, self.delta, self.trial)
                self._F(self.trial, self.Ft)
                self._residual(self.trial, self.Ft, self.Rt)
                trial_norm = self._rms(self.Rt)
                if trial_norm <= (1.0 - 1e-4 * lam) * rnorm:
                    break
                lam *= 0.5
            else:
                raise StepFailure(f"Newton line search failed (residual RMS {rnorm:.3e})")
            wp.copy(x, self.trial)
            self.Fx, self.Ft = self.Ft, self.Fx
            self.R, self.Rt = self.Rt, self.R
            rprev, rnorm = rnorm, trial_norm
            history.append(rnorm)
            newton += 1
        self.residual_history = history
        return newton, gmres

    def state(self):
        s = super().state()
        if self.o["preconditioner"] == "helmholtz":
            s["mean_depth"] = self.H  # 0 until fixed by the first step
        if self.o["method"] == "bdf2" and self.steps:
            s["previous"] = self._save(self.xprev)
        return s

    def restore(self, state):
        super().restore(state)
        if self.o["preconditioner"] == "helmholtz":
            self.H = float(self._entry(state, "mean_depth"))
        if self.o["method"] == "bdf2" and self.steps:
            self._load(self.xprev, state, "previous")

    def advance(self, x):
        o, m = self.o, self.model
        self.rhs_evals, self._cg_its = 0, 0
        if self.H == 0.0 and o["preconditioner"] == "helmholtz":
            self.H = m.topology.mean(x.numpy()[2])  # mean depth
        wp.copy(self.xn, x)
        if o["method"] == "bdf2" and self.steps > 0:
            self.beta = 2.0 / 3.0
            self._axpby(4.0 / 3.0, x, -1.0 / 3.0, self.xprev, self.b)
        elif o["method"] == "bdf2":
            self.beta = 1.0  # backward Euler start
            wp.copy(self.b, x)
        else:
            self.beta = o["theta"]
            self._F(x, self.Fx)  # F(x(n)): the explicit part and Newton's first F
            self._axpby(1.0, x, self.dt * (1.0 - o["theta"]), self.Fx, self.b)
        newton, gmres = self._newton(x, Fx_known=o["method"] == "theta")
        wp.copy(self.xprev, self.xn)
        m.hyperviscosity(x, self.dt)
        return StepStats(self.rhs_evals, {"newton": newton, "gmres": gmres, "cg": self._cg_its})
