"""Fully implicit Jacobian-free Newton–Krylov stepper (Evans, Taylor & Drake 2010, Mon. Wea.
Rev. 138, 3333; HOMME ``implicit_mod`` / ``residual``): the θ-method and BDF2 by Newton with
flexible GMRES on finite-difference Jacobian-vector products, preconditioned by the Helmholtz
solve of the gravity-wave block (``Implicit``, whose docstring gives the residual, the Newton
iteration, the preconditioner and the options), and its ``ImplicitOptions``.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from functools import partial

import warp as wp

from ..core.errors import StepFailure
from ..kernels import blas
from ..kernels import implicit as ik
from ..model.gravity_wave import check_mean_depth
from ..model.helmholtz import HelmholtzOptions, check_precision
from ..solvers.jacobian import FLOAT32_REFUSAL, FiniteDifferenceJacobian, KernelPasses
from ..solvers.krylov import FGMRES, KernelVectors
from .base import Stepper, StepStats, entry, gathered_copy, load_entry
from .capabilities import ErrorEstimates, TrialSteps
from .helmholtz_steps import REMOVED_SOLVER_OPTIONS

f64 = wp.float64


@dataclass(frozen=True)
class ImplicitOptions:
    """Scene table ``[implicit]`` (see ``Implicit``)."""

    method: str = "theta"
    theta: float = 0.5
    atol: float = 1e-8
    rtol: float = 0.0
    maxiter: int = 30
    gmres_tol: float = 1e-11
    gmres_restart: int = 30
    gmres_maxiter: int = 300
    preconditioner: str = "helmholtz"
    helmholtz_tol: float = 1e-2
    mean_depth: float = 0.0
    initial_guess: str = "extrapolate"
    precision: str = "float64"

    def __post_init__(self):
        object.__setattr__(self, "precision", check_precision(self.precision))  # frozen: the word as new
        if self.method not in ("theta", "bdf2"):
            raise ValueError(f"method must be 'theta' or 'bdf2' (got {self.method!r})")
        if not 0.5 <= self.theta <= 1.0:
            raise ValueError(f"theta must be in [0.5, 1] (got {self.theta})")
        if self.atol < 0 or self.rtol < 0 or (self.atol == 0 and self.rtol == 0):
            raise ValueError(f"atol and rtol must be >= 0, one of them > 0 (got {self.atol}, {self.rtol})")
        for name in ("maxiter", "gmres_restart", "gmres_maxiter"):
            if getattr(self, name) < 1:
                raise ValueError(f"{name} must be >= 1 (got {getattr(self, name)})")
        for name in ("gmres_tol", "helmholtz_tol"):
            if not 0 < getattr(self, name) < 1:
                raise ValueError(f"{name} must be in (0, 1) (got {getattr(self, name)})")
        if self.preconditioner not in ("none", "helmholtz"):
            raise ValueError(f"preconditioner must be 'none' or 'helmholtz' (got {self.preconditioner!r})")
        check_mean_depth(self.mean_depth)
        if self.initial_guess not in ("extrapolate", "previous"):
            raise ValueError(f"initial_guess must be 'extrapolate' or 'previous' (got {self.initial_guess!r})")


class Implicit(ErrorEstimates, TrialSteps, Stepper):
    """Fully implicit θ-method / BDF2 stepper by Jacobian-free Newton–Krylov.

    Each step solves R(x) = 0 on the DSS'd state, with F the model's DSS'd RHS:

      θ-method (``method = "theta"``; θ = 0.5 Crank–Nicolson, 1 backward Euler):
          R(x) = (x − x(n))/Δt − θ F(x) − (1−θ) F(x(n))
      BDF2 (``method = "bdf2"``; backward Euler on the first step):
          R(x) = (x − 4/3 x(n) + 1/3 x(n−1))/Δt − 2/3 F(x)

    both written R(x) = (x − b)/Δt − β F(x) with b fixed during the step. (HOMME
    multiplies by the mass matrix M; F here is already M⁻¹-weighted by the DSS.)

    Newton: δ from J δ = −R by right-preconditioned flexible GMRES
    (``krylov.FGMRES``, on Warp arrays: the same code on CPU threads, CUDA and MPI
    ranks; flexible because the preconditioner's inexact inner solve changes it
    from one iteration to the next), with J v a forward difference of F, ε = sqrt(ε_mach)(1 + ‖x‖)/‖v‖
    (``jacobian.FiniteDifferenceJacobian``); forcing
    terms by Eisenstat & Walker (1996) choice 2 (γ = 0.9, α = 2, safeguarded,
    η ≤ 0.9, η ≥ ``gmres_tol``); a backtracking line search (Armijo, halving up
    to 8 times) when the residual does not fall. Converged when the RMS of R is
    ≤ ``atol`` or ≤ ``rtol`` × its first value; at most ``maxiter`` (30)
    iterations, else the step fails (``StepFailure``). Newton starts from the
    extrapolation 2x(n) − x(n−1) (``initial_guess``; x(n) on the first step).

    Preconditioner (``preconditioner = "helmholtz"``, the default; Lott, Woodward
    & Evans 2015): the linearised gravity-wave block P = I/Δt − β L
    (L_v = −g∇h, L_h = −H∇·v, ``model.gravity_wave.GravityWaveOperator``), P⁻¹ = Δt (I − βΔt L)⁻¹
    through its Schur complement, the Helmholtz equation solved by the compiled
    mass-preconditioned CG to ``helmholtz_tol`` (1e-2: an inexact, varying inner
    solve, which flexible GMRES allows).

    Hyperviscosity is applied after the step, split from the implicit dynamics
    (forward Euler over Δt, subcycled as needed), as for the other steppers: inside
    the residual its ∇⁴ spectrum would dominate the Newton–Krylov iteration for
    a term that only damps the grid scale.

    Options (scene table ``[implicit]``): ``method`` ("theta" | "bdf2"),
    ``theta`` (0.5), ``atol`` (1e-8),
    ``rtol`` (0: off), ``maxiter`` (30), ``gmres_tol`` (1e-11, the floor of
    the forcing term), ``gmres_restart`` (30), ``gmres_maxiter`` (300 inner
    iterations), ``preconditioner`` ("helmholtz" | "none"), ``helmholtz_tol``
    (1e-2, the relative tolerance of the preconditioner's Helmholtz CG), ``mean_depth`` (H, m;
    0 = initial mean), ``initial_guess`` ("extrapolate": 2x(n) − x(n−1)
    after the first step, "previous": x(n)), ``precision`` ("float64" |
    "float32": the preconditioner's Helmholtz CG in float32 (the old "double" and "mixed" deprecated), one solve to
    ``helmholtz_tol``, no refinement).
    Under error control (``[time] control = "error"``; Crank–Nicolson, θ = 0.5, alone) each step
    also gives an ``error_estimate`` of its local error before the ∇⁴, the trapezoidal rule's
    against its second-order Adams–Bashforth predictor with variable steps (Gresho, Lee & Sani
    1980; Kay, Gresho, Griffiths & Silvester 2010, SIAM J. Sci. Comput. 32:111, eqs. 2.6–2.8):
    x_p = x(n) + Δt/2 ((2 + r) F(x(n)) − r F(x(n−1))), r = Δt/Δt_old, which is also Newton's
    first guess, and e = r (x − x_p) / (3 (1 + r)) (Milne's device: TR's error constant −1/12,
    AB2's 5/12 at r = 1). The first step has no F(x(n−1)): Heun's explicit trapezoidal rule
    predicts (one RHS more), and e = (x − x_p) / 3 (TR's −1/12 against Heun's 1/6 on a linear
    problem), of TR's order as after it (forward Euler's e = x − x_p, of second order, shrank
    the first step linearly in Δt, and under ``per_unit_step`` below dt_min). ``Courant`` limits
    none: the estimate alone sets Δt, through the gravity waves' phase error too.
    Reports Newton and GMRES iterations, preconditioner applications
    (``precond``) and their Helmholtz iterations per step; keeps the last
    step's residual history in ``residual_history``. Why these defaults: docs/explanation/defaults.md,
    "Defaults and why".
    """

    name = "implicit"
    Options = ImplicitOptions
    variable_dt = True  # the θ-method: its residual, Jacobian and preconditioner read Δt each call
    order = embedded_order = 2  # Crank–Nicolson, and the estimate's (TR against AB2)
    solvers = ("newton", "gmres", "precond", "helmholtz")
    float32_refusal = FLOAT32_REFUSAL
    removed_options = {
        **REMOVED_SOLVER_OPTIONS,
        "chebyshev_degree": REMOVED_SOLVER_OPTIONS["helmholtz_solver"],
        "krylov": "one flexible GMRES on Warp arrays runs on every device and rank count",
    }

    def __init__(self, model, dt, options=None):
        super().__init__(model, dt, options)
        o = self.o = dataclasses.asdict(self.options)
        dev, N = model.topology.device, self.N
        self.helmholtz = None
        if o["preconditioner"] == "helmholtz":  # a loose solve from zero each time
            solve = HelmholtzOptions(o["helmholtz_tol"], 1000, o["mean_depth"], o["precision"], guess_history=0)
            self.helmholtz = model.implicit_inverse(solve)
        for name in ("xn", "xprev", "b", "Fx", "R", "delta", "trial", "Ft", "Rt", "v", "z"):
            setattr(self, name, wp.zeros((3, N), dtype=f64, device=dev))
        self._spares: dict[str, wp.array] = {}  # what ``checkpoint`` copies into (``_saved``)
        # Krylov vectors live on unique nodes; the J·v's RHS evaluations are counted by the GMRES
        # iterations (one each), as a captured cycle runs no Python
        self.jacobian = FiniteDifferenceJacobian(model, model.rhs)
        self.topology = topo = model.topology
        self.nu = topo.nunique
        n3 = 3 * self.nu
        for name in ("w", "minus_R", "xu"):
            setattr(self, name, wp.zeros(n3, dtype=f64, device=dev))
        self.residual_history: list[float] = []
        self.variable_dt = o["method"] == "theta"  # BDF2's x(n−1) is its Δt's
        self.error_estimate = None  # made by ``estimate_errors`` under error control
        self._counts = dict.fromkeys(("gmres", "precond", "helmholtz"), 0)
        self.fgmres = FGMRES(n3, o["gmres_restart"], topo)

    @classmethod
    def changes_dt(cls, options: dict) -> bool:
        """The θ-method can (BDF2's x(n−1) is its Δt's)."""
        return options.get("method", "theta") == "theta"

    @classmethod
    def has_estimate(cls, options: dict) -> bool:
        """Crank–Nicolson (θ = 0.5) gives the TR–AB2 estimate (the class docstring)."""
        return cls.changes_dt(options) and options.get("theta", 0.5) == 0.5

    def estimate_errors(self) -> None:
        """Under error control: estimate each step's error (TR against AB2: F(x(n)) kept for
        the next step's predictor, which is also Newton's first guess)."""
        if self.has_estimate(self.o) and self.error_estimate is None:
            dev, N = self.model.topology.device, self.N
            self.error_estimate = wp.zeros((3, N), dtype=f64, device=dev)
            self.Fn, self.Fprev, self.xp = (wp.zeros((3, N), dtype=f64, device=dev) for _ in range(3))
            self.dt_old = math.nan  # no F(x(n−1)) yet

    # -- vector helpers ----------------------------------------------------------
    def _norm(self, a) -> float:
        """Euclidean norm of an array (3, N) or (3·nunique,)."""
        return self.topology.norm(a)

    def _rms(self, a) -> float:
        """RMS over the element-local nodes of the whole grid of a (3, N) array."""
        return self._norm(a) / math.sqrt(3 * self.topology.nnodes_total)

    def _axpby(self, a, x, b, y, out):
        self.model.pointwise(blas.axpby, f64(a), x, f64(b), y, out)

    def _F(self, x, out):
        self.model.rhs(x, out)
        self.rhs_evals += 1

    def _residual(self, x, F, R):
        self.model.pointwise(ik.residual, x, self.b, F, f64(1.0 / self.dt), f64(self.beta), R)

    # -- the linear operator: J P⁻¹ ----------------------------------------------
    def _precondition(self, r, z):
        """z = P⁻¹ r = Δt (I − βΔt L)⁻¹ r (element-local states; see the module docstring)."""
        self.helmholtz.solve(r, self.beta * self.dt, z, scale=self.dt)  # its iterations read after the GMRES solve
        self._counts["precond"] += 1

    def _scatter(self, u, out):
        self.jacobian.scatter(u, out)

    def _gather(self, a, v, out):
        self.jacobian.gather(a, v, out)

    def jacobian_product(self, w, out) -> None:
        """out = J w = w/Δt − β F'(x) w, Newton's Jacobian of the residual R (the class
        docstring) applied to w about the current iterate ``x`` (with its ``Fx`` = F(x) and
        ``xnorm``): one RHS evaluation, a forward difference (``jacobian.FiniteDifferenceJacobian``).
        w, out: unique-node vectors (3·nunique,), row r of node g at r·nunique + g (wind in
        m s⁻¹, depth in m; out in those units per s); out must not alias w. GMRES's product."""
        self.jacobian.apply(self.x, self.Fx, self.xnorm, w, out, 1.0 / self.dt, -self.beta)

    def _unique_precondition(self, w, out):
        """out = P⁻¹ w on unique-node vectors (out = w without a preconditioner)."""
        if self.helmholtz is None:
            wp.copy(out, w)
            return
        self._scatter(w, self.v)
        self._precondition(self.v, self.z)
        self._gather(1.0, self.z, out)

    def _cycle_key(self):
        """The key under which FGMRES captures a restart cycle as one graph (``FGMRES.solve``),
        or None where it cannot: a cycle is captured with the Warp-kernel backends
        (``KernelVectors``, ``KernelPasses``: CUDA's) on one rank, on CUDA with conditional
        graph nodes (driver ≥ 12.4) or one CPU thread, without a time-dependent forcing (its time a launch argument) and without the
        Helmholtz preconditioner (its CG reads its inner products back). Its launches
        depend on the backends, the iterate and F(x) arrays (Fx alternates), Δt and β."""
        m, topo = self.model, self.topology
        if (
            self.helmholtz is not None
            or "forcing" in m.terms
            or topo.distributed
            or not m.launches.guard.enabled
            or not isinstance(self.fgmres.vectors, KernelVectors)
            or not isinstance(self.jacobian.passes, KernelPasses)
            or not topo.backend.solver_graphs(m.launches.threads)
        ):
            return None
        return (id(self.fgmres.vectors), id(self.jacobian.passes), self.x.ptr, self.Fx.ptr, self.dt, self.beta)

    def _gmres(self, eta) -> None:
        """Solve J δ = −R (on unique nodes) to relative tolerance eta by right-preconditioned
        flexible GMRES; δ into ``delta``. Each iteration one J·v (one RHS)."""
        self._gather(-1.0, self.R, self.minus_R)
        its, _ = self.fgmres.solve(
            self.jacobian_product,
            self._unique_precondition,
            self.minus_R,
            self.w,
            eta,
            self.o["gmres_maxiter"],
            graph_key=self._cycle_key(),
            guard=self.model.launches.guard,
        )
        self.rhs_evals += its
        self._counts["gmres"] += its
        if self.helmholtz is not None:
            self._counts["helmholtz"] += self.helmholtz.iterations()  # and a failed preconditioner solve raised
        self._scatter(self.w, self.delta)

    # -- Newton ------------------------------------------------------------------------
    def forcing_term(self, k: int, rnorm: float, rprev: float | None, eta_prev: float | None) -> float:
        """The relative tolerance η of Newton iteration k's GMRES solve: Eisenstat & Walker's
        (1996, SIAM J. Sci. Comput. 17, 16) choice 2, γ (‖R_k‖/‖R_{k−1}‖)^α with γ = 0.9,
        α = 2 (0.1 for k = 0), safeguarded by γ η_{k−1}^α above 0.1, at most 0.9, at least
        ``gmres_tol`` and 0.5 ``atol``/‖R_k‖ (no oversolving). rnorm, rprev: the residual
        RMS of this and the last iterate (None for k = 0); eta_prev the last η."""
        gamma, alpha, o = 0.9, 2.0, self.o
        if k == 0:
            eta = 0.1
        else:
            eta = gamma * (rnorm / rprev) ** alpha
            safe = gamma * eta_prev**alpha
            if safe > 0.1:
                eta = max(eta, safe)
        eta = min(eta, 0.9)
        eta = max(eta, 0.5 * self._atol() / max(rnorm, 1e-300))  # do not oversolve the last iteration
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
        newton = 0
        eta = rprev = None
        while not (rnorm <= self._atol() or rnorm <= o["rtol"] * r0):
            if newton == o["maxiter"]:
                raise StepFailure(
                    f"Newton did not converge in {newton} iterations (residual RMS {rnorm:.3e} > {o['atol']:.1e})"
                )
            if not math.isfinite(rnorm):
                raise StepFailure("Newton residual is not finite")
            eta = self.forcing_term(newton, rnorm, rprev, eta)
            self._gather(1.0, x, self.xu)
            self.xnorm = self.jacobian.point_norm(self.xu)  # on the device with KernelPasses
            self._gmres(eta)
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
        return newton

    # -- the error estimate (under error control) -------------------------------------------
    def follow_tolerance(self, atol: float, rtol: float = 0.0, per_unit_step: bool = False) -> None:
        """Under error control with absolute tolerances ≥ ``atol`` (m s⁻¹, m): Newton converges
        to a residual RMS of at most 0.1 atol / Δt, a state error of about a tenth of the
        tolerance a step (SUNDIALS' nonlinear-solver coefficient 0.1), so that its own error stays
        below the step's; ``atol`` (1e-8 s⁻¹ in those units) still bounds it. The same per unit
        step: 0.1 atol / 1 day, a tenth of a step's share, doubled Newton's iterations (TC5 ne4,
        a day at a day's rtol 1e-4: 7222 against 3703) and moved h by 2e-5 m, where the
        tolerances apart moved it by 0.5 m (1e-3 against 1e-4)."""
        self.newton_atol = 0.1 * float(atol)

    def _atol(self) -> float:
        """Newton's absolute tolerance on the residual RMS this step (``follow_tolerance``)."""
        scaled = getattr(self, "newton_atol", None)
        return self.o["atol"] if scaled is None else min(self.o["atol"], scaled / self.dt)

    def _predict(self, x) -> None:
        """x = x_p from x(n) = ``xn`` and F(x(n)) = ``Fx``: AB2, or on the first step Heun's
        x(n) + Δt/2 (F(x(n)) + F(x(n) + Δt F(x(n)))) (its F at t(n+1) into ``Fprev``, free until
        ``_estimate``). F(x(n)) is kept by taking its buffer (Newton evaluates F at x_p into the
        other first)."""
        self.Fn, self.Fx = self.Fx, self.Fn
        dt = self.dt
        if math.isfinite(self.dt_old):
            r = dt / self.dt_old
            self._axpby(1.0, self.xn, 0.5 * dt * (2.0 + r), self.Fn, self.xp)
            self._axpby(1.0, self.xp, -0.5 * dt * r, self.Fprev, self.xp)
        else:
            self._axpby(1.0, self.xn, dt, self.Fn, self.xp)
            self._at(1.0)
            self._F(self.xp, self.Fprev)
            self._axpby(1.0, self.xn, 0.5 * dt, self.Fn, self.xp)
            self._axpby(1.0, self.xp, 0.5 * dt, self.Fprev, self.xp)
        wp.copy(x, self.xp)

    def _estimate(self, x) -> None:
        """``error_estimate`` = r (x − x_p) / (3 (1 + r)) (first step: (x − x_p) / 3); F(x(n)) kept."""
        r = self.dt / self.dt_old if math.isfinite(self.dt_old) else None
        c = 1.0 / 3.0 if r is None else r / (3.0 * (1.0 + r))
        self._axpby(c, x, -c, self.xp, self.error_estimate)
        self.Fn, self.Fprev = self.Fprev, self.Fn
        self.dt_old = self.dt

    # -- what carries over between steps ------------------------------------------------
    def _uses_previous(self) -> bool:
        """Whether the next step reads x(n−1): BDF2, or the extrapolated initial guess."""
        return self.steps > 0 and (self.o["method"] == "bdf2" or self.o["initial_guess"] == "extrapolate")

    def state(self):
        s = super().state()
        if self.helmholtz is not None:
            s["mean_depth"] = self.helmholtz.H  # 0 until fixed by the first step
        if self._uses_previous():
            s["previous"] = gathered_copy(self, self.xprev)
        if self.error_estimate is not None and math.isfinite(self.dt_old):  # the AB2 predictor's
            s["rhs_previous"], s["dt_previous"] = gathered_copy(self, self.Fprev), self.dt_old
        return s

    def restore(self, state):
        super().restore(state)
        if self.helmholtz is not None:
            self.helmholtz.restore(state, partial(entry, self))
        if self._uses_previous():
            load_entry(self, self.xprev, state, "previous")
        if self.error_estimate is not None:
            self.dt_old = math.nan
            if "dt_previous" in state:
                load_entry(self, self.Fprev, state, "rhs_previous")
                self.dt_old = float(state["dt_previous"])

    def checkpoint(self):
        # what ``state`` saves, as device copies: not gathered to the host every try (0.5 ms a
        # step at ne16, 4 %)
        saved = {"base": super().state()}
        if self.helmholtz is not None:
            saved["mean_depth"] = self.helmholtz.H
        if self._uses_previous():
            saved["previous"] = self._saved("previous", self.xprev)
        if self.error_estimate is not None and math.isfinite(self.dt_old):
            saved["rhs_previous"], saved["dt_old"] = self._saved("rhs_previous", self.Fprev), self.dt_old
        return saved

    def _saved(self, name: str, a: wp.array) -> wp.array:
        """a copied into the checkpoint's array ``name``, made once (one checkpoint is open at a time)."""
        if name not in self._spares:
            self._spares[name] = wp.empty_like(a)
        wp.copy(self._spares[name], a)
        return self._spares[name]

    def rollback(self, saved):
        super().restore(saved["base"])
        if self.helmholtz is not None:
            self.helmholtz.operator.H = saved["mean_depth"]
        if "previous" in saved:
            wp.copy(self.xprev, saved["previous"])
        if self.error_estimate is not None:
            self.dt_old = saved.get("dt_old", math.nan)
            if "rhs_previous" in saved:
                wp.copy(self.Fprev, saved["rhs_previous"])

    def advance(self, x):
        o, m = self.o, self.model
        self.rhs_evals = 0
        self._counts = dict.fromkeys(self._counts, 0)
        if self.helmholtz is not None:
            self.helmholtz.operator.set_depth(x)
        wp.copy(self.xn, x)
        if o["method"] == "bdf2" and self.steps > 0:
            self.beta = 2.0 / 3.0
            self._axpby(4.0 / 3.0, x, -1.0 / 3.0, self.xprev, self.b)
        elif o["method"] == "bdf2":
            self.beta = 1.0  # backward Euler start
            wp.copy(self.b, x)
        else:
            self.beta = o["theta"]
            self._at(0.0)
            self._F(x, self.Fx)  # F(x(n)): the explicit part and, without extrapolation, Newton's first F
            self._axpby(1.0, x, self.dt * (1.0 - o["theta"]), self.Fx, self.b)
        estimating = self.error_estimate is not None
        extrapolate = o["initial_guess"] == "extrapolate" and self.steps > 0 and not estimating
        if estimating:  # the predictor x_p, Newton's first guess
            self._predict(x)
        self._at(1.0)  # every F in the residual is at t(n+1)
        if extrapolate:
            self._axpby(2.0, self.xn, -1.0, self.xprev, x)  # 2x(n) − x(n−1)
        # F(x(n)) at t(n) is Newton's first F only if no term depends on time
        known = o["method"] == "theta" and not extrapolate and not estimating and "forcing" not in m.terms
        newton = self._newton(x, Fx_known=known)
        if estimating:
            self._estimate(x)
        wp.copy(self.xprev, self.xn)
        self._hyperviscosity(x)
        return StepStats(self.rhs_evals, {"newton": newton, **self._counts})
