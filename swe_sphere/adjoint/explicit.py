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
  B₀ the operator without hs (the model's ∇⁴ launches recorded with hs = 0); the tensor ∇⁴
  (its second K̃ the tensor's, K̃_V, also symmetric) has for transpose the operator with its
  two K̃ swapped (``Hyperviscosity.build(transposed=True)``); with ν_div ≠ ν the ∇δ term is
  not symmetric and its transpose is added apart (``StepAdjoint._divergent_transpose``);
- T's transpose is the model's (``model.transposes.TendencyTranspose``, the kernels
  ``kernels.tendency_adjoint``), whose λ is gathered back by the unweighted DSS,
  μ = R Q λ, written straight into the running sum of the stages' adjoints (``dss_update``).
The parameters (``parameters=True``): the ∇⁴ substeps x ← L x + c B₀ hs (L = I + c B₀, c ∝ ν)
give, with Δ₀ = c B₀ (Φ + hs) the first substep's increment and μ₁ the adjoint before the
last substep's transpose, ∂J/∂ν = S ⟨μ₁, Δ₀⟩ / ν over S substeps (L commutes with itself:
⟨L^(S−1−k) μ_S, L^k Δ₀⟩ is the same for every k), the wind rows for ν (= ν_div) and the h row
for ν_s; and ∂J/∂hs = (μ after − μ before the ∇⁴'s transpose)[h] (Σ_k c B₀ μ_(k+1) telescopes),
plus the forcing −g∇hs's share, the pressure gradient's transpose of Σ λ over the stages.
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


class StepAdjoint:
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

    def carried(self, stepper) -> list:
        """The (3, N) arrays ``stepper`` carries from step to step besides x, which the reverse
        sweep's states and adjoints hold after x's rows, in this order: none here (``leapfrog``'s
        x̃(n−1), ``multirate_ab``'s histories)."""
        return []

    def set_phase(self, stepper, k: int) -> None:
        """Put ``stepper`` at step k's phase before it takes step k again from a state of the
        sweep (beyond its clock and x): nothing here."""

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
        self.hv_states: list = []  # the ∇⁴'s forward substeps' states (``_divergent_parameters``)
        if m.hv is not None and m.hv.nu_max > 0:
            self.zero_hs = wp.zeros(N, dtype=f64, device=device)
            if self.parameters:  # Φ + hs and Δ₀ (``hyperviscosity_transpose``)
                self.phi, self.delta = zeros(3), zeros(3)
        self._zeros = zeros

    # what depends on Δt: the ∇⁴'s substeps and the launches recorded with Δt in their coefficients
    _PER_DT = (
        "substeps",
        "rkl",
        "_coef",
        "_stages",
        "_combinations",
        "_hv",
        "_adjoints",
        "_divergent",
        "_hv_unit",
        "_rkl_unit",
    )

    def _for_dt(self) -> None:
        """The records of a Δt not seen yet (``_PER_DT``), each made on first use."""
        m = self.model
        # the ∇⁴'s forward-Euler substeps, or its RKL1 stages (``Hyperviscosity.plan``), and the
        # coefficient of each of their ∇⁴ steps (``Hyperviscosity.rkl1``'s w₁Δt for RKL1)
        self.substeps, self.rkl = m.hv.plan(self.dt) if m.hv is not None and m.hv.nu_max > 0 else (0, False)
        s = self.substeps
        self._coef = -self.dt * 2.0 / (s * s + s) if self.rkl else -self.dt / max(s, 1)
        self._combinations: dict[tuple, list] = {}  # ``combine``'s recorded launches
        self._hv: dict[tuple, list] = {}  # ``substep``'s recorded launches, by array and direction
        self._adjoints: dict[int, tuple] = {}  # (μ, ``_record``'s launches), by μ's address
        self._divergent: dict[int, list] = {}  # ``_divergent_transpose``'s, by array
        self._hv_unit = None  # ``_divergent_parameters``' unit-coefficient ∇⁴ launches
        self._rkl_unit: dict[int, list] = {}  # ``_rkl1_transpose``'s, by stage
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
        """out = Σ c·x over (c, x) terms, zero coefficients left out (``LaunchRecorder.lincomb``,
        four terms a pass; out may alias any x only as the first term); recorded once per
        arrays and coefficients (the arrays are this object's, held as long as it)."""
        terms = [(c, x) for c, x in terms if c != 0.0]
        if not terms:
            out.zero_()
            return
        key = (out.ptr, out.shape, *((c, x.ptr, x.shape) for c, x in terms))  # a row view shares its array's ptr
        launches = self._combinations.get(key)
        if launches is None:
            launches = self._combinations[key] = self.combination(out, terms)
        for launch in launches:
            launch.launch()

    def combination(self, out, terms) -> list:
        """The launches of out = Σ c·x over (c, x) ``terms``, zero coefficients left out (out = 0
        for none): four terms in the first pass, three more in each next (out may alias any x
        only as the first term), for a record of one's own (``combine`` keeps them by key)."""
        terms = [(c, x) for c, x in terms if c != 0.0] or [(0.0, out)]
        passes = [terms[:4], *([(1.0, out), *terms[i : i + 3]] for i in range(4, len(terms), 3))]
        return [self.model.lincomb(out, p) for p in passes]

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
        """x ← x − (Δt/S) B₀ x in place (``transposed``: B₀'s transpose in the mass form): one ∇⁴
        substep without hs (the model's launches, recorded once per array with the model's hs
        swapped for zeros, as ``biharmonic_radius`` does). With ν_div ≠ ν the transpose is the
        operator's at ν_div = ν plus its ∇δ term's (``_divergent_transpose``)."""
        m = self.model
        divergent = transposed and m.hv.nu_div != m.hv.nu
        launches = self._hv.get((x.ptr, transposed))
        if launches is None:
            nus = (m.hv.nu, m.hv.nu, m.hv.nu_s) if divergent else None
            with m.operators.hs_as(self.zero_hs):
                launches = self._hv[x.ptr, transposed] = m.hv.build(x, self._coef, nus=nus, transposed=transposed)
        for launch in launches:
            launch.launch()
        if divergent:
            self._divergent_transpose(x, self._coef)

    def _divergent_transpose(self, x, coef: float) -> None:
        """x[wind] += coef · B_dᵀ μ, μ the x the substep started from: the transpose of the ∇δ
        term B_d = (ν_div − ν) Pᵀ RQ K̃₂ RQ W P G RQ W D (G the strong gradient, D the strong
        divergence, W spheremp, P the (east, north) → Cartesian frame), in the mass form
        B_dᵀ μ = (ν_div − ν) RQ Dᵀ(W s), s = RQ Gᵀ(W Pᵀ Z), Z = RQ K̃₂ P μ: the substep's first
        pass left ν Π Z in the ∇⁴'s Y₁ (Π's radial part Pᵀ drops). Gᵀ W is the pressure
        gradient's transpose (∂(−g G h)/∂h: −g Gᵀ W), Dᵀ W the continuity's at h = 1, v = 0
        (∂(−D(h v))/∂v: −Dᵀ W), each the tendency's transpose with those terms and unweighted DSS'd. Each
        reads only its own rows of k̄: ``kd`` holds Pᵀ Z in its wind rows and s in its h row.
        The projection Pᵀ on the host; the rest recorded once per x."""
        m, topo = self.model, self.model.topology
        if not hasattr(self, "kd"):
            self.kd, self.dss_out = self._zeros(3), self._zeros(3)
            self.unit_depth = wp.array(
                np.stack([np.zeros(m.topology.N), np.zeros(m.topology.N), np.ones(m.topology.N)]),
                dtype=f64,
                device=m.topology.device,
            )
            self.frame = m.operators.east.numpy() / m.hv.nu, m.operators.north.numpy() / m.hv.nu  # Pᵀ, and Y₁ = ν Π Z
        launches = self._divergent.get(x.ptr)
        if launches is None:
            H, U = slice(2, 3), slice(0, 2)
            launches = self._divergent[x.ptr] = [
                *self.tendency.transpose(
                    self.unit_depth, [(1.0, self.kd)], ("pressure_gradient",)
                ),  # linear: any state
                *topo.dss(self.xbar, False, self.dss_out),
                m.lincomb(self.kd[H], [(-1.0 / m.g, self.dss_out[H])]),  # s = RQ Gᵀ(W Pᵀ Z)
                *self.tendency.transpose(self.unit_depth, [(1.0, self.kd)], ("continuity",)),
                *topo.dss(self.xbar, False, self.dss_out),  # −RQ Dᵀ(W s)
                m.lincomb(x[U], [(1.0, x[U]), (-coef * (m.hv.nu_div - m.hv.nu), self.dss_out[U])]),
            ]
        Y = m.hv.hv_Y.numpy()[:3]
        east, north = self.frame
        self.kd[0:2].assign(np.stack([np.sum(Y * east, axis=0), np.sum(Y * north, axis=0)]))  # Pᵀ Z
        for launch in launches:
            launch.launch()

    def hyperviscosity_transpose(self, mu) -> None:
        """μ of the ∇⁴'s output → μ of its input Φ, in place (the ∇⁴'s transposed substeps); with
        ``parameters``, ∂J/∂ν, ∂J/∂ν_s and the hs adjoint of this step summed (module doc)."""

        def h(x):
            self.substep(x, transposed=True)

        if self.rkl:
            self._rkl1_transpose(mu)
            return
        if not self.parameters:
            for _ in range(self.substeps):
                h(mu)
            return
        m = self.model
        self.before_hyperviscosity(self.phi)
        self.combine(self.phi[2:3], [(1.0, self.phi[2:3]), (1.0, m.operators.hs.reshape((1, m.topology.N)))])  # Φ + hs
        self.combine(self.d_hs, [(1.0, self.d_hs), (-1.0, mu[2:3])])
        if m.hv.nu_div != m.hv.nu:  # L and ∂L/∂ν do not commute: the substeps' terms one by one
            self._divergent_parameters(mu)
            self.combine(self.d_hs, [(1.0, self.d_hs), (1.0, mu[2:3])])
            return
        wp.copy(self.delta, self.phi)
        self.substep(self.delta)
        self.combine(self.delta, [(1.0, self.delta), (-1.0, self.phi)])  # Δ₀
        for _ in range(self.substeps - 1):
            h(mu)
        w = m.topology.whole_sums(
            m.topology.grid.spheremp * mu.numpy() * self.delta.numpy()
        )  # the same bits on any ranks
        rows = np.array([w[0] + w[1], w[2]]) * self.substeps
        self.d_nu += np.divide(rows, [m.hv.nu, m.hv.nu_s], out=np.zeros(2), where=np.array([m.hv.nu, m.hv.nu_s]) > 0)
        h(mu)
        self.combine(self.d_hs, [(1.0, self.d_hs), (1.0, mu[2:3])])

    def _rkl1_transpose(self, mu) -> None:
        """μ of an RKL1 super-step's output → μ of its input, in place: the step (``Hyperviscosity.
        rkl1``) Y_1 = E Y_0, Y_j = μ_j E Y_(j−1) + ν_j Y_(j−2) (E y = y + Δ(y), Δ(y) = c B₀ (y + hs)
        its forward-Euler step) reversed, its stages last first: Ȳ_(j−1) += μ_j Eᵀ Ȳ_j, Ȳ_(j−2) +=
        ν_j Ȳ_j, and Ȳ_0 += Eᵀ Ȳ_1 (Eᵀ ``substep``'s transpose, μ_j = (2j − 1)/j, ν_j = −(j − 1)/j,
        μ_1 = 1). With ``parameters``: the stages taken again from Φ (``before_hyperviscosity``),
        ∂J/∂ν (wind rows: ν and ν_div moved together) and ∂J/∂ν_s (h row) += μ_j ⟨Ȳ_j, c B₁ (Y_(j−1)
        + hs)⟩, B₁ the operator at unit coefficients (``_divergent_parameters``' ∂B/∂ν), and the hs
        adjoint += μ_j (Eᵀ Ȳ_j − Ȳ_j)[h]."""
        m, s = self.model, self.substeps
        if not hasattr(self, "rkl_bars"):
            self.rkl_bars = [self._zeros(3) for _ in range(3)]
            self.rkl_work = self._zeros(3)
            self.rkl_deltas: list = []
            self.rkl_units: list = []
        cur, prev, prev2 = self.rkl_bars
        t = self.rkl_work
        if self.parameters:  # Δ_j = Δ(Y_(j−1)), the stages from Φ rolling over cur, prev, prev2 for now
            self.rkl_deltas += [self._zeros(3) for _ in range(s - len(self.rkl_deltas))]
            self.rkl_units += [self._zeros(3) for _ in range(s - len(self.rkl_units))]
            free, older = [cur, prev, prev2], None
            last = free.pop()
            self.before_hyperviscosity(last)  # Y_0 = Φ
            for j in range(1, s + 1):
                d = self.rkl_deltas[j - 1]
                self.combine(d, [(1.0, last)])
                self.combine(d[2:3], [(1.0, d[2:3]), (1.0, m.operators.hs.reshape((1, m.topology.N)))])  # Y_(j−1) + hs
                self.combine(t, [(1.0, d)])
                self.substep(d)
                self.combine(d, [(1.0, d), (-1.0, t)])  # Δ_j
                self._unit_step(t, j)  # c B₁ (Y_(j−1) + hs)
                if j < s:  # Y_j = μ_j (Y_(j−1) + Δ_j) + ν_j Y_(j−2)
                    a = (2.0 * j - 1.0) / j
                    new = free.pop()
                    self.combine(new, [(a, last), (a, d), *([(-(j - 1.0) / j, older)] if older is not None else [])])
                    if older is not None:
                        free.append(older)
                    older, last = last, new
        self.combine(cur, [(1.0, mu)])
        prev.zero_()
        prev2.zero_()
        for j in range(s, 0, -1):
            self.combine(t, [(1.0, cur)])
            self.substep(t, transposed=True)
            weight = (2.0 * j - 1.0) / j  # μ_j (1 for j = 1)
            if self.parameters:
                w = m.topology.whole_sums(m.topology.grid.spheremp * cur.numpy() * self.rkl_units[j - 1].numpy())
                self.d_nu += weight * np.array([w[0] + w[1], w[2]])
                self.combine(self.d_hs, [(1.0, self.d_hs), (weight, t[2:3]), (-weight, cur[2:3])])
            if j == 1:
                break
            self.combine(prev, [(1.0, prev), (weight, t)])
            self.combine(prev2, [(1.0, prev2), (-(j - 1.0) / j, cur)])
            cur, prev, prev2 = prev, prev2, cur
            prev2.zero_()
        self.combine(mu, [(1.0, prev), (1.0, t)])

    def _unit_step(self, y, j: int) -> None:
        """``rkl_units[j − 1]`` = c B₁ y (``_rkl1_transpose``), B₁ the ∇⁴ at unit coefficients
        without hs (y holds it), recorded once per stage."""
        m, out = self.model, self.rkl_units[j - 1]
        launches = self._rkl_unit.get(j)
        if launches is None:
            with m.operators.hs_as(self.zero_hs):
                launches = self._rkl_unit[j] = [
                    m.lincomb(out, [(0.0, out)]),
                    *m.hv.build(y, self._coef, out=out, nus=(1.0, 1.0, 1.0)),
                ]
        for launch in launches:
            launch.launch()

    def _divergent_parameters(self, mu) -> None:
        """μ ← the ∇⁴'s transposed substeps of μ, with ∂J/∂ν (ν and ν_div moved together) and
        ∂J/∂ν_s summed term by term: Σ_k ⟨μ_(k+1), c B₁ y_k⟩, y_k = Φ + hs after k forward
        substeps (held), B₁ the operator at unit coefficients (its wind rows ∂B/∂ν with ν_div − ν
        fixed, its h row ∂B/∂ν_s), c = −Δt/S: with ν_div ≠ ν the ∇δ term keeps ∂L/∂ν from
        commuting with L, so ``hyperviscosity_transpose``'s S⟨μ₁, Δ₀⟩/ν does not hold."""
        m, S, c = self.model, self.substeps, -self.dt / self.substeps
        if self._hv_unit is None:
            self.hv_states += [self._zeros(3) for _ in range(S - len(self.hv_states))]
            if not hasattr(self, "hv_unit"):
                self.hv_unit = self._zeros(3)
            with m.operators.hs_as(
                self.zero_hs
            ):  # c B₁ y_k into hv_unit, once per k (y_k holds hs: the model's is zero)
                self._hv_unit = [m.hv.build(y, c, out=self.hv_unit, nus=(1.0, 1.0, 1.0)) for y in self.hv_states[:S]]
        wp.copy(self.hv_states[0], self.phi)
        for k in range(1, S):
            wp.copy(self.hv_states[k], self.hv_states[k - 1])
            self.substep(self.hv_states[k])
        for k in reversed(range(S)):
            self.hv_unit.zero_()
            for launch in self._hv_unit[k]:
                launch.launch()
            w = m.topology.whole_sums(m.topology.grid.spheremp * mu.numpy() * self.hv_unit.numpy())
            self.d_nu += [w[0] + w[1], w[2]]
            self.substep(mu, transposed=True)

    def before_hyperviscosity(self, out) -> None:
        """out = Φ(x), the step before its ∇⁴: x + Δt Σ b_i K_i (the K_i kept with ``parameters``)."""
        self.combine(out, [(1.0, self.x), *((self.dt * b, k) for b, k in zip(self.b, self.K))])

    def hs_gradient(self) -> np.ndarray:
        """∂J/∂hs (N,) on this rank's nodes, continuous (mass form, as μ), summed over the steps reversed so far:
        the ∇⁴'s share and the forcing's (``TendencyTranspose.forcing_transpose`` of f̄)."""
        out = self.d_hs.numpy()[0]
        if not self.terms or "topography" not in self.model.terms:
            return out
        return out + self.tendency.forcing_transpose()

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
