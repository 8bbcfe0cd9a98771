"""The simulation: a scene's model, stepper and state, and the loop that steps them.

On Oceananigans' pattern, the loop (``Simulation.run``) is short and takes its
steps by one path; what happens around the steps is each a small part: the step
itself (``graphs.GraphedSteps``), the bad-state guard (``guard``), the activities
called at the steps their schedules name (``activities``: the run files and restart
files of ``writers``, callbacks, user writers, the log; all in ``Simulation.activities``),
signals (``interrupts``), and the counts and result (``summary``); the state's
diagnostics are ``state_diagnostics``."""

from __future__ import annotations

import contextlib
import dataclasses
import itertools
import signal
import sys
import time
from pathlib import Path

import numpy as np
import warp as wp
from threadpoolctl import threadpool_limits
from tqdm import tqdm

from ..cases.scoring import Scorer
from ..config.scene import Scene, resolve_scene, with_days
from ..core.backend import CHECK_EVERY_STEPS, Backend, pick_device
from ..core.clock import is_interval
from ..core.constants import DAY
from ..core.errors import BlowUp, Interrupted, ResourceError, SceneError, StepFailure
from ..core.graphs import GraphedSteps, default_mode, graphs_mode
from ..core.interrupts import StepAbandoned, StopSignals
from ..core.mpi import node_local_size
from ..core.runtime import run_bytes
from ..grid.cubed_sphere import CubedSphere
from ..grid.topology import Topology, rank_parts
from ..io import restart_file
from ..io.initial_state import from_function
from ..io.run_file import OUTPUT_FIELDS, check_distinct, check_target, node_dataset
from ..model.shallow_water import ShallowWater
from ..steppers import STEPPERS, StepStats, make_stepper
from ..steppers.initialization import digital_filter
from . import checkpoint as ckpt
from .activities import Callback, Log
from .guard import Guard
from .schedules import EverySteps, steps_of
from .state_diagnostics import StateDiagnostics
from .summary import Ledger, RunResult, Stop, interruption
from .writers import Checkpointer, RunFiles, run_attrs

# The names users catch and read from here (``swe_sphere.BlowUp``, ``swe_sphere.Interrupted``).
__all__ = ["ON_ROOT", "BlowUp", "Interrupted", "RunResult", "Simulation"]


RUN_ACTIVITIES = ("run_file", "checkpointer", "log")  # the names ``run`` gives its own activities
ON_ROOT = object()  # ``start`` on the ranks > 0 when rank 0 alone holds the whole-grid start state

MAX_HYPERVIS_EVALUATIONS = 10_000  # ∇⁴ evaluations a step; beyond, ν is ~10⁷ times its explicit bound or more


def _check_hyperviscosity(model: ShallowWater, scene: Scene) -> None:
    """Refuse (``SceneError``, before the run) a ν whose ∇⁴ sub-stepping
    (``hypervis.Hyperviscosity.plan``) would take more than
    ``MAX_HYPERVIS_EVALUATIONS`` evaluations a step: such a step runs for hours
    and is a mistyped coefficient, not a setting."""
    if model.hv is None or model.hv.nu_max == 0.0:
        return
    hv = model.hv
    evals, _ = hv.plan(scene.dt)
    if evals > MAX_HYPERVIS_EVALUATIONS:
        bound = 1.5 / (scene.dt * hv.biharmonic_radius())
        raise SceneError(
            f"hyperviscosity nu = {hv.nu_max:.3g} m^4/s is {hv.nu_max / bound:.2g}x its explicit bound "
            f"({bound:.3g} m^4/s at dt = {scene.dt:g} s): {evals:.3g} ∇⁴ evaluations a step (at most "
            f"{MAX_HYPERVIS_EVALUATIONS}); lower hyperviscosity.nu"
        )


def _check_memory(scene: Scene, comm, device: str = "cpu") -> None:
    """Refuse (``runtime.ResourceError``, one line, on every rank) a run whose
    estimated memory exceeds what is available on its device (a GPU's free memory,
    else the host's): the whole run on one process; over MPI ranks, the share of
    the ranks on each node (each holds its elements)."""
    need = run_bytes(scene.ne, scene.np, scene.stepper, nelem=scene.nelem)
    what = f"{scene.grid_text} with {scene.stepper}"
    backend = Backend.of(device)
    if comm is None or comm.size == 1:
        return backend.check_memory(need, what)
    local = node_local_size(comm)
    try:
        backend.check_memory(need * local // comm.size, f"{what} over {comm.size} MPI ranks ({local} on this node)")
        error = None
    except ResourceError as err:
        error = str(err)
    errors = [e for e in comm.allgather(error) if e is not None]  # every rank refuses if one node must
    if errors:
        err = ResourceError(errors[0])
        err.on_every_rank = True  # the console script says it once (rank 0), without MPI_Abort
        raise err


@contextlib.contextmanager
def _compile_timer(acc: list):
    """Add the seconds spent loading (compiling on a cold cache) Warp modules to acc[0]."""
    try:
        from warp._src.context import Module  # private: without it, compilation counts as stepping
    except ImportError:
        yield
        return
    real, depth = Module.load, [0]

    def load(self, *args, **kwargs):
        depth[0] += 1
        t0 = time.perf_counter()
        try:
            return real(self, *args, **kwargs)
        finally:
            depth[0] -= 1
            if depth[0] == 0:
                acc[0] += time.perf_counter() - t0

    Module.load = load
    try:
        yield
    finally:
        Module.load = real


class Simulation(StateDiagnostics):
    """Build the grid, case, model and stepper of a scene; ``run`` integrates it.

    A scene may be given as ``swe_sphere.run`` takes it, ``Simulation("tc2_steady", ne=4,
    days=2)``. Python drives it step by step with ``advance``, ``steps``, ``state`` and
    ``add_callback``; ``run`` integrates to the scene's end; ``from_checkpoint``
    continues a restart file instead of starting at t = 0.

    Parameters
    ----------
    scene : Scene, str or path
        A resolved scene, or a scene file or bundled name with ``overrides``
        (``config.resolve_scene``).
    device : {"cpu", "cuda"}, optional
        Warp device (default: CUDA when present, ``backend.pick_device``).
    progress : bool
        A tqdm bar (rank 0, stderr a terminal).
    comm : mpi4py communicator, optional
        Run one simulation over its ranks: each steps its part of the elements
        (``topology.Topology``), rank 0 writes the files; explicit steppers give the
        same bits on any number of ranks. None: this process alone.
    start : ndarray, shape (3, nnodes), optional
        A whole-grid state (u, v in m s⁻¹, h in m) to start from instead of the case's
        initial state and the scene's initialization (a restart's, or a digital-filter
        start made once for many runs, as a sweep's).
    initial : callable, optional
        ``initial(lat, lon) -> (h, u, v)`` (radians in; m, m s⁻¹ out), the state at
        t = 0 instead of the case's, which still gives fcor, hs and the truth errors
        are taken against (``initial_state.from_function``); the scene's digital
        filter, if any, then runs on it. Not with ``start``.
    initial_diagnostics : dict, optional
        The t = 0 diagnostics that relative changes are taken against, the same on
        every rank (a checkpoint's, when continuing); None: the start state's.
    graphs : {"auto", "on", "off"} or bool, optional
        Steps replayed as captured graphs (see Notes); default the environment's
        ``SWE_SPHERE_GRAPHS``, else "auto". Also an attribute to set.
    **overrides
        As for ``swe_sphere.run``: ``ne``, ``np``, ``dt``, ``days``, ``stepper`` and
        any scene value by its table.

    Attributes
    ----------
    check_every : int
        ``run`` reads the device's bad-state check back once a block of so many steps
        (``core.backend.CHECK_EVERY_STEPS``, 64), a failed block re-run one
        checked step at a time (``guard.Guard``; the same bits either way).
    dfi : FilterResult or None
        The digital-filter initialization's result, when the scene has one
        (``initialization``) and no ``start`` was given; its cost is in ``setup_time``.
    activities : dict
        What the loop does between steps, by name: each a schedule and a call
        (``simulation.activities``); callbacks and output writers of one's own go here.
    inputs : tuple of Path
        The files the simulation was made from (scene file, restart file), which
        ``run`` refuses to write over.

    Raises
    ------
    SceneError
        A bad scene, override, or ``initial`` state (wrong shape, non-finite, h <= 0).
    ValueError
        ``initial`` not callable or given with ``start``; an unknown ``graphs`` mode.
    ResourceError
        Too little memory for the grid.

    Notes
    -----
    With ``graphs`` "on", and "auto" on CUDA, ``run`` replays each step of a
    ``capturable`` stepper (the explicit ones; semi-implicit and IMEX after their first
    step, their Helmholtz CG's loops conditional nodes inside, on CUDA where Warp has
    them) as a graph captured of an earlier step with the same ``Stepper.graph_key``
    (on CUDA one host call a step instead of one a launch; the same bits as launched
    one by one), its first replay checked against the step launched plainly
    (``graphs.GraphedSteps``); a model with a time-dependent forcing runs plain. On a
    CPU it takes one thread a launch (SWE_SPHERE_THREADS=1) and one process; otherwise
    the steps run plain. "off": plain launches throughout (the solvers' own graphs
    too). A capture, replay or check that fails prints one line on stderr naming the
    feature, and the run goes on with plain launches from the plain step's state.
    """

    inputs: tuple = ()

    def __init__(
        self,
        scene,
        device: str | None = None,
        *,
        progress: bool = True,
        comm=None,
        start: np.ndarray | None = None,
        initial=None,
        initial_diagnostics: dict | None = None,
        graphs: str | bool | None = None,
        **overrides,
    ):
        graphs = graphs_mode(default_mode() if graphs is None else graphs)
        # Δt the simulation may fit to the user's intervals (``steps``): not given, restored or stated in a Scene
        self._own_dt = not isinstance(scene, Scene) and "dt" not in overrides and initial_diagnostics is None
        scene, inputs = resolve_scene(scene, overrides)
        device = pick_device(device)  # a name Warp does not know is refused in one line
        if initial is not None and (start is not None or not callable(initial)):
            raise ValueError("initial must be a function (lat, lon) -> (h, u, v), and not given with start")
        t0 = time.perf_counter()
        self._compile = [0.0]
        self.activities: dict = {}  # name -> activity (``activities``): the user's; ``run`` adds its own
        # single-threaded BLAS, as in ``run``: the ∇⁴'s power iteration (``_check_hyperviscosity``)
        # takes 40 norms, and OpenBLAS's threads spinning on a busy machine made them 0.3 s of CPU
        with _compile_timer(self._compile), threadpool_limits(limits=1, user_api="blas"):
            self._build(scene, device, progress, comm, start, initial, initial_diagnostics)
        self.graphs = graphs
        self.setup_time = time.perf_counter() - t0
        if inputs:
            self.inputs = inputs

    def _build(self, scene, device, progress, comm, start, initial, initial_diagnostics):
        _check_memory(scene, comm, device)
        self.scene, self.device = scene, device
        size, rank = (1, 0) if comm is None else (comm.size, comm.rank)
        mesh = scene.make_mesh()  # None: the equiangular cube
        self.case = case = scene.make_case()
        level = None  # over several ranks: the stepper's element levels, if its work goes by levels (lts)
        if size > 1:
            whole = lambda: CubedSphere(scene.ne, scene.np, case.planet.a, mesh=mesh)  # noqa: E731
            mine = STEPPERS[scene.stepper].partition_levels(whole, scene.stepper_options) if rank == 0 else None
            level = comm.bcast(mine, root=0)
        parts = rank_parts(scene.ne, size, mesh, level)
        local = CubedSphere(scene.ne, scene.np, case.planet.a, elements=parts[rank], mesh=mesh)  # this rank's only
        self.topology = topo = Topology(local, device, Backend.of(device).threads(), comm, parts=parts)
        self.root = rank == 0  # the rank that diagnoses, writes files and shows progress
        self.progress = progress and self.root
        # the whole grid and fields for diagnostics and output: on rank 0 only (None elsewhere)
        self.grid = topo.whole_grid()
        self.model = ShallowWater.from_scene(scene, local, case, device=device, topology=topo)
        self.g = self.model.g
        fcor, hs = self.model.fcor.numpy(), self.model.hs.numpy()  # the case's, as the model holds them
        self.fcor, self.hs = topo.gather(fcor), topo.gather(hs)
        _check_hyperviscosity(self.model, scene)
        self.stepper = make_stepper(scene.stepper, self.model, scene.dt, **scene.stepper_options)
        self.stepper.t0 = scene.start_day * DAY
        self.scorer = Scorer(case, self.model, topo, self.grid, self.hs, scene.reference_file)
        self.dfi = None
        if start is None:
            start = (
                np.stack(case.initial(local.lat, local.lon))
                if initial is None
                else from_function(initial, local.lat, local.lon)
            )
            if scene.digital_filter is not None:
                self.dfi = digital_filter(
                    scene.digital_filter,
                    start,
                    grid=local,
                    terms=scene.terms,
                    fcor=fcor,
                    hs=hs,
                    g=self.g,
                    device=device,
                    topology=topo,
                )
        else:
            start = topo.distribute(None if start is ON_ROOT else start, 3, "start state")
        self.x = self.model.new_state(*(self.dfi.x if self.dfi is not None else start))
        self.stepper.prepare(self.x)
        self.last_good = wp.clone(self.x)  # the state at the start of the block of steps in progress (``guard``)
        self.check_every = CHECK_EVERY_STEPS
        if not self.root:  # a fallback's warning once, from rank 0
            self.model.graph_guard.warn = lambda line: None
        self._graphed = GraphedSteps(device, self.model.graph_guard)
        self.initial = initial_diagnostics
        if initial_diagnostics is None:
            self.initial = self.diagnose(scene.start_day * DAY)
        self.step = 0  # steps taken since t = 0 (a branched run: since its branch day, ``Scene.start_day``)
        self.counters = {
            "rhs_evals": 0,
            "wall_time": 0.0,
            "cpu_time": 0.0,
            "iterations": {k: 0 for k in self.stepper.solvers},
        }

    # -- the step --------------------------------------------------------------
    @property
    def graphs(self) -> str:
        """The graph mode: "auto", "on" or "off" (set also as True, False; see the class)."""
        return self._graphed.mode

    @graphs.setter
    def graphs(self, value) -> None:
        self._graphed.mode = value

    def _take_step(self, watch: bool):
        """One step of the stepper on x and, with ``watch``, the bad-state flag's launch
        (``ShallowWater.watch``; the solvers' device counters left for the block's
        read), else with its solvers' counters read (``Stepper.counts``: raises
        ``StepFailure``); its ``StepStats``. With ``graphs``, steps replay as
        graphs (``graphs.GraphedSteps``)."""
        stats = self._graphed.step(self.stepper, self.model, self.x, watch)
        return stats if watch else StepStats(stats.rhs_evals, {**stats.iterations, **self.stepper.counts()})

    # -- restart --------------------------------------------------------------
    @classmethod
    def from_checkpoint(
        cls,
        checkpoint,
        device: str,
        *,
        days: float | None = None,
        stepper: str | None = None,
        dt: float | None = None,
        progress: bool = True,
        comm=None,
        graphs: str | bool | None = None,
    ) -> Simulation:
        """A simulation that continues a restart file, bitwise as if never stopped.

        With another ``stepper`` or ``dt`` than the checkpoint's it is a branch
        (``checkpoint.branch``): a new run from the checkpoint's state, its stepper's
        history dropped (multistep steppers start as at t = 0), its counters from zero
        and its invariants' changes against that state, steps counted from the
        checkpoint's day.

        Parameters
        ----------
        checkpoint : str, path or checkpoint.Checkpoint
            The restart file (read on rank 0 only, ``checkpoint.read_on_root``).
        device : {"cpu", "cuda"}
            Warp device.
        days : float, optional
            The new last model day, from t = 0 (default: the checkpointed scene's).
        stepper : str, optional
            Another stepper: a branch.
        dt : float, optional
            Another time step (s): a branch.
        progress, comm, graphs
            As for the constructor.

        Returns
        -------
        Simulation
            At the checkpoint's step.

        Raises
        ------
        CheckpointError
            An unreadable or damaged restart file, or a ``days`` before its step.
        SceneError
            A branch it cannot make (unknown stepper, dt <= 0, a length not whole steps).
        """
        ck = checkpoint if isinstance(checkpoint, ckpt.Checkpoint) else ckpt.read_on_root(checkpoint, comm)
        start = ON_ROOT if ck.x is None else ck.x  # ranks > 0 of ``read_on_root`` have no arrays
        if (stepper is not None and stepper != ck.scene.stepper) or (dt is not None and dt != ck.scene.dt):
            sim = cls(
                ckpt.branch(ck, stepper=stepper, dt=dt, days=days),
                device,
                progress=progress,
                comm=comm,
                start=start,
                graphs=graphs,
            )
        else:
            scene = ck.scene if days is None else with_days(ck.scene, days)
            if scene.nsteps < ck.step:
                raise ckpt.CheckpointError(
                    f"the run length {scene.days:g} days ends before the checkpoint (day {ck.scene.day(ck.step):g})"
                )
            sim = cls(
                scene,
                device,
                progress=progress,
                comm=comm,
                start=start,
                initial_diagnostics=ck.initial,  # the state handed out; no second digital filter
                graphs=graphs,
            )
            sim.restore_history(ck)
        if not isinstance(checkpoint, ckpt.Checkpoint):
            sim.inputs = (Path(checkpoint),)
        return sim

    def restore(self, ck: ckpt.Checkpoint) -> None:
        """Set the state, stepper history, counters and t = 0 invariants from a checkpoint."""
        try:
            x = self.topology.distribute(
                ck.x, 3, "checkpoint state"
            )  # ck.x on rank 0 only (``checkpoint.read_on_root``)
        except ValueError as err:
            raise ckpt.CheckpointError(str(err)) from None
        self.x.assign(x)
        self.restore_history(ck)

    def restore_history(self, ck: ckpt.Checkpoint) -> None:
        """``restore`` but the state (already ``ck.x``)."""
        try:
            self.stepper.restore(ck.stepper_state)
        except ValueError as err:
            raise ckpt.CheckpointError(f"checkpoint does not fit the stepper: {err}") from None
        self.step, self.counters, self.initial = ck.step, ck.counters, ck.initial

    def write_checkpoint(self, path, *, overwrite: bool = True, restart_every: float | None = None) -> Path:
        """Write a restart file of the current step (see ``checkpoint``): whole-grid
        fields, gathered from every rank (call on all), written by rank 0;
        ``restart_every`` (days) recorded for a continuation to keep."""
        x, state = self.topology.gather(self.x.numpy()), self.stepper.state()
        if not self.root:
            return Path(path)
        return restart_file.write(
            path,
            self.scene,
            self.step,
            x,
            state,
            self.counters,
            self.initial,
            grid=self.grid,
            overwrite=overwrite,
            restart_every=restart_every,
        )

    # -- driven from Python (Oceananigans' Simulation: step, inspect, call back) ---------
    def fit_dt(self, every: float, what: str = "every") -> None:
        """Shorten Δt, before the first step, to the largest that divides ``every`` (days),
        the run, its output intervals (where shorter than the run) and the intervals of
        the activities scheduled in days (``every``; their steps follow): the scene's clock
        fitted to them (``Clock.fitted``), a new stepper, and the start's diagnostics again
        (their Courant numbers); a note in ``scene.notes`` naming ``what``. ``SceneError``
        (one line) after the first step, for ``every`` <= 0, and where that Δt is less than
        half the present one (an interval of odd decimals: give a dt, or an interval of
        whole steps)."""
        s = self.scene
        if self.step != 0 or not is_interval(every):
            raise SceneError(
                f"dt is fitted to an interval > 0 before the first step (got {every!r} at step {self.step})"
            )
        outputs = [s.output_every_days, *(st["every_days"] for st in s.output_streams)]
        days = [a.schedule.days for a in self.activities.values() if getattr(a.schedule, "days", None) is not None]
        spans = (every, s.run_days, *(d for d in outputs if d < s.run_days), *days)
        clock = s.clock.fitted(*spans, source=f"{s.dt_source}, shortened to divide {what} = {every:g} days")
        if clock.dt < s.dt / 2:
            raise SceneError(
                f"{what} = {every:g} days is not a whole number of steps of dt = {s.dt:g} s, and the longest dt "
                f"that divides it, the run and its output intervals is {clock.dt:g} s, less than half: give a dt, "
                "or an interval of whole steps"
            )
        note = f"dt shortened from {s.dt:g} s to {clock.dt:g} s to divide {what} = {every:g} days"
        self.scene = dataclasses.replace(s, dt=clock.dt, notes=(*s.notes, note), dt_source=clock.source)
        _check_hyperviscosity(self.model, self.scene)
        self.stepper = make_stepper(self.scene.stepper, self.model, clock.dt, **self.scene.stepper_options)
        self.stepper.t0 = self.scene.start_day * DAY
        self.stepper.prepare(self.x)
        for activity in self.activities.values():
            if getattr(activity.schedule, "days", None) is not None:
                activity.schedule = self.every(days=activity.schedule.days)
        self.initial = self.diagnose(self.scene.start_day * DAY)

    def every(self, *, days: float | None = None, steps: int | None = None) -> EverySteps:
        """The schedule of an activity (``activities``) due after every step that is a
        multiple of ``steps``, or of the steps in ``days`` (whole steps), counted from
        step 0 (Oceananigans' ``IterationInterval``); not at step 0, whose state the
        caller has. ValueError for an interval that is not whole steps, or not exactly
        one of the two."""
        if (days is None) == (steps is None):
            raise ValueError("an interval needs exactly one of every_days, every_steps")
        if steps is not None and not (isinstance(steps, int) and steps >= 1):
            raise ValueError(f"every_steps must be an integer >= 1 (got {steps!r})")
        return EverySteps(steps) if days is None else EverySteps(self._steps_in(days, "every_days"), days)

    def _steps_in(self, days: float, what: str) -> int:
        """The whole number of steps in ``days`` (``what`` names it in a refusal), Δt first
        fitted to it (``fit_dt``) where Δt is the simulation's own and no step was taken."""
        if self._own_dt and self.step == 0 and is_interval(days) and not self.scene.clock.is_whole(days):
            self.fit_dt(days, what)
        return steps_of(self.scene, days, f"the interval {what}")

    def add_callback(
        self, fn, *, every_days: float | None = None, every_steps: int | None = None, name: str | None = None
    ) -> None:
        """Call ``fn(sim)`` after every ``every_steps``-th step, or every ``every_days``
        (``every``), in ``run``, ``advance`` and ``steps`` (Oceananigans' ``add_callback!``):
        an activity in ``activities`` under ``name`` (default "callback N"). ``fn`` may read
        ``sim.step``, ``sim.time``, ``sim.state()``; what it raises ends the run (its
        output files dropped). Under MPI add it on every rank. ValueError as ``every``."""
        schedule = self.every(days=every_days, steps=every_steps)
        if name is None:
            name = next(f"callback {k}" for k in itertools.count(1) if f"callback {k}" not in self.activities)
        self.activities[name] = Callback(fn, schedule)

    @property
    def time(self) -> float:
        """The model time of the current step, days since t = 0."""
        return self.scene.day(self.step)

    def advance(self, days: float) -> RunResult:
        """Step ``days`` further with ``run``'s loop (the same bits as one run; blow-up,
        signals and callbacks as there; no output file). Past the scene's end the run
        is lengthened (``config.with_days``).

        Parameters
        ----------
        days : float
            Model days, a whole number of steps.

        Returns
        -------
        RunResult
            Of these steps.

        Raises
        ------
        ValueError
            ``days`` is not a whole number of steps.
        BlowUp, StepFailure, Interrupted
            As ``run``.
        """
        target = self.step + self._steps_in(days, "days")
        if target > self.scene.nsteps:
            self.scene = with_days(self.scene, self.scene.start_day + target * self.scene.dt / DAY, "the scene's")
        return self.run(None, until_step=target)

    def steps(self, every: float):
        """Iterate the run to the scene's end, one multiple of ``every`` days from t = 0
        at a time (``for t in sim.steps(every=0.5): ds = sim.state()``); stops at the last
        multiple at or before the end.

        Where Δt is the simulation's own (no ``dt`` given, the scene named or a file:
        ``swe-sphere run`` shortens it likewise to divide the output interval) and no step
        has been taken, a Δt that does not divide ``every`` is first shortened to the
        largest that divides ``every``, the run, its output intervals and the callbacks'
        (``fit_dt``; so do ``advance`` and ``every`` for their intervals).

        Parameters
        ----------
        every : float
            Model days between yields, a whole number of steps.

        Yields
        ------
        float
            The model time reached (days since t = 0).

        Raises
        ------
        ValueError
            ``every`` is not then a whole number of steps (naming a Δt that was given).
        BlowUp, StepFailure, Interrupted
            As ``run``.
        """
        per = self._steps_in(every, "every")
        while (target := (self.step // per + 1) * per) <= self.scene.nsteps:
            self.run(None, until_step=target)
            yield self.time

    def state(self, remap: float | None = None):
        """The current state as an ``xarray.Dataset``; call on every rank.

        Parameters
        ----------
        remap : float, optional
            Grid spacing in degrees: the state on a regular lat-lon grid
            (``remap.remap_dataset``, with h_surface = h + hs). None: on the nodes.

        Returns
        -------
        xarray.Dataset or None
            On the nodes, as a run file holds one output time: h (m), u, v (m s⁻¹),
            vorticity, divergence (s⁻¹) on ``ncol`` with hs, area, lat, lon and ``time``
            in days (``run_file.node_dataset``); or on (lat, lon). None on ranks other
            than 0.

        Raises
        ------
        ValueError
            A ``remap`` spacing that does not divide 180 degrees.
        """
        whole = self.gather_fields(divergence=True)
        if not self.root:
            return None
        ds = node_dataset(
            self.grid,
            self.hs,
            self.time,
            {k: getattr(whole, k) for k in OUTPUT_FIELDS},
            {"scene": self.scene.as_dict(), "ne": self.scene.ne, "np": self.scene.np, "step": self.step},
        )
        if remap is None:
            return ds
        from ..io.remap import remap_dataset  # here: xarray and scipy.sparse, for the Python API's maps only

        return remap_dataset(ds, remap)

    def run(
        self,
        output: Path | None = None,
        *,
        overwrite: bool = False,
        restart_every: float | None = None,
        restart_file: Path | None = None,
        catch_signals: bool = True,
        compress: bool = False,
        history: str | None = None,
        on_output=None,
        notify=None,
        log=None,
        until_step: int | None = None,
    ) -> RunResult:
        """Integrate the scene from the current step; write ``output`` (netCDF) if given.

        Blocks of steps, each checked by the guard (``guard.Guard``), then the activities
        due (``activities``): the run file and its ``[[output.streams]]`` (``stream_path``),
        the restart file, the callbacks and writers in ``activities``, the log.

        Parameters
        ----------
        output : path, optional
            The run file.
        overwrite : bool
            Replace an existing output (and restart) file.
        restart_every : float, optional
            Write ``restart_file`` every so many model days and at the end.
        restart_file : path, optional
            Default ``restart_path(output)``. Without ``restart_every`` an existing
            default restart file is neither refused nor replaced.
        catch_signals : bool
            (Main thread only.) SIGINT/SIGTERM finish the current step, close the
            output (global attributes ``interrupted``, ``interrupted_at_day``) and
            write the restart file, then raise ``Interrupted``.
        compress : bool
            Fields as float32 with zlib.
        history : str, optional
            The command line, for the file's ``history`` attribute.
        on_output : callable, optional
            ``on_output(step, x)`` at every output step, x the (3, N) device state.
        notify : callable, optional
            ``notify(line)`` (rank 0) with a one-line note when the wall time estimated
            from the first steps exceeds a day, and when the run file's cells were
            built (not read from the cache).
        log : callable, optional
            ``log(line)`` (rank 0) with ``log_line`` every ``scene.log_every_steps``
            steps since t = 0 (given on every rank alike, or on none).
        until_step : int, optional
            Stop after this step (default: the scene's last; ``advance``).

        Returns
        -------
        RunResult
            Steps, RHS evaluations, solver iterations, times and the diagnostics' history.

        Raises
        ------
        OutputError
            An output or restart file exists (without ``overwrite``) or is an input.
        BlowUp
            After closing the output with every good output time and the last good
            state (the step before the failure); the result is on the exception.
        StepFailure
            A solver did not converge.
        Interrupted
            SIGINT or SIGTERM (with ``catch_signals``).
        """
        files, ckp, start, courant = self._open(
            output, overwrite, restart_every, restart_file, compress, history, on_output, notify
        )
        ledger = Ledger(self.counters, self.scene, self.step, notify if self.root else None)
        guard = Guard(self, self.scene.nsteps if until_step is None else until_step, ledger)
        stop = Stop()
        # single-threaded BLAS: the Krylov solvers' vectors are too short for threads to
        # pay, and on a busy machine OpenBLAS's spinning threads made a norm cost 10 ms
        with StopSignals(self.topology, catch_signals) as signals, threadpool_limits(limits=1, user_api="blas"):
            try:
                with self._during_run(files, ckp, log), _compile_timer(self._compile):
                    # a continuation's first time is the last of the file it continues (where its
                    # restart file was written): not written again, so the two files join without a repeat
                    files.record(self.step, whole=start, final=True, write=not self.step)
                    with self._progress_bar() as bar:
                        stop = self._loop(guard, signals, ledger, bar)
                    self._stopped(stop, files, ckp)
                files.close()  # under this run's handlers: a signal now waits, and is answered below
            except BaseException:
                files.abort()
                raise
        if stop.signum is None and stop.blowup is None:  # a signal after the last step's check: the output is whole
            stop.signum = signals.asked() or None
        result = ledger.result(
            self.step, files.history, courant, output, stop.blowup, ckp.written, self.setup_time, self._compile[0]
        )
        return self._outcome(stop, result, output, ckp)

    def _open(self, output, overwrite, restart_every, restart_file, compress, history, on_output, notify) -> tuple:
        """A run's run files and checkpointer (paths checked; the files created on rank 0),
        the start's gathered fields and its Courant numbers. ValueError for a user's
        activity under a name the run gives its own."""
        taken = sorted(set(self.activities) & set(RUN_ACTIVITIES))
        if taken:
            raise ValueError(f"activities {', '.join(taken)}: a run's own names (choose another)")
        ckp = Checkpointer(self, output, restart_every, restart_file, overwrite)
        files = RunFiles(self, output, on_output)
        if self.root:
            check_distinct([output, ckp.path, *files.paths], self.inputs)
            if ckp.path is not None:
                check_target(ckp.path, overwrite)
        with _compile_timer(self._compile):  # a continuation's first use of the diagnostic kernels
            start = self.gather_fields(divergence=files.divergence)  # the first output time's, on every rank
        courant = self.courant(start)
        if output is not None and self.root:
            files.open(run_attrs(self, history, courant), overwrite=overwrite, compress=compress, notify=notify)
        return files, ckp, start, courant

    @contextlib.contextmanager
    def _during_run(self, files: RunFiles, ckp: Checkpointer, log):
        """The run's own activities in ``activities`` (the run file and checkpointer before
        the user's, the log after), and the stepper's solver counters read with the
        bad-state check (``Stepper.deferred``), while the loop runs."""
        own = self.activities
        self.activities = {"run_file": files, "checkpointer": ckp, **own}
        if log is not None and self.scene.log_every_steps:
            self.activities["log"] = Log(log, EverySteps(self.scene.log_every_steps), files)
        self.stepper.deferred = True
        try:
            yield
        finally:
            self.stepper.deferred = False
            self.activities = own

    def _progress_bar(self) -> tqdm:
        # disable=None: a bar only on a terminal, not redrawn into a log (or mpiexec's pipe)
        return tqdm(
            initial=self.step,
            total=self.scene.nsteps,
            unit="step",
            disable=None if self.progress else True,
            file=sys.stderr,
            dynamic_ncols=True,
        )

    def _loop(self, guard: Guard, signals: StopSignals, ledger: Ledger, bar) -> Stop:
        """Blocks of steps to ``guard.stop_step``, the activities due called after each good
        step; a block that finds trouble is re-run a checked step at a time. Returns why
        the loop stopped (``summary.Stop``: nothing, a signal, an abandoned step or a blow-up)."""
        rerun_to = self.step  # steps up to here are re-run one at a time: their block found trouble
        while self.step < guard.stop_step:
            if self.step >= rerun_to and (signum := signals.asked()):  # every rank stops at the same step
                return Stop(signum=signum)
            b = self.step
            e = guard.block_end(b) if b >= rerun_to else b + 1  # a re-run goes on to the trouble it looks for
            m, trouble, detail = self._steps(b, e, guard, signals, ledger)
            if trouble is None:  # m > b: a step without trouble was taken
                self._after_steps(m, m - b, bar)
            elif trouble == "abandoned":
                return Stop(signum=detail, abandoned=(b, m))
            elif e > b + 1:  # the block is re-run from b, a checked step at a time
                rerun_to = m + 1 if trouble == "failure" else m  # a failure: in step m + 1
            else:
                return Stop(blowup=guard.message(b + 1, trouble, detail))
        return Stop()

    def _after_steps(self, n: int, done: int, bar) -> None:
        """Step n (the last of ``done`` steps) is good: the activities due there, the progress bar."""
        self.step = n
        for activity in list(self.activities.values()):
            if activity.schedule.due(n):
                activity(self)
        bar.update(done)
        if n % 50 < done or n == self.scene.nsteps:  # a multiple of 50 in the steps done
            bar.set_postfix(
                day=f"{self.scene.day(n):.2f}",
                sim_days_per_s=f"{n * self.scene.dt / DAY / max(self.counters['wall_time'], 1e-9):.3g}",
            )

    def _stopped(self, stop: Stop, files: RunFiles, ckp: Checkpointer) -> None:
        """Close the files of a run that stopped early: after a blow-up with the last good
        state (``step`` is the last good step again), after a signal with the current one
        and its restart file."""
        if stop.blowup is not None:
            files.end(self.step, self.last_good, blowup=stop.blowup)
        elif stop.signum is not None:
            name, day = signal.Signals(stop.signum).name, self.scene.day(self.step)
            files.end(self.step, interrupted=name, interrupted_at_step=self.step, interrupted_at_day=day)
            ckp.interrupted(self.step, abandoned=stop.abandoned is not None)

    def _outcome(self, stop: Stop, result: RunResult, output, ckp: Checkpointer) -> RunResult:
        """``result``, or ``BlowUp`` or ``Interrupted`` raised with it."""
        if stop.blowup is not None:
            err = BlowUp(stop.blowup)
            err.result = result
            raise err
        if stop.signum is not None:
            name = signal.Signals(stop.signum).name
            err = Interrupted(interruption(name, self.step, self.scene, output, ckp.kept, ckp.written, stop.abandoned))
            err.signum, err.result, err.checkpoint = stop.signum, result, ckp.written
            raise err
        return result

    def _steps(self, b: int, e: int, guard: Guard, signals: StopSignals, ledger: Ledger):
        """Steps b+1..e, the loop's one step path: a single step (e = b + 1) checked at
        once, a block's steps each flagged on the device and the flag read at its end
        (``guard.Guard``); a block stops early for a signal. Returns (m, trouble, detail): m the last step
        taken; trouble None when every state to m was good, else "bad", "unconverged",
        "failure" (a ``StepFailure`` in step m + 1) or "abandoned" (step m + 1), and then
        ``step`` is b again (``Guard.end``); detail a single step's bad node or failure
        message, or the signal that abandoned the step."""
        block = e > b + 1
        guard.begin(b, block)
        t0, cpu0 = time.perf_counter(), time.process_time()
        m, trouble, detail = b, None, None
        while m < e:
            if m > b and signals.asked():  # the loop stops at m, once checked
                break
            try:
                signals.in_step = time.perf_counter()
                stats = self._take_step(watch=block)
            except StepFailure as err:
                trouble, detail = "failure", str(err)
                break
            except StepAbandoned as err:  # the state of the last complete step is kept
                trouble, detail = "abandoned", err.signum
                break
            finally:
                signals.in_step = None
            ledger.add(stats)
            m += 1
            self.step = m  # the steps x holds (not yet checked)
        trouble, node = guard.end(b, trouble, ledger)
        ledger.account(m if block else b + 1, t0, cpu0)
        return m, trouble, node if trouble == "bad" else detail
