"""A run's members (``Simulation`` with ``members``, issue 85; one driver, issue 116): N members
of one scene, each with the bits of the single run from its initial state, in the same launches
on N copies of the grid (``members.grid.MemberGrid``) or each on a model of its own
(``members.units``' module doc); what is global over a grid (the ∇⁴'s spectral radius, every
member's invariants) taken from the one grid, not the copies. ``Members`` builds them and is the
run's diagnostics on (N, n) fields, as ``state_diagnostics.StateDiagnostics`` is a single run's."""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from threadpoolctl import threadpool_limits

from ..cases.scoring import Scorer
from ..core.arguments import got
from ..core.errors import ArgumentError, StepFailure
from ..core.mpi import RankMax
from ..grid.cubed_sphere import CubedSphere
from ..members import initial, units
from ..members.grid import MemberGrid
from ..model.diagnostics import invariants
from ..model.shallow_water import ShallowWater
from .build import check_memory
from .state_diagnostics import MemberAxis, WholeFields
from .writers import scene_attrs


@dataclass
class MemberFields(WholeFields):
    """A run's members' ``WholeFields`` (``Members.gather_fields``): u, v, h, vorticity and
    divergence (N, n) each on rank 0; ``held`` this rank's members' rows (u, v, h, vorticity[,
    divergence]), (rows, n) a member, on every rank."""

    held: list | None = None


class Members(MemberAxis):
    """``members`` (N ≥ 1) members of ``scene`` started from ``start`` (``Simulation``'s ``initial``),
    their units built on ``backend`` over the ranks of ``comm`` (rank r steps the r-th of R
    contiguous shares, ``held``), laid out by ``layout`` and ``blow_up`` (``units.layout``,
    ``units.POLICIES``); ``options`` the models' ``per_element`` and ``threads``. Attributes as
    ``Simulation``'s doc lists them for members (``grid``, ``copies``, ``units``, ``alike``, …);
    ``unit_held`` each unit's members (their indices), in order;
    ``out`` the units dropped ({unit index: step}, the integrator's, set by the driver); ``run`` the
    run's ``run_state.RunState`` (set by the driver). What the driver asks of a run, as of a single
    run's ``StateDiagnostics``: ``states``, ``restart_parts``, ``describe``, ``opening``, ``dropped``,
    ``drops``, ``bcast``, ``ranks`` (``last_good`` None: a blow-up's files keep no state)."""

    series = ("steps", "wall_time")  # the run file's per-time series; each member's are ``member_series``
    last_good = None

    def __init__(self, scene, members, start, backend, comm, graphs, layout, blow_up, **options):
        self.comm = comm if comm is not None and comm.size > 1 else None
        ranks, rank = (1, 0) if self.comm is None else (self.comm.size, self.comm.rank)
        if members < ranks:
            raise ArgumentError(f"members: {members} members over {ranks} MPI ranks (one a rank at least)")
        self.held, self.root = np.array_split(np.arange(members), ranks)[rank], rank == 0
        if scene.digital_filter is not None:  # not yet the single run's bits
            raise ArgumentError("scene: it starts from a digital filter (not yet with ensembles)")
        check_memory(scene, self.comm, backend, members)  # before the grid and the members' states are made
        self.scene, self.members = scene, members
        self.case = case = scene.make_case()
        self.grid = grid = CubedSphere(scene.ne, scene.np, case.planet.a, mesh=scene.make_mesh())
        # each member's case: its own with Variants (its state, Coriolis parameter and truth), else the scene's
        scenes, self.cases = start.scenes(scene, members) if isinstance(start, initial.Variants) else (None, None)
        # the variants' values, as a restart file keeps them (JSON)
        self.variants = None if self.cases is None else {k: np.asarray(v).tolist() for k, v in start.values.items()}
        starts = initial.initial_states(start, grid, case, members, self.cases)
        self.initial_states = initial.described(start)
        # measured on the starts made, whatever made them (a perturbation lost in h's rounding, a file, --vary)
        self.alike = initial.stay_alike(starts, start)
        if blow_up not in units.POLICIES:
            raise ArgumentError(f"blow_up must be one of {', '.join(map(repr, units.POLICIES))} (got {got(blow_up)})")
        self.options = {"device": backend.device, **options}
        self.blow_up, self.lines, self.out = blow_up, [], {}  # the lines of the members dropped
        self.layout = units.layout(scene, start, layout, backend.device, own=blow_up == "drop")
        # each unit's members (indices): all in one unit ("shared"), or one a unit ("in_turn")
        self.unit_held = [self.held] if self.layout == "shared" else list(self.held[:, None])
        # the held members' own (scene, case) with Variants, else None: the scene's and its case
        own = None if self.cases is None else [(scenes[k], self.cases[k]) for k in self.held]
        # built under Simulation's one BLAS thread, as a single run's: the ∇⁴'s power iteration takes 40 norms
        threads = backend.threads() if options["threads"] is None else options["threads"]
        parts = (grid, starts[self.held], backend, threads, self.options, graphs)
        build = units.shared_unit if self.layout == "shared" else units.own_units
        self.units, self.copies, self.one = build(scene, case, own, *parts)
        # hs and f on the host (held, n), read at every output time (the grid's and the members' alone); g a member
        self.hs = self.each(lambda u: u.model.operators.hs.numpy())
        self.fcor = self.each(lambda u: u.model.operators.fcor.numpy())
        self.g = [u.model.g for u in self.units for _ in range(u.members)]
        self.scorer = None
        # what ``StopSignals`` asks of the ranks: the one model's topology, or the members' ranks
        self.ranks = self.units[0].model.topology if self.comm is None else RankMax(self.comm)
        if self.alike and self.root:  # once built (a refusal says its own line alone); said at Simulation's caller
            warnings.warn(initial.alike_line(members), initial.MembersAlike, stacklevel=4)

    def __len__(self) -> int:
        """N, the members."""
        return self.members

    def each(self, read) -> np.ndarray:
        """(held, ..., n): ``read(unit)`` (..., its members·n) of every unit cut into this rank's members'
        columns, a member a row."""
        return np.stack([part for u in self.units for part in np.split(read(u), u.members, axis=-1)])

    def anywhere(self, flag: bool) -> bool:
        """Whether ``flag`` holds on any rank (collective)."""
        return bool(flag) if self.comm is None else self.comm.allreduce(int(bool(flag))) > 0

    def everyone(self, local) -> list:
        """Every rank's ``local`` (an entry a held member) in member order, on every rank (collective)."""
        return list(local) if self.comm is None else [e for part in self.comm.allgather(list(local)) for e in part]

    def everyone_shown(self, each: list) -> list:
        """``everyone`` of the held members' figures ``each`` (dicts), a dropped member's NaN (collective)."""
        return self.everyone(dict.fromkeys(d, np.nan) if i in self.out else d for i, d in enumerate(each))

    def on_root(self, local: list) -> list | None:
        """Every rank's ``local`` (an entry a held member or unit) in member order on rank 0, None on the
        others (collective)."""
        parts = [local] if self.comm is None else self.comm.gather(local, root=0)
        return None if parts is None else [e for part in parts for e in part]

    def bcast(self, value):
        """Rank 0's ``value`` on every rank (collective)."""
        return value if self.comm is None else self.comm.bcast(value, root=0)

    # -- the states on (N, n) ------------------------------------------------------------
    def held_states(self) -> np.ndarray:
        """(held, 3, n): this rank's members' states (a dropped member's NaN)."""
        states = self.each(lambda u: u.x.numpy())
        states[list(self.out)] = np.nan
        return states

    def states(self) -> np.ndarray:
        """(N, 3, n) float64: every member's u, v (m s⁻¹) and h (m) on the grid's element-local
        nodes (on every rank: collective)."""
        return np.stack(self.everyone(self.held_states()))

    def set_states(self, states) -> None:
        """Every member's state now (an ensemble filter's analysis, say): ``states`` (N, 3, n) u,
        v (m s⁻¹) and h (m) on the grid's element-local nodes, continuous, each rank taking its
        members' (a dropped member's, NaN in ``states()``, left out). The steppers go on from them
        as from their own (a multistep stepper's earlier states and a solver's guesses kept).
        ``ArgumentError`` as for an ``initial`` array, nothing set."""
        states = self._states_argument(states, self.grid.nnodes)
        going = [(u, k) for i, (u, k) in enumerate(zip(self.units, self.unit_held)) if i not in self.out]
        kept = np.concatenate([k for _, k in going]) if going else np.zeros(0, int)  # a dropped member's left as it is
        initial.checked_states(states[kept], self.case, "states", kept)
        for u, k in going:
            u.x.assign(np.concatenate(list(states[k]), axis=1))

    def gather_fields(self, x=None, divergence: bool = False) -> MemberFields:
        """Every member's u, v, h, vorticity and (``divergence``) divergence now, (N, n) each on
        rank 0 (a dropped member's NaN; None on the other ranks), as a single run's
        ``StateDiagnostics.gather_fields`` for its run files (``writers.RunFiles``), and this
        rank's members' own (``MemberFields.held``) on every rank (collective; ``x`` unread)."""
        x, zeta = self.each(lambda u: u.x.numpy()), self.each(lambda u: u.model.operators.vorticity(u.x))
        div = self.each(lambda u: u.model.operators.wind_divergence(u.x)) if divergence else None
        held = [np.stack([*x[k], zeta[k], *(() if div is None else (div[k],))]) for k in range(self.held.size)]
        each = self.on_root([np.full_like(m, np.nan) if i in self.out else m for i, m in enumerate(held)])
        # rank 0's (N, rows, n) as the rows u, v, h, vorticity[, divergence] by member; None on the others
        rows = [None] * 4 if each is None else np.stack(each).swapaxes(0, 1)
        return MemberFields(*rows, held=held)

    def diagnose(self, t: float, x=None, whole: MemberFields | None = None) -> dict:
        """Each member's mass, total energy, potential enstrophy (``invariants``) and errors at
        ``t`` (s) (``errors``), (N,) arrays by name (a dropped member's NaN) on every rank, as a
        single run's ``StateDiagnostics.diagnose`` for its run files (collective); ``whole`` this
        step's ``gather_fields`` where taken (``x`` unread)."""
        held = (self.gather_fields() if whole is None else whole).held
        each = [{**d, **e} for e, d in zip(self.errors_of([m[:3] for m in held], t), self.invariants_of(held))]
        each = self.everyone_shown(each)
        return {key: np.array([d[key] for d in each]) for key in each[0]}

    def errors_of(self, held, t: float) -> list[dict[str, float]]:
        """Each of this rank's members' errors at ``t`` (s) of their states ``held`` (held, 3, n)
        against the case's truth (``cases.scoring.Scorer.errors``; each variant's own)."""
        if self.scorer is None:  # one member's model for the wind errors' vorticity and divergence
            with threadpool_limits(limits=1, user_api="blas"):
                one = self.one or ShallowWater.from_scene(self.scene, self.grid, self.case, **self.options)
            # each variant's own truth, an exact solution (a reference holds the scene's values only)
            cases, ref = ([self.case], self.scene.reference_file) if self.cases is None else (self.cases, None)
            self.scorer = [Scorer(c, one, one.topology, self.grid, self.hs[0], ref) for c in cases]
        return [self.scorer[k % len(self.scorer)].errors(t, xk, *xk) for k, xk in zip(self.held, held)]

    def invariants_of(self, held: list) -> list[dict[str, float]]:
        """Each of this rank's members' invariants (``model.diagnostics.invariants`` on the one grid:
        the bits of the single run's) from their rows ``held`` (``MemberFields.held``)."""
        each = zip(held, self.hs, self.fcor, self.g)  # a member's rows, its hs, f and g
        return [invariants(self.grid, *rows[:3], hs, rows[3], fcor, g) for rows, hs, fcor, g in each]

    def invariants(self) -> list[dict[str, float]]:
        """Each member's mass (m³), total energy (m⁵ s⁻²) and potential enstrophy (m s⁻²)
        (``model.diagnostics.invariants`` on the one grid: the bits of the single run's; a dropped
        member's NaN, as in ``states()``; collective)."""
        return self.everyone_shown(self.invariants_of(self.gather_fields().held))

    def errors(self) -> list[dict[str, float]]:
        """Each member's errors now against the case's truth, as a single run's file has them
        (``cases.scoring.Scorer.errors``: Williamson et al. 1992's normalized l1, l2, l∞ of h and
        the wind against an exact solution, or against the scene's spectral reference where
        it stores this day); {} a member for a case with neither (a dropped member's NaN; collective)."""
        return self.everyone(self.errors_of(self.held_states(), self.run.seconds(self.run.step)))

    def fields(self) -> tuple:
        """Every member's u, v (m s⁻¹), h (m), (N, n) each on rank 0 ((None, None, None) on the
        others; a dropped member's NaN; collective)."""
        each = self.on_root(list(self.held_states()))
        return (None, None, None) if each is None else tuple(np.stack(each).swapaxes(0, 1))

    def divergence(self) -> np.ndarray | None:
        """Every member's divergence of the wind (N, n), DSS'd (s⁻¹), on rank 0 (None elsewhere; collective)."""
        return self.gather_fields(divergence=True).divergence

    def member_g(self) -> list[float]:
        """Each member's g (m s⁻²), on every rank (collective)."""
        return self.everyone(self.g)

    # -- blow-ups and dropped members -----------------------------------------------------
    def describe(self, bad: tuple) -> str:
        """The one line of a checked step gone bad, ``bad`` = (step, trouble, detail) of an
        ``integrator.core.Stop``, a blow-up: the members bad there (their states those of that step;
        the model's bad-node rule, ``BadNodes.mask``) but those dropped, the first one's place
        (collective); ``StepFailure`` for a failed solve."""
        step, trouble, detail = bad
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
        """(x, stepper state, what the file keeps of the start, grid) of every member for a restart
        file, on rank 0 (None on the others; collective): the members' arrays side by side."""
        policy = {"blow_up": self.blow_up, "dropped": {str(k): step for k, step in self.dropped.items()}}
        parts = self.on_root([(u.x.numpy(), u.stepper.state()) for u in self.units])  # every unit, member order
        if parts is None:
            return None
        x, state = units.restart_state(parts, self.layout)
        keep = {"initial_states": self.initial_states, "layout": self.layout, "variants": self.variants, **policy}
        return x, state, keep, MemberGrid(self.grid, self.members)

    def restore(self, ck) -> None:
        """The states and stepper histories of the checkpoint ``ck`` (an ensemble's) into the units."""
        for u, k in zip(self.units, self.unit_held):  # the unit's members' columns of the file's arrays
            nodes = np.arange(ck.x.shape[1]).reshape(ck.members, -1)[k].ravel()
            u.x.assign(ck.x[:, nodes])
            prefix = None if self.layout == "shared" else f"member{k[0]}_"
            u.stepper.restore(units.held_state(ck.stepper_state, nodes, prefix))
        dropped = {int(k): step for k, step in ck.initial.get("dropped", {}).items()}  # their last good states
        self.out |= {i: int(dropped[k]) for i, k in enumerate(self.held) if k in dropped}
        self.initial_states = ck.initial.get("initial_states", self.initial_states)

    def opening(self, files, start: MemberFields, history: str | None, name: str, dfi=None, device=None) -> tuple:
        """(no Courant numbers, the members' first diagnostics from ``start``, the run file's global
        attributes (``name`` the run's, ``scene_attrs``), what else ``RunFiles.open`` takes (``members``,
        ``member_series``)) of the run's files ``files``, their ``member_series`` (time, member) set;
        ``dfi`` and ``device`` a single run's (unread)."""
        first = self.diagnose(self.run.seconds(self.run.step), whole=start)
        files.member_series = tuple(first)
        attrs = {
            **scene_attrs(self.run.scene, "ensemble", history, name),
            **self.run.stepper.attrs(),
            "device": str(self.units[0].model.topology.device),
            "ensemble_layout": self.layout,
            "members": self.members,
            "initial_states": self.initial_states,
            "blow_up_policy": units.POLICIES[self.blow_up],
            **({"continued_from_day": self.run.time} if self.run.step else {}),
        }
        return {}, first, attrs, {"members": self.members, "member_series": files.member_series}
