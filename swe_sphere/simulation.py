"""The time loop: build everything from a scene, step, guard, write, summarise."""

from __future__ import annotations

import bisect
import contextlib
import math
import signal
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import warp as wp
from threadpoolctl import threadpool_limits
from tqdm import tqdm

from . import checkpoint as ckpt
from . import restart_file
from .config import Scene, SceneError, resolve_scene, with_days
from .constants import DAY
from .diagnostics import courant_numbers, invariants
from .graphs import GraphedSteps, default_mode, graphs_mode
from .grid import CubedSphere
from .initial_state import from_function
from .initialization import digital_filter
from .model import ShallowWater
from .mpi import node_local_size
from .output import OUTPUT_FIELDS, RunWriter, check_distinct, check_target, node_dataset
from .parallel import default_threads
from .remap import remap_dataset
from .runtime import Interrupted, ResourceError, check_memory, package_version, pick_device, run_bytes
from .scoring import Scorer, truth
from .steppers import StepFailure, StepStats, make_stepper
from .topology import Topology, rank_parts


ON_ROOT = object()  # ``start`` on the ranks > 0 when rank 0 alone holds the whole-grid start state


class BlowUp(RuntimeError):
    """The state became non-finite or the depth non-positive; the message gives step, time and place."""


@dataclass
class WholeFields:
    """One state's fields gathered on rank 0 (``Simulation.gather_fields``): u, v
    (m s⁻¹), h (m), vorticity and, when asked for, divergence (s⁻¹, DSS'd), (npts,)
    each on rank 0 and None on the other ranks (divergence None when not asked for).
    Every rank holds one: whether a rank gathers is decided by whether it was
    given one, never by its contents, so all ranks take the same collectives."""

    u: np.ndarray | None
    v: np.ndarray | None
    h: np.ndarray | None
    vorticity: np.ndarray | None
    divergence: np.ndarray | None = None


@dataclass
class Callback:
    """``fn(sim)`` called after every ``steps``-th step (``Simulation.add_callback``)."""

    fn: object
    steps: int


def stream_path(output: Path, name: str) -> Path:
    """The run file of output stream ``name`` beside a run's output: ``run.nc`` → ``run.NAME.nc``."""
    output = Path(output)
    return output.with_name(f"{output.stem}.{name}{output.suffix or '.nc'}")


ABANDON_AFTER = 1.0  # s a step may go on after SIGINT/SIGTERM before it is abandoned
# Steps between host reads of the bad-state check on a GPU (``Simulation.check_every``).
# A read waits for the device to drain its queue: ~10-50 µs, as long as a whole launch-bound
# ne30 step, so reading every step serialises the loop; 64 steps make it ~1 % of the time
# and bound the re-run that finds a blow-up's step to 64 steps (ClimaAtmos checks for NaN
# every 1024 steps, without the step). On a CPU a read costs nothing: every step is checked.
CHECK_EVERY_STEPS = 64
# A run's wall time is estimated from the steps after its first (which compiles kernels):
# this many of them, or as many as take this many seconds, whichever comes first.
ESTIMATE_STEPS, ESTIMATE_SECONDS = 3, 10.0


class _StepAbandoned(BaseException):
    """Raised from the signal handlers into a step that goes on ``ABANDON_AFTER``
    s after a stop was asked (a BaseException, so no solver's ``except`` keeps it)."""

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = signum


def restart_path(output: Path) -> Path:
    """The restart file beside a run's output: ``run.nc`` → ``run.restart.nc``."""
    output = Path(output)
    return output.with_name(output.stem + ".restart.nc")


MAX_HYPERVIS_EVALUATIONS = 10_000  # ∇⁴ evaluations a step; beyond, ν is ~10⁷ times its explicit bound or more


def _check_hyperviscosity(model: ShallowWater, scene: Scene) -> None:
    """Refuse (``SceneError``, before the run) a ν whose ∇⁴ sub-stepping
    (``ShallowWater.hypervis_plan``) would take more than
    ``MAX_HYPERVIS_EVALUATIONS`` evaluations a step: such a step runs for hours
    and is a mistyped coefficient, not a setting."""
    if "hyperviscosity" not in scene.terms or model.nu_max == 0.0:
        return
    evals, _ = model.hypervis_plan(scene.dt)
    if evals > MAX_HYPERVIS_EVALUATIONS:
        bound = 1.5 / (scene.dt * model.biharmonic_radius())
        raise SceneError(f"hyperviscosity nu = {model.nu_max:.3g} m^4/s is {model.nu_max / bound:.2g}x its explicit bound "
                         f"({bound:.3g} m^4/s at dt = {scene.dt:g} s): {evals:.3g} ∇⁴ evaluations a step (at most "
                         f"{MAX_HYPERVIS_EVALUATIONS}); lower hyperviscosity.nu")


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


@dataclass
class RunResult:
    """What a run produced: final diagnostics, counts and timings."""

    steps: int
    rhs_evals: int
    wall_time: float  # s in the time loop, compilation included (cumulative over restarts)
    setup_time: float
    diagnostics: dict
    courant: dict
    output: Path | None
    blowup: str | None = None
    history: list = field(default_factory=list)
    iterations: dict = field(default_factory=dict)
    compile_time: float = 0.0  # s of Warp module loading/compiling, setup and loop, this process
    first_step_time: float = math.nan  # s of this process's first step (launch recording, compilation)
    first_step: int = 0  # the step the run started from (0, or a checkpoint's)
    loop_time: float = 0.0  # s in this process's time loop
    checkpoint: Path | None = None  # the last restart file written


class Simulation:
    """Build the grid, case, model and stepper of a scene; ``run`` integrates it.

    ``device``: "cpu" or "cuda" (Warp device names). ``progress``: show a tqdm bar
    (on rank 0, when its stderr is a terminal).
    ``from_checkpoint`` continues a restart file instead of starting at t = 0.
    ``comm``: an mpi4py communicator to run one simulation over its ranks
    (``topology.Topology``: each rank steps its part of the elements; fields
    are gathered for diagnostics, and rank 0 writes the files); None: this
    process alone. Explicit steppers give the same bits on any number of ranks.
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

    ``check_every`` (steps; 1 on a CPU, ``CHECK_EVERY_STEPS`` on a GPU): ``run``
    checks the state for a non-finite value or h <= 0 after every step on the
    device (``ShallowWater.watch``) and reads the check back every so many steps
    and at every output, restart, log and callback step, so that a GPU step
    needs no host round trip; the solvers' iteration counters of the semi-implicit
    and IMEX steps are read there too (``Stepper.deferred``, ``Stepper.counts``),
    and a solve that missed its tolerance fails the block like a bad state. A
    block of steps whose check fails is re-run from its start (state, stepper
    history and counters kept there), one checked step at a time: the blow-up is
    reported at the step, time and place (a failed solve at the step and time),
    and the output holds, as with a check every step (the same bits either way).

    A scene may also be given as ``swe_sphere.run`` takes it, ``Simulation("tc2_steady",
    ne=4, days=2)``: a scene file or bundled name with overrides
    (``config.resolve_scene``), device None: CUDA when present
    (``runtime.pick_device``). Python drives it step by step with ``advance``,
    ``steps``, ``state`` and ``add_callback``; ``run`` integrates to the scene's end.
    """

    inputs: tuple = ()

    def __init__(self, scene, device: str | None = None, *, progress: bool = True, comm=None, start: np.ndarray | None = None,
                 initial=None, initial_diagnostics: dict | None = None, graphs: str | bool | None = None, **overrides):
        graphs = graphs_mode(default_mode() if graphs is None else graphs)
        scene, inputs = resolve_scene(scene, overrides)
        if device is None:
            device = pick_device()
        if initial is not None and (start is not None or not callable(initial)):
            raise ValueError("initial must be a function (lat, lon) -> (h, u, v), and not given with start")
        t0 = time.perf_counter()
        self._compile = [0.0]
        self.callbacks: list[Callback] = []
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
            local, scene.terms, fcor, hs, nu=scene.nu, nu_div=scene.nu_div, nu_s=scene.nu_s,
            hypervis_subcycle=scene.hypervis_subcycle, g=self.g, device=device, topology=topo,
            forcing=case.forcing() if "forcing" in scene.terms else None,
        )
        _check_hyperviscosity(self.model, scene)
        self.stepper = make_stepper(scene.stepper, self.model, scene.dt, **scene.stepper_options)
        self.stepper.t0 = scene.start_day * DAY
        self.scorer = Scorer(case, self.model, topo, self.grid, self.hs, scene.reference_file)
        self.dfi = None
        if start is None:
            start = np.stack(case.initial(local.lat, local.lon)) if initial is None else from_function(initial, local.lat, local.lon)
            if scene.digital_filter is not None:
                self.dfi = digital_filter(scene.digital_filter, start, grid=local, terms=scene.terms,
                                          fcor=fcor, hs=hs, g=self.g, device=device, topology=topo)
        else:
            start = topo.distribute(None if start is ON_ROOT else start, 3, "start state")
        self.x = self.model.new_state(*(self.dfi.x if self.dfi is not None else start))
        self.last_good = wp.clone(self.x)  # the state at the start of the block of steps in progress
        self.check_every = 1 if wp.get_device(device).is_cpu else CHECK_EVERY_STEPS
        if not self.root:  # a fallback's warning once, from rank 0
            self.model.graph_guard.warn = lambda line: None
        self._graphed = GraphedSteps(device, self.model.graph_guard)
        self.initial = initial_diagnostics
        if initial_diagnostics is None:
            self.initial = self.diagnose(scene.start_day * DAY)
        self.step = 0  # steps taken since t = 0 (a branched run: since its branch day, ``Scene.start_day``)
        self.counters = {"rhs_evals": 0, "wall_time": 0.0, "cpu_time": 0.0, "iterations": {k: 0 for k in self.stepper.solvers}}

    @property
    def graphs(self) -> str:
        """The graph mode: "auto", "on" or "off" (set also as True, False; see the class)."""
        return self._graphed.mode

    @graphs.setter
    def graphs(self, value) -> None:
        self._graphed.mode = value

    # -- restart --------------------------------------------------------------
    @classmethod
    def from_checkpoint(cls, checkpoint, device: str, *, days: float | None = None, stepper: str | None = None,
                        dt: float | None = None, progress: bool = True, comm=None, graphs: str | bool | None = None) -> Simulation:
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
            sim = cls(ckpt.branch(ck, stepper=stepper, dt=dt, days=days), device, progress=progress, comm=comm, start=start, graphs=graphs)
        else:
            scene = ck.scene if days is None else with_days(ck.scene, days)
            if scene.nsteps < ck.step:
                raise ckpt.CheckpointError(f"the run length {scene.days:g} days ends before the checkpoint (day {ck.scene.day(ck.step):g})")
            sim = cls(scene, device, progress=progress, comm=comm, start=start, initial_diagnostics=ck.initial,  # the state handed out; no second digital filter
                      graphs=graphs)
            sim._restore_history(ck)
        if not isinstance(checkpoint, ckpt.Checkpoint):
            sim.inputs = (Path(checkpoint),)
        return sim

    def restore(self, ck: ckpt.Checkpoint) -> None:
        """Set the state, stepper history, counters and t = 0 invariants from a checkpoint."""
        try:
            x = self.topology.distribute(ck.x, 3, "checkpoint state")  # ck.x on rank 0 only (``checkpoint.read_on_root``)
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
        return restart_file.write(path, self.scene, self.step, x, state, self.counters, self.initial, overwrite=overwrite,
                                  restart_every=restart_every)

    # -- diagnostics --------------------------------------------------------
    # Fields are gathered on rank 0, which diagnoses the whole grid (the same
    # arithmetic on any number of ranks) and broadcasts the figures.
    def fields(self, x=None):
        """u, v, h (npts,) of the whole grid, gathered on rank 0 (call on every rank;
        (None, None, None) on the others)."""
        a = self.topology.gather((self.x if x is None else x).numpy())
        return (None, None, None) if a is None else (a[0], a[1], a[2])

    def divergence(self, x=None) -> np.ndarray | None:
        """Divergence of the wind (npts,) of the whole grid, DSS'd (s⁻¹), on rank 0 (None elsewhere)."""
        return self.topology.gather(self.model.wind_divergence(self.x if x is None else x))

    def gather_fields(self, x=None, divergence: bool = False) -> WholeFields:
        """u, v, h, the vorticity and (``divergence``) the divergence of state x
        (default the current one), in one gather on rank 0 (call on every rank)."""
        x = self.x if x is None else x
        rows = [x.numpy(), self.model.vorticity(x)[None]]
        if divergence:
            rows.append(self.model.wind_divergence(x)[None])
        a = self.topology.gather(np.concatenate(rows))
        if a is None:
            return WholeFields(None, None, None, None)
        return WholeFields(a[0], a[1], a[2], a[3], a[4] if divergence else None)

    def diagnose(self, t: float, x=None, whole: WholeFields | None = None) -> dict:
        """Invariants (and their relative change), errors against the truth
        (``scoring.Scorer.errors``) and Courant numbers, on every rank (call on
        every rank). ``whole``: x's ``gather_fields`` when the caller has them (on
        every rank, or on none)."""
        whole = self.gather_fields(x) if whole is None else whole
        u, v, h, zeta = whole.u, whole.v, whole.h, whole.vorticity
        errors = self.scorer.errors(t, (self.x if x is None else x).numpy(), u, v, h)
        d = None
        if self.root:
            d = self._invariants(whole)
            d.update(errors)
            d.update(courant_numbers(self.grid, u, v, h, self.scene.dt, self.g, "pressure_gradient" in self.scene.terms))
        return self.topology.bcast(d)

    def _invariants(self, whole: WholeFields) -> dict:
        """The invariants of ``whole`` and their change relative to ``initial`` (rank 0)."""
        d = invariants(self.grid, whole.u, whole.v, whole.h, self.hs, whole.vorticity, self.fcor, self.g)
        if not self.case.h_is_depth:  # h is a tracer (TC1): only its mass is an invariant
            d = {"mass": d["mass"]}
        start = self.initial or d  # diagnosing the initial state itself
        for k in list(d):
            d[f"{k}_change"] = (d[k] - start[k]) / abs(start[k])
        return d

    def log_line(self, d: dict | None = None) -> str | None:
        """One line on the current step, as HOMME prints every ``statefreq`` steps:
        step, model day, relative changes of mass, total energy and potential
        enstrophy since t = 0 and the largest advective and gravity-wave Courant
        numbers over the nodes. ``d``: the step's ``diagnose`` when the caller has
        it; else the fields are gathered here (the one device synchronisation).
        Call on every rank; None on the ranks > 0."""
        if d is None:
            whole = self.gather_fields()
            if self.root:
                d = self._invariants(whole)
                d.update(courant_numbers(self.grid, whole.u, whole.v, whole.h, self.scene.dt, self.g,
                                         "pressure_gradient" in self.scene.terms))
        if not self.root:
            return None
        names = {"mass_change": "mass", "total_energy_change": "energy", "potential_enstrophy_change": "enstrophy"}
        changes = "".join(f"  {name} {d[k]:+.3e}" for k, name in names.items() if k in d)
        grav = "" if math.isnan(d["courant_gravity"]) else f" gravity-wave {d['courant_gravity']:.3f}"
        return (f"step {self.step} day {self.scene.day(self.step):.4f}{changes}  Courant advective "
                f"{d['courant_advective']:.3f}{grav}")

    def stability_warning(self) -> str | None:
        """A one-line warning when Δt exceeds the stepper's measured stability limit on
        the current state (``Stepper.courant_limit`` on (|v| + √(gh)) Δt/Δx for explicit
        steppers, ``Stepper.advective_courant_limit`` on |v| Δt/Δx for IMEX), else None."""
        kind = type(self.stepper)
        c = self.courant()
        if kind.courant_limit is not None:
            limit, what = kind.courant_limit, "a Courant number (|v| + sqrt(g h)) dt/dx"
            speed = c["courant_advective"] + (0.0 if math.isnan(c["courant_gravity"]) else c["courant_gravity"])
            source = "measured on TC2"
        elif kind.advective_courant_limit is not None:
            limit, what, speed = kind.advective_courant_limit, "an advective Courant number |v| dt/dx", c["courant_advective"]
            source = "its explicit advection's, measured on TC5, TC6 and Galewsky"
        else:
            return None
        if speed <= limit:
            return None
        return (f"warning: dt = {self.scene.dt:g} s gives {what} of {speed:.3g}, above "
                f"{self.scene.stepper}'s stability limit of about {limit:g} ({source}); it may blow up "
                f"(dt <= {self.scene.dt * limit / speed:.4g} s keeps below)")

    def courant(self, whole: WholeFields | None = None) -> dict:
        """Advective and gravity-wave Courant numbers of the scene's dt on the current
        state (call on every rank; ``whole``: its ``gather_fields`` when the caller
        has them, on every rank or on none)."""
        u, v, h = self.fields() if whole is None else (whole.u, whole.v, whole.h)
        c = courant_numbers(self.grid, u, v, h, self.scene.dt, self.g, "pressure_gradient" in self.scene.terms) if self.root else None
        return self.topology.bcast(c)

    # -- the loop -----------------------------------------------------------
    def output_steps(self, every_days: float | None = None) -> set[int]:
        """Steps with an output: every output interval (default the scene's
        ``output.every_days``) from step 0 (t = 0, or a branch's day), and the last."""
        s = self.scene
        every_days = s.output_every_days if every_days is None else every_days
        every = every_days * DAY / s.dt
        n_out = math.floor(s.run_days / every_days + 1e-9)
        return {min(s.nsteps, round(k * every)) for k in range(n_out + 1)} | {s.nsteps}

    def output_streams(self, output: Path | None) -> list[tuple[Path, tuple, set]]:
        """(path, fields, output steps) of each run file of ``output``: itself with the
        scene's ``output.fields``, then each ``[[output.streams]]`` (``stream_path``);
        [] without an output."""
        if output is None:
            return []
        s, output = self.scene, Path(output)
        return [(output, s.output_fields or OUTPUT_FIELDS, self.output_steps()),
                *((stream_path(output, st["name"]), st["fields"], self.output_steps(st["every_days"])) for st in s.output_streams)]

    def steps_of(self, days: float, what: str) -> int:
        """The whole number of steps in ``days``; ValueError naming ``what`` unless dt divides it."""
        s = self.scene
        per = round(days * DAY / s.dt) if isinstance(days, (int, float)) and math.isfinite(days) else 0
        if per < 1 or abs(per * s.dt - days * DAY) > 1e-6 * s.dt:
            raise ValueError(f"{what} must be a positive multiple of dt = {s.dt:g} s = {s.dt / DAY:.6g} days (got {days!r} days)")
        return per

    def restart_steps(self, every_days: float) -> set[int]:
        """Steps at which a run with ``--restart-every every_days`` writes its restart
        file (and the last step). Raises ValueError unless dt divides the interval."""
        s, per = self.scene, self.steps_of(every_days, "restart interval")
        return set(range(per, s.nsteps + 1, per)) | {s.nsteps}

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
        steps = every_steps if every_days is None else self.steps_of(every_days, "every_days")
        self.callbacks.append(Callback(fn, steps))

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
        target = self.step + self.steps_of(days, "days")
        if target > self.scene.nsteps:
            self.scene = with_days(self.scene, self.scene.start_day + target * self.scene.dt / DAY, "the scene's")
        return self.run(None, until_step=target)

    def steps(self, every: float):
        """Iterate the run to the scene's end, yielding the model time (days) at each
        multiple of ``every`` days from t = 0 (``for t in sim.steps(every=0.5):``
        ``ds = sim.state()``); stops at the last multiple at or before the end.
        ValueError unless ``every`` is a whole number of steps."""
        per = self.steps_of(every, "every")
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
        ds = node_dataset(self.grid, self.hs, self.time, {k: getattr(whole, k) for k in OUTPUT_FIELDS},
                          {"scene": self.scene.as_dict(), "ne": self.scene.ne, "np": self.scene.np, "step": self.step})
        if remap is None:
            return ds
        return remap_dataset(ds, remap)

    def run(self, output: Path | None = None, *, overwrite: bool = False, restart_every: float | None = None,
            restart_file: Path | None = None, catch_signals: bool = True, compress: bool = False,
            history: str | None = None, on_output=None, notify=None, log=None, until_step: int | None = None) -> RunResult:
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
        steps exceeds a day. ``log(line)``: called (rank 0) with ``log_line`` every
        ``scene.log_every_steps`` steps since t = 0 (given on every rank alike, or on
        none: the fields are gathered then). ``until_step``: stop after this step
        (default the scene's last; ``advance``). The scene's ``[[output.streams]]``
        are written beside ``output`` (``stream_path``), each at its own interval,
        and the callbacks (``add_callback``) are called. Raises ``BlowUp`` after closing the output with every
        good output time and the last good state (the step before the failure).
        """
        s, model, stepper = self.scene, self.model, self.stepper
        kept_restart = None  # an existing restart file this run would write only on a signal, and keeps
        if restart_file is None and output is not None:
            restart_file = restart_path(output)
            if restart_every is None and not overwrite and self.topology.bcast(self.root and restart_file.exists()):
                restart_file, kept_restart = None, restart_file
        ck_steps = self.restart_steps(restart_every) if restart_every is not None else set()
        if restart_every is not None and restart_file is None:
            raise ValueError("a restart interval needs an output or restart file")
        streams = self.output_streams(output)  # (path, fields, steps) of every run file, the main one first
        if self.root:
            check_distinct([output, restart_file, *(path for path, _, _ in streams)], self.inputs)
        if restart_file is not None and self.root:
            check_target(restart_file, overwrite)
        divergence = any("divergence" in fields for _, fields, _ in streams)
        with _compile_timer(self._compile):  # a continuation's first use of the diagnostic kernels
            start = self.gather_fields(divergence=divergence)  # the first output time's, on every rank
        courant = self.courant(start)
        solver_series = [f"{k}_iterations" for k in stepper.solvers]
        series = ["steps", "rhs_evals", *solver_series, "wall_time", *self.initial.keys()]
        writers = [None] * len(streams)  # rank 0's RunWriters, one a stream
        if output is not None and self.root:
            stamp = time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())
            attrs = {
                "title": f"swe_sphere run of scene {s.name}",
                "history": f"{stamp}: {history or f'swe_sphere.Simulation.run of scene {s.name}'} (swe_sphere {package_version()})",
                "source": f"swe_sphere {package_version()}",
                "swe_sphere_version": package_version(),
                "scene": s.as_dict(),
                "case": s.case,
                "ne": s.ne,
                "np": s.np,
                "stepper": s.stepper,
                **stepper.attrs(),  # e.g. which Butcher table ran
                "dt": s.dt,
                "device": self.device,
                "mpi_ranks": self.topology.comm.size,
                "initialization": "none" if s.initialization is None else s.initialization["method"],
                "reference": truth(self.case, s.reference_file),  # what the error series are against
                **{f"planet_{k}": v for k, v in s.planet.items()},  # planet_radius (m), planet_omega (1/s), planet_gravity (m/s^2)
                **(self.dfi.attrs(s.digital_filter) if self.dfi is not None else {}),
                **({"continued_from_day": s.day(self.step)} if self.step else {}),
                **ckpt.branch_attrs(s),
                **{k: v for k, v in courant.items() if math.isfinite(v)},
            }
            try:
                for i, (path, fields, _) in enumerate(streams):
                    writers[i] = RunWriter(path, self.grid, self.hs, attrs, series, overwrite=overwrite, compress=compress, fields=fields)
            except BaseException:
                for w in writers:
                    if w is not None:
                        w.abort()
                raise
        out_steps = set().union(*(steps for _, _, steps in streams)) if streams else self.output_steps()
        last = [None] * len(streams)  # the step each run file wrote last (on every rank)
        stop_step = s.nsteps if until_step is None else until_step
        c, history = self.counters, []
        c.setdefault("cpu_time", 0.0)  # a restart file written before runs kept their CPU time
        first_step, first_time, written, wall0 = self.step, math.nan, [None], c["wall_time"]
        estimating, since = notify is not None and self.root, math.nan  # the wall clock at the end of the first step

        def record(step, x=None, whole=None, final=False):
            """Diagnose ``step`` and write it to the run files whose schedule holds it (``final``: to every one)."""
            if whole is None:  # once per output time, on every rank
                whole = self.gather_fields(x, divergence=divergence)
            d = self.diagnose(s.start_day * DAY + step * s.dt, x, whole)
            d.update(steps=step, rhs_evals=c["rhs_evals"], wall_time=c["wall_time"], cpu_time=c["cpu_time"])
            d.update({f"{k}_iterations": c["iterations"].get(k, 0) for k in stepper.solvers})
            history.append(d)
            if on_output is not None:
                on_output(step, self.x if x is None else x)
            for i, (_, _, steps) in enumerate(streams):
                if (final or step in steps) and last[i] != step:
                    last[i] = step
                    if writers[i] is not None:  # rank 0 (the fields DSS'd, element-local, s-1)
                        writers[i].append(s.day(step), whole.u, whole.v, whole.h, {k: d[k] for k in series},
                                          vorticity=whole.vorticity, divergence=whole.divergence)

        def unwritten(step) -> bool:  # a step some run file (or, without one, the history) lacks
            return step not in out_steps or any(at != step for at in last)

        def save_restart():
            written[0] = self.write_checkpoint(restart_file, overwrite=overwrite or written[0] is not None, restart_every=restart_every)

        stop: list[int] = []
        handlers = {}
        in_step = [None]  # perf_counter at the start of the step in progress; None between steps

        def abandon(signum, frame):  # SIGALRM: a stop was asked ABANDON_AFTER s ago and the step goes on
            if in_step[0] is not None and stop:
                in_step[0] = None
                raise _StepAbandoned(stop[0])

        def on_signal(signum, frame):
            stop.append(signum)
            if in_step[0] is not None and self.topology.comm.size == 1:  # ranks must stop at the same step
                if time.perf_counter() - in_step[0] > ABANDON_AFTER:
                    abandon(signum, frame)
                signal.setitimer(signal.ITIMER_REAL, ABANDON_AFTER)

        if catch_signals and threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM):
                if signal.getsignal(sig) is not signal.SIG_IGN:  # respect a parent's "ignore" (nohup, `&`)
                    handlers[sig] = signal.signal(sig, on_signal)
            if handlers:
                handlers[signal.SIGALRM] = signal.signal(signal.SIGALRM, abandon)
        # Blocks of steps between reads of the device (``check_every``): a block ends at
        # every output, restart, log and callback step, at the run's end and first step.
        every, marks = max(1, int(self.check_every)), sorted(out_steps | ck_steps)

        def block_end(b: int) -> int:
            """The last step of the block that starts after step b."""
            if every == 1 or b == first_step:  # the first step alone: its time is first_step_time
                return b + 1
            ends = [stop_step, (b // every + 1) * every]
            i = bisect.bisect_right(marks, b)
            ends += marks[i : i + 1]
            if log is not None and s.log_every_steps:
                ends.append((b // s.log_every_steps + 1) * s.log_every_steps)
            ends += [(b // cb.steps + 1) * cb.steps for cb in self.callbacks]
            if b < first_step + 1 + ESTIMATE_STEPS:  # the wall-time estimate's steps (on every rank alike)
                ends.append(first_step + 1 + ESTIMATE_STEPS)
            return min(ends)

        def block(b: int, e: int):
            """Steps b+1..e, each state flagged on the device (``ShallowWater.watch``) and
            the solvers' iterations counted there (``Stepper.deferred``), both read once at
            the end; stops early for a signal. Returns (m, trouble): m the last step taken,
            trouble None when every state to m was good, else "bad", "unconverged" (a
            solve in steps b+1..m failed, ``Stepper.counts``), "failure" (a
            ``StepFailure`` in step m + 1) or "abandoned" (step m + 1);
            on trouble the state, stepper history and counters are those of step b again."""
            nonlocal interrupted
            saved = stepper.state(), c["rhs_evals"], dict(c["iterations"])
            wp.copy(self.last_good, self.x)
            t0, cpu0 = time.perf_counter(), time.process_time()
            m, trouble = b, None
            while m < e:
                if m > b and self.topology.max(stop[0] if stop else 0):  # the loop stops at m, once checked
                    break
                try:
                    in_step[0] = time.perf_counter()
                    stats = self._take_step(watch=True)
                except StepFailure:
                    trouble = "failure"
                    break
                except _StepAbandoned as err:
                    trouble, interrupted = "abandoned", err.signum
                    break
                finally:
                    in_step[0] = None
                add(stats)
                m += 1
                self.step = m  # the steps x holds (not yet checked)
            if model.watched_bad() and trouble is None:  # the block's host read (and synchronisation)
                trouble = "bad"
            try:  # the solvers' device counters of the block's steps (zeroed, also after trouble)
                counts = stepper.counts()
            except StepFailure:  # a solve in steps b+1..m failed: which one, the re-run tells
                trouble = trouble or "unconverged"
            account(m, t0, cpu0)
            if trouble is None:
                add(StepStats(0, counts))
            else:
                self.step = b
                wp.copy(self.x, self.last_good)
                stepper.restore(saved[0])
                c["rhs_evals"], c["iterations"] = saved[1], saved[2]
            return m, trouble

        def account(n: int, t0: float, cpu0: float) -> None:
            """Book the time since t0, cpu0 (the device synchronised after step n)."""
            nonlocal first_time, since, estimating
            dt_wall = time.perf_counter() - t0
            c["wall_time"] += dt_wall
            c["cpu_time"] += time.process_time() - cpu0  # the process's threads summed: one thread for a reproducible cost
            if n == first_step + 1:
                first_time, since = dt_wall, time.perf_counter()
            elif estimating:  # the loop's own time (output, progress bar) counted
                timed, spent = n - first_step - 1, time.perf_counter() - since
                if timed >= ESTIMATE_STEPS or spent >= ESTIMATE_SECONDS:
                    estimating, left = False, spent / timed * (s.nsteps - n)
                    if left > DAY:
                        notify(f"this run will take about {left / DAY:.3g} days of wall time to day {s.days:g} "
                               f"({spent / timed:.3g} s a step over steps {first_step + 2}-{n}; {s.nsteps - n} steps left)")

        def add(stats) -> None:
            if stats is not None:
                c["rhs_evals"] += stats.rhs_evals
                for k, it in stats.iterations.items():
                    c["iterations"][k] = c["iterations"].get(k, 0) + it

        def finish(n: int, done: int) -> None:
            """Step n (the last of ``done`` steps) is good: output, restart, callbacks, log, progress."""
            self.step = n
            if n in out_steps:
                record(n)
            if n in ck_steps:
                save_restart()
            for callback in self.callbacks:
                if n % callback.steps == 0:
                    callback.fn(self)
            if log is not None and s.log_every_steps and n % s.log_every_steps == 0:
                line = self.log_line(history[-1] if n in out_steps else None)
                if line is not None:
                    log(line)
            bar.update(done)
            if n % 50 < done or n == s.nsteps:  # a multiple of 50 in the steps done
                bar.set_postfix(day=f"{s.day(n):.2f}", sim_days_per_s=f"{n * s.dt / DAY / max(c['wall_time'], 1e-9):.3g}")

        # single-threaded BLAS: the Krylov solvers' vectors are too short for threads to
        # pay, and on a busy machine OpenBLAS's spinning threads made a norm cost 10 ms
        limits = threadpool_limits(limits=1, user_api="blas")
        stepper.deferred = True  # its solvers' device counters read with the bad-state check (``_take_step``, ``block``)
        blowup = interrupted = None
        abandoned = False
        try:
            with _compile_timer(self._compile):
                record(self.step, whole=start, final=True)
                # disable=None: a bar only on a terminal, not redrawn into a log (or mpiexec's pipe)
                bar = tqdm(initial=self.step, total=s.nsteps, unit="step", disable=None if self.progress else True, file=sys.stderr,
                           dynamic_ncols=True)
                with bar:
                    rerun_to = self.step  # steps up to here are re-run one at a time: their block found trouble
                    while self.step < stop_step:
                        if self.step >= rerun_to:  # a re-run goes on to the trouble it looks for
                            signum = int(self.topology.max(stop[0] if stop else 0))  # every rank stops at the same step
                            if signum:
                                interrupted = signum
                                break
                        b = self.step
                        e = block_end(b) if b >= rerun_to else b + 1
                        if e > b + 1:
                            m, trouble = block(b, e)
                            if trouble is None:
                                if m > b:
                                    finish(m, m - b)
                                continue
                            if trouble == "abandoned":
                                abandoned = (b, m)
                                break
                            rerun_to = m + 1 if trouble == "failure" else m  # a failure: in step m + 1
                            continue
                        # one step, checked: the state before it kept, the check read at once
                        n = b + 1
                        t0, cpu0 = time.perf_counter(), time.process_time()
                        wp.copy(self.last_good, self.x)
                        try:
                            in_step[0] = t0
                            stats = self._take_step(watch=False)
                            failure = None
                        except StepFailure as err:
                            stats, failure = None, str(err)
                        except _StepAbandoned as err:  # the state of the last complete step is kept
                            wp.copy(self.x, self.last_good)
                            interrupted, abandoned = err.signum, (b, b)
                            break
                        finally:
                            in_step[0] = None
                        bad = model.first_bad_node(self.x) if failure is None else None
                        wp.synchronize_device(self.device)
                        account(n, t0, cpu0)
                        add(stats)
                        if bad is not None or failure is not None:
                            blowup = self._blowup_message(n, bad) if failure is None else (
                                f"step {n} failed (model time {s.day(n):.4f} days): {failure}"
                            )
                            if unwritten(n - 1):
                                record(n - 1, self.last_good, final=True)
                            for w in writers:
                                if w is not None:
                                    w.set_attrs(blowup=blowup)
                            break
                        finish(n, 1)
                    if interrupted is not None:
                        if unwritten(self.step):
                            record(self.step, final=True)
                        # after an abandoned step the stepper's history is half updated: no restart file
                        if restart_file is not None and self.step not in ck_steps and not abandoned:
                            save_restart()
                        for w in writers:
                            if w is not None:
                                w.set_attrs(interrupted=signal.Signals(interrupted).name, interrupted_at_step=self.step,
                                            interrupted_at_day=s.day(self.step))
            for w in writers:
                if w is not None:
                    w.close()  # under this run's handlers: a signal now waits, and is answered below
        except BaseException:
            for w in writers:
                if w is not None:
                    w.abort()
            raise
        finally:
            stepper.deferred = False
            limits.restore_original_limits()
            if handlers:
                signal.setitimer(signal.ITIMER_REAL, 0)
            for sig, handler in handlers.items():
                signal.signal(sig, handler)
        if interrupted is None and blowup is None:  # a signal after the last step's check: the output is whole
            interrupted = int(self.topology.max(stop[0] if stop else 0)) or None
        result = RunResult(
            steps=self.step,
            rhs_evals=c["rhs_evals"],
            wall_time=c["wall_time"],
            setup_time=self.setup_time,
            diagnostics=history[-1],
            courant=courant,
            output=output,
            blowup=blowup,
            history=history,
            iterations=dict(c["iterations"]),
            compile_time=self._compile[0],
            first_step_time=first_time,
            first_step=first_step,
            loop_time=c["wall_time"] - wall0,
            checkpoint=written[0],
        )
        if blowup is not None:
            err = BlowUp(blowup)
            err.result = result
            raise err
        if interrupted is not None:
            name, day = signal.Signals(interrupted).name, s.day(self.step)
            if self.step == s.nsteps:  # the run had ended (an interruption inside it stops before its last step)
                kept = [f"the output {output} is complete"] if output is not None else []
                when = f"after the last step (model time {day:.4f} days)"
            else:
                kept = [f"output so far in {output}"] if output is not None else []
                if kept_restart is not None:
                    kept.append(f"no restart file: {kept_restart} exists (--overwrite, or overwrite=True in Python, replaces it)")
                how = ""
                if abandoned:
                    b, m = abandoned  # steps b+1..m were taken in a block not yet checked: dropped with m + 1
                    before = f" with steps {b + 1}-{m} before it (not yet checked)" if m > b else ""
                    how = f"; step {m + 1} abandoned after {ABANDON_AFTER:g} s{before} (no restart file from it)"
                when = f"at step {self.step} (model time {day:.4f} days){how}"
            kept += [f"restart file {written[0]}"] if written[0] is not None else []
            err = Interrupted("; ".join([f"interrupted by {name} {when}", *kept]))
            err.signum, err.result, err.checkpoint = interrupted, result, written[0]
            raise err
        return result

    def _take_step(self, watch: bool):
        """One step of the stepper on x and, with ``watch``, the bad-state flag's launch
        (``ShallowWater.watch``; the solvers' device counters left for the block's
        read), else with its solvers' counters read (``Stepper.counts``: raises
        ``StepFailure``); its ``StepStats``. With ``graphs``, steps replay as
        graphs (``graphs.GraphedSteps``)."""
        stats = self._graphed.step(self.stepper, self.model, self.x, watch)
        return stats if watch else StepStats(stats.rhs_evals, {**stats.iterations, **self.stepper.counts()})

    def _blowup_message(self, step: int, p: int) -> str:
        """Where node p (whole-grid index) went bad, on every rank (call on every rank)."""
        u, v, h = self.fields()
        if not self.root:
            return self.topology.bcast(None)
        lat, lon = np.degrees(self.grid.lat[p]), np.degrees(self.grid.lon[p])
        what = "non-finite value" if not all(math.isfinite(f[p]) for f in (u, v, h)) else f"depth h = {h[p]:.4g} m <= 0"
        return self.topology.bcast(
            f"blow-up at step {step} (model time {self.scene.day(step):.4f} days): {what} "
            f"at lat {lat:.2f}, lon {lon:.2f} degrees"
        )
