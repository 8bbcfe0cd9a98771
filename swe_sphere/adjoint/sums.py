"""What every step's adjoint (``reverse.TapeAdjoint``) works in and sums: the mass form of the
adjoints, the model's transposes it holds, and the parameters' gradients.

Adjoints are carried as the continuous fields μ = R Q λ (λ the element-local adjoint: ∂J/∂x
over every copy; Q the sum over a node's copies, R the inverse assembled mass rspheremp): the
gradient in the mass inner product, δJ = Σ spheremp · μ · δx over the element-local nodes for a
continuous δx. F = M⁻¹ Q W T(x) (T the element-local tendency, W the element mass spheremp,
M⁻¹ = R). In that form
- the DSS's transpose is λ_T = W μ_K (R and Q commute, R being continuous);
- the ∇⁴ is its own transpose, R Q Bᵀ = B R Q (the tensor ∇⁴'s with its Laplacians swapped,
  the ∇δ term's added apart): the model's ``model.transposes.HyperviscosityTranspose``;
- T's transpose is the model's (``model.transposes.TendencyTranspose``, the kernels
  ``kernels.tendency_adjoint``), whose λ is gathered back by the unweighted DSS, μ = R Q λ.
The parameters (``parameters=True``): ∂J/∂ν, ∂J/∂ν_s and the ∇⁴'s share of ∂J/∂hs summed by
the ∇⁴'s transpose (``HyperviscosityTranspose.transpose``), plus the forcing −g∇hs's share of
∂J/∂hs, the pressure gradient's transpose of Σ λ over the F evaluations (``fbar``).
F is linear in g (its pressure gradient and topography, −g∇(h + hs)) and in Ω (the Coriolis
term f (v, −u), f ∝ Ω), so with k̄ the adjoint of an F(Y) (continuous, as μ),
g ∂J/∂g = Σ ⟨k̄, F_g(Y)⟩ and Ω ∂J/∂Ω = Σ ⟨k̄, f (v, −u)⟩ over the evaluations (``d_planet``),
F_g the model's RHS of those two terms alone; x(0), hs and a case's forcing held fixed.
Checked by dot-product tests of each piece and Taylor tests of the whole (``tests/adjoint``).
"""

from __future__ import annotations

import numpy as np
import warp as wp

from ..core.errors import ArgumentError
from ..model.shallow_water import ShallowWater

f64 = wp.float64


# the tapes whose reverses an adjoint keeps recorded (``reverse.TapeAdjoint``): a controlled run
# takes its Δt from a grid of 16 an octave (``simulation.adaptive.DT_GRID``), so few recur at once
HELD_DTS = 8


def refusal(model: ShallowWater, dt: float) -> str | None:
    """Why the adjoint cannot serve ``model`` at step dt (None: it can)."""
    if model.hv is not None:
        if model.hv.nu_div != model.hv.nu and model.hv.nu == 0:
            return "nu_div != nu with nu = 0 has no adjoint yet (its ∇δ term's transpose reads the ν-scaled pass)"
    return None


class Transposes:
    """What every step's adjoint holds and sums beside its own reverse (``reverse.TapeAdjoint``):
    the tendency's transposes, the parameters' sums (``d_nu``, ``d_planet``, ``d_hs``,
    ``hs_gradient``; module doc)."""

    def _setup(self, model: ShallowWater, dt: float, parameters: bool, t0: float) -> None:
        """What every step's adjoint holds (``refusal`` checked): the transposes' x̄ and f̄, the
        parameters' sums and the ∇⁴'s substeps."""
        why = refusal(model, dt)
        if why is not None:
            raise ArgumentError(why)
        self.model, self.dt, self.parameters, self.t0 = model, float(dt), bool(parameters), float(t0)
        m, N, device = model, model.topology.N, model.topology.device

        def zeros(rows):
            return wp.zeros((rows, N), dtype=f64, device=device)

        self.tendency = m.operators.tendency_transpose(m.terms, m.g)  # Fᵀ: ``transpose``'s launches
        # the terms F holds, the x̄ its transposes write, f̄ = Σ λ's wind rows (the forcing −g∇hs's adjoint)
        self.terms, self.xbar, self.fbar = self.tendency.terms, self.tendency.xbar, self.tendency.fbar
        self.d_nu = np.zeros(2)  # ∂J/∂ν (wind rows), ∂J/∂ν_s (h row), m⁻⁴ s · J
        self.d_planet = np.zeros(2)  # g ∂J/∂g, Ω ∂J/∂Ω (J): the evaluations' ⟨k̄, F's g and Ω terms⟩
        self.g_terms = tuple(t for t in ("pressure_gradient", "topography") if t in m.terms)
        self.d_hs = zeros(1)  # the ∇⁴'s share of ∂J/∂hs, continuous (mass form)
        self._zeros = zeros

    def planet_terms(self, Y, kbar, g_terms=None, coriolis: bool = True, part=None) -> None:
        """Add an F evaluation's ⟨k̄, g F_g(Y)⟩ and ⟨k̄, f (v, −u)⟩ to ``d_planet`` (module doc), Y the
        state its F read, k̄ = Σ c·a over (c, a) ``kbar`` as its transpose reads them (the same
        bits on any ranks); F_g the RHS of ``g_terms`` (None: the model's pressure gradient and
        topography), the Coriolis term's share only where its F holds it (``coriolis``); with
        ``part`` (an ``ElementPart``: F the part's f_P) both by ``rhs_part``."""
        m = self.model
        g_terms = self.g_terms if g_terms is None else tuple(t for t in g_terms if t in m.terms)
        kb, w, y = sum(c * a.numpy() for c, a in kbar), m.topology.grid.spheremp, Y.numpy()
        if not hasattr(self, "f_g"):
            self.f_g = self._zeros(3)

        def winds(terms):  # ⟨k̄, F⟩ node by node over the wind rows, F the RHS of ``terms`` at Y
            if part is None:
                m.rhs(Y, self.f_g, terms)
            else:  # f_P writes the nodes its elements touch alone
                self.f_g.zero_()
                m.rhs_part(Y, self.f_g, part, terms)
            F = self.f_g.numpy()
            return kb[0] * F[0] + kb[1] * F[1]

        pressure = winds(g_terms) if g_terms else np.zeros_like(w)
        if not hasattr(self, "fcor"):
            self.fcor = m.operators.fcor.numpy() if "coriolis" in m.terms else np.zeros_like(w)
        if not coriolis or "coriolis" not in m.terms:
            rotation = np.zeros_like(w)
        elif part is None:
            rotation = self.fcor * (kb[0] * y[1] - kb[1] * y[0])
        else:
            rotation = winds(("coriolis",))
        self.d_planet += m.topology.whole_sums([w * pressure, w * rotation])

    def hs_gradient(self) -> np.ndarray:
        """∂J/∂hs (N,) on this rank's nodes, continuous (mass form, as μ), summed over the steps reversed so far:
        the ∇⁴'s share and the forcing's (``TendencyTranspose.forcing_transpose`` of f̄)."""
        out = self.d_hs.numpy()[0]
        if not self.terms or "topography" not in self.model.terms:
            return out
        return out + self.tendency.forcing_transpose()
