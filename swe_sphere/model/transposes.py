"""The transposes of the model's operators, for the gradients of a run (``swe_sphere.adjoint``).

``TendencyTranspose`` (made by ``ElementOperators.tendency_transpose``) launches x̄ = Tᵀ(Y) W k̄,
T the element-local tendency of ``ShallowWater.rhs`` at the state Y, W the element mass spheremp
and k̄ a continuous adjoint of F(Y) in the mass form (μ = R Q λ, R the inverse assembled mass,
Q the sum over a node's copies: ``adjoint.reverse``'s module doc); R Q x̄ by the unweighted DSS
that the caller writes where it needs it is then the adjoint of Y. The kernels are
``kernels.tendency_adjoint``'s (written by hand: one element kernel a stage on the CPU, two
per-node gathers on CUDA). ``HyperviscosityTranspose`` (``Hyperviscosity.transpose``) and
``GravityTranspose`` (``GravityWaveOperator.transpose``: Lᵀ and the transposed implicit solve)
read it. ``PlanetSums``: the evaluations' sums that give ∂J/∂g and ∂J/∂Ω.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import warp as wp

from ..kernels import tendencies, tendency_adjoint

f64 = wp.float64


class TendencyTranspose:
    """The tendency's transpose for the terms of ``terms`` that F holds (``kernels.tendencies.
    TENDENCY_TERMS`` order) at gravity ``g`` (m s⁻²), on ``operators``' arrays and layout (an
    ``ElementOperators``), its launches through their ``LaunchRecorder``.

    Arrays (device, element-local, N the nodes): ``xbar`` (3, N), what each transpose writes;
    ``fbar`` (2, N), Σ λ's wind rows over the transposes with topography (the adjoint of the
    forcing −g∇hs, for ∂J/∂hs: ``forcing_transpose``); the element mass ``spheremp`` (N,; m²);
    made on first use: ``kbar`` (3, N), k̄ combined where the kernels cannot read it as it is,
    and ``adj`` (5, N), the per-node kernels' reference-derivative adjoints."""

    def __init__(self, operators, terms: tuple, g: float):
        self.operators, self.g = operators, g
        self.topology, self.launches = operators.topology, operators.launches
        self.terms = tuple(t for t in tendencies.TENDENCY_TERMS if t in terms)
        self.xbar = self._zeros(3)
        self.fbar = self._zeros(2)
        self.spheremp = wp.array(self.topology.grid.spheremp, dtype=f64, device=self.topology.device)

    def _zeros(self, rows: int) -> wp.array2d:
        return wp.zeros((rows, self.topology.N), dtype=f64, device=self.topology.device)

    def transpose(self, Y, kbar, terms=None, runs=None) -> list:
        """Launches of x̄ = Tᵀ(Y) W k̄ into ``xbar``, k̄ = Σ c·k over (c, k) ``kbar`` (element-local
        (3, N) arrays or row views), T the tendency of ``terms`` (None: all this object's): the
        element kernel on the CPU's layout, reading up to three terms; the per-node ``point`` and
        ``gather`` on CUDA's; k̄ combined by a pass of its own first where they cannot read it as
        it is. ``runs``: (start, stop) element ranges, the tendency of those elements alone (x̄
        zero on the others). The recorded launches read the arrays, not their values: replay
        them for new values."""
        ops, rec, launches = self.operators, self.launches, []
        if runs is not None:
            launches.append(rec.lincomb(self.xbar, [(0.0, self.xbar)]))
        ranges = [None] if runs is None else list(runs)
        terms = self.terms if terms is None else tuple(t for t in self.terms if t in terms)
        if len(kbar) > 3 or not ops.per_element and kbar != [(1.0, kbar[0][1])]:
            if not hasattr(self, "kbar"):
                self.kbar = self._zeros(3)
            more = (rec.lincomb(self.kbar, [(1.0, self.kbar), *kbar[i : i + 3]]) for i in range(4, len(kbar), 3))
            launches, kbar = [*launches, rec.lincomb(self.kbar, kbar[:4]), *more], [(1.0, self.kbar)]
        np_ = self.topology.grid.np
        if ops.per_element:
            R, (c, k) = ops.as_rows, zip(*kbar)
            c, k = [*c, *(0.0,) * (3 - len(c))], [*k, *(k[0],) * (3 - len(k))]
            kernel = tendency_adjoint.element(terms, np_, len(kbar))
            args = [*map(R, (Y, ops.D, ops.Dinv, ops.metdet, ops.fcor, self.spheremp)), self.g, ops.dvv_rows]
            args += [wp.vec3d(*c), *map(R, k), R(self.xbar), R(self.fbar)]
            return [*launches, *(rec.elements(kernel, args, elements=r) for r in ranges)]
        if not hasattr(self, "adj"):
            self.adj = self._zeros(5)
        point = [Y, ops.D, ops.Dinv, ops.metdet, ops.fcor, self.spheremp, ops.dvv, kbar[0][1]]
        point += [self.adj, self.xbar, self.fbar]
        gather = [Y, ops.D, ops.Dinv, ops.metdet, ops.dvv, self.g, self.adj, self.xbar]
        kernels = (
            (tendency_adjoint.point(terms, np_), point),
            (tendency_adjoint.gather(terms, np_), gather),
        )
        return [*launches, *(rec.nodes(k, self.topology.N, a, elements=r) for r in ranges for k, a in kernels)]

    def forcing_transpose(self) -> np.ndarray:
        """The forcing −g∇hs's share of ∂J/∂hs (N,) on this rank's nodes, continuous (mass form):
        R Q of the pressure gradient's transpose of ``fbar`` (the forcing is the pressure gradient
        of hs), by the per-node kernels on either layout, unrecorded (once a gradient)."""
        ops, topo, N = self.operators, self.topology, self.topology.N
        kbar = wp.array(np.concatenate([self.fbar.numpy(), np.zeros((1, N))]), dtype=f64, device=topo.device)
        ones, xbar, d = wp.ones(N, dtype=f64, device=topo.device), wp.zeros_like(kbar), wp.zeros_like(kbar)
        adj = self._zeros(5)
        point = [kbar, ops.D, ops.Dinv, ops.metdet, ops.fcor, ones, ops.dvv, kbar, adj, xbar, self.fbar]
        terms = ("pressure_gradient",)
        wp.launch(tendency_adjoint.point(terms, topo.grid.np), N, [*point, 0], device=topo.device)
        gather = [kbar, ops.D, ops.Dinv, ops.metdet, ops.dvv, self.g, adj, xbar]
        wp.launch(tendency_adjoint.gather(terms, topo.grid.np), N, [*gather, 0], device=topo.device)
        for launch in topo.dss(xbar, False, d):
            launch.launch()
        return d.numpy()[2]


class PlanetSums:
    """g ∂J/∂g and Ω ∂J/∂Ω of a gradient, summed over the F evaluations a reverse meets
    (``adjoint.reverse``'s module doc): F is linear in g (−g∇(h + hs)) and in Ω (f (v, −u), f ∝
    Ω), so with k̄ the adjoint of an F(Y), g ∂J/∂g = Σ ⟨k̄, F_g(Y)⟩ and Ω ∂J/∂Ω = Σ ⟨k̄, f (v,
    −u)⟩, F_g the RHS of ``model``'s pressure gradient and topography alone (``g_terms``).
    ``sums`` (2,) J, added to in place by ``add``; a (3, N) work array made at the first."""

    def __init__(self, model):
        self.model, self.sums = model, np.zeros(2)
        self.g_terms = tuple(t for t in ("pressure_gradient", "topography") if t in model.terms)
        self._f = self._fcor = None

    def add(self, Y, kbar, g_terms=None, coriolis: bool = True, part=None) -> None:
        """Add an F evaluation's ⟨k̄, g F_g(Y)⟩ and ⟨k̄, f (v, −u)⟩ to ``sums``, Y the state its F
        read, k̄ = Σ c·a over (c, a) ``kbar`` as its transpose reads them (the same bits on any
        ranks); F_g the RHS of ``g_terms`` (None: ``self.g_terms``), the Coriolis term's share only
        where its F holds it (``coriolis``); with ``part`` (an ``ElementPart``: F the part's f_P)
        both by ``rhs_part``."""
        m = self.model
        g_terms = self.g_terms if g_terms is None else tuple(t for t in g_terms if t in m.terms)
        kb, w, y = sum(c * a.numpy() for c, a in kbar), m.topology.grid.spheremp, Y.numpy()
        if self._f is None:
            self._f = wp.zeros((3, m.topology.N), dtype=f64, device=m.topology.device)
            self._fcor = m.operators.fcor.numpy() if "coriolis" in m.terms else np.zeros_like(w)

        def winds(terms):  # ⟨k̄, F⟩ node by node over the wind rows, F the RHS of ``terms`` at Y
            if part is None:
                m.rhs(Y, self._f, terms)
            else:  # f_P writes the nodes its elements touch alone
                self._f.zero_()
                m.rhs_part(Y, self._f, part, terms)
            F = self._f.numpy()
            return kb[0] * F[0] + kb[1] * F[1]

        pressure = winds(g_terms) if g_terms else np.zeros_like(w)
        if not coriolis or "coriolis" not in m.terms:
            rotation = np.zeros_like(w)
        elif part is None:
            rotation = self._fcor * (kb[0] * y[1] - kb[1] * y[0])
        else:
            rotation = winds(("coriolis",))
        self.sums += m.topology.whole_sums([w * pressure, w * rotation])


class Combinations:
    """Linear combinations out = Σ c·x of device arrays, their launches (``LaunchRecorder.lincomb``
    through ``launches``) recorded once per arrays and coefficients: the reverse sweep's sums."""

    def __init__(self, launches):
        self.launches = launches
        self._records: dict[tuple, list] = {}

    def combine(self, out, terms) -> None:
        """out = Σ c·x over (c, x) terms, zero coefficients left out (``LaunchRecorder.lincomb``,
        four terms a pass; out may alias any x only as the first term); recorded once per
        arrays and coefficients (the arrays must be held as long as this object)."""
        terms = [(c, x) for c, x in terms if c != 0.0]
        if not terms:
            out.zero_()
            return
        key = (out.ptr, out.shape, *((c, x.ptr, x.shape) for c, x in terms))  # a row view shares its array's ptr
        launches = self._records.get(key)
        if launches is None:
            launches = self._records[key] = self.combination(out, terms)
        for launch in launches:
            launch.launch()

    def combination(self, out, terms) -> list:
        """The launches of out = Σ c·x over (c, x) ``terms``, zero coefficients left out (out = 0
        for none): four terms in the first pass, three more in each next (out may alias any x
        only as the first term), for a record of one's own (``combine`` keeps them by key)."""
        terms = [(c, x) for c, x in terms if c != 0.0] or [(0.0, out)]
        passes = [terms[:4], *([(1.0, out), *terms[i : i + 3]] for i in range(4, len(terms), 3))]
        return [self.launches.lincomb(out, p) for p in passes]


class GravityTranspose:
    """The transposes of ``linear``'s L x = (−g G h, −H D v) (a ``model.gravity_wave.
    GravityWaveOperator`` about its depth H, m) and of its implicit solve A_a = I − aL in the
    mass form (μ = R Q λ, ⟨a, b⟩ = Σ spheremp·a·b), made by ``GravityWaveOperator.transpose``
    for the adjoints of the steps that solve with L (``adjoint.tape``: semi_implicit, the IMEX pairs);
    ``solver`` the Helmholtz solver of A_a they solve with (a ``model.helmholtz.
    HelmholtzSolver`` about ``linear``: ``solve(r, a, z)``, ``iterations()``).

    Lᵀ: L is the Jacobian of F's pressure gradient and continuity at x_H = (0, 0, H), so
    Lᵀ μ = R Q Tᵀ(x_H) W μ, those two terms' transpose as any F's (``TendencyTranspose``).
    A_a⁻ᵀ: GLL differentiation sums by parts (W D + Dᵀ W = B along each direction, applied to
    metdet c^i h, c the contravariant wind), and the element-edge terms cancel between
    neighbours for continuous v and h, so in the mass form D and −G are each other's transposes
    (⟨D v, h⟩ = −⟨v, G h⟩) and Lᵀ (v, h) = (H G h, g D v) = −S L S⁻¹, S = diag(1, 1, g/H). With
    Z = diag(1, 1, −1) (Z L Z = −L): A_aᵀ = I + a S L S⁻¹ = S Z A_a Z S⁻¹, hence
    A_a⁻ᵀ μ = S Z A_a⁻¹ Z S⁻¹ μ: the h row times −H/g, the forward's Helmholtz solve at a (its
    operator M + a²gH K is symmetric: ``model.helmholtz``), the h row times −g/H.

    Arrays (device): x_H (3, N), made and filled when H is first read (the stepper fixes H by
    its first step: piecewise constant, held); the h row's scalings recorded once per array."""

    def __init__(self, linear, solver):
        self.linear, self.solver, self.model = linear, solver, linear.model
        self.combinations = Combinations(self.model.launches)
        self.depth, self.H = None, 0.0

    def _fix_depth(self) -> None:
        """x_H's depth row from ``linear``'s H, where it changed (or was not made)."""
        if self.depth is None or self.linear.H != self.H:
            self.H, topo = self.linear.H, self.model.topology
            if self.depth is None:
                self.depth = wp.zeros((3, topo.N), dtype=f64, device=topo.device)
            self.depth.assign(np.stack([np.zeros(topo.N), np.zeros(topo.N), np.full(topo.N, self.H)]))

    def transpose(self, tendency: TendencyTranspose, kbar) -> list:
        """Launches of x̄ = Tᵀ(x_H) W k̄ into ``tendency.xbar`` (element-local), k̄ = Σ c·a over
        (c, a) ``kbar`` ((3, N) arrays): Lᵀ k̄ = R Q x̄ by the unweighted DSS that follows."""
        self._fix_depth()
        return tendency.transpose(self.depth, kbar, ("continuity", "pressure_gradient"))

    def solve(self, mu, a: float) -> None:
        """μ ← A_a⁻ᵀ μ in place, A_a = I − aL, a (s) > 0, μ (3, N) continuous (mass form; the
        class doc): the h row times −H/g, ``solver``'s solve at a to its ``tol``, the h row times
        −g/H. ``StepFailure`` where the CG misses ``tol`` within ``maxiter``."""
        H, g, h = self.linear.H, self.model.g, mu[2:3]
        self.combinations.combine(h, [(-H / g, h)])
        self.solver.solve(mu, a, mu)
        self.combinations.combine(h, [(-g / H, h)])
        self.solver.iterations()


class HyperviscosityTranspose:
    """The transpose of ``hv``'s split ∇⁴ step over Δt = ``dt`` (s) (``Hyperviscosity.apply``: S
    forward-Euler substeps x ← x + c B x, or an RKL1 super-step) in the mass form, μ = R Q λ
    (``adjoint.reverse``'s module doc), made by ``Hyperviscosity.transpose``: the ∇⁴ is its own
    transpose, R Q Bᵀ = B R Q (B = Pᵀ R Q K̃ Π R Q K̃ P, K̃ the element weak Laplacian plus the
    mass shift, symmetric; P the (east, north) → Cartesian basis and Π the tangent projection,
    continuous and per node), so μ ← μ + c B₀ μ with B₀ the operator without hs (the model's
    ∇⁴ launches recorded with hs = 0); the tensor ∇⁴'s transpose has its two K̃ swapped
    (``Hyperviscosity.build(transposed=True)``); with ν_div ≠ ν the ∇δ term is not symmetric and
    its transpose is added apart (``divergent_transpose``, through ``tendency``, a
    ``TendencyTranspose``).

    ``substeps``, ``rkl``: the step's plan (``Hyperviscosity.plan``); ``coef`` (s) the
    coefficient c of each of its ∇⁴ steps (−Δt/S, or RKL1's −w₁Δt). The launches are recorded once
    per array and kept for this Δt; the work arrays ((3, N), made on first use, the transposes of
    one adjoint sharing them: ``shared``, another Δt's) in ``work``."""

    def __init__(self, hv, tendency: TendencyTranspose, dt: float, shared: HyperviscosityTranspose | None = None):
        self.hv, self.model, self.tendency, self.dt = hv, hv.model, tendency, float(dt)
        m = self.model
        N, device = m.topology.N, m.topology.device
        self.work = SimpleNamespace(zero_hs=wp.zeros(N, dtype=f64, device=device)) if shared is None else shared.work
        self.substeps, self.rkl = hv.plan(self.dt)
        s = self.substeps
        self.coef = -self.dt * 2.0 / (s * s + s) if self.rkl else -self.dt / max(s, 1)
        self.combinations = Combinations(m.launches)  # this Δt's sums' launches
        self._substeps: dict[tuple, list] = {}  # ``substep``'s recorded launches, by array and direction
        self._divergent: dict[int, list] = {}  # ``divergent_transpose``'s, by array
        self._units = None  # ``_divergent_parameters``' unit-coefficient ∇⁴ launches
        self._rkl_units: dict[int, list] = {}  # ``_unit_step``'s, by stage

    def _zeros(self, rows: int) -> wp.array2d:
        return wp.zeros((rows, self.model.topology.N), dtype=f64, device=self.model.topology.device)

    def substep(self, x, transposed: bool = False) -> None:
        """x ← x + c B₀ x in place (``transposed``: B₀'s transpose in the mass form), x (3, N): one ∇⁴
        substep without hs (the model's launches, recorded once per array with the model's hs
        swapped for zeros, as ``Hyperviscosity.biharmonic_radius`` does). With ν_div ≠ ν the
        transpose is the operator's at ν_div = ν plus its ∇δ term's (``divergent_transpose``)."""
        m, hv = self.model, self.hv
        divergent = transposed and hv.nu_div != hv.nu
        launches = self._substeps.get((x.ptr, transposed))
        if launches is None:
            nus = (hv.nu, hv.nu, hv.nu_s) if divergent else None
            with m.operators.hs_as(self.work.zero_hs):
                launches = self._substeps[x.ptr, transposed] = hv.build(x, self.coef, nus=nus, transposed=transposed)
        for launch in launches:
            launch.launch()
        if divergent:
            self.divergent_transpose(x, self.coef)

    def divergent_transpose(self, x, coef: float) -> None:
        """x[wind] += coef · B_dᵀ μ, μ the x (3, N) the substep started from: the transpose of the ∇δ
        term B_d = (ν_div − ν) Pᵀ RQ K̃₂ RQ W P G RQ W D (G the strong gradient, D the strong
        divergence, W spheremp, P the (east, north) → Cartesian frame), in the mass form
        B_dᵀ μ = (ν_div − ν) RQ Dᵀ(W s), s = RQ Gᵀ(W Pᵀ Z), Z = RQ K̃₂ P μ: the substep's first
        pass left ν Π Z in the ∇⁴'s Y₁ (Π's radial part Pᵀ drops). Gᵀ W is the pressure
        gradient's transpose (∂(−g G h)/∂h: −g Gᵀ W), Dᵀ W the continuity's at h = 1, v = 0
        (∂(−D(h v))/∂v: −Dᵀ W), each the tendency's transpose with those terms and unweighted DSS'd. Each
        reads only its own rows of k̄: ``kd`` holds Pᵀ Z in its wind rows and s in its h row.
        The projection Pᵀ on the host; the rest recorded once per x."""
        m, topo, w, t = self.model, self.model.topology, self.work, self.tendency
        if not hasattr(w, "kd"):
            w.kd, w.dss_out = self._zeros(3), self._zeros(3)
            w.unit_depth = wp.array(
                np.stack([np.zeros(m.topology.N), np.zeros(m.topology.N), np.ones(m.topology.N)]),
                dtype=f64,
                device=m.topology.device,
            )
            w.frame = m.operators.east.numpy() / self.hv.nu, m.operators.north.numpy() / self.hv.nu  # Pᵀ, Y₁ = ν Π Z
        launches = self._divergent.get(x.ptr)
        if launches is None:
            H, U = slice(2, 3), slice(0, 2)
            launches = self._divergent[x.ptr] = [
                *t.transpose(w.unit_depth, [(1.0, w.kd)], ("pressure_gradient",)),  # linear: any state
                *topo.dss(t.xbar, False, w.dss_out),
                m.lincomb(w.kd[H], [(-1.0 / m.g, w.dss_out[H])]),  # s = RQ Gᵀ(W Pᵀ Z)
                *t.transpose(w.unit_depth, [(1.0, w.kd)], ("continuity",)),
                *topo.dss(t.xbar, False, w.dss_out),  # −RQ Dᵀ(W s)
                m.lincomb(x[U], [(1.0, x[U]), (-coef * (self.hv.nu_div - self.hv.nu), w.dss_out[U])]),
            ]
        Y = self.hv.hv_Y.numpy()[:3]
        east, north = w.frame
        w.kd[0:2].assign(np.stack([np.sum(Y * east, axis=0), np.sum(Y * north, axis=0)]))  # Pᵀ Z
        for launch in launches:
            launch.launch()

    def transpose(self, mu, phi=None, d_nu=None, d_hs=None) -> None:
        """μ (3, N) of the ∇⁴ step's output → μ of its input Φ, in place (the transposed substeps, or
        RKL1's stages, ``_rkl1_transpose``). With ``phi`` (a callable writing Φ into a (3, N)
        array), the parameters' sums of this step added: ∂J/∂ν (wind rows: ν = ν_div moved
        together) and ∂J/∂ν_s (h row) into ``d_nu`` (2,; m⁻⁴ s · J, numpy, in place), the hs
        adjoint into ``d_hs`` (1, N; continuous, mass form). The substeps x ← L x + c B₀ hs
        (L = I + c B₀, c ∝ ν) give, with Δ₀ = c B₀ (Φ + hs) the first substep's increment and μ₁
        the adjoint before the last substep's transpose, ∂J/∂ν = S ⟨μ₁, Δ₀⟩ / ν over S substeps
        (L commutes with itself: ⟨L^(S−1−k) μ_S, L^k Δ₀⟩ is the same for every k), and
        ∂J/∂hs = (μ after − μ before)[h] (Σ_k c B₀ μ_(k+1) telescopes); with ν_div ≠ ν term by
        term (``_divergent_parameters``). The sums are the same bits on any ranks."""

        def h(x):
            self.substep(x, transposed=True)

        if self.rkl:
            self._rkl1_transpose(mu, phi, d_nu, d_hs)
            return
        if phi is None:
            for _ in range(self.substeps):
                h(mu)
            return
        m, hv, w, combine = self.model, self.hv, self.work, self.combinations.combine
        if not hasattr(w, "phi"):  # Φ + hs and Δ₀
            w.phi, w.delta = self._zeros(3), self._zeros(3)
        phi(w.phi)
        combine(w.phi[2:3], [(1.0, w.phi[2:3]), (1.0, m.operators.hs.reshape((1, m.topology.N)))])  # Φ + hs
        combine(d_hs, [(1.0, d_hs), (-1.0, mu[2:3])])
        if hv.nu_div != hv.nu:  # L and ∂L/∂ν do not commute: the substeps' terms one by one
            self._divergent_parameters(mu, d_nu)
            combine(d_hs, [(1.0, d_hs), (1.0, mu[2:3])])
            return
        wp.copy(w.delta, w.phi)
        self.substep(w.delta)
        combine(w.delta, [(1.0, w.delta), (-1.0, w.phi)])  # Δ₀
        for _ in range(self.substeps - 1):
            h(mu)
        sums = m.topology.whole_sums(m.topology.grid.spheremp * mu.numpy() * w.delta.numpy())
        rows = np.array([sums[0] + sums[1], sums[2]]) * self.substeps
        d_nu += np.divide(rows, [hv.nu, hv.nu_s], out=np.zeros(2), where=np.array([hv.nu, hv.nu_s]) > 0)
        h(mu)
        combine(d_hs, [(1.0, d_hs), (1.0, mu[2:3])])

    def _rkl1_transpose(self, mu, phi, d_nu, d_hs) -> None:
        """μ of an RKL1 super-step's output → μ of its input, in place: the step (``Hyperviscosity.
        rkl1``) Y_1 = E Y_0, Y_j = μ_j E Y_(j−1) + ν_j Y_(j−2) (E y = y + Δ(y), Δ(y) = c B₀ (y + hs)
        its forward-Euler step) reversed, its stages last first: Ȳ_(j−1) += μ_j Eᵀ Ȳ_j, Ȳ_(j−2) +=
        ν_j Ȳ_j, and Ȳ_0 += Eᵀ Ȳ_1 (Eᵀ ``substep``'s transpose, μ_j = (2j − 1)/j, ν_j = −(j − 1)/j,
        μ_1 = 1). With ``phi`` (``transpose``): the stages taken again from Φ, ∂J/∂ν (wind rows: ν
        and ν_div moved together) and ∂J/∂ν_s (h row) += μ_j ⟨Ȳ_j, c B₁ (Y_(j−1) + hs)⟩, B₁ the
        operator at unit coefficients (``_divergent_parameters``' ∂B/∂ν), and the hs adjoint += μ_j
        (Eᵀ Ȳ_j − Ȳ_j)[h]."""
        m, s, w, combine = self.model, self.substeps, self.work, self.combinations.combine
        if not hasattr(w, "rkl_bars"):
            w.rkl_bars = [self._zeros(3) for _ in range(3)]
            w.rkl_work = self._zeros(3)
            w.rkl_deltas, w.rkl_units = [], []
        cur, prev, prev2 = w.rkl_bars
        t = w.rkl_work
        if phi is not None:  # Δ_j = Δ(Y_(j−1)), the stages from Φ rolling over cur, prev, prev2 for now
            w.rkl_deltas += [self._zeros(3) for _ in range(s - len(w.rkl_deltas))]
            w.rkl_units += [self._zeros(3) for _ in range(s - len(w.rkl_units))]
            free, older = [cur, prev, prev2], None
            last = free.pop()
            phi(last)  # Y_0 = Φ
            for j in range(1, s + 1):
                d = w.rkl_deltas[j - 1]
                combine(d, [(1.0, last)])
                combine(d[2:3], [(1.0, d[2:3]), (1.0, m.operators.hs.reshape((1, m.topology.N)))])  # Y_(j−1) + hs
                combine(t, [(1.0, d)])
                self.substep(d)
                combine(d, [(1.0, d), (-1.0, t)])  # Δ_j
                self._unit_step(t, j)  # c B₁ (Y_(j−1) + hs)
                if j < s:  # Y_j = μ_j (Y_(j−1) + Δ_j) + ν_j Y_(j−2)
                    a = (2.0 * j - 1.0) / j
                    new = free.pop()
                    combine(new, [(a, last), (a, d), *([(-(j - 1.0) / j, older)] if older is not None else [])])
                    if older is not None:
                        free.append(older)
                    older, last = last, new
        combine(cur, [(1.0, mu)])
        prev.zero_()
        prev2.zero_()
        for j in range(s, 0, -1):
            combine(t, [(1.0, cur)])
            self.substep(t, transposed=True)
            weight = (2.0 * j - 1.0) / j  # μ_j (1 for j = 1)
            if phi is not None:
                sums = m.topology.whole_sums(m.topology.grid.spheremp * cur.numpy() * w.rkl_units[j - 1].numpy())
                d_nu += weight * np.array([sums[0] + sums[1], sums[2]])
                combine(d_hs, [(1.0, d_hs), (weight, t[2:3]), (-weight, cur[2:3])])
            if j == 1:
                break
            combine(prev, [(1.0, prev), (weight, t)])
            combine(prev2, [(1.0, prev2), (-(j - 1.0) / j, cur)])
            cur, prev, prev2 = prev, prev2, cur
            prev2.zero_()
        combine(mu, [(1.0, prev), (1.0, t)])

    def _unit_step(self, y, j: int) -> None:
        """``rkl_units[j − 1]`` = c B₁ y (``_rkl1_transpose``), B₁ the ∇⁴ at unit coefficients
        without hs (y holds it), recorded once per stage."""
        m, out = self.model, self.work.rkl_units[j - 1]
        launches = self._rkl_units.get(j)
        if launches is None:
            with m.operators.hs_as(self.work.zero_hs):
                launches = self._rkl_units[j] = [
                    m.lincomb(out, [(0.0, out)]),
                    *self.hv.build(y, self.coef, out=out, nus=(1.0, 1.0, 1.0)),
                ]
        for launch in launches:
            launch.launch()

    def _divergent_parameters(self, mu, d_nu) -> None:
        """μ ← the ∇⁴'s transposed substeps of μ, with ∂J/∂ν (ν and ν_div moved together) and
        ∂J/∂ν_s summed into ``d_nu`` term by term: Σ_k ⟨μ_(k+1), c B₁ y_k⟩, y_k = Φ + hs after k
        forward substeps (held), B₁ the operator at unit coefficients (its wind rows ∂B/∂ν with
        ν_div − ν fixed, its h row ∂B/∂ν_s), c = −Δt/S: with ν_div ≠ ν the ∇δ term keeps ∂L/∂ν
        from commuting with L, so ``transpose``'s S⟨μ₁, Δ₀⟩/ν does not hold."""
        m, S, c, w = self.model, self.substeps, -self.dt / self.substeps, self.work
        if self._units is None:
            if not hasattr(w, "hv_states"):
                w.hv_states, w.hv_unit = [], self._zeros(3)
            w.hv_states += [self._zeros(3) for _ in range(S - len(w.hv_states))]
            with m.operators.hs_as(w.zero_hs):  # c B₁ y_k into hv_unit, once per k (y_k holds hs: the model's is zero)
                self._units = [self.hv.build(y, c, out=w.hv_unit, nus=(1.0, 1.0, 1.0)) for y in w.hv_states[:S]]
        wp.copy(w.hv_states[0], w.phi)
        for k in range(1, S):
            wp.copy(w.hv_states[k], w.hv_states[k - 1])
            self.substep(w.hv_states[k])
        for k in reversed(range(S)):
            w.hv_unit.zero_()
            for launch in self._units[k]:
                launch.launch()
            sums = m.topology.whole_sums(m.topology.grid.spheremp * mu.numpy() * w.hv_unit.numpy())
            d_nu += [sums[0] + sums[1], sums[2]]
            self.substep(mu, transposed=True)
