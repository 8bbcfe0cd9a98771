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
- the ∇⁴ is its own transpose, R Q Bᵀ = B R Q (the tensor ∇⁴'s with its Laplacians swapped,
  the ∇δ term's added apart): the model's ``model.transposes.HyperviscosityTranspose``;
- T's transpose is the model's (``model.transposes.TendencyTranspose``, the kernels
  ``kernels.tendency_adjoint``), whose λ is gathered back by the unweighted DSS,
  μ = R Q λ, written straight into the running sum of the stages' adjoints (``dss_update``).
The parameters (``parameters=True``): ∂J/∂ν, ∂J/∂ν_s and the ∇⁴'s share of ∂J/∂hs summed by
the ∇⁴'s transpose (``HyperviscosityTranspose.transpose``), plus the forcing −g∇hs's share of
∂J/∂hs, the pressure gradient's transpose of Σ λ over the stages.
F is linear in g (its pressure gradient and topography, −g∇(h + hs)) and in Ω (the Coriolis
term f (v, −u), f ∝ Ω), so with k̄_i the adjoint of K_i = F(Y_i) (continuous, as μ),
g ∂J/∂g = Σ_i ⟨k̄_i, F_g(Y_i)⟩ and Ω ∂J/∂Ω = Σ_i ⟨k̄_i, f (v_i, −u_i)⟩ (``d_planet``), F_g the
model's RHS of those two terms alone; x(0), hs and a case's forcing held fixed.
Checked by dot-product tests of each piece and a Taylor test of the whole (``tests/adjoint``).
The forward states are the model's own stepper's; the stages are recomputed here from x(n)
by the table's Butcher form (the same to round-off as the stepper's combinations), each F at its
stage's time: a time-dependent forcing (TC4's) adds to F a term that does not depend on x, so
it moves the stages, not the transposes.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from ..core.errors import ArgumentError
from ..model.launches import Update
from ..model.shallow_water import ShallowWater
from ..model.transposes import Combinations

f64 = wp.float64


# the Δt whose records an adjoint keeps besides its own (``StepAdjoint.set_dt``): a controlled run
# takes its Δt from a grid of 16 an octave (``simulation.adaptive.DT_GRID``), so few recur at once
HELD_DTS = 8


def refusal(model: ShallowWater, dt: float) -> str | None:
    """Why the adjoint cannot serve ``model`` at step dt (None: it can)."""
    if model.hv is not None:
        if model.hv.nu_div != model.hv.nu and model.hv.nu == 0:
            return "nu_div != nu with nu = 0 has no adjoint yet (its ∇δ term's transpose reads the ν-scaled pass)"
    return None


class Transposes:
    """What every step's adjoint holds and sums beside its own reverse (``StepAdjoint``, the tape's
    ``reverse.TapeAdjoint`` and their kin): the tendency's and ∇⁴'s transposes, the parameters' sums
    (``d_nu``, ``d_planet``, ``d_hs``, ``hs_gradient``)."""

    def _setup(self, model: ShallowWater, dt: float, parameters: bool, t0: float) -> None:
        """What every step's adjoint holds (``refusal`` checked): the transposes' x̄ and f̄, the
        parameters' sums and the ∇⁴'s substeps."""
        why = refusal(model, dt)
        if why is not None:
            raise ArgumentError(why)
        self.model, self.dt, self.parameters, self.t0 = model, float(dt), bool(parameters), float(t0)
        m, N, device = model, model.topology.N, model.topology.device
        self._held: dict[float, dict] = {}  # another Δt's records (``set_dt``)

        def zeros(rows):
            return wp.zeros((rows, N), dtype=f64, device=device)

        self.tendency = m.operators.tendency_transpose(m.terms, m.g)  # Fᵀ: ``transpose``'s launches
        # the terms F holds, the x̄ its transposes write, f̄ = Σ λ's wind rows (the forcing −g∇hs's adjoint)
        self.terms, self.xbar, self.fbar = self.tendency.terms, self.tendency.xbar, self.tendency.fbar
        self.Ybar: list = []  # the buffers of the Ȳ_j an earlier stage's k̄ reads (``_record``)
        self.d_nu = np.zeros(2)  # ∂J/∂ν (wind rows), ∂J/∂ν_s (h row), m⁻⁴ s · J
        self.d_planet = np.zeros(2)  # g ∂J/∂g, Ω ∂J/∂Ω (J): the stages' ⟨k̄_i, F's g and Ω terms⟩
        self.g_terms = tuple(t for t in ("pressure_gradient", "topography") if t in m.terms)
        self.d_hs = zeros(1)  # the ∇⁴'s share of ∂J/∂hs, continuous (mass form)
        self.hv_transpose = None  # the ∇⁴'s transposed step (``_for_dt``), None without the ∇⁴
        self._zeros = zeros

    def planet_terms(self, Y, kbar, g_terms=None, coriolis: bool = True, part=None) -> None:
        """Add a stage's ⟨k̄, g F_g(Y)⟩ and ⟨k̄, f (v, −u)⟩ to ``d_planet`` (module doc), Y the
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


class StepAdjoint(Transposes):
    """The adjoint of one step of ``model`` by the explicit table ``table`` (a
    ``steppers.butcher.Table``) at Δt = ``dt`` (s), the run's steps from model time ``t0``
    (s): ``reverse(x, mu, k)`` maps the continuous adjoint μ of x(k+1) to that of x(k) in
    place, x = x(k). With ``parameters``, ``reverse``
    also sums ∂J/∂ν, ∂J/∂ν_s (``d_nu``) and the hs adjoint (``d_hs``, ``hs_gradient``) over
    the steps reversed. CPU or CUDA; on a rank's part of the grid (the model's ``topology``:
    μ on its nodes, the DSS's exchanges in the transposes, ``d_nu`` the same on every rank,
    the same bits on any number of ranks). ``ArgumentError`` (``refusal``) for a model it cannot
    serve.

    Work arrays (3, N) held: the s stages Y_i; K_j = F(Y_j) only where a stage after the next
    reads it (with ``parameters``: all); the Ȳ_j an earlier stage's k̄ reads, as many as are
    live at once (kgu35, rk4: one); x̄, a running sum of the Ȳ, and k̄ where the transposes
    cannot read it as a combination (``TendencyTranspose``): kgu35 eight, with (2, N) f̄."""

    def __init__(self, model: ShallowWater, table, dt: float, parameters: bool = False, t0: float = 0.0):
        self._setup(model, dt, parameters, t0)
        self.A = [[float(a) for a in row] for row in table.A_E]
        self.b = [float(b) for b in table.b_E]
        self.c = tuple(table.c)  # the stages' abscissae, as the stepper's ``_at`` takes them
        s, A, zeros = len(self.b), self.A, self._zeros
        keep_k = [self.parameters or any(A[l][j] for l in range(j + 2, s)) for j in range(s)]
        self.Y = [zeros(3) for _ in range(s)]
        self.x = self.Y[0]  # Y_0 = x(n): an explicit table's first row is zero
        self.K = [zeros(3) if keep else None for keep in keep_k]
        self._for_dt()

    # what depends on Δt: the ∇⁴'s transposed step and the launches recorded with Δt in their coefficients
    _PER_DT = ("hv_transpose", "substeps", "combinations", "_stages", "_adjoints")

    def _for_dt(self) -> None:
        """The records of a Δt not seen yet (``_PER_DT``), each made on first use."""
        m = self.model
        if m.hv is not None and m.hv.nu_max > 0:  # its work arrays shared with the last Δt's
            self.hv_transpose = m.hv.transpose(self.tendency, self.dt, self.hv_transpose)
        # the ∇⁴'s forward-Euler substeps, or its RKL1 stages (``Hyperviscosity.plan``)
        self.substeps = 0 if self.hv_transpose is None else self.hv_transpose.substeps
        self.combinations = Combinations(m.launches)  # ``combine``'s recorded launches
        self._adjoints: dict[int, tuple] = {}  # (μ, ``_record``'s launches), by μ's address
        self._stages = self._stage_plan(self._zeros)

    def set_dt(self, dt: float) -> None:
        """Reverse the next steps at Δt = ``dt`` (s): a run whose steps the controller chose
        (``gradient(..., history=)``). The records of the last ``HELD_DTS`` Δt are kept, so
        that a Δt that recurs replays its launches. ``ArgumentError`` (``refusal``) for a Δt the
        adjoint cannot serve."""
        dt = float(dt)
        if dt == self.dt:
            return
        why = refusal(self.model, dt)
        if why is not None:
            raise ArgumentError(why)
        self._held[self.dt] = {key: getattr(self, key) for key in self._PER_DT}
        if len(self._held) > HELD_DTS:
            del self._held[next(iter(self._held))]
        self.dt = dt
        held = self._held.pop(dt, None)
        if held is None:
            self._for_dt()
        else:
            self.__dict__.update(held)

    def _stage_plan(self, zeros) -> list:
        """Per stage i: (F(Y_i)'s ``Update``s, or None where no later stage nor ``parameters``
        reads K_i; Y_(i+1)'s terms where it is formed by a pass of its own, else None): Y_(i+1)
        = x + Δt Σ_j a_(i+1)j K_j written by F(Y_i)'s DSS (``rhs_update``) where it is at most
        three terms, two of them arrays, F(Y_i) one."""
        A, dt, s, plan = self.A, self.dt, len(self.b), []
        for i in range(s):
            updates, separate = [], None
            if self.K[i] is not None:
                updates.append(Update(self.K[i], ((1.0, None),)))
            if i + 1 < s:
                row = A[i + 1]
                arrays = [(dt * row[j], self.K[j]) for j in range(i) if row[j]]
                terms = [(1.0, self.x), *arrays]
                if row[i] and len(terms) <= 2:
                    updates.append(Update(self.Y[i + 1], (*terms, (dt * row[i], None))))
                else:
                    if row[i] and self.K[i] is None:  # Y_(i+1) reads K_i by a pass of its own
                        self.K[i] = zeros(3)
                        updates.insert(0, Update(self.K[i], ((1.0, None),)))
                    separate = [*terms, *([(dt * row[i], self.K[i])] if row[i] else [])]
            plan.append((updates or None, separate))
        return plan

    def combine(self, out, terms) -> None:
        """out = Σ c·x over (c, x) terms, recorded for this Δt (``Combinations.combine``)."""
        self.combinations.combine(out, terms)

    def stages(self, k: int = 0) -> None:
        """Y_i of step k from x = Y_0 (the Butcher form), and the K_i = F(Y_i) kept
        (``_stage_plan``); each F at the stepper's time of its stage, t0 + (k + c_i)·Δt (a
        time-dependent forcing reads it: it adds to F, not to F's Jacobian)."""
        m = self.model
        for i, (updates, separate) in enumerate(self._stages):
            if updates is not None:
                m.set_time(self.t0 + (k + self.c[i]) * self.dt)
                m.rhs_update(self.Y[i], updates)
            if separate is not None:
                self.combine(self.Y[i + 1], separate)

    def substep(self, x, transposed: bool = False) -> None:
        """One ∇⁴ substep without hs in place, or its transpose (``HyperviscosityTranspose.substep``)."""
        self.hv_transpose.substep(x, transposed)

    def hyperviscosity_transpose(self, mu) -> None:
        """μ of the ∇⁴'s output → μ of its input Φ (``before_hyperviscosity``), in place (the model's
        ``HyperviscosityTranspose``); with ``parameters``, ∂J/∂ν, ∂J/∂ν_s and the hs adjoint of
        this step summed into ``d_nu`` and ``d_hs`` (module doc)."""
        sums = (self.before_hyperviscosity, self.d_nu, self.d_hs) if self.parameters else ()
        self.hv_transpose.transpose(mu, *sums)

    def before_hyperviscosity(self, out) -> None:
        """out = Φ(x), the step before its ∇⁴: x + Δt Σ b_i K_i (the K_i kept with ``parameters``)."""
        self.combine(out, [(1.0, self.x), *((self.dt * b, k) for b, k in zip(self.b, self.K))])

    def _record(self, mu) -> list:
        """The launches of the stages' transposes, last stage first, as (Y_i, k̄_i's terms, its
        launches) a stage (``reverse``): k̄_i = Δt (b_i μ + Σ_j a_ji
        Ȳ_j), x̄ = Tᵀ(Y_i) W k̄_i, Ȳ_i = R Q x̄ written by the unweighted DSS into a running
        sum, the last into μ += Σ Ȳ_i, and where an earlier stage reads it into a buffer of
        its own, freed after its last reader's transpose (kgu35, rk4: one; a stage with no
        terms contributes nothing)."""
        dt, s, A = self.dt, len(self.b), self.A
        reads = {}  # each active stage: the j of the Ȳ_j its k̄ reads
        for i in reversed(range(s) if self.terms else ()):
            js = [j for j in range(i + 1, s) if A[j][i] and j in reads]
            if self.b[i] or js:
                reads[i] = js
        active = sorted(reads, reverse=True)
        last_read = {j: min(i for i in reads if j in reads[i]) for js in reads.values() for j in js}
        if len(active) > 1 and not hasattr(self, "acc"):
            self.acc = self._zeros(3)
        segments, ybar, free = [], {}, list(self.Ybar)
        for n, i in enumerate(active):
            kbar = [(dt * self.b[i], mu)] if self.b[i] else []
            kbar += [(dt * A[j][i], ybar[j]) for j in reads[i]]
            launches = self.tendency.transpose(self.Y[i], kbar)
            free += [ybar[j] for j in reads[i] if last_read[j] == i]  # read: its buffer free for Ȳ_i
            updates = []
            if i in last_read:
                if not free:
                    self.Ybar.append(self._zeros(3))
                    free.append(self.Ybar[-1])
                ybar[i] = free.pop()
                updates.append((ybar[i], ((1.0, None),)))
            total = mu if n == len(active) - 1 else self.acc
            updates.append((total, ((1.0, mu if n == 0 else self.acc), (1.0, None))))
            launches += self.model.topology.dss_update(self.xbar, updates, weighted=False)
            segments.append((self.Y[i], kbar, launches))
        return segments

    def reverse(self, x, mu, k: int = 0) -> None:
        """μ of x(k+1) → μ of x(k), in place; x = x(k) (read only), k the step's index (its
        stages' times, ``stages``)."""
        wp.copy(self.x, x)  # the stages read this object's arrays only (their records)
        self.stages(k)
        if self.substeps:
            self.hyperviscosity_transpose(mu)
        self._replay(mu)

    def reverse_dynamics(self, x, mu, k: int = 0) -> None:
        """``reverse`` without the ∇⁴'s transpose: the table's stages alone (a step that is a
        substep of another's, ``multirate_ab``)."""
        wp.copy(self.x, x)
        self.stages(k)
        self._replay(mu)

    def _replay(self, mu) -> None:
        """The transposes after the ∇⁴'s on μ: ``_record``'s segments, recorded once per μ, with
        the parameters' sums of each F's (Y, k̄) before its launches (a segment's fourth entry,
        where it has one: ``planet_terms``' g_terms and coriolis)."""
        recorded = self._adjoints.get(mu.ptr)
        if recorded is None:
            recorded = self._adjoints[mu.ptr] = (mu, self._record(mu))
        for Y, kbar, launches, *which in recorded[1]:
            if self.parameters and kbar is not None:
                self.planet_terms(Y, kbar, *(which[0] if which else ()))
            for launch in launches:
                launch.launch()
