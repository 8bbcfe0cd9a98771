"""A run's members, of any size (issue 124: one run of any size; JAX codes map one step over a
leading member axis, SpeedyWeather keeps one ``PrognosticVariables`` whatever the configuration):
``Members`` builds the N members of a scene as units (``integrator.core.Unit``) and answers for
their states and diagnostics over (N, 3, n), the member axis first. A single run is its one
member, laid out "shared" over this rank's share of the elements (``units.element_unit``); N
members are in the same launches on N copies of the grid (``members.grid.MemberGrid``) or each on
a model of its own (``units``' module doc), over the ranks by member. Each member has the bits of
its single run; what is global over a grid (the ∇⁴'s spectral radius, the invariants) is taken
from the one grid, not the copies."""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from ..cases.scoring import Scorer
from ..core.arguments import got
from ..core.errors import ArgumentError, CheckpointError, StepFailure
from ..core.mpi import RankMax
from ..grid.cubed_sphere import CubedSphere
from ..integrator.core import FixedDt, Integrator, trouble_line
from ..io.restart_file import members_state, unit_state
from ..io.run_file import area_rms, member_statistics
from ..model.diagnostics import courant_numbers, invariants
from ..model.shallow_water import ShallowWater
from ..steppers.stability import stability_limit, stability_line
from . import initial, units
from .grid import MemberGrid


@dataclass
class WholeFields:
    """The members' fields gathered on rank 0 (``Members.gather_fields``): u, v (m s⁻¹), h (m),
    vorticity and, when asked for, divergence (s⁻¹, DSS'd), (N, n) each, a single run's (n,), on
    rank 0 and None on the other ranks (divergence None when not asked for); the tracers' masses
    hq (m; (K, n), the scene's [tracers]; None without); ``held`` this rank's members' rows (u, v,
    h, vorticity[, divergence]), (held, rows, n) on the whole grid (None on a single run's ranks
    > 0). Whether a rank gathers is decided by whether it was given one, never by its contents,
    so all ranks take the same collectives."""

    u: np.ndarray | None
    v: np.ndarray | None
    h: np.ndarray | None
    vorticity: np.ndarray | None
    divergence: np.ndarray | None = None
    masses: np.ndarray | None = None
    held: np.ndarray | None = None


class Members:
    """The ``members`` (N ≥ 1; None: a single run, N = 1 with a single run's files) members of
    ``scene`` started from ``start`` (``Simulation``'s ``initial``) on ``backend``: a single run over
    the ranks of ``comm`` by element (``given``: its start (3 + K, n) on rank 0, ``initial.ON_ROOT``
    on the others), N members by member (rank r the r-th of R contiguous shares, ``held``), laid out
    by ``layout`` and ``blow_up`` (``units.layout``, ``units.POLICIES``); ``options`` the models'
    ``per_element`` and ``threads``. Raises as ``Simulation``. Attributes as ``Simulation``'s doc
    lists them (``grid`` the whole grid on rank 0, ``units``, ``copies``, ``alike``, …);
    ``unit_held`` each unit's members; ``out`` the units dropped ({unit index: step}); ``run`` the
    run's ``run_state.RunState`` (set by the driver). Rank 0 diagnoses the whole grid (the same
    arithmetic on any number of ranks) and broadcasts the figures."""

    dfi = scorer = copies = cases = variants = None
    alike, initial_states = False, "the case's"

    def __init__(
        self, scene, members, start, backend, comm, graphs, layout=None, blow_up="stop", given=None, **options
    ):
        self.scene, self.members, self.out, self.lines = scene, members, {}, []  # the lines of the members dropped
        if blow_up not in units.POLICIES:
            raise ArgumentError(f"blow_up must be one of {', '.join(map(repr, units.POLICIES))} (got {got(blow_up)})")
        self.blow_up, self.comm = blow_up, None if members is None or comm is None or comm.size < 2 else comm
        ranks, rank = (1, 0) if self.comm is None else (self.comm.size, self.comm.rank)
        if members is not None and members < ranks:
            raise ArgumentError(f"members: {members} members over {ranks} MPI ranks (one a rank at least)")
        self.held = np.array_split(np.arange(members or 1), ranks)[rank]
        if members is not None and scene.digital_filter is not None:  # not yet the single run's bits
            raise ArgumentError("scene: it starts from a digital filter (not yet with ensembles)")
        # before the grid and the states are made; a single run's elements over comm
        units.check_memory(scene, comm if members is None else self.comm, backend, members)
        if members is None:
            unit, self.dfi, (self.case, topo, self.grid, hs, fcor, scorer) = units.element_unit(
                scene, backend, comm, given, start, graphs, options.get("per_element"), options.get("threads")
            )
            self.units, self.layout, self.scorer, self.nnodes = [unit], "shared", [scorer], topo.nnodes_total
            self.root, self.g = topo.comm.rank == 0, [unit.model.g]
            # the whole grid's hs and f on rank 0 alone (gathered), a member's axis added
            self.hs, self.fcor = (None, None) if hs is None else (hs[None], fcor[None])
        else:
            self._build(scene, members, start, backend, graphs, layout, **options)
        self.unit_held = [self.held] if self.layout == "shared" else list(self.held[:, None])
        self.topology = self.units[0].model.topology
        # what ``StopSignals`` asks of the ranks: the one model's topology, or the members' ranks
        self.ranks = self.topology if self.comm is None else RankMax(self.comm)

    def _build(self, scene, members, start, backend, graphs, layout, **options) -> None:
        """N members' units from ``start`` (``initial.initial_states``) on the one grid's copies, or a model each."""
        self.root = self.comm is None or self.comm.rank == 0
        self.case = case = scene.make_case()
        self.grid = grid = CubedSphere(scene.ne, scene.np, case.planet.a, mesh=scene.make_mesh())
        # each member's case: its own with Variants (its state, Coriolis parameter and truth), else the scene's
        scenes, self.cases = start.scenes(scene, members) if isinstance(start, initial.Variants) else (None, None)
        # the variants' values, as a restart file keeps them (JSON)
        self.variants = None if self.cases is None else {k: np.asarray(v).tolist() for k, v in start.values.items()}
        starts = initial.initial_states(start, grid, case, members, self.cases, scene)
        self.initial_states = initial.described(start)
        # measured on the starts made, whatever made them (a perturbation lost in h's rounding, a file, --vary)
        self.alike = initial.stay_alike(starts, start)
        models = {"device": backend.device, **options}  # what each ShallowWater takes
        self.layout = units.layout(scene, start, layout, backend.device, own=self.blow_up == "drop")
        # the held members' own (scene, case) with Variants, else None: the scene's and its case
        own = None if self.cases is None else [(scenes[k], self.cases[k]) for k in self.held]
        # built under Simulation's one BLAS thread, as a single run's: the ∇⁴'s power iteration takes 40 norms
        threads = backend.threads() if options["threads"] is None else options["threads"]
        parts = (grid, starts[self.held], backend, threads, models, graphs)
        build = units.shared_unit if self.layout == "shared" else units.own_units
        self.units, self.copies, one = build(scene, case, own, *parts)
        # hs and f on the host (held, n), read at every output time (the grid's and the members' alone); g a member
        self.hs = self.each(lambda u: u.model.operators.values("hs").copy())
        self.fcor = self.each(lambda u: u.model.operators.values("fcor").copy())
        self.g, self.nnodes = [u.model.g for u in self.units for _ in range(u.members)], grid.nnodes
        one = one or ShallowWater.from_scene(scene, grid, case, **models)  # one member's: the wind errors' ζ and δ
        # each variant's own truth, an exact solution (a reference holds the scene's values only)
        cases, ref = ([case], scene.reference_file) if self.cases is None else (self.cases, None)
        self.scorer = [Scorer(c, one, one.topology, grid, self.hs[0], ref) for c in cases]
        if self.alike and self.root:  # once built (a refusal says its own line alone); said at Simulation's caller
            warnings.warn(initial.alike_line(members), initial.MembersAlike, stacklevel=4)

    def __len__(self) -> int:
        """N, the members."""
        return self.members or 1

    def integrator(self) -> Integrator:
        """The one step loop over the units (``integrator.core.Integrator``): members' a block watched,
        a checked step plain (``units.member_step``), a member dropped where it blows up (``blow_up``)."""
        more = {"anywhere": self.anywhere, "drop": self.blow_up == "drop", "lone": False} if self.members else {}
        core = Integrator(self.units, FixedDt(units.member_step) if more else None, **more)
        core.out = self.out  # the units dropped
        return core

    # -- over the ranks ----------------------------------------------------------------------
    def each(self, read, whole: bool = False) -> np.ndarray | None:
        """(held, ..., n): ``read(unit)`` (..., its members·n) of every unit cut into this rank's members'
        columns, a member a row; ``whole``: on the whole grid (a single run's gathered on rank 0, None
        on its other ranks; ``Topology.gather``). One member's is a view of ``read``'s array."""
        parts = []
        for u in self.units:
            a = u.model.topology.gather(read(u)) if whole else read(u)
            if a is None:
                return None
            parts += np.split(a, u.members, axis=-1)
        return parts[0][None] if len(parts) == 1 else np.stack(parts)

    def on_root(self, local) -> list | None:
        """Every rank's ``local`` (an entry a held member or unit) in member order on rank 0, None on the
        others (collective)."""
        parts = [local] if self.comm is None else self.comm.gather(list(local), root=0)
        return [e for part in parts for e in part] if self.root else None

    def shown(self, held) -> list | None:
        """``on_root`` of this rank's members' ``held`` (held, ..., n; None on a single run's ranks > 0),
        a dropped member's NaN."""
        return self.on_root(
            None if held is None else [np.full_like(m, np.nan) if i in self.out else m for i, m in enumerate(held)]
        )

    def whole(self, read) -> np.ndarray | None:
        """(N, ..., n) ``read(unit)`` of every member on the whole grid (``each``), on rank 0 (None on the
        others; a dropped member's NaN, ``shown``; collective)."""
        each = self.shown(self.each(read, whole=True))
        return None if each is None else np.stack(each)

    def bcast(self, value):
        """Rank 0's ``value`` on every rank (collective)."""
        return self.topology.bcast(value) if self.comm is None else self.comm.bcast(value, root=0)

    def everyone(self, local, shown: bool = False) -> list:
        """Every rank's ``local`` (an entry a held member) in member order, on every rank (collective);
        ``shown``: figures (dicts), a dropped member's NaN."""
        if shown and local is not None:
            local = [dict.fromkeys(d, np.nan) if i in self.out else d for i, d in enumerate(local)]
        return self.bcast(self.on_root(local))

    def anywhere(self, flag: bool) -> bool:
        """Whether ``flag`` holds on any rank (collective)."""
        return bool(flag) if self.comm is None else self.comm.allreduce(int(bool(flag))) > 0

    # -- the states on (N, n) ------------------------------------------------------------
    def states(self) -> np.ndarray:
        """(N, 3, n) float64: every member's u, v (m s⁻¹) and h (m) on the whole grid's element-local
        nodes (a row more for each tracer's mass hq; a dropped member's NaN), on every rank (collective)."""
        return self.bcast(self.whole(lambda u: u.model.held.values(u.x)))

    def set_states(self, states) -> None:
        """Every member's state now (an ensemble filter's analysis, say): ``states`` (N, 3, n) u,
        v (m s⁻¹) and h (m) on the grid's element-local nodes (a row more for each tracer's mass hq),
        continuous (a single run's read on rank 0 and handed out over the ranks, each rank of
        members taking its members'; a dropped member's, NaN in ``states()``, left out). The
        steppers go on from them as from their own (a multistep stepper's earlier states and a
        solver's guesses kept). ``ArgumentError`` for another shape, a state not finite or an h <= 0
        of a depth, nothing set."""
        rows = self.units[0].model.rows
        try:
            states = np.asarray(states, dtype=float)
        except (TypeError, ValueError):
            raise ArgumentError(f"states must be numbers (m s⁻¹ and m) (got {got(states)})") from None
        if states.shape != (len(self), rows, self.nnodes):
            raise ArgumentError(f"states must have shape {(len(self), rows, self.nnodes)} (got {states.shape})")
        going = [(u, k) for i, (u, k) in enumerate(zip(self.units, self.unit_held)) if i not in self.out]
        kept = np.concatenate([k for _, k in going]) if going else np.zeros(0, int)  # a dropped member's left as it is
        if self.topology.comm.rank == 0:  # a single run's on rank 0, members' on theirs
            initial.checked_states(states[kept], self.case, "states", kept)
        for u, k in going:  # a kept float32 state's mass taken again: the new states' is the one to keep
            u.model.held.assign(
                u.x, u.model.topology.distribute(np.concatenate(list(states[k]), axis=1), rows, "states")
            )

    def fields(self) -> tuple:
        """Every member's u, v (m s⁻¹), h (m), (N, n) each on rank 0 ((None, None, None) on the
        others; a dropped member's NaN; collective)."""
        each = self.whole(lambda u: u.model.held.values(u.x)[:3])
        return (None, None, None) if each is None else tuple(each.swapaxes(0, 1))

    def divergence(self) -> np.ndarray | None:
        """Every member's divergence of the wind (N, n), DSS'd (s⁻¹), on rank 0 (None elsewhere; collective)."""
        return self.whole(lambda u: u.model.operators.wind_divergence(u.model.held.float64(u.x, once=True)))

    def gather_fields(self, x=None, divergence: bool = False) -> WholeFields:
        """u, v, h, the vorticity and (``divergence``) the divergence of every member now, or of a
        single run's state x, in one gather on rank 0 (call on every rank): (N, n) each, a single
        run's (n,) as its run file holds them (``writers.RunFiles``)."""

        def rows(u):
            y = u.model.held.float64(u.x if x is None else x, once=True)  # the run's state in float64 (``model.held``)
            div = [u.model.operators.wind_divergence(y)[None]] if divergence else []
            values = y.numpy()
            return np.concatenate([values[:3], u.model.operators.vorticity(y)[None], *div, values[3:]])

        held = self.each(rows, whole=True)
        each = self.shown(held)
        if each is None:
            return WholeFields(*([None] * 4), held=held)
        # rows u, v, h, vorticity (, divergence), masses; a single run's the gathered array's views (no copy)
        a, n = each[0] if self.members is None else np.stack(each).swapaxes(0, 1), 5 if divergence else 4
        return WholeFields(*a[:n], masses=a[n:] if self.units[0].model.tracers else None, held=held)

    # -- diagnostics ---------------------------------------------------------------------
    def diagnose(self, t: float, x=None, whole: WholeFields | None = None) -> dict:
        """The figures of the run's files at ``t`` (s), on every rank (collective): a single run's
        invariants and their relative change, errors against the truth (``scoring.Scorer.errors``)
        and Courant numbers (of its state x, default the current one); members' mass, total energy,
        potential enstrophy and errors, (N,) arrays by name (a dropped member's NaN). ``whole``: this
        step's ``gather_fields`` where taken (on every rank, or on none)."""
        whole = self.gather_fields(x) if whole is None else whole
        if self.members is None:
            values = self.units[0].model.held.values(self.run.x if x is None else x)
            errors = self.scorer[0].errors(t, values, whole.u, whole.v, whole.h)
            return self.bcast(self.figures(whole, errors) if self.root else None)
        each = [{**d, **e} for e, d in zip(self.errors_of(t, whole.held, whole.held), self.invariants_of(whole.held))]
        each = self.everyone(each, shown=True)
        return {key: np.array([d[key] for d in each]) for key in each[0]}

    def errors_of(self, t: float, local, held) -> list[dict[str, float]]:
        """Each of this rank's members' errors at ``t`` (s) against the case's truth
        (``cases.scoring.Scorer.errors``; each variant's own) of their states on this rank's nodes
        ``local`` (held, ≥ 3, its n) and on the whole grid ``held`` (None on a single run's ranks > 0)."""
        wholes = [None] * len(local) if held is None else [m[:3] for m in held]
        return [
            self.scorer[k % len(self.scorer)].errors(t, xk, *(w if w is not None else [None] * 3))
            for k, xk, w in zip(self.held, local, wholes)
        ]

    def invariants_of(self, held) -> list[dict[str, float]] | None:
        """Each of this rank's members' invariants (``model.diagnostics.invariants`` on the one grid:
        the bits of the single run's) and its tracers' masses ``<name>_mass`` (∫hq dA, m³, as
        ``figures``') from their rows ``held`` (``WholeFields.held``, the masses last; None: None)."""
        if held is None:
            return None
        names = [f"{name}_mass" for name, _ in self.scene.tracers]
        each = zip(held, self.hs, self.fcor, self.g)  # a member's rows, hs, f and g
        return [
            invariants(self.grid, *r[:3], hs, r[3], f, g)
            | {k: float(self.grid.integrate(hq)) for k, hq in zip(names, r[len(r) - len(names) :], strict=True)}
            for r, hs, f, g in each
        ]

    def invariants(self) -> list[dict[str, float]]:
        """Each member's mass (m³), total energy (m⁵ s⁻²) and potential enstrophy (m s⁻²)
        (``model.diagnostics.invariants`` on the one grid: the bits of the single run's; a dropped
        member's NaN, as in ``states()``; collective)."""
        return self.everyone(self.invariants_of(self.gather_fields().held), shown=True)

    def errors(self) -> list[dict[str, float]]:
        """Each member's errors now against the case's truth, as the run files have them
        (``cases.scoring.Scorer.errors``: Williamson et al. 1992's normalized l1, l2, l∞ of h and
        the wind against an exact solution, or against the scene's spectral reference where
        it stores this day); {} a member for a case with neither (a dropped member's NaN; collective)."""
        values = lambda u: u.model.held.values(u.x)  # noqa: E731
        local, held = self.each(values), self.each(values, whole=True)
        return self.everyone(self.errors_of(self.run.seconds(self.run.step), local, held), shown=True)

    def h_spread_rms(self) -> float:
        """The members' spread of h now (m): the area-weighted RMS over the sphere of their
        standard deviation (``io.run_file.member_statistics``, ``area_rms``; 0 for one member), the
        run file's ``h_spread_rms`` (collective)."""
        h = self.states()[:, 2]
        return self.bcast(area_rms(self.grid, member_statistics(self.grid.to_unique(h))[1]) if self.root else None)

    def courant(self) -> list[dict]:
        """Each member's advective and gravity-wave Courant numbers at the run's Δt on its state now
        (``model.diagnostics.courant_numbers``), N dicts on every rank (collective)."""
        u, v, h = self.fields()
        g = self.everyone(self.g)
        return self.bcast([self.courant_at(*m, gk) for m, gk in zip(zip(u, v, h), g)] if self.root else None)

    def largest_dt_within_limit(self) -> list[float | None]:
        """Each member's Δt (s) at which its Courant number now reaches the stepper's measured
        stability limit (``stability_warning``'s); None for a stepper without one (collective)."""
        limits = [stability_limit(self.run.stepper, c) for c in self.courant()]
        return [None if limit is None else self._dt() * limit[0] / limit[2] for limit in limits]

    def stability_warning(self) -> list[str | None]:
        """Each member's one-line warning where Δt exceeds the stepper's measured stability limit
        on its state now (``largest_dt_within_limit``), else None (collective)."""
        stepper, options = self.run.stepper, self.run.scene.stepper_options
        return [stability_line(stepper, options, stability_limit(stepper, c), self._dt()) for c in self.courant()]

    def _dt(self) -> float:
        """The run's dt (s): the scene's, or under step control the controller's current one (the
        step it goes on with, not one cut short to land on an output time)."""
        return self.run.scene.dt if self.run.control is None else self.run.control.dt

    def courant_at(self, u, v, h, g: float) -> dict:
        """``diagnostics.courant_numbers`` at the run's dt (``_dt``) on whole-grid fields (rank 0)."""
        pressure = "pressure_gradient" in self.run.scene.terms  # gravity waves only with the pressure gradient term
        return courant_numbers(self.grid, u, v, h, self._dt(), g, pressure)

    def figures(self, whole: WholeFields, errors=()) -> dict:
        """A single run's invariants of ``whole`` and their change relative to ``initial``, ``errors``
        and the Courant numbers (rank 0)."""
        u, v, h, hs, fcor, g = whole.u, whole.v, whole.h, self.hs[0], self.fcor[0], self.g[0]
        d = invariants(self.grid, u, v, h, hs, whole.vorticity, fcor, g)
        if not self.case.h_is_depth:  # h is a tracer (TC1): only its mass is an invariant
            d = {"mass": d["mass"]}
        for (name, _), hq in zip(self.run.scene.tracers, () if whole.masses is None else whole.masses, strict=True):
            d[f"{name}_mass"] = float(self.grid.integrate(hq))  # ∫hq dA (m³), conserved as h's
        start = self.run.initial or d  # diagnosing the initial state itself
        d |= {f"{k}_change": (d[k] - start[k]) / abs(start[k]) for k in d}
        d.update(errors, **self.courant_at(u, v, h, g))
        return d

    # -- blow-ups and dropped members -----------------------------------------------------
    def describe(self, bad: tuple) -> str:
        """The one line of a checked step gone bad, ``bad`` = (step, trouble, detail) of an
        ``integrator.core.Stop``: a single run's (``trouble_line``), or the members bad there (their
        states those of that step; the model's bad-node rule, ``BadNodes.mask``) but those dropped,
        the first one's place (collective; ``StepFailure`` for a failed solve)."""
        step, trouble, detail = bad
        if self.members is None:
            day = self.run.time if self.run.control is not None else self.run.scene.day(step)
            return trouble_line(self.units[0].model, self.run.x, bad, day)
        if trouble == "failure":
            raise StepFailure(detail)
        self.run.core.step = step
        day, bad = self.run.time, self.units[0].model.bad_nodes.mask(self.states())
        members = [int(k) for k in np.setdiff1d(np.flatnonzero(bad.any(axis=1)), list(self.dropped))]  # but dropped
        where, last = self.place(np.argmax(bad[members[0]])), "; none left" if self.blow_up == "drop" else ""
        return (
            f"member{'s' if len(members) > 1 else ''} {', '.join(map(str, members))} of {self.members} blew up at "
            f"step {step} (model time {day:.4f} days; member {members[0]} first at {where}): "
            f"every member stopped (policy: {units.POLICIES[self.blow_up]}{last})"
        )

    def drop(self, step: int, bad: list) -> None:
        """Record the (index, unit, first bad node) ``bad`` dropped at ``step`` (a fixed Δt's): their lines."""
        for i, _, node in bad:
            day = self.run.scene.day(step)
            self.lines.append(
                f"member {self.held[i]} of {self.members} blew up at step {step} (model time {day:.4f} days; first "
                f"at {self.place(node)}): dropped, the others go on (policy: {units.POLICIES['drop']})"
            )

    def place(self, node: int) -> str:
        """Where the grid's element-local node ``node`` is, as a blow-up's line says it."""
        return f"lat {np.degrees(self.grid.lat[node]):.2f}, lon {np.degrees(self.grid.lon[node]):.2f} degrees"

    @property
    def dropped(self) -> dict[int, int]:
        """{member: the step it blew up at} of the members dropped (policy "drop"; collective)."""
        return dict(self.everyone([(int(self.held[i]), step) for i, step in self.out.items()]))

    @property
    def drops(self) -> list[str]:
        """The one line of each member dropped, in the order they were (collective)."""
        return self.everyone(self.lines)

    # -- restart files ---------------------------------------------------------------------
    def restart_parts(self) -> tuple | None:
        """(x, stepper state, what the file keeps of the start, grid, a kept float32 state's h − H₀
        or None: ``model.held``) of every member for a restart file, on rank 0 (None on the others;
        collective): the members' arrays side by side."""
        policy = {"blow_up": self.blow_up, "dropped": {str(k): step for k, step in self.dropped.items()}}
        held = self.units[0].model.held
        targets = self.mass_targets()
        gather = lambda u, a: None if a is None else u.model.topology.gather(a)  # noqa: E731
        parts = self.on_root(
            [
                (gather(u, u.model.held.values(u.x)), gather(u, held.departure(u.x)), u.stepper.state())
                for u in self.units
            ]
        )
        if parts is None:
            return None
        x, state = members_state([(x, st) for x, _, st in parts], self.layout)  # every unit, member order
        departure = np.concatenate([y for _, y, _ in parts]) if held.kept else None
        fixed = {} if targets is None else {"mass_fixer": targets}
        if self.members is None:
            return x, state, {**self.run.initial, **fixed}, self.grid, departure
        keep = {"initial_states": self.initial_states, "layout": self.layout, "variants": self.variants, **policy}
        return x, state, {**keep, **fixed}, MemberGrid(self.grid, self.members), departure

    def mass_targets(self) -> list[float] | None:
        """The mass each member's fixer keeps (m³, in member order, on rank 0; collective) where
        the run keeps the float32 state (``model.held``, ``model.mass_fixer``: taken as its state
        was set; a restart file keeps them); None otherwise (a fixer taking each step's start's)."""
        model = self.units[0].model
        if not model.held.kept or model.mass_fixer is None:
            return None
        return self.on_root([t for u in self.units for t in u.model.mass_fixer.targets])

    def restore(self, ck, state: bool = True) -> None:
        """The states and stepper histories of the checkpoint ``ck`` (of the run's kind) into the units
        (a single run's state read on rank 0 and handed out, not where ``state`` is False: it was the
        start; ``CheckpointError`` for another grid's)."""
        if self.members is None:
            held = self.units[0].model.held
            try:
                if state or held.kept:  # a kept float32 state's bits are the file's h_departure, not h's rounding
                    values = self.topology.distribute(ck.x, self.units[0].model.rows, "checkpoint state")
                    departure = None
                    if held.kept:  # rank 0's: the file's, or (a file without it) h's rounding
                        bits = ck.departure if ck.departure is not None or ck.x is None else held.rounded(ck.x)[2]
                        departure = self.topology.distribute(bits, 1, "checkpoint h_departure")[0]
                    held.assign(self.run.x, values, departure)
            except ValueError as err:
                raise CheckpointError(str(err)) from None
            self.run.stepper.restore(ck.stepper_state)
            self.run.initial = {k: v for k, v in ck.initial.items() if k != "mass_fixer"}
            self._restore_targets(ck.initial)
            return
        targets = ck.initial.get("mass_fixer")  # a kept float32 state's, a member each
        for u, k in zip(self.units, self.unit_held):  # the unit's members' columns of the file's arrays
            nodes = np.arange(ck.x.shape[1]).reshape(ck.members, -1)[k].ravel()
            u.model.held.assign(u.x, ck.x[:, nodes], None if ck.departure is None else ck.departure[nodes])
            if targets is not None:
                u.model.mass_fixer.targets = [targets[m] for m in k]
            prefix = None if self.layout == "shared" else f"member{k[0]}_"
            u.stepper.restore(unit_state(ck.stepper_state, nodes, prefix))
        dropped = {int(k): step for k, step in ck.initial.get("dropped", {}).items()}  # their last good states
        self.out |= {i: int(dropped[k]) for i, k in enumerate(self.held) if k in dropped}
        self.initial_states = ck.initial.get("initial_states", self.initial_states)

    def _restore_targets(self, kept: dict) -> None:
        """A single run's fixer's mass from a restart file's (``mass_targets``; none kept: the
        state's own, taken as it was set)."""
        if "mass_fixer" in kept:
            self.units[0].model.mass_fixer.targets = kept["mass_fixer"]
