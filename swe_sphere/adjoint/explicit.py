"""The adjoint of one explicit Runge–Kutta step of a ``ShallowWater`` model (its table's
stages, then the split ∇⁴), for the gradients of a run (``gradient``).

The step's map is x(n+1) = H(Φ(x(n))), Φ the table's stages
(Y_i = x + Δt Σ_j a_ij K_j, K_i = F(Y_i), Φ(x) = x + Δt Σ b_i K_i) and H the ∇⁴ substeps
x ← x + c B x. F = M⁻¹ Q W T(x): T the element-local tendency, W the element mass spheremp,
Q the sum over a node's copies, M⁻¹ = R the inverse assembled mass rspheremp (the weighted DSS).

Adjoints are carried as the continuous fields μ = R Q λ (λ the element-local adjoint: ∂J/∂x
over every copy): the gradient in the mass inner product, δJ = Σ spheremp · μ · δx over the
element-local nodes for a continuous δx. In that form
- the DSS's transpose is λ_T = W μ_K (R and Q commute, R being continuous);
- the ∇⁴ is its own transpose: R Q Bᵀ = B R Q, since B = Pᵀ R Q K̃ Π R Q K̃ P with K̃ the
  element weak Laplacian plus the mass shift (symmetric), P the (east, north) → Cartesian
  basis and Π the tangent projection, both continuous and per node, so μ ← μ + c B₀ μ with
  B₀ the operator without hs (a model of its own with hs = 0);
- T's transpose is Warp's generated adjoint of ``kernels.taped.tendency`` (``wp.Tape``),
  whose λ is gathered back by the unweighted DSS, μ = R Q λ.
Checked by dot-product tests of each piece and a Taylor test of the whole (``tests/adjoint``).
The forward states are the model's own stepper's; the stages are recomputed here from x(n)
by the table's Butcher form (the same to round-off as the stepper's combinations).
"""

from __future__ import annotations

import numpy as np
import warp as wp

from ..kernels import taped, tendencies
from ..model.shallow_water import ShallowWater

f64 = wp.float64


def _refusal(model: ShallowWater, dt: float) -> str | None:
    """Why the adjoint cannot serve ``model`` at step dt (None: it can)."""
    if model.forcing is not None:
        return "the forcing term has no adjoint yet"
    if len(model.topology.neighbours):
        return "gradients run on one rank only (MPI: not yet)"
    if model.hv is not None:
        if model.hypervis_scaling is not None:
            return "the tensor ∇⁴ (hypervis_scaling) is not self-adjoint: no adjoint yet"
        if model.nu_div != model.nu:
            return "nu_div != nu (the ∇δ term) has no adjoint yet"
        if model.hv.nu_max > 0 and model.hv.plan(dt)[1]:
            return "the RKL1 ∇⁴ super-step has no adjoint yet"
    return None


class StepAdjoint:
    """The adjoint of one step of ``model`` by the explicit table ``table`` (a
    ``steppers.butcher.Table``) at Δt = ``dt`` (s): ``reverse(x, mu)`` maps the continuous
    adjoint μ of x(n+1) to that of x(n) in place, x = x(n). One rank, CPU or CUDA.
    ValueError (``_refusal``) for a model it cannot serve."""

    def __init__(self, model: ShallowWater, table, dt: float):
        why = _refusal(model, dt)
        if why is not None:
            raise ValueError(why)
        self.model, self.dt = model, float(dt)
        self.A = [[float(a) for a in row] for row in table.A_E]
        self.b = [float(b) for b in table.b_E]
        m, N, device = model, model.N, model.device
        terms = tuple(t for t in tendencies.TENDENCY_TERMS if t in m.terms)
        self.kernel = taped.tendency(terms, m.grid.np) if terms else None
        self.forcing = m.topo_forcing if m.topo_forcing is not None else m.vec_work
        self.spheremp = wp.array(m.grid.spheremp, dtype=f64, device=device)
        s = len(self.b)
        self.Y = [wp.zeros((3, N), dtype=f64, device=device) for _ in range(s)]
        self.K = [wp.zeros((3, N), dtype=f64, device=device) for _ in range(s)]
        self.Ybar = [wp.zeros((3, N), dtype=f64, device=device) for _ in range(s)]
        self.kbar = wp.zeros((3, N), dtype=f64, device=device)
        self.x = wp.zeros((3, N), dtype=f64, device=device)  # x(n), copied in by ``reverse``
        self.lam = wp.zeros((3, N), dtype=f64, device=device)  # λ of the element-local tendency
        self._combinations: dict[tuple, list] = {}  # ``combine``'s recorded launches
        self.xt = wp.zeros((3, N), dtype=f64, device=device, requires_grad=True)
        self.tend = wp.zeros((3, N), dtype=f64, device=device, requires_grad=True)
        # the ∇⁴ without hs: B₀, the linear part the adjoint applies (see the module's doc)
        self.hv_model = None
        if m.hv is not None and m.hv.nu_max > 0:
            self.hv_model = ShallowWater(
                m.grid,
                ("hyperviscosity",),
                np.zeros(N),
                np.zeros(N),
                nu=m.nu,
                nu_div=m.nu_div,
                nu_s=m.nu_s,
                hypervis_subcycle=m.hypervis_subcycle,
                device=device,
                threads=m.threads,
                topology=m.topology,
            )

    def combine(self, out, terms) -> None:
        """out = Σ c·x over (c, x) terms, zero coefficients left out (``LaunchRecorder.lincomb``,
        four terms a pass; out may alias any x only as the first term); recorded once per
        arrays and coefficients (the arrays are this object's, held as long as it)."""
        terms = [(c, x) for c, x in terms if c != 0.0]
        if not terms:
            out.zero_()
            return
        key = (out.ptr, *((c, x.ptr) for c, x in terms))
        launches = self._combinations.get(key)
        if launches is None:
            passes = [terms[:4], *([(1.0, out), *terms[i : i + 3]] for i in range(4, len(terms), 3))]
            launches = self._combinations[key] = [self.model.lincomb(out, p) for p in passes]
        for launch in launches:
            launch.launch()

    def stages(self, x) -> None:
        """Y_i and K_i = F(Y_i) of the step from x (the Butcher form)."""
        m, dt = self.model, self.dt
        for i in range(len(self.b)):
            self.combine(self.Y[i], [(1.0, x), *((dt * a, self.K[j]) for j, a in enumerate(self.A[i][:i]))])
            m.rhs(self.Y[i], self.K[i])

    def rhs_transpose(self, Y, kbar, out) -> None:
        """out = μ of Y from μ of F(Y) = ``kbar``: R Q Tᵀ(Y) W kbar."""
        m = self.model
        wp.launch(taped.weigh, (3, m.N), [self.spheremp, kbar, self.lam], device=m.device)
        wp.copy(self.xt, Y)
        self.xt.grad.zero_()
        tape = wp.Tape()
        with tape:
            args = [self.xt, m.D, m.Dinv, m.metdet, m.fcor, self.forcing, m.dvv, m.g, self.tend]
            wp.launch(self.kernel, m.N, args, device=m.device)
        tape.backward(grads={self.tend: self.lam})
        for launch in m.topology.dss(self.xt.grad, False, out):
            launch.launch()

    def reverse(self, x, mu) -> None:
        """μ of x(n+1) → μ of x(n), in place; x = x(n) (read only)."""
        dt, s = self.dt, len(self.b)
        if self.hv_model is not None:
            self.hv_model.hyperviscosity(mu, dt)  # its own transpose: see the module's doc
        wp.copy(self.x, x)  # the stages read this object's arrays only (``combine``'s records)
        self.stages(self.x)
        for i in reversed(range(s)):
            later = [(dt * self.A[j][i], self.Ybar[j]) for j in range(i + 1, s)]
            self.combine(self.kbar, [(dt * self.b[i], mu), *later])
            if self.kernel is None:
                self.Ybar[i].zero_()
            else:
                self.rhs_transpose(self.Y[i], self.kbar, self.Ybar[i])
        self.combine(mu, [(1.0, mu), *((1.0, y) for y in self.Ybar)])
