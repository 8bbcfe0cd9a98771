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
  B₀ the operator without hs (the model's ∇⁴ launches recorded with hs = 0);
- T's transpose is ``kernels.tendency_adjoint`` (written by hand: two gathers a stage), whose
  λ is gathered back by the unweighted DSS, μ = R Q λ.
The parameters (``parameters=True``): the ∇⁴ substeps x ← L x + c B₀ hs (L = I + c B₀, c ∝ ν)
give, with Δ₀ = c B₀ (Φ + hs) the first substep's increment and μ₁ the adjoint before the
last substep's transpose, ∂J/∂ν = S ⟨μ₁, Δ₀⟩ / ν over S substeps (L commutes with itself:
⟨L^(S−1−k) μ_S, L^k Δ₀⟩ is the same for every k), the wind rows for ν (= ν_div) and the h row
for ν_s; and ∂J/∂hs = (μ after − μ before the ∇⁴'s transpose)[h] (Σ_k c B₀ μ_(k+1) telescopes),
plus the forcing −g∇hs's share, the pressure gradient's transpose of Σ λ over the stages.
Checked by dot-product tests of each piece and a Taylor test of the whole (``tests/adjoint``).
The forward states are the model's own stepper's; the stages are recomputed here from x(n)
by the table's Butcher form (the same to round-off as the stepper's combinations).
"""

from __future__ import annotations

import numpy as np
import warp as wp

from ..kernels import tendencies, tendency_adjoint
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
    adjoint μ of x(n+1) to that of x(n) in place, x = x(n). With ``parameters``, ``reverse``
    also sums ∂J/∂ν, ∂J/∂ν_s (``d_nu``) and the hs adjoint (``d_hs``, ``hs_gradient``) over
    the steps reversed. One rank, CPU or CUDA. ValueError (``_refusal``) for a model it
    cannot serve."""

    def __init__(self, model: ShallowWater, table, dt: float, parameters: bool = False):
        why = _refusal(model, dt)
        if why is not None:
            raise ValueError(why)
        self.model, self.dt, self.parameters = model, float(dt), bool(parameters)
        self.A = [[float(a) for a in row] for row in table.A_E]
        self.b = [float(b) for b in table.b_E]
        m, N, device = model, model.N, model.device

        def zeros(rows):
            return wp.zeros((rows, N), dtype=f64, device=device)

        s = len(self.b)
        self.Y, self.K, self.Ybar = ([zeros(3) for _ in range(s)] for _ in range(3))
        self.kbar, self.x, self.xbar, self.adj = zeros(3), zeros(3), zeros(3), zeros(5)
        self.fbar = zeros(2)  # Σ λ's wind rows: the adjoint of the forcing −g∇hs
        self.spheremp = wp.array(m.grid.spheremp, dtype=f64, device=device)
        self._combinations: dict[tuple, list] = {}  # ``combine``'s recorded launches
        terms = tuple(t for t in tendencies.TENDENCY_TERMS if t in m.terms)
        self.transposes = [self._transpose(terms, Y, Ybar) for Y, Ybar in zip(self.Y, self.Ybar)] if terms else None
        self.d_nu = np.zeros(2)  # ∂J/∂ν (wind rows), ∂J/∂ν_s (h row), m⁻⁴ s · J
        self.d_hs = zeros(1)  # the ∇⁴'s share of ∂J/∂hs, continuous (mass form)
        self.substeps = 0  # of the ∇⁴ (forward Euler)
        self._hv: dict[int, list] = {}  # ``substep``'s recorded launches, by array
        if m.hv is not None and m.hv.nu_max > 0:
            self.substeps = m.hv.plan(self.dt)[0]
            self.zero_hs = wp.zeros(N, dtype=f64, device=device)
            self.phi, self.delta = zeros(3), zeros(3)

    def _transpose(self, terms, Y, Ybar) -> list:
        """The recorded launches of Ybar = R Q Tᵀ(Y) W kbar (``kernels.tendency_adjoint``)."""
        m, np_ = self.model, self.model.grid.np
        point = [Y, m.D, m.Dinv, m.metdet, m.fcor, self.spheremp, m.dvv, self.kbar, self.adj, self.xbar, self.fbar]
        gather = [Y, m.D, m.Dinv, m.metdet, m.dvv, m.g, self.adj, self.xbar]
        return [
            m.launches.nodes(tendency_adjoint.point(terms, np_), m.N, point),
            m.launches.nodes(tendency_adjoint.gather(terms, np_), m.N, gather),
            *m.topology.dss(self.xbar, False, Ybar),
        ]

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

    def substep(self, x) -> None:
        """x ← x − (Δt/S) B₀ x in place: one ∇⁴ substep without hs (the model's launches, recorded
        once per array with the model's hs swapped for zeros, as ``biharmonic_radius`` does)."""
        launches = self._hv.get(x.ptr)
        if launches is None:
            m = self.model
            hs, m.hs = m.hs, self.zero_hs
            try:
                launches = self._hv[x.ptr] = m.hv.build(x, -self.dt / self.substeps)
            finally:
                m.hs = hs
        for launch in launches:
            launch.launch()

    def hyperviscosity_transpose(self, mu) -> None:
        """μ of the ∇⁴'s output → μ of its input Φ, in place (the ∇⁴ its own transpose); with
        ``parameters``, ∂J/∂ν, ∂J/∂ν_s and the hs adjoint of this step summed (module doc)."""
        h = self.substep
        if not self.parameters:
            for _ in range(self.substeps):
                h(mu)
            return
        m, dt = self.model, self.dt
        self.combine(self.phi, [(1.0, self.x), *((dt * b, k) for b, k in zip(self.b, self.K))])
        self.combine(self.phi[2:3], [(1.0, self.phi[2:3]), (1.0, m.hs.reshape((1, m.N)))])  # Φ + hs
        wp.copy(self.delta, self.phi)
        h(self.delta)
        self.combine(self.delta, [(1.0, self.delta), (-1.0, self.phi)])  # Δ₀
        self.combine(self.d_hs, [(1.0, self.d_hs), (-1.0, mu[2:3])])
        for _ in range(self.substeps - 1):
            h(mu)
        w = self.model.grid.spheremp * mu.numpy() * self.delta.numpy()
        rows = np.array([w[:2].sum(), w[2].sum()]) * self.substeps
        self.d_nu += np.divide(rows, [m.nu, m.nu_s], out=np.zeros(2), where=np.array([m.nu, m.nu_s]) > 0)
        h(mu)
        self.combine(self.d_hs, [(1.0, self.d_hs), (1.0, mu[2:3])])

    def hs_gradient(self) -> np.ndarray:
        """∂J/∂hs (N,), continuous (mass form, as μ), summed over the steps reversed so far:
        the ∇⁴'s share and the forcing's, R Q of the pressure gradient's transpose of f̄."""
        m, N = self.model, self.model.N
        out = self.d_hs.numpy()[0]
        if self.transposes is None or "topography" not in m.terms:
            return out
        kbar = wp.array(np.concatenate([self.fbar.numpy(), np.zeros((1, N))]), dtype=f64, device=m.device)
        ones, xbar, d = wp.ones(N, dtype=f64, device=m.device), wp.zeros_like(kbar), wp.zeros_like(kbar)
        point = [kbar, m.D, m.Dinv, m.metdet, m.fcor, ones, m.dvv, kbar, self.adj, xbar, self.fbar]
        terms = ("pressure_gradient",)  # the forcing is −g∇hs: the pressure gradient of hs
        wp.launch(tendency_adjoint.point(terms, m.grid.np), N, [*point, 0], device=m.device)
        gather = [kbar, m.D, m.Dinv, m.metdet, m.dvv, m.g, self.adj, xbar]
        wp.launch(tendency_adjoint.gather(terms, m.grid.np), N, [*gather, 0], device=m.device)
        for launch in m.topology.dss(xbar, False, d):
            launch.launch()
        return out + d.numpy()[2]

    def reverse(self, x, mu) -> None:
        """μ of x(n+1) → μ of x(n), in place; x = x(n) (read only)."""
        dt, s = self.dt, len(self.b)
        wp.copy(self.x, x)  # the stages read this object's arrays only (``combine``'s records)
        self.stages(self.x)
        if self.substeps:
            self.hyperviscosity_transpose(mu)
        for i in reversed(range(s)):
            later = [(dt * self.A[j][i], self.Ybar[j]) for j in range(i + 1, s)]
            self.combine(self.kbar, [(dt * self.b[i], mu), *later])
            if self.transposes is None:
                self.Ybar[i].zero_()
            else:
                for launch in self.transposes[i]:
                    launch.launch()
        self.combine(mu, [(1.0, mu), *((1.0, y) for y in self.Ybar)])
