"""N members of one scene advanced together, each with the bits of the single run from its
initial state (issue 85, any stepper at a fixed Δt; issue 100, a controlled Δt the same for every
member, ``control``): in the same launches on N copies of the grid (``members.MemberGrid``) or
each on a model of its own (``units``' module doc), what is global over a grid (the ∇⁴'s spectral
radius, every member's invariants) taken from the one grid, not the copies."""

from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

from ..cases.scoring import Scorer
from ..config.scene import resolve_scene
from ..core.arguments import callable_argument, got, integer_argument, number_argument
from ..core.backend import CHECK_EVERY_STEPS, Backend, pick_device
from ..core.errors import ArgumentError, StepFailure
from ..core.graphs import default_mode, graphs_mode
from ..core.interrupts import StopSignals
from ..core.mpi import RankMax
from ..grid.cubed_sphere import CubedSphere
from ..integrator import FixedDt, Integrator, Stop, forwarded
from ..io.run_file import area_rms, member_statistics
from ..model.diagnostics import invariants
from ..model.shallow_water import ShallowWater
from ..simulation.activities import add_callback
from ..simulation.build import check_memory
from ..simulation.guard import RunObserver
from ..simulation.loop import (
    check_run_arguments,
    check_run_files,
    integrate,
    outcome,
    own_activities,
    run_steps,
)
from ..simulation.restart import continued, restore_run, write_restart
from ..simulation.run_state import RunState
from ..simulation.schedules import EverySteps, at_its_end
from ..simulation.state_diagnostics import WholeFields
from ..simulation.summary import Ledger
from ..simulation.writers import Checkpointer, RunFiles, scene_attrs
from .control import STEERED, member_control
from .initial import Perturbation, Variants, checked_states, described, initial_states
from .members import MemberGrid, member_part
from .units import (
    POLICIES,
    blow_up_line,
    drop_line,
    held_state,
    member_step,
    on_rank_zero,
    own_units,
    shared_unit,
    stepper_state,
    unit_members,
)
from .units import layout as members_layout


class Ensemble:
    """``members`` members of one scene, its grid and stepper, advanced in the same launches;
    member k's state after n steps has the same bits as the single run's (``Simulation``
    with ``start`` member k's initial state, or this class with ``members=1``).

    Parameters
    ----------
    scene : Scene, str or path
        As ``Simulation`` takes it, with ``overrides`` (``config.resolve_scene``): any stepper,
        without a digital filter; its Δt fixed, or under ``time.control`` the same for every member
        (``control.member_control``: in the same launches, on one rank).
    members : int ≥ 1, optional
        N, the number of members (None: the scene's [ensemble] ``members``).
    initial : None, array (N, 3, n), Perturbation, MemberFile or Variants
        The members' initial states: None, the case's for every member (or the scene's
        [ensemble] ``perturbation`` and ``seed`` where it names one > 0); an array of rows
        u, v (m s⁻¹) and h (m) on the grid's n element-local nodes (``CubedSphere``'s order,
        continuous); a ``Perturbation`` of the case's; a ``MemberFile``, an ensemble's run file;
        ``Variants``, each member's own case, Ω, g or ν.
    device : {"cpu", "cuda"}, optional
        As ``Simulation``'s (``backend.pick_device``).
    per_element, threads : bool or None, int or None
        The model's kernel layout and CPU threads (``ShallowWater``'s: None, the device's).
    graphs : {"auto", "on", "off"} or bool, optional
        As ``Simulation``'s: each step a CUDA graph ("auto", the default, or
        ``SWE_SPHERE_GRAPHS``: on CUDA only), checked bit for bit against plain launches.
    comm : mpi4py communicator, optional
        The members over its ranks (``mpiexec -n R``; at least one a rank): rank r steps the
        r-th of R contiguous shares of them (``held``) in its own launches, every member the
        bits it has on one rank; the states, invariants and errors are gathered on every
        rank, the run and restart files written by rank 0. Call every method on every rank.
    layout : {None, "shared", "in_turn"}, optional
        How the members step (``units``' module doc): in the same launches ("shared", where
        they can) or each on a model of its own ("in_turn"); None: "shared" on CUDA, "in_turn"
        on a CPU or where the members need a model each (``units.layout``).
    blow_up : {"stop", "drop"}, optional
        A blow-up's policy (``POLICIES``): stop every member (the default), or drop the member
        and go on ("in_turn" then).
    **overrides
        As ``Simulation``'s.

    Attributes
    ----------
    scene, members, dt : the resolved ``Scene``, N, Δt (s).
    inputs : tuple of Path, the files the scene was read from (its file, a mesh's, a start's):
        ``run`` writes over none of them.
    held : int array, the members this rank steps (all on one rank); root : whether it is rank 0.
    grid : the one ``CubedSphere``; copies : the ``MemberGrid`` of the held members' copies
        (None in turn: nothing steps on them).
    alike : bool, more than one member and every one of them the same start (no perturbation
        or one of 0 m, no states, file or variants given): they stay alike, their spread 0.
    layout : "shared" (the held members in the same launches) or "in_turn" (each on a model of
        its own; ``units``' module doc); units : the ``integrator.Unit`` s that step them (one, or one
        a member); model, stepper : the first unit's ``ShallowWater`` and stepper.
    step_count : int, the steps taken; graphs_kept : int, the step graphs replayed (``Simulation``'s).
    control : the ``simulation.adaptive.StepControl`` of every member's Δt (None at a fixed Δt);
        day : float, the model day reached.

    Raises
    ------
    ArgumentError
        Naming ``members`` (not an integer ≥ 1), ``initial`` (another shape or kind, non-finite, or
        h ≤ 0 in a member where h is a depth: the member named) or ``scene``, before the model is built.
    SceneError
        As ``Simulation``'s. A blow-up in ``step``, ``advance`` and ``run``: see ``step``.
    """

    def __init__(
        self,
        scene,
        members: int | None = None,
        initial=None,
        *,
        device=None,
        per_element=None,
        threads=None,
        graphs=None,
        comm=None,
        layout=None,
        blow_up="stop",
        **overrides,
    ):
        scene, self.inputs = resolve_scene(scene, overrides)
        asked = scene.ensemble  # the scene's [ensemble] table, or None
        if members is None and asked is None:
            raise ArgumentError("members must be given, or the scene name them ([ensemble] members)")
        members = integer_argument("members", asked["members"] if members is None else members, 1)
        if initial is None and asked is not None and asked["perturbation"] > 0:
            initial = Perturbation(asked["perturbation"], asked["seed"], asked.get("degrees"))
        self.comm = comm if comm is not None and comm.size > 1 else None
        ranks, rank = (1, 0) if self.comm is None else (self.comm.size, self.comm.rank)
        if members < ranks:
            raise ArgumentError(f"members: {members} members over {ranks} MPI ranks (one a rank at least)")
        self.held, self.root = np.array_split(np.arange(members), ranks)[rank], rank == 0
        graphs = graphs_mode(default_mode() if graphs is None else graphs)
        if scene.digital_filter is not None:  # not yet the single run's bits (a controlled Δt: ``member_control``'s)
            raise ArgumentError("scene: it starts from a digital filter (not yet with ensembles)")
        backend = Backend.of(pick_device(device, comm=self.comm))
        check_memory(scene, self.comm, backend, members)  # before the grid and the members' states are made
        self.scene, self.members, self.dt = scene, members, scene.dt
        self.case = case = scene.make_case()
        self.grid = grid = CubedSphere(scene.ne, scene.np, case.planet.a, mesh=scene.make_mesh())
        # each member's case: its own with Variants (its state, Coriolis parameter and truth), else the scene's
        scenes = initial.scenes(scene, members) if isinstance(initial, Variants) else [scene] * members
        self.cases = [s.make_case() for s in scenes] if isinstance(initial, Variants) else None
        # the variants' values, as a restart file keeps them (JSON)
        self._variants = None if self.cases is None else {k: np.asarray(v).tolist() for k, v in initial.values.items()}
        starts = initial_states(initial, grid, case, members, self.cases)
        self.initial = described(initial)
        self.alike = members > 1 and (initial is None or isinstance(initial, Perturbation) and initial.amplitude == 0)
        if blow_up not in POLICIES:
            raise ArgumentError(f"blow_up must be one of {', '.join(map(repr, POLICIES))} (got {got(blow_up)})")
        options = {"device": backend.device, "per_element": per_element, "threads": threads}
        self.blow_up, self._drops = blow_up, []  # the lines of the members dropped
        self.layout = members_layout(scene, initial, layout, backend.device, own=blow_up == "drop")
        held = starts[self.held]
        # one BLAS thread, as ``Simulation``: the ∇⁴'s power iteration takes 40 norms
        with threadpool_limits(limits=1, user_api="blas"):
            threads = backend.threads() if threads is None else threads
            if self.layout == "shared":
                fcor = None if self.cases is None else [self.cases[k].fcor(grid.lat, grid.lon) for k in self.held]
                unit, self.copies, self._one = shared_unit(
                    scene, grid, case, held, fcor, backend, threads, options, graphs
                )
                self.units = [unit]
            else:
                cases = self.cases or [case] * members
                pick = lambda items: [items[k] for k in self.held]  # noqa: E731
                self.units = own_units(pick(scenes), grid, pick(cases), held, backend, threads, options, graphs)
                self.copies, self._one = None, self.units[0].model
        self.model, self.stepper = self.units[0].model, self.units[0].stepper
        # hs and f on the host, read at every output time (the grid's and the members' alone); g a member
        self._hs = self._side(lambda u: u.model.operators.hs.numpy())
        self._fcor = self._side(lambda u: u.model.operators.fcor.numpy())
        self._g = [u.model.g for u in self.units for _ in range(u.members)]
        self.control = member_control(scene, self.units, self.layout, self.comm)  # None at a fixed Δt
        # the one step loop over the units (``integrator``): a block watched, a checked step plain (``member_step``)
        drop = blow_up == "drop"
        self.core = Integrator(self.units, FixedDt(member_step), anywhere=self._anywhere, drop=drop, lone=False)
        self._out = self.core.out  # dropped units: {unit index: the step it blew up at}
        self.run_state = RunState(self.core, scene, self.control)  # what activities read; its counters a run's
        self.counters = self.run_state.counters
        self.activities: dict = {}  # name -> activity (``simulation.activities``): ``add_callback``'s; ``run``'s own
        self._options, self._scorer = options, None

    def _member(self, a: np.ndarray, k: int) -> np.ndarray:
        """The k-th held member's columns (..., n) of ``a`` (..., held·n), its members side by side."""
        return member_part(a, k, self.grid.nnodes)

    def _side(self, read) -> np.ndarray:
        """``read(unit)`` of every unit, its members' columns side by side (held·n on the last axis)."""
        parts = [read(u) for u in self.units]
        return parts[0] if len(parts) == 1 else np.concatenate(parts, axis=-1)

    def set_states(self, states) -> None:
        """Every member's state now (an ensemble filter's analysis, say): ``states`` (N, 3, n) u,
        v (m s⁻¹) and h (m) on the grid's element-local nodes, continuous, each rank taking its
        members' (a dropped member's, NaN in ``states()``, left out). The steppers go on from them
        as from their own (a multistep stepper's earlier states and a solver's guesses kept).
        ``ArgumentError`` as for an ``initial`` array, nothing set."""
        shape = (self.members, 3, self.grid.nnodes)
        try:
            states = np.asarray(states, dtype=float)
        except (TypeError, ValueError):
            raise ArgumentError(f"states must be numbers (m s⁻¹ and m) (got {got(states)})") from None
        if states.shape != shape:
            raise ArgumentError(f"states must have shape {shape} (got {states.shape})")
        pairs = enumerate(zip(self.units, unit_members(self.layout, self.held)))
        going = [(u, k) for i, (u, k) in pairs if i not in self._out]
        kept = np.concatenate([k for _, k in going]) if going else np.zeros(0, int)  # a dropped member's left as it is
        checked_states(states[kept], self.case, "states", kept)
        for u, k in going:
            u.x.assign(np.concatenate(list(states[k]), axis=1))

    # -- stepping ------------------------------------------------------------------
    def step(self, n: int = 1) -> None:
        """Advance every member n steps (n an integer ≥ 0), by the integrator (``integrator``): the
        bad-state check (a non-finite value, or h ≤ 0 where h is a depth) runs on the device every
        step, read once every ``CHECK_EVERY_STEPS`` steps, a failed block taken again step by step to
        name the step; on CUDA each step a graph (``core.graphs.GraphedSteps``). A blow-up in any
        member raises ``BlowUp`` naming every member bad at that step, the states those of that
        step (``blow_up`` "stop", the default); or drops those members and goes on ("drop", in
        turn: not stepped again, NaN in the states and outputs from then, ``dropped`` and ``drops``
        saying which and where), raising only when none is left; ``StepFailure`` where a solve
        failed, the states those of the step before;
        ``ArgumentError`` under step control (``advance``, ``run``)."""
        n = integer_argument("n", n, 0)
        if self.control is not None:
            raise ArgumentError("Ensemble.step takes steps of a fixed dt: under step control, advance(days) or run")
        self._stepped(self.step_count + n)

    def _steps(self, stop_step: int, last_day=None, signals=None, bar=None, lines=None, notify=None) -> Stop:
        """Steps to ``stop_step`` (under step control to the model day ``last_day``) by a run's
        loop (``simulation.loop.run_steps``) under a run's hooks (``RunObserver``; members dropped,
        ``_drop``; with ``signals``, a run's blocks: ``RunObserver.timed``); a stop asked returned
        (``Stop``), ``notify(line)`` told a wall time estimated above a day (``summary.Ledger``)."""
        ledger = Ledger(self.counters, self.scene, self.step_count, notify)
        kw = {"timed": signals is not None, "dropped": self._drop}
        parts = (self.run_state, self.activities, self, ledger, stop_step, CHECK_EVERY_STEPS, signals, bar, lines)
        observer = RunObserver(*parts, **kw)
        return run_steps(self.core, self.control, last_day, self.activities, observer, stop_step, self._bad)

    def _stepped(self, stop_step: int, last_day=None) -> None:
        """``_steps`` to ``stop_step`` (``last_day``) outside a run: ``BlowUp`` for a blow-up."""
        outcome(self._steps(stop_step, last_day), self.run_state, None, None)

    def _bad(self, bad: tuple) -> str:
        """The line of a checked step gone bad, ``bad`` = (step, trouble, detail) of an
        ``integrator.Stop`` (the states those of that step); ``StepFailure`` for a failed solve."""
        step, trouble, detail = bad
        if trouble == "failure":
            raise StepFailure(detail)
        self.step_count = step
        return self._blow_up(step)

    def add_callback(self, fn, *, every_steps: int | None = None, every_days: float | None = None) -> None:
        """Call ``fn(self)`` after every ``every_steps``-th step from step 0 (under step control, of
        the accepted steps), or every ``every_days`` (whole steps of a fixed Δt), in ``step``,
        ``advance`` and ``run`` (``Simulation.add_callback``'s); what it raises ends the stepping.
        ``ArgumentError`` (one line) for ``fn`` not callable, not one interval, or a bad one."""
        callable_argument("fn", fn, "a callable fn(ensemble)", ArgumentError)
        if (every_steps is None) == (every_days is None):
            raise ArgumentError("an interval needs exactly one of every_steps, every_days")
        if every_days is not None:
            days, clock = number_argument("every_days", every_days, "days", low=0.0), self.scene.clock
            if self.control is not None or not clock.is_whole(days):
                raise ArgumentError(str(clock.refusal("every_days", days)) if self.control is None else STEERED)
            every_steps = clock.steps_in(days)
        add_callback(self.activities, fn, EverySteps(integer_argument("every_steps", every_steps, 1)))

    step_count = forwarded("core.step", "The steps taken (``Integrator.step``).")

    day = forwarded("run_state.time", "The model time reached, days since t = 0 (under step control the control's).")

    @property
    def wall_time(self) -> float:
        """The seconds spent stepping (``step``, ``advance``, ``run``; over restarts)."""
        return self.counters["wall_time"]

    def _blow_up(self, step: int) -> str:
        """The one line of a blow-up at ``step``: the members bad there, the first one's place (collective)."""
        return blow_up_line(self.states(), self.dropped, self.grid, self.case, self.blow_up, step, self.day)

    def _drop(self, bad: list, step: int) -> None:
        """Record the (index, unit, first bad node) ``bad`` dropped at ``step`` and their lines."""
        day = self.scene.day(step)
        self._drops += [drop_line(self.grid, self.held[i], self.members, node, step, day) for i, _, node in bad]

    def mark_dropped(self, dropped: dict) -> None:
        """Members dropped before ({member: step}, a restart file's): not stepped again, NaN after."""
        self._out |= {i: int(dropped[k]) for i, k in enumerate(self.held) if k in dropped}

    @property
    def dropped(self) -> dict[int, int]:
        """{member: the step it blew up at} of the members dropped (policy "drop"; collective)."""
        return dict(self._everyone([(int(self.held[i]), step) for i, step in self._out.items()]))

    @property
    def drops(self) -> list[str]:
        """The one line of each member dropped, in the order they were (collective)."""
        return self._everyone(self._drops)

    def _anywhere(self, flag: bool) -> bool:
        """Whether ``flag`` holds on any rank (collective)."""
        return bool(flag) if self.comm is None else self.comm.allreduce(int(bool(flag))) > 0

    def _everyone(self, local: list) -> list:
        """Every rank's ``local`` (an entry a held member) in member order, on every rank (collective)."""
        return list(local) if self.comm is None else [e for part in self.comm.allgather(list(local)) for e in part]

    def advance(self, days: float) -> None:
        """Advance every member by ``days`` (whole steps of the scene's Δt, ``core.clock``'s rule;
        ``ArgumentError`` with its refusal otherwise), as ``step``."""
        days = number_argument("days", days, "days", low=0.0)
        if self.control is not None:  # Δt the controller's, landing on the day reached
            self._stepped(sys.maxsize, self.day + days)
            return
        clock = self.scene.clock
        if days and not clock.is_whole(days):
            raise ArgumentError(str(clock.refusal("days", days)))
        self.step(clock.steps_in(days) if days else 0)

    def run(
        self,
        output,
        *,
        restart_every: float | None = None,
        overwrite: bool = False,
        compress: bool = False,
        history: str | None = None,
        progress: bool = False,
        notify=None,
        progress_lines=None,
    ) -> Path:
        """Advance every member to the scene's last day, writing the run file ``output`` (netCDF)
        at the first step (not a continuation's, the last time of the file it continues) and every
        ``output.every_days`` (``simulation.schedules.output_steps``): each field (time, member,
        ncol) with its mean and spread, each member's mass, total energy, potential enstrophy and
        errors against the case's truth (``errors``), the RMS spread of h (``RunWriter``); and
        each ``[[output.streams]]`` as a run writes it, ``<output stem>.<name>.nc`` with its own
        fields at its own interval, the members as in the run file (``writers.RunFiles``). ``restart_every``
        (days, whole steps): the restart file ``<output stem>.restart.nc`` (``write_checkpoint``)
        at those days and the last; without it, one is written when SIGINT or SIGTERM stops the
        run (not over an existing one unless ``overwrite``). A blow-up that stops all (``BlowUp``)
        or a signal (``Interrupted``, after a block of steps: the step reached written, and its
        restart file) closes the run files with every good output time (its attribute ``stopped``
        says why; a signal's ``interrupted*``, as a run's) and raises; members dropped go as NaN, their lines in ``dropped_members``.
        ``OutputError`` for a path that may not be written (``overwrite``: replace it) or that is one of
        ``inputs``, ``OutputError`` and ``SceneError`` naming an argument of another kind
        (``simulation.loop.check_run_arguments``), ValueError for an activity under a run's own
        name (``run_file``, ``checkpointer``); ``ArgumentError``
        at the run's end (``advance`` past it); ``SceneError`` for a restart interval that is not whole
        steps; ``compress``: the fields as float32 with zlib; ``progress``: a bar on stderr where it is a
        terminal; ``notify(line)``: told what the run file's cells cost or that they were left out
        (``RunWriter.cells_notes``); ``progress_lines``: a ``simulation.progress.ProgressLines``
        (rank 0's lines of progress). Returns the run file's path."""
        s = self.scene
        check_run_arguments(output, overwrite, restart_every, None, compress, True)
        if self.day >= s.days:
            raise ArgumentError(at_its_end("Ensemble", self.step_count, s))  # a file of no time
        # the restart files as a run's (``writers.Checkpointer``), those at its interval written over an older one
        rewrite = overwrite or restart_every is not None
        ckp = Checkpointer(
            self.run_state, self.write_checkpoint, self._from_root, self.root, output, restart_every, None, rewrite
        )
        attrs = {
            **scene_attrs(s, "ensemble", history, "swe_sphere.Ensemble.run"),
            **self.stepper.attrs(),
            "device": str(self.model.topology.device),
            "ensemble_layout": self.layout,
            "members": self.members,
            "initial_states": self.initial,
            "blow_up_policy": POLICIES[self.blow_up],
            **({"continued_from_day": self.day} if self.step_count else {}),
        }
        # the run file and its streams as a run's (``writers.RunFiles``), the members along the member axis
        hs = self._member(self._hs, 0)
        files = RunFiles(self.run_state, self, self.grid, hs, output, series=("steps", "wall_time"))
        check_run_files(self.activities, self.root, self.inputs, files, ckp, rewrite)
        start = self.gather_fields(divergence=files.divergence)  # the first output's fields and figures (collective)
        first = self.diagnose(self.run_state.seconds(self.step_count), whole=start)
        files.member_series = tuple(first)  # the invariants and the errors the case has
        if self.root:
            kw = {"overwrite": overwrite, "compress": compress, "notify": notify}
            files.open(attrs, **kw, members=self.members, member_series=files.member_series)
        signals = StopSignals(self.model.topology if self.comm is None else RankMax(self.comm), catch=True)

        def blocks(signals, bar) -> Stop:
            lines = progress_lines if self.root else None
            return self._steps(s.nsteps, s.days, signals, bar, lines, notify if self.root else None)

        def dropped() -> dict:  # the members dropped (collective)
            drops = self.drops
            return {"dropped_members": "; ".join(drops)} if drops else {}

        during = own_activities(self.activities, files, ckp)
        why = lambda err: {"stopped": str(err) or type(err).__name__}  # noqa: E731
        kw = {"progress": progress, "lines": progress_lines, "diagnosed": first, "why": "stopped", "kept": why}
        stop = integrate(self.run_state, files, ckp, start, signals, blocks, during, **kw, closing=dropped)
        outcome(stop, self.run_state, output, ckp)
        return Path(output)

    # -- restart files -------------------------------------------------------------
    def write_checkpoint(self, path, *, overwrite: bool = False, restart_every: float | None = None) -> Path:
        """Write the restart file ``path`` of the current step (``io.restart_file``: every member's
        state and its stepper's history, the member count, the layout and the variants):
        ``from_checkpoint`` continues it bitwise. ``OutputError`` where ``path`` exists and not
        ``overwrite``. Written by rank 0, the members' arrays gathered there (collective)."""
        x, state = self._side(lambda u: u.x.numpy()), stepper_state(self.units, self.layout, self.held)
        policy = {"blow_up": self.blow_up, "dropped": {str(k): step for k, step in self.dropped.items()}}
        if self.comm is not None:  # the ranks' members side by side, in member order; every rank's scalars
            x, state = on_rank_zero(self.comm, x, state)
            if not self.root:
                return Path(path)
        kept = {"overwrite": overwrite, "restart_every": restart_every, "members": self.members}
        initial = {"initial_states": self.initial, "layout": self.layout, "variants": self._variants, **policy}
        grid = self.copies if self.copies is not None and self.comm is None else MemberGrid(self.grid, self.members)
        return write_restart(path, self.run_state, x, state, initial, grid, **kept)

    @classmethod
    def from_checkpoint(cls, path, *, days=None, device=None, per_element=None, threads=None, graphs=None, comm=None):
        """The ensemble of the restart file ``path`` (``write_checkpoint``, or ``run``'s), at its
        step, to ``days`` (model days from t = 0; None: the file's scene's): every member's next
        steps the bits of the uninterrupted run's (with its variants' scenes). ``CheckpointError``
        (one line) for a file ``simulation.checkpoint.read`` refuses, a single run's restart
        file, or ``days`` before the file's day; the other arguments as the constructor's (the
        layout the file's)."""
        ck, scene, *_ = continued(path, days, members=True)
        n = ck.x.shape[1] // ck.members
        states = ck.x.reshape(3, ck.members, n).transpose(1, 0, 2)
        variants = ck.initial.get("variants")  # the members' own scenes, then the file's states
        initial = states if variants is None else Variants(variants)
        options = {"device": device, "per_element": per_element, "threads": threads, "graphs": graphs, "comm": comm}
        layout, policy = ck.initial.get("layout", "shared"), ck.initial.get("blow_up", "stop")
        ens = cls(scene, ck.members, initial, **options, layout=layout, blow_up=policy)

        def restore() -> None:  # the file's states and stepper histories into the units
            for u, k in zip(ens.units, unit_members(ens.layout, ens.held)):
                nodes = (k[:, None] * n + np.arange(n)).ravel()  # the unit's members' columns of the file's arrays
                u.x.assign(ck.x[:, nodes])
                prefix = None if ens.layout == "shared" else f"member{k[0]}_"
                u.stepper.restore(held_state(ck.stepper_state, nodes, prefix))

        restore_run(ens.run_state, ck, restore)  # then its step, counters and step control, as a run's
        ens.mark_dropped({int(k): step for k, step in ck.initial.get("dropped", {}).items()})  # their last good states
        ens.initial = ck.initial.get("initial_states", ens.initial)
        return ens

    def errors(self) -> list[dict[str, float]]:
        """Each member's errors now against the case's truth, as a single run's file has them
        (``cases.scoring.Scorer.errors``: Williamson et al. 1992's normalized l1, l2, l∞ of h and
        the wind against an exact solution, or against the scene's spectral reference where
        it stores this day); {} a member for a case with neither."""
        return self._everyone(self._errors(self._held_states(), self.run_state.seconds(self.step_count)))

    def _errors(self, held, t: float) -> list[dict[str, float]]:
        """``errors`` at ``t`` (s) of this rank's members' states ``held`` (held, 3, n)."""
        if self._scorer is None:  # one member's model for the wind errors' vorticity and divergence
            with threadpool_limits(limits=1, user_api="blas"):
                one = self._one or ShallowWater.from_scene(self.scene, self.grid, self.case, **self._options)
            # each variant's own truth, an exact solution (a reference holds the scene's values only)
            cases, ref = ([self.case], self.scene.reference_file) if self.cases is None else (self.cases, None)
            self._scorer = [Scorer(c, one, one.topology, self.grid, self._member(self._hs, 0), ref) for c in cases]
        return [self._scorer[k % len(self._scorer)].errors(t, xk, *xk) for k, xk in zip(self.held, held)]

    def gather_fields(self, x=None, divergence: bool = False) -> MemberFields:
        """Every member's u, v, h, vorticity and (``divergence``) divergence now, (N, n) each on
        rank 0 (a dropped member's NaN; None on the other ranks), as a run's
        ``StateDiagnostics.gather_fields`` for its run files (``writers.RunFiles``), and this
        rank's members' own (``MemberFields.held``) on every rank (collective; ``x`` unread)."""
        x, zeta = self._side(lambda u: u.x.numpy()), self._side(lambda u: u.model.operators.vorticity(u.x))
        div = self._side(lambda u: u.model.operators.wind_divergence(u.x)) if divergence else None
        rows = [*(x[r] for r in range(3)), zeta, *(() if div is None else (div,))]
        held = [np.stack([self._member(a, k) for a in rows]) for k in range(self.held.size)]
        shown = [np.full_like(m, np.nan) if i in self._out else m for i, m in enumerate(held)]
        each = shown if self.comm is None else self.comm.gather(shown, root=0)
        if not self.root:
            return MemberFields(None, None, None, None, held=held)
        each = np.stack(each if self.comm is None else [m for part in each for m in part])  # (N, rows, n)
        return MemberFields(*(each[:, r] for r in range(4)), None if div is None else each[:, 4], held=held)

    def diagnose(self, t: float, x=None, whole: MemberFields | None = None) -> dict:
        """Each member's mass, total energy, potential enstrophy (``invariants``) and errors at
        ``t`` (s) (``errors``), (N,) arrays by name (a dropped member's NaN) on every rank, as a
        run's ``StateDiagnostics.diagnose`` for its run files (collective); ``whole`` this
        step's ``gather_fields`` where taken (``x`` unread)."""
        held = (self.gather_fields() if whole is None else whole).held
        errors = self._errors([m[:3] for m in held], t)
        each = [{**d, **e} for d, e in zip(self._invariants(held), errors)]
        each = self._everyone(dict.fromkeys(d, np.nan) if i in self._out else d for i, d in enumerate(each))
        return {key: np.array([d[key] for d in each]) for key in each[0]}

    def _from_root(self, value):
        """Rank 0's ``value`` on every rank (collective)."""
        return value if self.comm is None else self.comm.bcast(value, root=0)

    @property
    def graphs_kept(self) -> int:
        """The step graphs checked against plain launches and kept (0 with graphs off)."""
        return sum(u.graphed.kept for u in self.units)

    # -- the members' states ----------------------------------------------------
    def states(self) -> np.ndarray:
        """(N, 3, n) float64: every member's u, v (m s⁻¹) and h (m) on the grid's element-local
        nodes (on every rank: collective)."""
        return np.stack(self._everyone(self._held_states()))

    def _held_states(self) -> np.ndarray:
        """(held, 3, n): this rank's members' states."""
        x = self._side(lambda u: u.x.numpy())
        states = np.stack([self._member(x, k) for k in range(self.held.size)])
        states[list(self._out)] = np.nan  # a dropped member has no state
        return states

    def fields(self, member: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(u, v, h), each (n,), of ``member`` (0 … N − 1) on the grid's element-local nodes
        (m s⁻¹, m s⁻¹, m). ``ArgumentError`` for another member."""
        member = integer_argument("member", member, 0)
        if member >= self.members:
            raise ArgumentError(f"member must be in 0..{self.members - 1} (got {member})")
        return tuple(self.states()[member].copy())

    def h_spread_rms(self) -> float:
        """The ensemble spread of h now (m): the area-weighted RMS over the sphere of the members'
        standard deviation (``io.run_file.member_statistics``, ``area_rms``), the run file's
        ``h_spread_rms``."""
        h = np.stack([self.grid.to_unique(states[2]) for states in self.states()])
        return area_rms(self.grid, member_statistics(h)[1])

    def invariants(self) -> list[dict[str, float]]:
        """Each member's mass (m³), total energy (m⁵ s⁻²) and potential enstrophy (m s⁻²)
        (``model.diagnostics.invariants`` on the one grid: the bits of the single run's)."""
        return self._everyone(self._invariants(self.gather_fields().held))

    def _invariants(self, held: list) -> list[dict[str, float]]:
        """``invariants`` of this rank's members' rows ``held`` (``MemberFields.held``)."""
        one = self._member
        return [
            invariants(self.grid, *rows[:3], one(self._hs, k), rows[3], one(self._fcor, k), self._g[k])
            for k, rows in enumerate(held)
        ]


@dataclass
class MemberFields(WholeFields):
    """An ensemble's ``WholeFields`` (``Ensemble.gather_fields``): u, v, h, vorticity and divergence
    (N, n) each on rank 0; ``held`` this rank's members' rows (u, v, h, vorticity[, divergence]),
    (rows, n) a member, on every rank."""

    held: list | None = None
