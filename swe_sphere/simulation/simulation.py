"""The simulation: a scene's model, stepper and state, and the loop that steps them.

On Oceananigans' pattern, the loop (``Simulation.run``) is short and takes its
steps by one path; what happens around the steps is each a small part: the step
itself (``graphs.GraphedSteps``), the bad-state guard (``guard``), the run files and
restart files (``writers``), callbacks (``callbacks``), signals (``interrupts``),
and the counts and result (``summary``); the state's diagnostics are
``state_diagnostics``."""

from __future__ import annotations

import contextlib
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
from ..core.constants import DAY
from ..core.errors import BlowUp, Interrupted, ResourceError, SceneError, StepFailure
from ..core.graphs import GraphedSteps, default_mode, graphs_mode
from ..core.interrupts import StepAbandoned, StopSignals
from ..core.mpi import node_local_size
from ..core.parallel import default_threads
from ..core.runtime import check_memory, pick_device, run_bytes
from ..grid.cubed_sphere import CubedSphere
from ..grid.topology import Topology, rank_parts
from ..io import restart_file
from ..io.initial_state import from_function
from ..io.remap import remap_dataset
from ..io.run_file import OUTPUT_FIELDS, check_distinct, check_target, node_dataset
from ..model.shallow_water import ShallowWater
from ..steppers import StepStats, make_stepper
from ..steppers.initialization import digital_filter
from . import checkpoint as ckpt
from .callbacks import Callbacks
from .guard import CHECK_EVERY_STEPS, Guard
from .schedules import steps_of
from .state_diagnostics import StateDiagnostics
from .summary import Ledger, RunResult, interruption
from .writers import Checkpointer, RunFiles, run_attrs

# The names users catch and read from here (``swe_sphere.BlowUp``, ``swe_sphere.Interrupted``).
__all__ = ["ON_ROOT", "BlowUp", "Interrupted", "RunResult", "Simulation"]


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
    need, what = run_bytes(scene.ne, scene.np, scene.stepper), f"ne={scene.ne} np={scene.np} with {scene.stepper}"
    dev = wp.get_device(device)
    if comm is None or comm.size == 1:
        return check_memory(need, what, dev)
    local = node_local_size(comm)
    try:
        check_memory(need * local // comm.size, f"{what} over {comm.size} MPI ranks ({local} on this node)", dev)
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

    ``device``: "cpu" or "cuda" (Warp device names). ``progress``: a tqdm bar (rank 0,
    stderr a terminal). ``from_checkpoint`` continues a restart file instead of t = 0.
    ``comm``: an mpi4py communicator to run one simulation over its ranks (each steps
    its part of the elements, ``topology.Topology``; rank 0 writes the files); None:
    this process alone. Explicit steppers give the same bits on any number of ranks.
    ``start``: a whole-grid state (3, npts) (u, v in m s⁻¹, h in m) to start from
    instead of the case's initial state and the scene's initialization (a
    restart's, or a digital-filter start made once for many runs, as a sweep's).
    With the scene's ``initialization`` (a digital filter, see
    ``initialization``) and no ``start``, the filter runs here (its cost is part
    of ``setup_time``) and ``dfi`` holds its ``FilterResult``, else None.
    ``inputs``: the files the simulation was made from (its scene file, restart
    file), which ``run`` refuses to write over.
    ``initial``: a function ``initial(lat, lon) -> (h, u, v)`` (radians in; m,
    m s⁻¹ out) giving the state at t = 0 instead of the case's, which still
    gives fcor, hs and the truth errors are taken against
    (``initial_state.from_function``; ``SceneError`` for a wrong shape, a
    non-finite value or h <= 0); the scene's digital filter, if any, then runs on it.
    ``initial_diagnostics``: the t = 0 diagnostics that relative changes are taken against,
    the same on every rank (a checkpoint's, when continuing: the start state is
    then not diagnosed for nothing); None: the start state's (``diagnose(0)``).

    ``graphs`` ("auto", "on" or "off", or True for "on", False for "off"; default
    the environment's ``SWE_SPHERE_GRAPHS``, else "auto"; ``graphs.graphs_mode``,
    ValueError for another value; also an attribute to set): with "on", and "auto" on
    CUDA, ``run`` replays each step of a ``capturable`` stepper (the explicit ones;
    semi-implicit and IMEX after their first step, their Helmholtz CG's loops
    conditional nodes inside, on CUDA where Warp has them) as a graph captured of an
    earlier step with the same ``Stepper.graph_key`` (on CUDA a CUDA graph, one host
    call a step instead of one a launch; the same bits as launched one by one), its
    first replay checked against the step launched plainly
    (``graphs.GraphedSteps``); a model with a time-dependent forcing runs plain. On
    a CPU it takes one thread a launch (SWE_SPHERE_THREADS=1; Warp replays a CPU
    graph in one thread) and one process; otherwise the steps run plain. "off":
    plain launches throughout (the solvers' own graphs too). A capture, replay or
    check that fails prints one line on stderr naming the feature, and the run goes
    on with plain launches from the plain step's state.
    ``check_every`` (steps; 1 on a CPU, ``guard.CHECK_EVERY_STEPS`` on a GPU): ``run``
    reads the device's bad-state check back once a block of so many steps, a failed
    block re-run one checked step at a time (``guard.Guard``; the same bits either way).

    A scene may also be given as ``swe_sphere.run`` takes it, ``Simulation("tc2_steady",
    ne=4, days=2)``: a scene file or bundled name with overrides
    (``config.resolve_scene``), device None: CUDA when present
    (``runtime.pick_device``). Python drives it step by step with ``advance``,
    ``steps``, ``state`` and ``add_callback``; ``run`` integrates to the scene's end.
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
        scene, inputs = resolve_scene(scene, overrides)
        if device is None:
            device = pick_device()
        if initial is not None and (start is not None or not callable(initial)):
            raise ValueError("initial must be a function (lat, lon) -> (h, u, v), and not given with start")
        t0 = time.perf_counter()
        self._compile = [0.0]
        self.callbacks = Callbacks()
        with _compile_timer(self._compile):
            self._build(scene, device, progress, comm, start, initial, initial_diagnostics)
        self.graphs = graphs
        self.setup_time = time.perf_counter() - t0
        if inputs:
            self.inputs = inputs

    def _build(self, scene, device, progress, comm, start, initial, initial_diagnostics):
        _check_memory(scene, comm, device)
        self.scene, self.device = scene, device
        size, rank = (1, 0) if comm is None else (comm.size, comm.rank)
        parts = rank_parts(scene.ne, size)
        self.case = case = scene.make_case()
        local = CubedSphere(scene.ne, scene.np, case.planet.a, elements=parts[rank])  # this rank's elements only
        self.topology = topo = Topology(local, device, default_threads(device), comm, parts=parts)
        self.root = rank == 0  # the rank that diagnoses, writes files and shows progress
        self.progress = progress and self.root
        # the whole grid and fields for diagnostics and output: on rank 0 only (None elsewhere)
        self.grid = topo.whole_grid()
        fcor, hs = case.fcor(local.lat, local.lon), case.hs(local.lat, local.lon)
        self.fcor, self.hs = topo.gather(fcor), topo.gather(hs)
        self.g = case.planet.g
        self.model = ShallowWater(
            local,
            scene.terms,
            fcor,
            hs,
            nu=scene.nu,
            nu_div=scene.nu_div,
            nu_s=scene.nu_s,
            hypervis_subcycle=scene.hypervis_subcycle,
            g=self.g,
            device=device,
            topology=topo,
            forcing=case.forcing() if "forcing" in scene.terms else None,
        )
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
        self.last_good = wp.clone(self.x)  # the state at the start of the block of steps in progress (``guard``)
        self.check_every = 1 if wp.get_device(device).is_cpu else CHECK_EVERY_STEPS
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
        """A simulation that continues a restart file (path or ``checkpoint.Checkpoint``),
        to model day ``days`` (from t = 0; default the checkpointed scene's),
        bitwise as if never stopped. With another ``stepper`` or ``dt`` (s) than
        the checkpoint's it is a branch (``checkpoint.branch``): a new run from the
        checkpoint's state, its stepper's history dropped (multistep steppers start
        as at t = 0), its counters from zero and its invariants' changes against
        that state, steps counted from the checkpoint's day. ``graphs`` as for the
        constructor. Raises
        ``checkpoint.CheckpointError`` or ``config.SceneError`` (one line)."""
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
            sim._restore_history(ck)
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
        self._restore_history(ck)

    def _restore_history(self, ck: ckpt.Checkpoint) -> None:
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
            overwrite=overwrite,
            restart_every=restart_every,
        )

    # -- driven from Python (Oceananigans' Simulation: step, inspect, call back) ---------
    def add_callback(self, fn, *, every_days: float | None = None, every_steps: int | None = None) -> None:
        """Call ``fn(sim)`` after every step n that is a multiple of ``every_steps``
        (or of the steps in ``every_days``, whole steps) counted from step 0, in
        ``run``, ``advance`` and ``steps`` (Oceananigans' ``add_callback!`` with an
        ``IterationInterval``); not at step 0, whose state the caller has. ``fn`` may
        read ``sim.step``, ``sim.time``, ``sim.state()``; what it raises ends the run
        (its output files dropped). Under MPI add it on every rank. ValueError for
        an interval that is not whole steps, or not exactly one of the two."""
        if (every_days is None) == (every_steps is None):
            raise ValueError("add_callback needs exactly one of every_days, every_steps")
        if every_steps is not None and not (isinstance(every_steps, int) and every_steps >= 1):
            raise ValueError(f"every_steps must be an integer >= 1 (got {every_steps!r})")
        steps = every_steps if every_days is None else steps_of(self.scene, every_days, "every_days")
        self.callbacks.add(fn, steps)

    @property
    def time(self) -> float:
        """The model time of the current step, days since t = 0."""
        return self.scene.day(self.step)

    def advance(self, days: float) -> RunResult:
        """Step ``days`` (a whole number of steps) further, with ``run``'s loop (same
        bits as one run; blow-up, signals and callbacks as there; no output file).
        Past the scene's end the run is lengthened (``config.with_days``). Returns
        the ``RunResult`` of these steps; raises ValueError for a ``days`` that is
        not whole steps, and what ``run`` raises."""
        target = self.step + steps_of(self.scene, days, "days")
        if target > self.scene.nsteps:
            self.scene = with_days(self.scene, self.scene.start_day + target * self.scene.dt / DAY, "the scene's")
        return self.run(None, until_step=target)

    def steps(self, every: float):
        """Iterate the run to the scene's end, yielding the model time (days) at each
        multiple of ``every`` days from t = 0 (``for t in sim.steps(every=0.5):``
        ``ds = sim.state()``); stops at the last multiple at or before the end.
        ValueError unless ``every`` is a whole number of steps."""
        per = steps_of(self.scene, every, "every")
        while (target := (self.step // per + 1) * per) <= self.scene.nsteps:
            self.run(None, until_step=target)
            yield self.time

    def state(self, remap: float | None = None):
        """The current state as an ``xarray.Dataset`` (rank 0; None on the others; call
        on every rank): on the nodes as a run file holds one output time (h, u, v,
        vorticity, divergence on ``ncol`` with hs, area, lat, lon; ``time`` in days;
        ``output.node_dataset``), or with ``remap`` (degrees) on a regular lat-lon grid
        (``remap.remap_dataset``, with h_surface = h + hs)."""
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

        ``overwrite``: replace an existing output (and restart) file; else
        ``output.OutputError``. ``restart_every`` (days): write ``restart_file``
        (default ``restart_path(output)``) every so many days and at the end.
        ``catch_signals`` (main thread only): SIGINT/SIGTERM finish the current
        step, close the output (global attributes ``interrupted``,
        ``interrupted_at_day``) and write the restart file, then raise
        ``Interrupted``; without ``restart_every`` an existing default restart
        file is neither refused nor replaced (no restart file on a signal).
        ``compress``: float32 + zlib fields. ``history``: the
        command line, for the file's ``history`` attribute. ``on_output(step, x)``: called
        at every output step with the (3, N) device state. ``notify(line)``: called
        (rank 0) with a one-line note when the wall time estimated from the first
        steps exceeds a day, and when the run file's cells were built (not cached). ``log(line)``: called (rank 0) with ``log_line`` every
        ``scene.log_every_steps`` steps since t = 0 (given on every rank alike, or on
        none: the fields are gathered then). ``until_step``: stop after this step
        (default the scene's last; ``advance``). The scene's ``[[output.streams]]``
        are written beside ``output`` (``stream_path``), each at its own interval,
        and the callbacks (``add_callback``) are called. Raises ``BlowUp`` after closing the output with every
        good output time and the last good state (the step before the failure).
        """
        s, stepper = self.scene, self.stepper
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
        stop_step = s.nsteps if until_step is None else until_step
        log_every = s.log_every_steps if log is not None else 0
        ledger = Ledger(self.counters, s, self.step, notify if self.root else None)
        guard = Guard(self, stop_step, sorted(files.steps | ckp.steps), log_every, ledger)

        def finish(n: int, done: int) -> None:
            """Step n (the last of ``done`` steps) is good: output, restart, callbacks, log, progress."""
            self.step = n
            if n in files.steps:
                files.record(n)
            if n in ckp.steps:
                ckp.save()
            self.callbacks(self, n)
            if log_every and n % log_every == 0:
                line = self.log_line(files.history[-1] if n in files.steps else None)
                if line is not None:
                    log(line)
            bar.update(done)
            if n % 50 < done or n == s.nsteps:  # a multiple of 50 in the steps done
                bar.set_postfix(
                    day=f"{s.day(n):.2f}",
                    sim_days_per_s=f"{n * s.dt / DAY / max(self.counters['wall_time'], 1e-9):.3g}",
                )

        blowup = interrupted = abandoned = None
        # single-threaded BLAS: the Krylov solvers' vectors are too short for threads to
        # pay, and on a busy machine OpenBLAS's spinning threads made a norm cost 10 ms
        with StopSignals(self.topology, catch_signals) as signals, threadpool_limits(limits=1, user_api="blas"):
            stepper.deferred = True  # its solvers' device counters read with the bad-state check (``guard``)
            try:
                with _compile_timer(self._compile):
                    files.record(self.step, whole=start, final=True)
                    # disable=None: a bar only on a terminal, not redrawn into a log (or mpiexec's pipe)
                    with tqdm(
                        initial=self.step,
                        total=s.nsteps,
                        unit="step",
                        disable=None if self.progress else True,
                        file=sys.stderr,
                        dynamic_ncols=True,
                    ) as bar:
                        rerun_to = self.step  # steps up to here are re-run one at a time: their block found trouble
                        while self.step < stop_step:
                            if self.step >= rerun_to and (
                                signum := signals.asked()
                            ):  # every rank stops at the same step
                                interrupted = signum
                                break
                            b = self.step
                            e = (
                                guard.block_end(b) if b >= rerun_to else b + 1
                            )  # a re-run goes on to the trouble it looks for
                            m, trouble, detail = self._steps(b, e, guard, signals, ledger)
                            if trouble is None:  # m > b: a step without trouble was taken
                                finish(m, m - b)
                            elif trouble == "abandoned":
                                interrupted, abandoned = detail, (b, m)
                                break
                            elif e > b + 1:  # the block is re-run from b, a checked step at a time
                                rerun_to = m + 1 if trouble == "failure" else m  # a failure: in step m + 1
                            else:
                                blowup = guard.message(b + 1, trouble, detail)
                                if files.unwritten(b):
                                    files.record(b, self.last_good, final=True)
                                files.set_attrs(blowup=blowup)
                                break
                    if interrupted is not None:
                        if files.unwritten(self.step):
                            files.record(self.step, final=True)
                        # after an abandoned step the stepper's history is half updated: no restart file
                        if ckp.path is not None and self.step not in ckp.steps and not abandoned:
                            ckp.save()
                        files.set_attrs(
                            interrupted=signal.Signals(interrupted).name,
                            interrupted_at_step=self.step,
                            interrupted_at_day=s.day(self.step),
                        )
                files.close()  # under this run's handlers: a signal now waits, and is answered below
            except BaseException:
                files.abort()
                raise
            finally:
                stepper.deferred = False
        if interrupted is None and blowup is None:  # a signal after the last step's check: the output is whole
            interrupted = signals.asked() or None
        result = ledger.result(
            self.step, files.history, courant, output, blowup, ckp.written, self.setup_time, self._compile[0]
        )
        if blowup is not None:
            err = BlowUp(blowup)
            err.result = result
            raise err
        if interrupted is not None:
            err = Interrupted(
                interruption(signal.Signals(interrupted).name, self.step, s, output, ckp.kept, ckp.written, abandoned)
            )
            err.signum, err.result, err.checkpoint = interrupted, result, ckp.written
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
