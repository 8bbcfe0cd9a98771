"""The ∇⁴ hyperviscosity of a ``ShallowWater`` model, applied split from the dynamics.

``Hyperviscosity`` holds what the ∇⁴ needs beyond the model's arrays (its work
arrays, the operator's spectral radius, each Δt's plan of forward-Euler substeps
or an RKL1 super-step) and records its launches through the model's recorder (``launches.LaunchRecorder``). Mirrors
HOMME's ``biharmonic_wk`` and ``advance_hypervis`` (``viscosity_mod``,
``prim_advance_mod``); the kernels are ``kernels.hyperviscosity``. With the model's
``hypervis_scaling`` s, HOMME's tensor ∇⁴ (Guba et al. 2014): the second Laplacian reads a fixed
metric of V (``tensor_metric``), so the effective ν goes as Δx^s along each element direction.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from ..core.parallel import array_key
from ..grid.quality import element_bilinear, hypervis_tensor
from ..kernels import hyperviscosity, hyperviscosity_across, hyperviscosity_element, hyperviscosity_node, operators
from ..kernels import tracers as tracers_k
from .hyperviscosity_plan import evaluations, forward_euler_substeps, rkl1_stages
from .launches import Update
from .precision import rounded
from .transposes import HyperviscosityTranspose, TendencyTranspose

f64 = wp.float64


class Hyperviscosity:
    """The ∇⁴ of ``model`` (a ``ShallowWater`` whose terms name "hyperviscosity";
    its ν, ν_div, ν_s and ``hypervis_subcycle``): ``operator`` B x, ``apply`` over a
    step, and the step's plan (``substeps``, ``stages``, ``plan``) from the
    operator's spectral radius (``biharmonic_radius``). Allocates its work arrays
    (12 rows of N and the fixed metric's 4 on the per-element layout, 20 on the per-node one) once.

    In the model's precision (``ShallowWater``'s ``precision``; ``dtype`` its float type): under
    float32 the weak Laplacians, their work arrays (but the per-node layout's Y₁, the DSS's
    float64 output, read and rounded) and the geometry they read (``geometry``: Dinv, east,
    north, xyz; spheremp and dvv the tendency's, ``ShallowWater.tendency_arrays``; the fixed
    metrics), computed in float64 and rounded once, are float32; the state, hs and δ stay
    float64, read and rounded, the free surface h + hs − H₀ (H₀ the tendency's reference depth)
    formed in float64; the DSSs sum in float64 and the last adds coef·Y₂ to the float64 state
    in float64. The adjoint's transposes are float64's alone.

    ``across_elements``: W, the elements a vector of the CPU's weak Laplacians at np ≥ 5
    (``kernels.hyperviscosity_across.laplacian_across``, the bits of the rows'; 0 or 1: a thread an
    element, on rows, as at np ≤ 4), read when a model is built (a benchmark's switch); its
    metric then also held in the across layout (3 rows of N more)."""

    across_elements: int = 16

    def __init__(self, model):
        self.model = m = model
        N, device = m.N, m.device
        t = m.tendency_arrays
        self.dtype = dtype = t.dtype  # the model's float type: the ∇⁴'s
        # the frame the passes read (``_frame``), in that type (Dinv the tendency's; spheremp, dvv: t.mass, t.dvv)
        ops = m.operators
        self.geometry = {"Dinv": t.Dinv, **{k: ops.rounded(k, dtype) for k in ("east", "north", "xyz")}}
        # Y₁ (``kernels.hyperviscosity``); the per-node layout's is the DSS's output, float64
        self.hv_Y = wp.zeros((4, N), dtype=dtype if ops.per_element else f64, device=device)
        # the weak form of Y₁ (and Y₂'s on the per-node layout)
        self.hv_L = wp.zeros((4, N), dtype=dtype, device=device)
        # the weak Laplacian's metric, fixed: computed once, not by every ∇⁴ evaluation
        if ops.per_element or m.tracers:
            metric = wp.zeros((4, N), dtype=f64, device=device)
            m.launches.nodes(hyperviscosity.laplacian_metric, N, [ops.one_use("Dinv"), m.spheremp, metric]).launch()
            self.hv_metric = rounded(metric, dtype)  # read by the tracers' ∇⁴ on either layout
        if ops.per_element:
            self.hv_L2 = wp.zeros((4, N), dtype=dtype, device=device)  # the weak form of Y₂ (L holds Y₁'s)
        else:  # the Cartesian state and the weak Laplacian's flux of the per-node kernels
            self.hv_X = wp.zeros((4, N), dtype=dtype, device=device)
            self.hv_flux = wp.zeros((8, N), dtype=dtype, device=device)
        self.lanes = self._lanes()  # W of ``laplacian_across``, 0: the rows
        self._across_metrics: dict = {}  # a metric's rows 0..2 in the across layout, by its address
        if self.lanes:  # each CPU thread's scratch X, fx, fy and fx's memory as rows (``laplacian_across``)
            vw = wp.types.vector(length=self.lanes, dtype=dtype)
            np_, slots = m.grid.np, max(1, m.launches.threads)
            self._scratch = wp.zeros((slots, 3, np_**2), dtype=vw, device=device)
            rows = [operators.row_vectors(self._scratch[i, 1].view(dtype).flatten(), np_) for i in range(slots)]
            self._per_part = {"scratch": [self._scratch[i] for i in range(slots)], "R": rows}
        # the tensor ∇⁴'s second Laplacian reads its own fixed metric (``tensor_metric``); None: constant ν
        self.hv_tensor = None if m.hypervis_scaling is None else self.tensor_metric(m.hypervis_scaling)
        self._plan: tuple[float, tuple[int, bool]] | None = None  # (dt, its plan): the last dt's only
        self._biharmonic_radius = None
        self._rkl_buffers: dict = {}  # RKL1's Y_{j−1} or Y_{j−2} beside x, by x's shape (``rkl1``)
        # the tracers' ∇⁴ (``build_tracers``, ``build_stage``): the state's rows it acts on from
        # ``_tracer_row`` (with the limiter h's too, its element-local values the limiter's weights; in
        # the stages h's too, its ∇⁴ there), its work arrays the first weak Laplacian, its DSS Y₁, the second
        self._tracer_row = 2 if m.limiter is not None or m.stage_hyperviscosity else 3
        rows = m.rows - self._tracer_row
        self._tracer_work = (
            tuple(wp.zeros((rows, N), dtype=f64, device=device) for _ in range(3)) if m.tracers else None
        )

    def build(self, x, coef, out=None, nus=None, transposed=False, mode="add", prev=None, weight=0.0, depth=None):
        """Launches of out += coef·B x, B = ν∇⁴ the hyperviscosity operator
        (``kernels.hyperviscosity``) with coefficients ``nus`` = (ν, ν_div, ν_s)
        (None: the split ∇⁴'s, ``split_nus``); out = x if None. ``mode`` "euler": out = x + coef·B x instead;
        "rkl": out = t + ν·(prev − t), t = x + coef·B x, ν = ``weight``, an RKL1 stage (``rkl1``; out may alias x
        or prev), each in the last pass (``kernels.hyperviscosity.dss_apply``). Three passes on the per-element
        layout (the second weak Laplacian sums the first DSS itself), six on the
        per-node one (a flux pass before each weak Laplacian, the first forming the
        Cartesian wind as it reads it, and the first DSS), and the divergence δ and
        its DSS first when ν_div ≠ ν.
        ``transposed``: the tensor ∇⁴'s transpose in the mass form (for the adjoint), its two
        Laplacians' metrics swapped: B = Pᵀ RQ K̃_V RQ Π K̃ P with each K̃ symmetric has
        M⁻¹Bᵀ M = Pᵀ RQ K̃ Π RQ K̃_V P, the tensor's first (the constant ∇⁴ is its own);
        ValueError with ν_div ≠ ν (its ∇δ term is not symmetric). ``depth``: the reference
        depth H₀ (m) a float32 ∇⁴ takes the free surface from (None: the tendency's; 0 for an
        operator on other than a state, ``biharmonic_radius``'); unread in float64."""
        m = self.model
        out = x if out is None else out
        nu, nu_div, nu_s = self.split_nus if nus is None else nus
        shift = 2.0 / m.grid.radius**2  # HOMME: "so we dont damp rigid rotation"
        c = wp.types.vector(length=4, dtype=self.dtype)(nu, nu_div - nu, nu_s, shift)
        if depth is None:  # a float32 state kept between steps holds h − H₀ already (``model.held``)
            depth = m.tendency_arrays.depth if x.dtype is f64 else 0.0
        depth = float(depth)
        divergent = nu_div != nu
        if transposed and divergent:
            raise ValueError("the ∇⁴ with nu_div != nu has no transpose")
        swap = transposed and self.hv_tensor is not None  # which pass reads the tensor: the second, or the first
        # δ = DSS(∇·v), read only when divergent
        launches = m.operators.divergence_launches(x, m.operators.scalar_dss) if divergent else []
        laplacian = self._element_laplacian if m.operators.per_element else self._node_laplacian
        first, second = (laplacian(x, c, divergent, swap, s, depth) for s in (False, True))
        passes = [*launches, *first, *second]
        return [*passes, *self._dss_apply(x, coef, out, mode, prev, weight)]

    def _lanes(self) -> int:
        """W for ``laplacian_across`` (``across_elements``) where it applies: the per-element
        layout at np ≥ 5 with at least W elements; else 0 (the rows, one element a thread)."""
        m, w = self.model, int(self.across_elements)
        np_ = m.grid.np
        ok = m.operators.per_element and np_ >= 5 and w > 1 and m.N // np_**2 >= w
        return w if ok else 0

    def _in_place(self, out: wp.array2d, src: wp.array2d | None = None) -> list:
        """``laplacian_across``'s Lw and Yw: its Laplacians ``out`` and the second pass's Y₁ ``src``
        (4, N) as vectors of 16 where its transposes write and read them in place
        (``hyperviscosity_across.shuffled``); the scratch, not read, in their stead otherwise."""
        stand_in = self._per_part["scratch"][0]
        if not hyperviscosity_across.shuffled(self.model.grid.np, self.lanes, self.dtype):
            return [stand_in, stand_in]
        return [operators.row_vectors(a, 16) if a is not None else stand_in for a in (out, src)]

    def _across_metric(self, metric: wp.array2d) -> wp.array2d:
        """``metric``'s rows 0..2 in ``laplacian_across``'s layout (``kernels.operators.across_layout``),
        made once for each fixed metric (the constant ∇⁴'s, the tensor's)."""
        key = metric.ptr
        if key not in self._across_metrics:
            m, vw = self.model, wp.types.vector(length=self.lanes, dtype=self.dtype)
            values = operators.across_layout(metric.numpy()[:3], self.lanes, m.grid.np)
            self._across_metrics[key] = (wp.array(values, dtype=vw, device=m.device), metric)
        return self._across_metrics[key][0]

    def _delta(self, divergent: bool) -> wp.array2d:
        """(1, N) float64: the array of δ the weak Laplacians take, the DSS'd divergence
        (``ElementOperators.scalar_dss``, ``build``'s first pass writes it) where ν_div ≠ ν; else
        unread (the kernels compile its reads out), and hs's memory stands in, so that a float32
        state's model holds no float64 work array for it (``ElementOperators``' ``on_demand``)."""
        ops = self.model.operators
        return ops.scalar_dss if divergent else ops.hs.reshape((1, self.model.N))

    def _element_laplacian(self, x, c, divergent: bool, swap: bool, second: bool, depth: float) -> list:
        """``build``'s launches of one weak Laplacian on the per-element layout: the first
        (``second`` False) the weak form of Y₁ in L from ``x``, the second that of Y₂ in L2 from
        the DSS of L, which it sums element by element itself (on rows where the topology has
        them). ``c`` the kernels' coefficients (ν, ν_div − ν, ν_s, 2/a²), ``divergent`` ν_div ≠ ν,
        ``swap`` the tensor's metric read by the first pass instead of the second, ``depth`` the
        reference depth H₀ (m; ``build``'s)."""
        m, dtype = self.model, self.dtype
        np_, L, Y, delta = m.grid.np, self.hv_L, self.hv_Y, self._delta(divergent)
        frame = self._frame(*() if second else self._first_names(divergent), rows=True, depth=depth)
        metric = self.hv_tensor if self.hv_tensor is not None and second != swap else self.hv_metric
        args = [
            m.operators.as_rows(m.operators.hs),
            m.operators.as_rows(delta),
            c,
            frame,
            m.operators.as_rows(metric),
            m.tendency_arrays.dvv_rows,
        ]
        W, nelem = self.lanes, m.N // np_**2
        across = [self._across_metric(metric), *(v[0] for v in self._per_part.values())] if W else []
        if not second:  # x, d and Y are not read
            kernel = hyperviscosity_element.laplacian_element(False, divergent, np_, dtype=dtype)
            head = [L, m.topology.dss_copies, Y, m.operators.as_rows(x)]
            rows = [*head, *args, m.operators.as_rows(L), m.launches.block]
            if not W:
                return [m.launches.elements(kernel, rows)]
            blocks = nelem // W
            inputs = [m.operators.as_rows(x), *args, m.operators.as_rows(L), *across, *self._in_place(L)]
            launches = [
                m.launches.record(
                    hyperviscosity_across.laplacian_across(False, divergent, np_, W, dtype=dtype),
                    blocks,
                    inputs,
                    nodes_per_index=W * np_**2,
                    per_part=self._per_part,
                )
            ]
            if blocks * W < nelem:  # the elements past the last whole block: on rows
                launches.append(m.launches.elements(kernel, rows, elements=(blocks * W, nelem)))
            return launches

        # the first DSS in the second pass, element by element: on rows where the topology has them
        tail = [*args, m.operators.as_rows(self.hv_L2)]
        if m.topology.edges is not None:
            rows = lambda rows, copies, ghosts, np_: hyperviscosity_element.laplacian_element(  # noqa: E731
                True, divergent, np_, copies, ghosts, rows=True, dtype=dtype
            )
            if not W:
                return m.topology.by_element(L, rows, [m.operators.as_rows(Y), *tail])
            return m.topology.by_element(
                L,
                lambda _, copies, ghosts, np_: hyperviscosity_across.laplacian_across(
                    True, divergent, np_, W, copies, ghosts, dtype
                ),
                [m.operators.as_rows(Y), *tail, *across, *self._in_place(self.hv_L2, Y)],
                lanes=W,
                per_part=self._per_part,
                rest=(rows, [m.operators.as_rows(Y), *tail]),
            )
        return m.topology.gathering(
            L,
            lambda rows, copies, ghosts: hyperviscosity_element.laplacian_element(
                True, divergent, np_, copies, ghosts, dtype=dtype
            ),
            [Y, m.operators.as_rows(Y), *tail],
        )

    def _node_laplacian(self, x, c, divergent: bool, swap: bool, second: bool, depth: float) -> list:
        """``build``'s launches of one weak Laplacian on the per-node layout, a flux pass and
        then the Laplacian's: the first (``second`` False) the weak form of Y₁ in L from ``x``
        (its flux pass forming the Cartesian wind in hv_X as it reads it), the second that of Y₂
        in L from the DSS of L (Y₁), that DSS first. ``c``, ``divergent``, ``swap`` and ``depth`` as
        ``_element_laplacian``'s."""
        m, t = self.model, self.model.tendency_arrays
        N, np_, L, Y = m.N, m.grid.np, self.hv_L, self.hv_Y
        tensor = self.hv_tensor is not None and second != swap
        src = Y if second else self.hv_X  # what laplacian_node reads at its node
        # the first forms X, writes it in hv_X
        flux = hyperviscosity_node.laplacian_flux(not second, tensor, m.operators.static_np, self.dtype)
        flux_args = [
            Y if second else x,
            m.operators.hs,
            self._frame("east", "north", depth=depth),
            t.Dinv,
            t.mass,
            self.hv_tensor if tensor else t.Dinv,  # the tensor's metric, else not read
            t.dvv,
            np_,
            self.hv_flux,
            self.hv_X,  # written by the first alone
        ]
        passes = list(m.topology.dss(L, 0, Y)) if second else []  # the first DSS: Y₁
        passes.append(m.launches.nodes(flux, N, flux_args))
        mass = self.hv_tensor[3] if tensor else t.mass  # the weight of the +2Y₁/a² shift
        args = [
            self.hv_flux,
            src,
            self._delta(divergent),
            c,
            self._frame(*() if second else self._first_names(divergent)),
            mass,
            t.dvv,
            np_,
            L,
        ]
        kernel = hyperviscosity_node.laplacian_node(second, divergent, m.operators.static_np, self.dtype)
        return [*passes, m.launches.nodes(kernel, N, args)]

    def _dss_apply(self, x, coef: float, out, mode: str, prev, weight: float) -> list:
        """``build``'s last pass's launches: the second Laplacian's weak form (L2 on the
        per-element layout, L on the per-node one) summed over its copies (the DSS) and applied,
        out += coef·B x, or as ``mode`` says ("euler", "rkl" with ``prev`` and ``weight``, ν;
        ``kernels.hyperviscosity.dss_apply``), on the CPU's element rows where the topology has
        them (``Topology.by_element``)."""
        m = self.model
        by_element = m.operators.per_element and m.topology.edges is not None
        rows = m.operators.as_rows if by_element else (lambda a: a)
        last = [f64(coef), self._frame("east", "north", rows=by_element)]
        last += [rows(out), rows(x), rows(out if prev is None else prev), f64(weight)]
        if by_element:  # the CPU's element rows (``Topology.by_element``)
            return m.topology.by_element(
                self.hv_L2,
                lambda rows, copies, ghosts, np_: hyperviscosity.dss_apply_elements(
                    copies, ghosts, np_, mode, self.dtype, out.dtype
                ),
                last,
            )
        return m.topology.gathering(
            self.hv_L2 if m.operators.per_element else self.hv_L,
            lambda rows, copies, ghosts: hyperviscosity.dss_apply(
                copies, ghosts=ghosts, mode=mode, dtype=self.dtype, state=out.dtype
            ),
            last,
        )

    def transpose(
        self, tendency: TendencyTranspose, dt: float, shared: HyperviscosityTranspose | None = None
    ) -> HyperviscosityTranspose:
        """The transpose of ``apply`` over dt (s) in the mass form, for an adjoint
        (``model.transposes.HyperviscosityTranspose``): ``tendency`` its ∇δ term's transposes
        read (ν_div ≠ ν), its work arrays ``shared``'s (the same adjoint's at another Δt) or its own."""
        return HyperviscosityTranspose(self, tendency, dt, shared)

    def tensor_metric(self, scaling: float) -> wp.array2d:
        """The fixed metric (4, N) of the tensor ∇⁴'s second Laplacian, ∇·(V∇Y₁) + 2 v Y₁/a²
        (Guba et al. 2014; HOMME ``biharmonic_wk`` with ``hypervis_scaling``): rows 0..2 the
        quadrature-weighted spheremp · Dinv V Dinvᵀ (G₁₁, G₁₂, G₂₂; ``kernels.hyperviscosity``'s
        ``laplacian_element`` and ``laplacian_flux`` read it as the constant ∇⁴ reads spheremp ·
        Dinv Dinvᵀ), row 3 spheremp · v with v = tr V / 2 the isotropic part of V (HOMME adds
        2Y₁/a² unscaled, whose units are not those of ∇·(V∇Y₁); scaled, s = 0 is the constant
        operator). V = ``grid.quality.hypervis_tensor`` (ν·V the effective ν ∝ Δx^s per element
        direction), made continuous by a spheremp-weighted DSS over the ranks and then bilinear
        in each element from its corners, as HOMME's ``dss_hvtensor``. Built once, with the grid,
        in float64 (in the ∇⁴'s float type: ``dtype``)."""
        m = self.model
        grid = m.grid
        raw = wp.array(hypervis_tensor(grid, scaling), dtype=f64, device=m.device)
        continuous = wp.zeros_like(raw)
        for launch in m.topology.dss(raw, True, continuous):
            launch.launch()
        V11, V12, V22 = element_bilinear(continuous.numpy(), grid.rule)
        d0, d1, d2, d3 = grid.Dinv  # Dinv = [[d0, d1], [d2, d3]]
        w = grid.spheremp
        # Dinv V Dinvᵀ, V symmetric
        a11, a12, a21, a22 = d0 * V11 + d1 * V12, d0 * V12 + d1 * V22, d2 * V11 + d3 * V12, d2 * V12 + d3 * V22
        metric = np.stack(
            [w * (a11 * d0 + a12 * d1), w * (a11 * d2 + a12 * d3), w * (a21 * d2 + a22 * d3), w * (V11 + V22) / 2]
        )
        return wp.array(metric, dtype=self.dtype, device=m.device)  # rounded once under float32

    def _first_names(self, divergent: bool) -> tuple:
        """The node frame's arrays the first ∇⁴ pass reads (``_frame``): the position (and on the
        per-element layout the wind's basis), with ``divergent`` ∇δ's Dinv and the basis; the
        second pass reads none."""
        basis = ("east", "north") if self.model.operators.per_element or divergent else ()
        return ("xyz", *basis, *(("Dinv",) if divergent else ()))

    def _frame(self, *names, rows=False, depth=0.0):
        """A ``kernels.hyperviscosity.frame_type`` of the ∇⁴'s float type holding its geometry
        arrays of these names (``geometry``: xyz, east, north, Dinv), the others null: what a ∇⁴
        pass reads and no more (a launch's arguments are what ``benchmarks/gpu/gpu_model.py`` counts
        as its traffic), and the reference ``depth`` H₀ (m; ``build``'s, read by the first pass);
        with ``rows``, the element kernels' frame of their row views (``as_rows``)."""
        m = self.model
        np_ = m.grid.np
        frame = hyperviscosity.frame_type(operators.row_type(np_, self.dtype) if rows else self.dtype)()
        for name in names:
            array = self.geometry[name]
            setattr(frame, name, m.operators.as_rows(array) if rows else array)
        frame.h0 = operators.row_type(np_)(depth) if rows else depth
        return frame

    def operator(self, x: wp.array2d, out: wp.array2d) -> None:
        """out (3, N) = B x, the hyperviscosity operator ν∇⁴ with the model's
        ν, ν_div, ν_s applied to the state x (rows u, v in m s⁻² and h + hs in
        m s⁻¹; ``kernels.hyperviscosity``): dx/dt = −B x is the dissipation.
        ``out`` must not alias ``x``."""
        m = self.model
        out.zero_()
        m.launches.replay(("hvop", array_key(x), array_key(out)), (x, out), lambda: self.build(x, 1.0, out))

    def biharmonic_radius(self, iterations: int = 20) -> float:
        """Largest eigenvalue λ (m⁻⁴) of the discrete ∇⁴ operator with unit
        coefficients (ν = ν_div = ν_s = 1 m⁴ s⁻¹, wind and height together), by
        power iteration from a fixed random continuous state. Forward Euler on
        dx/dt = −ν∇⁴x is stable for max(ν, ν_div, ν_s) Δt λ ≤ 2. With the tensor
        (``tensor_metric``), λ is the tensor operator's: its top mode sits on the element with
        the largest ∇⁴ Courant number ν_eff Δt / Δx⁴ (the smallest one under constant ν; under
        s = 4 every element's is alike), which so sets ``substeps`` and ``stages``."""
        m = self.model
        if self._biharmonic_radius is None:
            rng = np.random.default_rng(0)
            z = m.topology.standard_normal(rng, 3)  # the same vector on any ranks
            z = wp.array(z, dtype=f64, device=m.device)
            w, zc = wp.zeros_like(z), wp.zeros_like(z)
            for launch in m.topology.dss(z, 1, zc):
                launch.launch()
            lam = 0.0
            with m.operators.hs_as(wp.zeros_like(m.operators.hs)):  # the operator without the hs and H₀ offsets
                launches = self.build(zc, 1.0, w, nus=(1.0, 1.0, 1.0), depth=0.0)
            for _ in range(iterations):
                zc.assign(zc.numpy() / m.topology.norm(zc))
                w.zero_()
                for launch in launches:
                    launch.launch()
                lam = m.topology.norm(w)  # ‖∇⁴ z‖
                wp.copy(zc, w)
            self._biharmonic_radius = lam
        return self._biharmonic_radius

    def use_biharmonic_radius(self, radius: float) -> None:
        """Take ``radius`` (m⁻⁴, > 0) as ``biharmonic_radius`` instead of computing it: a model
        whose operator is block-diagonal in copies of another's (an ensemble's members, each
        a copy of one grid) has that grid's λ, and handed it plans the same substeps and
        stages as the one grid (its own power iteration, from another random vector, would
        land on other bits). ValueError unless finite and > 0."""
        if not np.isfinite(radius) or radius <= 0:
            raise ValueError(f"the biharmonic radius must be finite and > 0 (got {radius})")
        self._biharmonic_radius, self._plan = float(radius), None

    @property
    def nu(self) -> float:
        """ν (m⁴ s⁻¹), the rotational wind's coefficient: the model's (``ShallowWater``'s ``nu``)."""
        return self.model.nu

    @property
    def nu_div(self) -> float:
        """ν_div (m⁴ s⁻¹), the divergent wind's: the model's."""
        return self.model.nu_div

    @property
    def nu_s(self) -> float:
        """ν_s (m⁴ s⁻¹), the free surface h + hs's: the model's."""
        return self.model.nu_s

    @property
    def every(self) -> int:
        """k, the steps between ∇⁴ applications, each over the k steps' span (the model's
        ``hypervis_every``, the scene's ``hyperviscosity.every``; 1: every step): a stepper that
        allows it applies ``apply`` over kΔt after every k-th step (``steppers.base.Stepper``)."""
        return self.model.hypervis_every

    @property
    def nu_max(self) -> float:
        """The largest of ν, ν_div, ν_s (m⁴ s⁻¹) of the split ∇⁴ (``split_nus``): what limits its steps."""
        return max(self.split_nus)

    def substeps(self, dt: float) -> int:
        """Forward-Euler substeps for ``apply`` over dt (``forward_euler_substeps``)."""
        return forward_euler_substeps(self.nu_max * dt * self.biharmonic_radius(), self.model.hypervis_subcycle)

    def stages(self, dt: float) -> int:
        """RKL1 stages for ``apply`` over dt (``rkl1_stages``)."""
        return rkl1_stages(self.nu_max * dt * self.biharmonic_radius())

    def plan(self, dt: float) -> tuple[int, bool]:
        """(∇⁴ evaluations, RKL1?) of one ``apply`` over dt (``evaluations`` at ν dt λ, λ
        ``biharmonic_radius``); the last dt's kept (a controlled run's dt changes every step)."""
        if self._plan is None or self._plan[0] != dt:
            self._plan = (dt, evaluations(self.nu_max * dt * self.biharmonic_radius(), self.model.hypervis_subcycle))
        return self._plan[1]

    def build_tracers(self, src, out, prev, mode: str, c: tuple) -> list:
        """Launches of one ∇⁴ evaluation of the tracers (rows 3.. of the states), before the
        depth's of the same substep or stage (``apply``): Y₂ = M⁻¹DSS(L₂), L₂ the weak Laplacian
        (the tensor's where the ∇⁴ has one) of Y₁ = M⁻¹DSS(L₁), L₁ = ν_s·the weak Laplacian of
        hq + q·hs from ``src`` (``kernels.tracers.tracer_laplacian``;
        HOMME ``biharmonic_wk_scalar``), then by ``mode`` with the coefficients ``c``: "add", out +=
        c₀·Y₂ (out = src); "euler", out = src + c₀·Y₂; "rkl", out = t + c₁·(prev − t), t = src +
        c₀·Y₂ (an RKL1 stage, c = (coef, ν), the depth's form: ``rkl1``), as the second DSS sums
        (``Topology.dss_update``), or with
        the model's limiter, limited before it (``limiter.TracerLimiter.stage``: q against h's own
        element-local values, h's Laplacians computed beside the tracers' for them, so that q = 1
        stays 1; h itself is left to the depth's ∇⁴). out may alias src and
        prev. The launches (and the DSSs' exchanges) serve every tracer at once."""
        m = self.model
        L2 = self._tracer_work[2]
        if mode == "rkl":  # the terms of t + c₁·(prev − t), t = 1·src + c₀·Y₂ (``dss.rkl_stage``)
            terms = ((1.0, src), (c[1], prev), (c[0], None))
        else:
            terms = ((1.0, out if mode == "add" else src), (c[0], None))
        launches = self._tracer_laplacians(src, L2, "")
        if m.limiter is not None:  # HOMME limits the tracers' biharmonic with their transport (euler_step)
            return [*launches, *m.limiter.stage(Update(out, terms), L2, True, first=2, rkl=mode == "rkl")]
        sliced = tuple((a, None if a_src is None else a_src[3:]) for a, a_src in terms)
        return [*launches, *m.topology.dss_update(L2, [(out[3:], sliced)], weighted=False, rkl=mode == "rkl")]

    def _tracer_laplacians(self, src, out, into: str) -> list:
        """The launches of L₂, the weak Laplacian (the tensor's where the ∇⁴ has one) of Y₁ =
        M⁻¹DSS(L₁), L₁ = ν_s·the weak Laplacian of hq + q·hs (from ``_tracer_row``: with h's, h + hs)
        from ``src`` (``kernels.tracers.tracer_laplacian``; HOMME ``biharmonic_wk_scalar``), into
        ``out`` as ``into`` says (``kernels.tracers.INTO``: written, or subtracted from a tendency)."""
        m = self.model
        ops, (L1, Y1, _) = m.operators, self._tracer_work
        second = self.hv_tensor if self.hv_tensor is not None else self.hv_metric
        dvv, rows, np_, mass = m.tendency_arrays.dvv_rows, ops.as_rows, m.grid.np, m.tendency_arrays.mass
        return [
            m.launches.elements(
                tracers_k.tracer_laplacian(True, np_, self._tracer_row),
                [rows(src), rows(ops.hs), rows(self.hv_metric), dvv, m.nu_s, rows(L1), rows(mass)],
            ),
            *m.topology.dss(L1, False, Y1),
            m.launches.elements(
                tracers_k.tracer_laplacian(False, np_, into=into),
                [rows(Y1), rows(ops.hs), rows(second), dvv, 1.0, rows(out), rows(mass)],
            ),
        ]

    def build_stage(self, x, tend, weighted: bool) -> list:
        """Launches of the depth's and the tracers' ν_s ∇⁴ inside a stage's right-hand side (the
        model's ``stage_hyperviscosity``; HOMME's ``advance_nonstag_rk``, its ``biharmonic_wk`` of q
        in every stage): −ν_s ∇⁴ of h + hs and of each q(h + hs) from the stage's state ``x``,
        subtracted from the element-local tendency ``tend``'s rows 2.. (spheremp-weighted where
        ``weighted``, else pointwise) before its DSS, so that the stage's limiter limits it with the
        transport (HOMME limits Qtens so made). h's and a tracer's are the same arithmetic where hq
        = h (q = 1 stays 1), and each weak ∇⁴ sums to zero (the masses kept)."""
        return self._tracer_laplacians(x, tend[2:], "weighted" if weighted else "pointwise")

    @property
    def split_nus(self) -> tuple[float, float, float]:
        """(ν, ν_div, ν_s) of the ∇⁴ applied split from the dynamics (``apply``): the model's, with
        ν_s 0 where its ν_s acts inside the stages instead (``stage_hyperviscosity``)."""
        m = self.model
        return (m.nu, m.nu_div, 0.0 if m.stage_hyperviscosity else m.nu_s)

    def apply(self, x: wp.array2d, dt: float) -> None:
        """Apply ∇⁴ hyperviscosity over dt (s) in place, split from the dynamics:
        n = ``substeps(dt)`` forward-Euler steps of x −= (dt/n) B x
        (B: ``operator``, ν ∇⁴ with ν, ν_div, ν_s)
        (HOMME ``advance_hypervis`` with ``hypervis_subcycle``), or, when that
        takes more ∇⁴ evaluations than an s-stage RKL1 super-time-step
        (``stages``; n > s, n set by stability rather than by the scene's
        subcycle: from n = 3, so a step that needs one or two substeps keeps forward
        Euler), the RKL1 step, whose cost grows as
        √(ν dt λ) instead of linearly (TC5 ne16, dt_g the gravity-wave limit:
        n / s = 6 / 3, 15 / 5, 45 / 9 at 4, 10, 30 dt_g).
        Why RKL1 and not the second-order RKL2: RKL2's amplification of the
        stiff modes is ≈ 1/2 a step (a_s + b_s P_s, a_s, b_s → 1/2) where the
        exact factor is ~0; with it IMEX ARS(2,3,2) at 12 dt_g on TC5 ne8 blew
        up on day 4, as with forward Euler it does not. RKL1's P_s damps the
        interior of its interval to ≲ 0.3; the split is first order anyway.
        Does nothing (launches nothing) with ν = ν_div = ν_s = 0 (``split_nus``: ν_s 0 where it acts
        in the stages, ``build_stage``). With the model's tracers (and
        ν_s ≠ 0, ``tracer_hyperviscosity``, not in the stages) each substep or stage is preceded by the tracers' own
        (``build_tracers``: ν_s ∇⁴ of q(h + hs), each tracer a scalar field alone, ∫hq conserved,
        h's arithmetic where hq = h; q·hs of the substep's or stage's own state).
        """
        m = self.model
        if self.nu_max == 0.0:
            return
        tracers = bool(m.tracers) and m.nu_s != 0.0 and m.tracer_hyperviscosity and not m.stage_hyperviscosity
        n, rkl = self.plan(dt)
        if rkl:
            self.rkl1(x, dt, n, tracers)
            return
        coef = -dt / n
        for _ in range(n):
            if tracers:  # before the depth's substep, whose h the limiter's element-local values start from
                m.launches.replay(("hv_tracers", x.ptr), (x,), lambda c: self.build_tracers(x, x, x, "add", c), (coef,))
            m.launches.replay(("hv", x.ptr), (x,), lambda c: self.build(x, c[0]), (coef,))

    def rkl1(self, x: wp.array2d, dt: float, s: int, tracers: bool = False) -> None:
        """One s-stage RKL1 step (Meyer, Balsara & Aslam 2014, eqs. 10–11) of
        dx/dt = M(x) = −B x over dt (s), in place on the state x (3, N): Y_0 = x, Y_1 = E(Y_0),
        Y_j = μ_j E(Y_{j−1}) + ν_j Y_{j−2}, μ_j = (2j − 1)/j, ν_j = −(j − 1)/j,
        with E one forward-Euler step of w₁Δt, w₁ = 2/(s² + s); first order, stable for
        ν dt λ ≤ s² + s. Since μ_j + ν_j = 1 each stage is formed as t + ν_j (Y_{j−2} − t), t =
        E(Y_{j−1}): μ_j·t + ν_j·Y_{j−2} rounded fl(μ_j)·h and fl(ν_j)·h alike at nearly every
        node (fl(5/3) + fl(−2/3) ≠ 1), +2.5e-16 of the mass an application (Galewsky ne8 np8,
        +1.5e-14 a day); the difference form rounds without a bias. ``apply``'s super-step with
        s = ``stages(dt)``; any s ≥ 2 here (a convergence study's). Each stage is one ∇⁴ evaluation whose last pass forms Y_j
        (``build``'s "euler" and "rkl" modes), in x and one work array: Y_j overwrites Y_{j−2},
        or x at the last stage (each read at its own node only). ``tracers``: each stage preceded by
        the tracers' (``apply``'s)."""
        m = self.model
        if (x.shape, x.dtype) not in self._rkl_buffers:
            self._rkl_buffers[x.shape, x.dtype] = wp.zeros_like(x)
        coef = -dt * 2.0 / (s * s + s)

        def stage(src, out, prev, mode, nu=0.0):
            key = ("hv", mode, src.ptr, out.ptr, prev.ptr)
            if (
                tracers
            ):  # the tracers' stage before the depth's (``apply``), its coefficients as ``build_tracers`` takes them
                build = lambda c: self.build_tracers(src, out, prev, mode, c)  # noqa: E731
                c = (coef,) if mode == "euler" else (coef, nu)
                m.launches.replay(("hv_tracers", *key[1:]), (src, out, prev), build, c)
            build = lambda c: self.build(src, c[0], out, mode=mode, prev=prev, weight=c[1] if mode == "rkl" else 0.0)  # noqa: E731
            m.launches.replay(key, (src, out, prev), build, (coef, nu) if mode == "rkl" else (coef,))

        prev, cur = x, self._rkl_buffers[x.shape, x.dtype]
        stage(x, cur, x, "euler")  # Y_1
        for j in range(2, s + 1):
            out = x if j == s else prev  # Y_{j−2} is not needed after this stage
            stage(cur, out, prev, "rkl", -(j - 1.0) / j)
            prev, cur = cur, out
