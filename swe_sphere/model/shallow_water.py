"""The shallow-water model: right-hand side and diagnostics operators, and its ∇⁴ (``hypervis``).

``ShallowWater`` uploads the grid once, allocates its work arrays once and
records every kernel launch the first time it is used on a given pair of
arrays; afterwards ``rhs`` and ``hyperviscosity`` only replay recorded
launches (no allocation in the time loop). The tendency kernel is compiled
for the scene's terms alone (``kernels.tendencies.tendency``); the
hyperviscosity kernels run only when it is a term, the forcing kernel (an
analytic function of position and model time, ``set_time``) only when the
scene names ``forcing``. Mirrors HOMME's ``compute_and_apply_rhs`` + ``advance_hypervis``.
"""

from __future__ import annotations

import functools

import numpy as np
import warp as wp

from ..core.arguments import array_argument, got, integer_argument, number_argument
from ..core.backend import Backend, same_device
from ..core.constants import EARTH
from ..core.errors import ArgumentError
from ..grid.cubed_sphere import CubedSphere
from ..grid.topology import Topology
from ..kernels import departure, operators, tendencies
from .arguments import checked_terms, checked_tracers
from .bad_nodes import BadNodes
from .element_operators import ElementOperators
from .filter import ElementFilter
from .gravity_wave import GravityWaveOperator
from .held import HeldState
from .helmholtz import HelmholtzOptions, HelmholtzSolver
from .hyperviscosity import Hyperviscosity
from .lanes import TendencyLanes
from .launches import LaunchRecorder, check_updates
from .limiter import TracerLimiter
from .mass_fixer import MassFixer
from .parts import ElementPart, element_runs
from .precision import TendencyArrays, precision_dtype, reference_depth, state_dtype

f64 = wp.float64


class ShallowWater:
    """Vector-invariant shallow-water equations on a cubed-sphere SE grid.

    Parameters
    ----------
    grid : CubedSphere
    terms : iterable of names from ``arguments.TERMS``; a term not named is neither compiled nor run.
    fcor, hs : (N,) Coriolis parameter (s⁻¹) and surface height (m), element-local.
    nu, nu_div, nu_s : hyperviscosity coefficients (m⁴ s⁻¹) of the rotational
        wind, the divergent wind and the free surface h + hs (HOMME's names;
        None: ``nu``), used if "hyperviscosity" is a term
        (``kernels.hyperviscosity``).
    hypervis_subcycle : forward-Euler substeps per ``hyperviscosity`` call.
    hypervis_every : the steps k between ∇⁴ applications (each over the k steps' span): a
        stepper applies it at every k-th step (``steppers.base.Stepper.dissipate``); 1: every step.
    hypervis_scaling : None (constant ν) or s ≥ 0: HOMME's tensor ∇⁴ (``hypervis_scaling``;
        Guba et al. 2014), effective ν·(Δx / Δx_ref)^s per element direction
        (``hyperviscosity.Hyperviscosity.tensor_metric``).
    element_filter : None, or (mu, p, s) of a Boyd–Vandeven element filter applied with the ∇⁴
        (``hyperviscosity``: every step, or every k-th with it; ``filter.ElementFilter``,
        ``grid.gll.boyd_vandeven``): mu in (0, 1], p > 0, s in (0, 1); ValueError otherwise.
    forcing : (kernel, params) of the "forcing" term, supplied by the case
        (``cases.ForcedLow.forcing``): a pointwise kernel (xyz, east, north,
        params, t, tend, block, offset) that adds the forcing at model time t
        to the element-local tendency before its DSS (``kernels.forcing``).
    device : "cpu" or "cuda".
    threads : CPU threads per launch (None: ``SWE_SPHERE_THREADS``, else the
        usable CPUs; ignored on CUDA). Each element-local launch runs as that
        many disjoint node ranges at once (``swe_sphere.core.parallel``); the
        results are the same bits for any thread count.
    per_element : the kernels' layout: one thread per element (None: on a CPU
        device, where a launch is a serial loop and the element's data stays
        in cache) or one thread per node (on CUDA). Same results to round-off.
    topology : the ``Topology`` that assembles the grid's elements (DSS,
        unique-node vectors, global reductions); None: one over the whole grid.
        Its ``backend`` (``core.backend``) is the model's ``backend``, the device's
        choices decided once.
    precision : "float64" (default), "float32" or "float32_state": the float type the tendency
        and the ∇⁴ are computed in (``model.precision``: under "float32" the state, its updates
        and every sum stay float64; under "float32_state" an explicit Runge–Kutta step holds its
        state and stages in float32 too, ``state_dtype``: ``model.precision``'s note).
    compensated : under "float32_state", whether the run holds the float32 state from step to
        step (False, the default: ``held``, ``kernels.departure``), or a float64 state between
        steps, each step's float32 increment added to it in float64 (True: compensated, converted
        at each step's two ends); unread otherwise.
    mass_fixer : under "float32_state", whether a step's end puts back the mass ∫h its start
        held (True, the default: ``model.mass_fixer``); unread otherwise.
    depth : a float32 tendency's and ∇⁴'s reference depth H₀ (m; ``precision.TendencyArrays``): None, 0
        (no shift); ``from_case`` gives the midpoint of its initial depth's extremes.
    tracers : K ≥ 0 passive tracers (``from_scene``: the scene's [tracers]), carried as their
        masses hq (m) in rows 3..3+K−1 of the state, in flux form by the continuity's own
        arithmetic (``kernels.tendencies``: ∂(hq)/∂t = −∇·(hq v)), so that q = 1 stays 1 and
        each tracer's mass ∫hq is conserved as h's; 0: the tendency kernels hold no tracer code.
        With the ∇⁴ each tracer mass takes ν_s ∇⁴ of q(h + hs) (``hyperviscosity``), unless
        ``tracer_hyperviscosity`` is False.
    limiter : "none" (default) or "optimization": the tracers' shape-preserving limiter
        (``limiter.TracerLimiter``: Guba et al. 2014, HOMME's limiter 8) within the bounds of a
        step's start, which an explicit Runge–Kutta stepper applies to each stage's element-local
        values before their DSS (``rhs_update``'s ``limit``) and to the tracers' ∇⁴.
    tracer_hyperviscosity : True (default): the tracers take the ∇⁴ (``tracers`` above); False:
        none on them (q = 1 then drifts where the depth is damped; their masses are still kept).
    stage_hyperviscosity : False (default): the depth's and the tracers' ν_s ∇⁴ applied once a
        step, split after it (``hyperviscosity``); True: inside every stage's right-hand side
        instead, from the stage's state (HOMME's ``advance_nonstag_rk``; ``hv.build_stage``),
        limited with the stage's transport where the model has a limiter; the wind's ν, ν_div
        stay split. Needs tracers, the "hyperviscosity" term and ``tracer_hyperviscosity``. The
        stages then step ν_s ∇⁴ explicitly: ν_s Δt λ within the stepper's stability interval
        (``hv.biharmonic_radius`` λ).
    lanes : the tendency's vector lanes on the CPU's elements at np 4 (``model.lanes``): W
        elements a vector, a thread W elements; None (default): the measured choice of the
        precision's float type (``lanes.LANES``: float32 16, float64 0); 0: its GLL rows, an element
        a thread. Unread where they do not apply (np ≠ 4, the per-node layout, tracers).

    Raises
    ------
    ValueError
        An unknown term, a negative ν, or the forcing term without a forcing or without any
        tendency term to add to.
    ArgumentError
        (a ``SweSphereError`` and ``ValueError``) naming the argument for a ``grid`` that is not a
        ``CubedSphere``, ``fcor`` or ``hs`` not finite numbers of shape (N,), ν, g, the subcycle,
        ``tracers`` or ``lanes`` not numbers in range, tracers without the continuity term or
        under a precision other than "float64" (``precision.tracers_refusal``),
        ``stage_hyperviscosity`` without tracers, the term or ``tracer_hyperviscosity``, a ``device`` that is
        not a name, or a ``device`` other than its ``topology``'s (the model's arrays would live
        where its launches do not: an illegal memory access on CUDA).

    Notes
    -----
    The state is a ``wp.array2d`` (3 + K, N) of rows u, v (m s⁻¹, east/north), h
    (fluid depth, m) and the K tracer masses hq (m), element-local and continuous (equal on all
    copies); ``rows`` = 3 + K.
    """

    # what writes the launches of the operators built on this model (the gravity-wave operator,
    # the Helmholtz solves) on a tape: None here; a gradient's ``adjoint.tape.TapedModel`` injects
    # its tape, so that those operators need not know of the adjoint
    recorder = None

    def __init__(
        self,
        grid: CubedSphere,
        terms,
        fcor,
        hs,
        *,
        nu=0.0,
        nu_div=None,
        nu_s=None,
        hypervis_subcycle=1,
        hypervis_scaling=None,
        hypervis_every=1,
        element_filter=None,
        g=EARTH.g,
        device="cpu",
        threads=None,
        per_element=None,
        topology=None,
        forcing=None,
        precision="float64",
        compensated=False,
        mass_fixer=True,
        depth=None,
        tracers=0,
        limiter="none",
        tracer_hyperviscosity=True,
        stage_hyperviscosity=False,
        lanes=None,
    ):
        if not isinstance(grid, CubedSphere):
            raise ArgumentError(f"grid must be a CubedSphere (got {got(grid)})")
        fcor = array_argument("fcor", fcor, (grid.nnodes,), "s⁻¹")
        hs = array_argument("hs", hs, (grid.nnodes,), "m")
        for name, value in (("nu", nu), ("nu_div", nu_div), ("nu_s", nu_s)):
            if value is not None:
                number_argument(name, value, "m⁴ s⁻¹", low=0.0)
        integer_argument("hypervis_subcycle", hypervis_subcycle, low=1)
        integer_argument("hypervis_every", hypervis_every, low=1)
        if element_filter is not None:
            mu, p, s = element_filter
            if not (0.0 < mu <= 1.0 and p > 0.0 and 0.0 < s < 1.0):
                raise ValueError(
                    f"element_filter (mu, p, s) needs 0 < mu <= 1, p > 0, 0 < s < 1 (got {element_filter})"
                )
        number_argument("g", g, "m s⁻²", positive=True)
        if not isinstance(device, str) or not device:
            raise ArgumentError(f"device must be a device's name such as 'cpu' or 'cuda' (got {got(device)})")
        if topology is not None and not same_device(device, topology.backend.device):
            raise ArgumentError(
                f"device {device!r} is not its topology's ({topology.backend.device!r}): give the topology's device"
            )
        terms = checked_terms(terms, forcing)
        if lanes is not None:
            integer_argument("lanes", lanes, low=0)
        checked_tracers(tracers, terms, limiter, precision, tracer_hyperviscosity, stage_hyperviscosity)
        self.tracers, self.rows = int(tracers), 3 + int(tracers)
        self.tracer_hyperviscosity = bool(tracer_hyperviscosity)  # the ∇⁴ on them (``hyperviscosity``)
        self.stage_hyperviscosity = bool(stage_hyperviscosity)  # ν_s ∇⁴ in the stages (``_build_tendency``)
        dtype = precision_dtype(precision)
        self.forcing = forcing if "forcing" in terms else None
        self.time = 0.0  # s, the model time of the next RHS evaluation (``set_time``)
        self._forcing_launches = []  # every recorded forcing launch, whose t set_time sets
        self.nu_div, self.nu_s = float(nu if nu_div is None else nu_div), float(nu if nu_s is None else nu_s)
        self.grid, self.terms, self.device = grid, terms, device
        self.backend = Backend.of(device) if topology is None else topology.backend  # decided once
        self.threads = self.backend.threads() if threads is None else int(threads)
        if self.threads < 1:
            raise ValueError(f"threads must be >= 1 (got {threads})")
        self.nu, self.hypervis_subcycle, self.g = float(nu), int(hypervis_subcycle), float(g)
        self.hypervis_scaling = None if hypervis_scaling is None else float(hypervis_scaling)
        self.hypervis_every = int(hypervis_every)
        per_element = self.backend.per_element if per_element is None else bool(per_element)
        N = grid.nnodes
        self.N = N
        self.topology = topo = Topology(grid, self.backend, self.threads) if topology is None else topology
        self.spheremp = topo.spheremp

        # every launch of the model and of what acts on its states, recorded once and replayed
        self.launches = LaunchRecorder(self.backend, self.threads, grid.np, N, topo.nunique, per_element)
        self.precision = precision
        self.state_dtype, self.compensated = state_dtype(precision), bool(compensated)
        # the float64 geometry on the device where the steps read it; a float32 state's steps read
        # their float32 copies, so that there it is uploaded where read and the diagnostics' let go
        gravity = self.g if "topography" in terms else None
        on_demand = self.state_dtype is not f64
        self.operators = ElementOperators(grid, topo, self.launches, per_element, device, fcor, hs, gravity, on_demand)
        # the float32 state's global mass fixer (None: none)
        self.mass_fixer = MassFixer(self) if mass_fixer and self.state_dtype is not f64 else None
        # the tendency's vector lanes where they pay (``model.lanes``), and what the tendency kernels
        # read and write, in the precision's float type (no float32 rows of the geometry the lanes hold)
        self.lanes = TendencyLanes(self, lanes, dtype, per_element)
        depth = 0.0 if depth is None else number_argument("depth", depth, "m")
        self.tendency_arrays = TendencyArrays.of(
            dtype,
            self.operators,
            self.spheremp[:N],
            "topography" in terms,
            depth,
            self.rows,
            rows_geometry=not self.lanes.applies(self.tracers),
        )
        self.held = HeldState(self)  # the state a run holds between steps, and its float64 reads
        # the tracers' limiter (a scene's tracers.limiter); None: none
        self.limiter = TracerLimiter(self) if self.tracers and limiter != "none" else None
        self.hv = Hyperviscosity(self) if "hyperviscosity" in terms else None  # the ∇⁴: its plan, work arrays, launches
        self.filter = None if element_filter is None else ElementFilter(self, *element_filter)  # a scene's [filter]
        self.bad_nodes = BadNodes(self)  # the check of a state for non-finite or dry nodes

    @functools.cached_property
    def tend(self) -> wp.array2d:
        """(rows, N) float64 element-local work array of the operators built on the model (the
        gravity-wave operator's): the tendency's own under float64; under float32 an array of
        its own, made on first use (a float32 run of an explicit stepper never holds it)."""
        t = self.tendency_arrays
        return t.tend if t.dtype is f64 else wp.zeros((self.rows, self.N), dtype=f64, device=self.device)

    @property
    def topo_forcing(self) -> wp.array2d | None:
        """(2, N) float64 −g ∇hs (m s⁻², east/north) at the element-local nodes on the device (None
        without the "topography" term): its constant forcing, the gradient of the surface height by
        the element's operators (``ElementOperators``' ``forcing``, uploaded on first read)."""
        return self.operators.forcing if "forcing" in self.operators.geometry else None

    @classmethod
    def from_case(cls, grid: CubedSphere, case, terms, **options) -> ShallowWater:
        """The model of ``case`` on ``grid``: the case's Coriolis parameter and surface height at
        the grid's nodes, its planet's g and, with the "forcing" term, its forcing. ``case``: a
        ``cases.library.Case`` (taken by its methods ``fcor``, ``hs``, ``forcing`` and its
        ``planet``: the model sits below the cases); ``options`` the constructor's others
        (nu…, device, threads, per_element, topology). Raises as the constructor."""
        fcor, hs = case.fcor(grid.lat, grid.lon), case.hs(grid.lat, grid.lon)
        forcing = case.forcing() if "forcing" in terms else None
        if options.get("precision", "float64") != "float64" and options.get("depth") is None:
            options["depth"] = reference_depth(case.initial(grid.lat, grid.lon)[2], options.get("topology"))
        return cls(grid, terms, fcor, hs, g=case.planet.g, forcing=forcing, **options)

    @classmethod
    def from_scene(cls, scene, grid: CubedSphere, case=None, **options) -> ShallowWater:
        """The model a scene calls for on ``grid`` (the whole grid, or a rank's part): its
        terms and ∇⁴ (``nu``, ``nu_div``, ``nu_s``, ``hypervis_subcycle``,
        ``hypervis_scaling``, ``hypervis_every``) and its case's fields (``from_case``; ``case``: the scene's,
        ``scene.make_case()``, if None). ``scene``: a ``config.Scene``, read by those
        attributes alone (config sits above the model, which imports nothing of it);
        ``options`` the constructor's others (device, threads, per_element, topology)."""
        case = scene.make_case() if case is None else case
        hyperviscosity = {
            "nu": scene.nu,
            "nu_div": scene.nu_div,
            "nu_s": scene.nu_s,
            "hypervis_subcycle": scene.hypervis_subcycle,
            "hypervis_scaling": scene.hypervis_scaling,
            "hypervis_every": scene.hypervis_every,
            "element_filter": scene.element_filter,
        }
        options.setdefault("precision", scene.precision)
        options.setdefault("compensated", scene.compensated)
        options.setdefault("mass_fixer", scene.mass_fixer)
        options.setdefault("tracers", len(scene.tracers))
        options.setdefault("limiter", scene.tracer_limiter)
        options.setdefault("tracer_hyperviscosity", scene.tracer_hyperviscosity)
        options.setdefault("stage_hyperviscosity", scene.tracer_stage_hyperviscosity)
        return cls.from_case(grid, case, scene.terms, **hyperviscosity, **options)

    # -- the recorder's (``launches.LaunchRecorder``) -----------------------
    def lincomb(self, out, terms):
        """``launches.lincomb``: the recorded launch of out = Σ c·x over (c, x) terms."""
        return self.launches.lincomb(out, terms)

    def pointwise(self, kernel, *inputs, unique=False) -> None:
        """``launches.run_pointwise``: run a pointwise kernel, recorded on first use."""
        self.launches.run_pointwise(kernel, *inputs, unique=unique)

    # -- right-hand side ----------------------------------------------------
    def _build_tendency(self, x, named, part=None):
        """Launches that write the element-local tendency of the terms ``named``
        into ``tendency_arrays.tend`` (or, given an ``ElementPart``, into its ``tend`` over its
        elements only), the rows (lo, hi) they write (a continuity half
        writes dh alone, a momentum half du, dv) and whether it is mass-weighted. Without a
        forcing the kernel writes spheremp·F, whose unweighted DSS is F's weighted one: the
        DSS then reads no copy's mass (0.72–0.84× a DSS update at ne30 np4 and ne12 np8); a
        forcing adds F_forcing after it, so there F and the weighted DSS. With
        ``stage_hyperviscosity`` and "hyperviscosity" named, −ν_s ∇⁴ of h + hs and of the tracers'
        q(h + hs) is subtracted from rows 2.. last (``hv.build_stage``; ValueError for a ``part``)."""
        terms = tuple(term for term in tendencies.TENDENCY_TERMS if term in named)
        t = self.tendency_arrays
        tend, runs = (t.tend, [None]) if part is None else (part.tend, part.runs)
        launches, ops = [], self.operators
        forced = self.forcing is not None and "forcing" in named
        K = self.tracers if "continuity" in terms else 0  # the tracers ride the continuity
        departed = x.dtype is not f64  # a float32 state's h − H₀ (``precision.state_dtype``)
        if terms and self.lanes.applies(K):  # float32 at np 4: W elements a vector, a block of them a thread
            for blocks in element_runs(self.lanes.blocks(runs), 0):
                launches.append(self.lanes.launch(x, tend, terms, not forced, blocks))
        elif terms:
            forcing = t.forcing if t.forcing is not None else t.Dinv[0:2]  # read only with topography
            args = [x, t.Dinv, t.metdet, t.fcor, forcing, t.mass]
            for run in runs:
                if ops.per_element:
                    kernel = tendencies.tendency_element(terms, self.grid.np, not forced, t.dtype, K, departed)
                    h0 = operators.row_type(self.grid.np, x.dtype)(t.depth)
                    inputs = [*map(ops.as_rows, args), self.g, h0, t.dvv_rows, ops.as_rows(tend)]
                    launches.append(self.launches.elements(kernel, inputs, run))
                else:
                    kernel = tendencies.tendency(terms, ops.static_np, not forced, t.dtype, K, departed)
                    inputs = [*args, t.dvv, self.grid.np, self.g, t.depth, tend]
                    launches.append(self.launches.nodes(kernel, self.N, inputs, elements=run))
        if forced:
            kernel, params = self.forcing
            for run in runs:
                launch = self.launches.pointwise(
                    kernel, None, [ops.xyz, ops.east, ops.north, params, f64(self.time), tend], run
                )
                self._forcing_launches.append(launch)
                launches.append(launch)
        if self.stage_hyperviscosity and K and "hyperviscosity" in named and self.nu_s != 0.0:
            if part is not None:  # its Laplacians' DSS between them is the whole grid's
                raise ValueError("a part's right-hand side has no stage ∇⁴ (stage_hyperviscosity)")
            launches.extend(self.hv.build_stage(x, tend, not forced))
        lo = 0 if forced or set(terms) - {"continuity"} else 2
        hi = 3 + K if "continuity" in terms else 3 if forced else 2
        return launches, lo, hi, not forced

    def _build_rhs(self, x, out, named, part=None):
        launches, lo, hi, weighted = self._build_tendency(x, named, part)
        tend = self.tendency_arrays.tend if part is None else part.tend
        rows = (lambda a: a) if (lo, hi) == (0, self.rows) else (lambda a: a[lo:hi])
        if part is None:
            launches.extend(self.topology.dss(rows(tend), not weighted, rows(out)))
        else:
            launches.extend(self.topology.dss_at(rows(tend), not weighted, rows(out), part.nodes, part.copies))
        return launches

    def _build_rhs_update(self, x, updates, named, limit=False):
        launches, lo, hi, weighted = self._build_tendency(x, named)
        groups = []  # (rows, [(out, terms)]): one DSS for each run of at most two updates of the same rows
        rest = []  # F is zero in the rows its terms do not write: there the arrays' combination alone
        limited = []  # the last update's tracer rows limited in tend before its DSS pass (``limit``)
        if limit:
            last = updates[-1]
            if last.rows is not None or hi <= 3 or sum(src is None for _, src in last.terms) != 1:
                raise ValueError("a limited update is of all rows, with tracers, and holds F once")
            limited = self.limiter.stage(last, self.tendency_arrays.tend, weighted, assemble=False)
        for n, (out, terms, rows) in enumerate(updates):
            if rows is None:
                arrays = tuple((a, src) for a, src in terms if src is not None)
                for r0, r1 in ((0, lo), (hi, self.rows)):
                    if r0 < r1:
                        if not arrays:
                            raise ValueError(
                                f"an update of F alone into rows {r0}:{r1}, which the terms {named} do not write"
                            )
                        rest.append(self.lincomb(out[r0:r1], ((a, src[r0:r1]) for a, src in arrays)))
            r0, r1 = (lo, hi) if rows is None else (rows.start, rows.stop)
            if not lo <= r0 < r1 <= hi:
                raise ValueError(f"an update of rows {r0}:{r1}, of which the terms {named} write only {lo}:{hi}")
            sliced = (out[r0:r1], tuple((a, None if src is None else src[r0:r1]) for a, src in terms))
            alone = limited and n == len(updates) - 1  # its own pass: the tracer rows it reads are limited
            if groups and groups[-1][0] == (r0, r1) and len(groups[-1][1]) < 2 and not alone:
                groups[-1][1].append(sliced)
            else:
                groups.append(((r0, r1), [sliced]))
        for k, ((r0, r1), group) in enumerate(groups):
            assembled = 0
            if limited and k == len(groups) - 1:  # after the earlier passes, which read tend's unlimited tracer rows,
                launches.extend(limited)  # and before its own, which writes the arrays the limiter reads
                assembled = r1 - 3
            tend = self.tendency_arrays.tend[r0:r1]
            launches.extend(self.topology.dss_update(tend, group, weighted=not weighted, assembled=assembled))
        return launches + rest  # after the tendency, which may read their outputs

    def set_time(self, t: float) -> None:
        """Set the model time t (s) at which ``rhs`` evaluates a time-dependent
        term (the forcing): a kernel argument of the recorded launches, so
        nothing is recompiled or re-recorded. Steppers call it before each RHS
        evaluation with the stage time; without a forcing it only stores t."""
        self.time = float(t)
        for launch in self._forcing_launches:
            launch.set_param_by_name("t", f64(t))

    def _rhs_terms(self, terms):
        """The RHS terms to evaluate: all the scene's for None, else ``terms``
        (ValueError unless a non-empty subset of them without hyperviscosity)."""
        if terms is None:
            return self.terms
        if not terms or not set(terms) <= set(self.terms) - {"hyperviscosity"}:
            raise ValueError(
                f"rhs terms must be a non-empty subset of {self.terms} without hyperviscosity (got {terms})"
            )
        return terms

    def rhs(self, x: wp.array2d, out: wp.array2d, terms: tuple | None = None) -> None:
        """out = F(x, t): the DSS'd tendency (3, N) of the non-dissipative terms
        (du/dt, dv/dt in m s⁻²; dh/dt in m s⁻¹) at the model time t
        (``set_time``; only the forcing depends on it). ``out`` must not alias ``x``.
        ``terms``: a non-empty subset of the scene's tendency terms and "forcing"
        to evaluate alone (None: all; a forward–backward stepper's continuity and
        momentum halves), compiled for that subset; only the rows it writes are
        assembled and written (a continuity half leaves out's du, dv rows as they
        were, a momentum half its dh row). ValueError names a term the scene lacks."""
        key = self.rhs_key(x, out, terms)
        self.launches.replay(key, (x, out), lambda: self._build_rhs(x, out, key[1]))

    def rhs_part(self, x: wp.array2d, out: wp.array2d, part: ElementPart, terms: tuple | None = None) -> None:
        """out = f_P(x, t) = M⁻¹ DSS(the element-local tendency of ``part``'s elements
        alone), the others' taken as zero, as ``rhs`` computes F (``terms`` likewise),
        written at the nodes the part touches (``part.nodes``) and nowhere else: out's
        other nodes keep what they hold (zero, for a buffer given to this part alone). Over
        parts that cover every element once, Σ_P f_P = F to round-off (the GLL mass is
        diagonal: Diaz & Grote 2009, SIAM J. Sci. Comput. 31:1985, §2). The tendency
        kernels run over the part's element ranges only and the DSS over its nodes: a cost
        in proportion to its elements (and the ranges' gaps). ``out`` must not alias ``x``.
        On several ranks every rank calls it for the same part (the neighbours' copies are
        exchanged), the same bits as on one (the copies summed in one global order)."""
        key = ("rhs_part", id(part), *self.rhs_key(x, out, terms)[1:])
        self.launches.replay(key, (x, out, part), lambda: self._build_rhs(x, out, key[2], part))

    def rhs_update(self, x: wp.array2d, updates, terms: tuple | None = None, limit: bool = False) -> None:
        """F = F(x, t) as ``rhs`` computes it, not stored but written, as its DSS
        makes it, into linear combinations (an explicit stage's x + aΔt F with
        no pass of its own): for each ``Update(out, terms, rows)`` of ``updates``,
        in order, out[rows] = Σ a·src[rows] over terms (a, src), src a (3, N) array
        or None standing for F; rows a slice of the rows the ``terms`` of the
        RHS write, or None: all three, F zero in the rows the terms do not
        write (as ``rhs`` leaves a zeroed out). One to three terms, at most two
        arrays and F once; consecutive updates of the same rows share one DSS, two at a
        time. Outputs may alias x (only the tendency reads it, before) and the
        terms (a later update reads an earlier one's result). Summed left to
        right as ``blas.axpby``/``axpbypcz``: the bits of ``rhs`` followed by
        those combinations. Recorded once per arrays, the coefficients launch
        arguments set in place (``LaunchRecorder.replay_updates``: a new Δt records nothing);
        ValueError for rows F lacks; TypeError for an update that is not an ``Update``.
        ``limit``: the last update (of all rows, F in it once) a stage's state, its tracers' rows
        limited before their DSS (``limiter.TracerLimiter.stage``; the model's limiter), read
        by nothing after it."""
        terms, updates = self._rhs_terms(terms), check_updates(updates)
        self.launches.replay_updates(
            ("rhs_update", terms, x.ptr, bool(limit)),
            (x,),
            updates,
            lambda u: self._build_rhs_update(x, u, terms, bool(limit)),
        )

    def rhs_kernels(self, x: wp.array2d, out: wp.array2d) -> list[str]:
        """Names of the kernels ``rhs(x, out)`` launches (recorded on first use)."""
        key = self.rhs_key(x, out)
        if self.launches.recorded(key) is None:
            self.rhs(x, out)
        return [launch.kernel.key for launch in self.launches.recorded(key)]

    def rhs_key(self, x: wp.array2d, out: wp.array2d, terms: tuple | None = None) -> tuple:
        """The key under which ``rhs(x, out, terms)`` records its launches (``launches.recorded``)."""
        return ("rhs", self._rhs_terms(terms), x.ptr, out.ptr)

    # -- hyperviscosity (``hypervis.Hyperviscosity``) ----------------------
    def hyperviscosity(self, x: wp.array2d, dt: float) -> None:
        """Apply ∇⁴ hyperviscosity over dt (s) in place, split from the dynamics
        (``hv.apply``: forward-Euler substeps or an RKL1 super-step, HOMME's
        ``advance_hypervis``), then the element filter once (``filter.apply``, a scene's
        [filter]; HOMME ``filter_P``); nothing without the term and the filter. The tracers'
        masses each substep or stage after h's (``hv.apply``: ν_s ∇⁴ of q(h + hs), q read before
        h's ∇⁴), unless ``tracer_hyperviscosity`` is False."""
        if self.hv is None and self.filter is None:
            return
        # a kept float32 state (``held``) in place, its first Laplacian reading h − H₀ + hs and its
        # last DSS adding to it (rounded once); with a filter, tracers or ν_div ≠ ν (δ's operator
        # reads float64), on its float64 copy
        direct = self.filter is None and not self.tracers and self.nu_div == self.nu
        held, x = x, (x if direct else self.held.float64(x))
        if self.hv is not None:
            self.hv.apply(x, dt)
        if self.filter is not None:
            self.filter.apply(x)
        if held is not x:
            self.held.store(x, held)

    # -- the implicit split (Dinosaur's ``implicit_terms`` / ``implicit_inverse``) ----------
    def implicit_terms(self, mean_depth: float = 0.0) -> GravityWaveOperator:
        """L, the linear gravity-wave terms about the depth H (m; 0: the first state's mean,
        ``GravityWaveOperator.set_depth``), a new operator on this model: the implicit part of
        the semi-implicit, IMEX and JFNK steppers and the fast part of the multirate split.
        ValueError without the continuity and pressure-gradient terms or for H < 0."""
        return GravityWaveOperator(self, mean_depth)

    def implicit_inverse(
        self, options: HelmholtzOptions, linear: GravityWaveOperator | None = None, warm: bool = False
    ) -> HelmholtzSolver:
        """(I − aL)⁻¹ for any a: a new ``HelmholtzSolver`` about ``linear`` (None: the
        ``implicit_terms`` about ``options.mean_depth``) with the solve's ``options``; ``warm``:
        its solves start from the last (or the projection on past) solutions."""
        return HelmholtzSolver(self.implicit_terms(options.mean_depth) if linear is None else linear, options, warm)

    # -- the float32 state (``precision = "float32_state"``: ``kernels.departure``) ---------------
    def to_step_state(self, x: wp.array2d, y: wp.array2d) -> None:
        """y (3, N, ``state_dtype``) = the state a step's stages carry of x (3, N float64): u, v
        and h − H₀ rounded once to float32 (``kernels.departure.to_departure``); x's mass taken
        for ``from_step_state`` to put back (``mass_fixer``). Nothing where y is x (the run keeps
        the float32 state: ``held``, whose mass is taken as the run's state is set, not in a step)."""
        if y is x:
            return
        self.launches.run_lanes(departure.to_departure, x, f64(self.tendency_arrays.depth), y)
        if self.mass_fixer is not None:
            self.mass_fixer.measure(x)

    def from_step_state(self, y: wp.array2d, x: wp.array2d) -> None:
        """x (3, N float64) from a step's float32 state y at the step's end: the step's increment
        y − ``to_step_state``(x) added in float64 (``compensated``), or y + H₀; nothing where y
        is x (the float32 state kept: ``held``)."""
        if y is x:
            return
        kernel = departure.add_increment if self.compensated else departure.from_departure
        self.launches.run_lanes(kernel, y, f64(self.tendency_arrays.depth), x)

    def restore_mass(self, x: wp.array2d) -> None:
        """At a float32 state's step's end (after its ∇⁴, whose float32 Laplacians round too):
        x's depth moved uniformly to the mass ∫h that ``to_step_state`` took (``mass_fixer``);
        nothing without the fixer."""
        if self.mass_fixer is not None:
            self.mass_fixer.restore(x)

    def new_state(self, u=None, v=None, h=None, masses=None) -> wp.array2d:
        """A (rows, N) device state from element-local numpy rows (zeros where None); ``masses``
        the tracers' masses hq (K, N) (m; None: zeros)."""
        a = np.zeros((self.rows, self.N))
        for r, f in enumerate((u, v, h)):
            if f is not None:
                a[r] = f
        if masses is not None:
            a[3:] = masses
        return wp.array(a, dtype=f64, device=self.device)
