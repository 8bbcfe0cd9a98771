"""The simulation: a scene's model, stepper and state, and the loop that steps them, on
Oceananigans' pattern: one short loop (``Simulation.run``) and around its steps a small part each
(the package's doc lists them), of one member or N (issue 116: one driver). Its run loop, restarts
and driving from Python are its own methods over the functions of ``loop`` and ``checkpoint`` (no
mixins); ``members.members.Members`` builds its members for every N (a single run its one
member) and is its states and diagnostics over (N, 3, n), whose answers the simulation's names
give under one squeeze rule (``squeeze``; issue 124: one run of any size)."""

from __future__ import annotations

import time
import warnings
from operator import attrgetter
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

from ..config.scene import Scene, resolve_scene, with_days
from ..core.arguments import (
    callable_argument,
    comm_argument,
    flag_argument,
    got,
    mapping_argument,
    number_argument,
)
from ..core.backend import CHECK_EVERY_STEPS, Backend, pick_device
from ..core.constants import DAY
from ..core.errors import ArgumentError, BlowUp, Interrupted, SceneError
from ..core.graphs import default_mode, graphs_mode
from ..core.interrupts import StopSignals
from ..core.runtime import compile_timer
from ..integrator.core import Stop, forwarded
from ..io.run_file import OUTPUT_FIELDS, node_dataset
from ..members.initial import asked
from ..members.members import Members
from ..members.units import step_control
from . import checkpoint as ckpt
from .activities import add_callback, log_activity
from .checkpoint import restore_run, write_restart
from .guard import RunObserver
from .intervals import Intervals
from .loop import check_run_arguments, integrate, open_files, outcome, own_activities, run_steps
from .names import delegated, of_one, squeeze, squeezed
from .run_state import RunState
from .schedules import EverySteps, at_its_end
from .summary import Ledger, RunResult

# The names users catch and read from here (``swe_sphere.BlowUp``, ``swe_sphere.Interrupted``).
__all__ = ["BlowUp", "Interrupted", "RunResult", "Simulation"]


# the old names of a simulation's parts, each a one-line ``DeprecationWarning`` where read
# (the intervals' names: their owner's, ``intervals``)
RENAMED = {"ensemble": "members", "diagnostics": "members"}
RENAMED |= {name: f"intervals.{name}" for name in ("fitted_dt", "use_dt", "fit_dt")}


class Simulation:
    """Build the grid, case, model and stepper of a scene, of one member or N; ``run`` integrates it.

    A scene may be given as ``swe_sphere.run`` takes it, ``Simulation("tc2_steady", ne=4, days=2)``. Python drives
    it step by step with ``advance``, ``steps``, ``state`` and ``add_callback``; ``run`` integrates to the scene's
    end; ``from_checkpoint`` continues a restart file instead of starting at t = 0. With ``members`` (or a scene's
    [ensemble]) it steps N members of the scene, member k with the bits of the single run from its initial state: in
    the same launches on N copies of the grid, or each on a model of its own (``layout``), its diagnostics and run
    files on (N, n) fields (``members.Members``). Every name means the same for every N: ``fields``, ``divergence``,
    ``courant``, ``stability_warning``, ``largest_dt_within_limit``, ``invariants``, ``errors`` and ``state`` answer
    with a single run's shapes and dicts for N = 1 and with the member axis first for N > 1 (``squeeze``);
    ``states`` and ``set_states`` take (N, 3, n) for every N; ``x``, ``last_good`` and ``try_step`` (one member's
    state and step) raise ``ArgumentError`` naming ``states()`` for N > 1, and ``stepper`` for members each on a
    stepper of their own.

    Parameters
    ----------
    scene : Scene, str or path
        A resolved scene, or a scene file or bundled name with ``overrides``
        (``config.resolve_scene``).
    device : {"cpu", "cuda"}, optional
        Warp device (default: ``SWE_SPHERE_DEVICE`` where set, else CUDA when present; ``backend.pick_device``).
    members : int ≥ 1, optional
        N, the members (None: the scene's [ensemble] ``members`` where it has one, else one run).
        Any stepper, without a digital filter; Δt fixed, or under ``time.control`` the same for
        every member (in the same launches, on one rank).
    progress : bool
        A tqdm bar (rank 0, stderr a terminal).
    comm : mpi4py communicator, optional
        Run one simulation over its ranks: each steps its part of the elements (``topology.Topology``), rank 0 writes
        the files; explicit steppers give the same bits on any number of ranks. Members: rank r steps the r-th of R
        contiguous shares of them (at least one a rank), the states gathered on every rank. None: this process alone.
    start : ndarray, shape (3, nnodes), optional
        A whole-grid state (u, v in m s⁻¹, h in m) to start from instead of the case's initial state and the scene's
        initialization (a restart's, or a digital-filter start made once for many runs, as a sweep's).
    initial : callable, or with members None, array (N, 3, n), Perturbation, MemberFile or Variants
        ``initial(lat, lon) -> (h, u, v)`` (radians in; m, m s⁻¹ out), the state at t = 0 instead of the case's, which
        still gives fcor, hs and the truth errors are taken against (``initial_state.from_function``); the scene's
        digital filter, if any, then runs on it. Not with ``start``. Members: None, the case's for every member (or
        the scene's [ensemble] ``perturbation`` and ``seed``); an array of rows u, v (m s⁻¹), h (m) on the grid's n
        element-local nodes; a ``Perturbation`` of the case's; a ``MemberFile`` (an ensemble's run file); ``Variants``
        (each member's own case, Ω, g or ν; ``members.initial``).
    initial_diagnostics : dict, optional
        The t = 0 diagnostics that relative changes are taken against, the same on
        every rank (a checkpoint's, when continuing); None: the start state's.
    graphs : {"auto", "on", "off"} or bool, optional
        Steps replayed as captured graphs (see Notes); default the environment's
        ``SWE_SPHERE_GRAPHS``, else "auto". Also an attribute to set.
    layout : {None, "shared", "in_turn"}, optional
        Members: in the same launches ("shared", where they can) or each on a model of its own
        (``members.units``' module doc); None: "shared" on CUDA, "in_turn" on a CPU.
    blow_up : {"stop", "drop"}
        Members: a blow-up stops every member, or drops the member and goes on ("in_turn").
    per_element, threads : bool or None, int or None
        The models' kernel layout and CPU threads (``ShallowWater``'s; None: the device's), a single
        run's as the members'.
    **overrides
        As for ``swe_sphere.run``: ``ne``, ``np``, ``dt``, ``days``, ``stepper``, ``precision``
        and any scene value by its table; with ``members``, an [ensemble] table
        (``ensemble={"perturbation": 1.0}``) takes N as its ``members``, as ``load_scene`` does.

    Attributes
    ----------
    check_every : int
        ``run`` reads the device's bad-state check back once a block of so many steps
        (``core.backend.CHECK_EVERY_STEPS``, 64), a failed block re-run one checked step at a time
        (``integrator.core.Integrator``; the same bits either way).
    dfi : FilterResult or None
        The digital-filter initialization's result, when the scene has one
        (``initialization``) and no ``start`` was given; its cost is in ``setup_time``.
    activities : dict
        What the loop does between steps, by name: each a schedule and a call
        (``simulation.activities``); callbacks and output writers of one's own go here.
    inputs : tuple of Path
        The files the simulation was made from (scene file, restart file), which
        ``run`` refuses to write over.
    members : Members
        The members' states and diagnostics over (N, 3, n), N = ``len(members)``, the member axis
        first in every answer (``members.members.Members``: their fields gathered on rank 0,
        invariants, errors, Courant numbers, ``units``, ``held``, ``layout``, ``copies``, ``alike``,
        ``initial_states``, …; ``members.members`` N, None for a single run, whose files are a single
        run's). ``ensemble`` and ``diagnostics`` are its deprecated names.
    intervals : Intervals
        The run's intervals in whole steps and Δt fitted to them (``intervals``): ``every`` (also
        the simulation's), ``fitted_dt``, ``use_dt``, ``fit_dt`` (the simulation's names of these
        deprecated).
    backend : Backend
        The device's choices (``core.backend``), decided once; ``device`` its name.

    Raises
    ------
    SceneError
        A bad scene, override, or ``initial`` state (wrong shape, non-finite, h <= 0); a function
        ``initial`` for members.
    ValueError
        ``initial`` not callable or given with ``start``; an unknown ``graphs`` mode; members:
        ``ArgumentError`` naming ``members``, ``initial`` (the member), ``layout`` or ``blow_up``.
    ResourceError
        Too little memory for the grid.

    Warns
    -----
    MembersAlike
        Members that start alike, to the bit, on one scene (``members.initial.stay_alike``): they
        stay alike, their spread 0 m.

    Notes
    -----
    With ``graphs`` "on", and "auto" on CUDA, ``run`` replays each step of a ``capturable`` stepper (the explicit
    ones; semi-implicit and IMEX after their first step, their Helmholtz CG's loops conditional nodes inside, on
    CUDA where Warp has them) as a graph captured of an earlier step with the same ``GraphCapture.graph_key`` (on
    CUDA one host call a step instead of one a launch; the same bits as launched one by one), its first replay
    checked against the step launched plainly (``graphs.GraphedSteps``); a model with a time-dependent forcing runs
    plain. On a CPU it takes one thread a launch (SWE_SPHERE_THREADS=1) and one process; otherwise the steps run
    plain. "off": plain launches throughout (the solvers' own graphs too). A capture, replay or check that fails
    prints one line on stderr naming the feature, and the run goes on with plain launches from the plain step's
    state.
    """

    inputs: tuple = ()
    _of_members = False  # a run of members even where neither ``members`` nor the scene names them (refused)
    restart_every: float | None = None  # days: a continuation's, its checkpoint's (``from_checkpoint``)
    check_every = CHECK_EVERY_STEPS

    def __init__(
        self,
        scene,
        device: str | None = None,
        *,
        members: int | None = None,
        progress: bool = True,
        comm=None,
        start: np.ndarray | None = None,
        initial=None,
        initial_diagnostics: dict | None = None,
        graphs: str | bool | None = None,
        layout: str | None = None,
        blow_up: str = "stop",
        per_element: bool | None = None,
        threads: int | None = None,
        **overrides,
    ):
        progress = flag_argument("progress", progress, SceneError)
        graphs = graphs_mode(default_mode() if graphs is None else graphs)
        # Δt the simulation may fit to the user's intervals (``steps``): not given, restored or stated in a Scene
        own_dt = not isinstance(scene, Scene) and "dt" not in overrides and initial_diagnostics is None
        if members is not None and any(k.split(".")[0] == "ensemble" for k in overrides):
            overrides = {**overrides, "members": members}  # N in the scene's table too, as ``load_scene`` takes it
        scene, inputs = resolve_scene(scene, overrides)
        comm_argument("comm", comm)
        backend = Backend.of(pick_device(device, comm=comm))  # a name Warp does not know is refused in one line
        members, initial, start = asked(scene, members, initial, start, self._of_members)  # N (None: a single run)
        if initial_diagnostics is not None:
            mapping_argument("initial_diagnostics", initial_diagnostics)
        t0 = time.perf_counter()
        # the seconds compiling; name -> activity (``activities``): the user's, ``run`` adds its own
        self._compile, self.activities = [0.0], {}
        self.backend, self.device, self.progress = backend, backend.device, progress
        # single-threaded BLAS, as in ``run``: the ∇⁴'s power iteration (``config.parts.check_hyperviscosity``)
        # takes 40 norms, and OpenBLAS's threads spinning on a busy machine made them 0.3 s of CPU
        with compile_timer(self._compile), threadpool_limits(limits=1, user_api="blas"):
            options = {"given": start, "per_element": per_element, "threads": threads}
            m = self.members = Members(scene, members, initial, backend, comm, graphs, layout, blow_up, **options)
            self.case, self.grid, self.root, self.dfi, self.topology = m.case, m.grid, m.root, m.dfi, m.topology
            self.model, self.progress = m.units[0].model, self.progress and m.root
            self.hs, self.fcor, self.g = (None, None, self.model.g) if m.hs is None else (m.hs[0], m.fcor[0], m.g[0])
            self.scorer = m.scorer and m.scorer[0]  # a single run's (members': built when first asked)
            self.core = m.integrator()
            m.run = self.run_state = RunState(self.core, scene, initial=initial_diagnostics)
            if initial_diagnostics is None:  # before the step control: their Courant numbers at the scene's dt
                self.run_state.initial = m.diagnose(scene.start_day * DAY)
            # Δt chosen step to step (``Scene.control``): the loop's steps land on its times
            self.core.control = step_control(scene, m.units[0], m.members, m.layout, m.comm)
            self.counters["iterations"].update(dict.fromkeys(self.core.units[0].stepper.solvers, 0))
        self.intervals = Intervals(self.run_state, self.activities, self.members, own_dt)
        self.setup_time = time.perf_counter() - t0
        if inputs:
            self.inputs = inputs

    # -- restarts and branches (``checkpoint``)
    from_checkpoint = classmethod(ckpt.from_checkpoint)

    # -- the run's state (``run_state.RunState``): the scene it runs, its step control, t = 0 diagnostics, counters
    scene = forwarded("run_state.scene", "The ``Scene`` run (resolved; a fitted Δt or a lengthened run replace it).")
    control = forwarded("core.control", "The integrator's ``StepControl`` under ``Scene.control``, else None.")
    initial = forwarded("run_state.initial", "The t = 0 diagnostics changes are taken against (members: (N,) each).")
    counters = forwarded("core.counters", "RHS evaluations, wall and CPU seconds and solver iterations so far.")
    time = forwarded("run_state.time", "Days since t = 0 at the current step (``RunState.time``).")
    event_day = forwarded("run_state.event_day", "The day a controlled step landed on (``RunState.event_day``).")

    # -- the members' states and diagnostics (``members.members.Members``), squeezed (``squeeze``)
    fields = squeezed(Members.fields)
    divergence = squeezed(Members.divergence)
    courant = squeezed(Members.courant)
    stability_warning = squeezed(Members.stability_warning)
    largest_dt_within_limit = squeezed(Members.largest_dt_within_limit)
    invariants = squeezed(Members.invariants)
    errors = squeezed(Members.errors)
    states = delegated(Members.states, attrgetter("members"))
    set_states = delegated(Members.set_states, attrgetter("members"))
    h_spread_rms = delegated(Members.h_spread_rms, attrgetter("members"))

    # -- the step: the integrator's (``integrator.core.Integrator``, one unit of one member) and its graphs
    step = forwarded("core.step", "Steps taken since t = 0 (a branch: since its day, ``Scene.start_day``).")
    x = of_one("x", "x", "The state (3, n) on the device: rows u, v (m s⁻¹), h (m) on this rank's nodes.")
    last_good = of_one("last_good", "start", "The state (3, n) at the start of the step or block in progress.")
    # a step of the stepper, not watched nor counted: a controlled run's tries (``integrator.control.StepControl``)
    try_step = of_one("try_step", "try_step", "One step of the stepper on a state x (3, n) in place (``Unit``).")

    stepper = of_one("stepper", "stepper", "The stepper prepared on the state, of every member (``steppers``).", True)

    @property
    def graphs(self):
        """Graph mode of every member's steps: "auto", "on", "off" (or True, False; see Notes)."""
        return self.core.units[0].graphed.mode

    @graphs.setter
    def graphs(self, mode) -> None:
        for u in self.core.units:
            u.graphed.mode = mode

    @property
    def graphs_kept(self) -> int:
        """Step graphs checked and kept (``GraphedSteps.kept``, over the units); 0 where steps run plain."""
        return sum(u.graphed.kept for u in self.core.units)

    @property
    def graphs_checked(self) -> int:
        """Step graphs compared bit for bit with plain ones (``GraphedSteps.checked``, over the units)."""
        return sum(u.graphed.checked for u in self.core.units)

    dropped = property(lambda sim: sim.members.dropped, doc=Members.dropped.__doc__)
    drops = property(lambda sim: sim.members.drops, doc=Members.drops.__doc__)

    def __getattr__(self, name: str):
        """An old name of a part (``RENAMED``), after its one-line ``DeprecationWarning``."""
        if name not in RENAMED:
            raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")
        warnings.warn(f"Simulation.{name} is deprecated: Simulation.{RENAMED[name]}", DeprecationWarning, stacklevel=2)
        return attrgetter(RENAMED[name])(self)

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
        progress_lines=None,
        until_day: float | None = None,
    ) -> RunResult:
        """Integrate the scene from the current step; write ``output`` (netCDF) if given.

        Blocks of steps by the integrator, each checked by its guard (``integrator.core.Integrator``), Δt the fixed
        one's or under step control the controller's (``guard.RunObserver.steer``), then the activities due
        (``activities``): the run file and its ``[[output.streams]]``, the restart file, the callbacks and writers,
        the log.

        Parameters
        ----------
        output : path, optional
            The run file.
        overwrite : bool
            Replace an existing output (and restart) file.
        restart_every : float, optional
            Write ``restart_file`` every so many model days and at the end (a continuation:
            default its checkpoint's interval, ``restart_every``).
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
            ``notify(line)`` (rank 0): a note of a wall time estimated above a day, or a cells build.
        log : callable, optional
            ``log(line)`` (rank 0) with ``log_line`` every ``scene.log_every_steps``
            steps since t = 0 (given on every rank alike, or on none).
        until_step : int, optional
            Stop after this step (default: the scene's last; ``advance``; not under step control).
        until_day : float, optional
            Under step control, the model day to land on and stop at (default: the scene's last;
            ``advance``).
        progress_lines : cli.progress.ProgressLines, optional
            Rank 0's lines of progress where no bar is drawn (``start(day, end_day)``, ``tick(step, day)``).

        Returns
        -------
        RunResult
            Steps, RHS evaluations, solver iterations, times and the diagnostics' history.

        Raises
        ------
        ValueError
            ``until_step`` under step control (``scene.control``).
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
        check_run_arguments(output, overwrite, restart_every, restart_file, compress, catch_signals)
        if restart_every is None and (output is not None or restart_file is not None):
            restart_every = self.restart_every  # a continuation's: the interval its checkpoint was written at
        end = self.core.step >= until_step if until_step is not None else self.time >= (until_day or self.scene.days)
        if output is not None and end:
            raise ArgumentError(at_its_end(type(self).__name__, self.core.step, self.scene))  # a file of no time
        paths, opts = (output, overwrite, restart_every, restart_file), (compress, history, on_output, notify)
        files, ckp, start, courant, first = open_files(self, *paths, *opts, self._compile)
        ledger = Ledger(self.counters, self.scene, self.core.step, notify if self.root else None)
        signals = StopSignals(self.members.ranks, catch_signals)
        d, lines = self.members, progress_lines if self.root else None
        parts = (self.run_state, self.activities, self, ledger, self.check_every, signals)

        def blocks(bar) -> Stop:
            # the steps under the run's guard, members dropped where they blow up (``Members.drop``)
            observer = RunObserver(*parts, bar, lines, d.drop if d.members else None)
            return run_steps(self.core, observer, d.describe, until_step, until_day)

        # the run's own activities (the log after the user's), a single run's solver counters read with the check
        every, one = self.scene.log_every_steps, d.members is None
        more = {"log": log_activity(log, EverySteps(every), files)} if log is not None and every and one else {}
        during = own_activities(self.activities, files, ckp, self.stepper if one else None, **more)
        how = {"progress": self.progress, "lines": progress_lines, "compiling": self._compile}
        stop = integrate(self.run_state, files, ckp, start, signals, blocks, during, d, first, **how)
        times = {"setup_time": self.setup_time, "compile_time": self._compile[0]}
        done = {"courant": courant, "output": output, "blowup": stop.blowup, "checkpoint": ckp.written, **times}
        result = ledger.result(self.core.step, files.history, **done)
        return outcome(stop, self.run_state, output, ckp, result)

    # -- driven from Python (Oceananigans' ``Simulation``: step, inspect, call back); intervals of whole
    # steps, Δt fitted to them where it is the simulation's own (``intervals``: ``every``, ``fit_dt``, …)
    every = delegated(Intervals.every, attrgetter("intervals"))

    def add_callback(
        self, fn, *, every_days: float | None = None, every_steps: int | None = None, name: str | None = None
    ) -> None:
        """Call ``fn(self)`` after every ``every_steps``-th step, or every ``every_days`` (``every``), in ``run``,
        ``advance`` and ``steps`` (Oceananigans' ``add_callback!``): an activity in ``activities`` under ``name``
        (default "callback N"). ``fn`` may read ``sim.step``, ``sim.time``, ``sim.state()``; what it raises ends the
        run (its output files dropped). Under MPI add it on every rank. ``SceneError`` for ``fn`` not callable,
        ``name`` not a str, and as ``every``."""
        callable_argument("fn", fn, "a callable fn(sim)", SceneError)
        if name is not None and not isinstance(name, str):
            raise SceneError(f"name must be a str or None (got {got(name)})")
        add_callback(self.activities, fn, self.every(days=every_days, steps=every_steps), name)

    def advance(self, days: float) -> RunResult:
        """Step ``days`` further with ``run``'s loop (the same bits as one run; blow-up, signals and callbacks as there;
        no output file); under step control the steps land on the day reached. Past the scene's end the run is
        lengthened (``config.with_days``).

        Parameters
        ----------
        days : float
            Model days, a whole number of steps at a fixed Δt.

        Returns
        -------
        RunResult
            Of these steps.

        Raises
        ------
        ValueError
            ``days`` is not a whole number of steps (at a fixed Δt), or not a number ≥ 0.
        BlowUp, StepFailure, Interrupted
            As ``run``.
        """
        number_argument("days", days, "days", low=0.0, error=SceneError)
        if self.control is not None:  # Δt the controller's, landing on the day reached
            end = self.time + days
            if end > self.scene.days:
                self.scene = with_days(self.scene, end, "the scene's")
            return self.run(None, until_day=end)
        return self._advance_to(self.core.step + (self.intervals.steps_in(days, "days") if days else 0))

    def _advance_to(self, target: int) -> RunResult:
        """Steps to ``target`` by ``run``'s loop (the scene lengthened past its end)."""
        if target > self.scene.nsteps:
            self.scene = with_days(self.scene, self.scene.start_day + target * self.scene.dt / DAY, "the scene's")
        return self.run(None, until_step=target)

    def steps(self, every: float):
        """Iterate the run to the scene's end, one multiple of ``every`` days from t = 0 at a time (``for t in
        sim.steps(every=0.5): ds = sim.state()``); stops at the last multiple at or before the end.

        Where Δt is the simulation's own (no ``dt`` given, the scene named or a file: ``swe-sphere run`` shortens it
        likewise to divide the output interval) and no step has been taken, a Δt that does not divide ``every`` is
        first shortened to the largest that divides ``every``, the run, its output intervals and the callbacks'
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
        ArgumentError
            Under step control ([time] control): the controller chooses the steps (``advance``
            steps under it, landing on the day reached).
        BlowUp, StepFailure, Interrupted
            As ``run``.
        """
        if self.control is not None:
            raise ArgumentError(
                "Simulation.steps steps a fixed dt: under step control ([time] control) the controller chooses the "
                "steps, and a run goes to its end (Simulation.run)"
            )
        per = self.intervals.steps_in(every, "every")
        while (target := (self.core.step // per + 1) * per) <= self.scene.nsteps:
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
            On the nodes, as a run file holds one output time: h (m), u, v (m s⁻¹), vorticity, divergence (s⁻¹)
            on ``ncol`` (N > 1: (``member``, ``ncol``), the ``squeeze`` rule), hs (members share it), area, lat,
            lon and ``time`` in days (``run_file.node_dataset``); or on (lat, lon). None on ranks other than 0.

        Raises
        ------
        ValueError
            A ``remap`` spacing that does not divide 180 degrees.
        """
        whole = self.members.gather_fields(divergence=True)
        if not self.root:
            return None
        each = {k: getattr(whole, k) for k in OUTPUT_FIELDS}  # (n,) a single run's, (N, n) members'
        fields = {k: squeeze(len(self.members), f) if f.ndim == 2 else f for k, f in each.items()}
        attrs = {"scene": self.scene.as_dict(), "ne": self.scene.ne, "np": self.scene.np, "step": self.core.step}
        ds = node_dataset(self.grid, self.hs, self.time, fields, attrs)
        if remap is None:
            return ds
        from ..io.remap import remap_dataset  # here: xarray and scipy.sparse, for the Python API's maps only

        return remap_dataset(ds, remap)

    # -- restarts: its state and history restored from a checkpoint, its restart file written

    def restore(self, ck: ckpt.Checkpoint, *, state: bool = True) -> None:
        """Set every member's state, stepper history, the counters, the step control and t = 0 invariants from a
        checkpoint of the run's kind (``CheckpointError`` for a state of another grid, or a history that does not fit
        the stepper); ``state`` False: a single run's state left as it is (built from ``ck``'s, ``from_checkpoint``:
        handed out over the ranks once)."""
        restore_run(self.run_state, ck, lambda: self.members.restore(ck, state))

    def write_checkpoint(self, path, *, overwrite: bool = False, restart_every: float | None = None) -> Path:
        """Write a restart file of the current step (see ``checkpoint``): whole-grid fields, gathered from every rank
        (call on all), written by rank 0; ``restart_every`` (days) recorded for a continuation to keep. Members: every
        member's state and its stepper's history, the member count, the layout and the variants. An existing ``path``
        is replaced only with ``overwrite`` (else ``OutputError``), as every writer of the package does."""
        d = self.members  # (x, stepper states, initial, grid) on rank 0, else None; an ensemble's member count
        parts, kept = d.restart_parts(), {"overwrite": overwrite, "restart_every": restart_every, "members": d.members}
        kept["analysed"] = getattr(self.case, "analysed", None)  # a reanalysis start's: its continuation's case
        return Path(path) if parts is None else write_restart(path, self.run_state, *parts, **kept)
