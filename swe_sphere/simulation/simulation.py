"""The simulation: a scene's model, stepper and state, and the loop that steps them.

On Oceananigans' pattern, the loop (``Simulation.run``) is short and takes its
steps by one path; what happens around the steps is each a small part: the step
itself (``graphs.GraphedSteps``), the bad-state guard (``guard``), the activities
called at the steps their schedules name (``activities``: the run files and restart
files of ``writers``, callbacks, user writers, the log; all in ``Simulation.activities``),
signals (``interrupts``), and the counts and result (``summary``). The build is
``build``'s, restarts and branches ``restart``'s, driving from Python ``drive``'s (their
functions bound here as methods); the state's diagnostics a ``state_diagnostics``
component, ``Simulation.diagnostics``."""

from __future__ import annotations

import contextlib
import signal
import sys
import time
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits
from tqdm import tqdm

from ..config.scene import Scene, resolve_scene
from ..core.arguments import (
    array_argument,
    comm_argument,
    flag_argument,
    got,
    mapping_argument,
    number_argument,
    path_argument,
)
from ..core.backend import Backend, pick_device
from ..core.errors import ArgumentError, BlowUp, Interrupted, OutputError, SceneError, StepFailure
from ..core.graphs import GraphedSteps, default_mode, graphs_mode
from ..core.interrupts import StepAbandoned, StopSignals
from ..io.output_files import check_distinct, check_target
from ..steppers import StepStats
from . import drive, restart
from .activities import Log, is_due
from .adaptive import steer
from .build import ON_ROOT, build
from .guard import Guard
from .schedules import EverySteps
from .summary import Ledger, RunResult, Stop, interruption
from .writers import Checkpointer, RunFiles, run_attrs

# The names users catch and read from here (``swe_sphere.BlowUp``, ``swe_sphere.Interrupted``).
__all__ = ["BlowUp", "Interrupted", "RunResult", "Simulation"]


RUN_ACTIVITIES = ("run_file", "checkpointer", "log")  # the names ``run`` gives its own activities


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


class Simulation:
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
        Warp device (default: ``SWE_SPHERE_DEVICE`` where set, else CUDA when present; ``backend.pick_device``).
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
    diagnostics : StateDiagnostics
        The state's fields gathered on rank 0, invariants, errors, Courant numbers and
        the log line (``state_diagnostics``); ``fields``, ``divergence``, ``courant``,
        ``stability_warning`` and ``largest_dt_within_limit`` are also the simulation's.
    backend : Backend
        The device's choices (``core.backend``), decided once; ``device`` its name.

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
        progress = flag_argument("progress", progress, SceneError)
        graphs = graphs_mode(default_mode() if graphs is None else graphs)
        # Δt the simulation may fit to the user's intervals (``steps``): not given, restored or stated in a Scene
        self._own_dt = not isinstance(scene, Scene) and "dt" not in overrides and initial_diagnostics is None
        scene, inputs = resolve_scene(scene, overrides)
        backend = Backend.of(pick_device(device))  # a name Warp does not know is refused in one line
        if initial is not None and (start is not None or not callable(initial)):
            raise ArgumentError(
                f"initial must be a function (lat, lon) -> (h, u, v), and not given with start (got {got(initial)})"
            )
        comm_argument("comm", comm)
        if start is not None and start is not ON_ROOT:
            start = array_argument("start", start, (3, None), "m s⁻¹ and m")  # the grid's columns: ``distribute``
        if initial_diagnostics is not None:
            mapping_argument("initial_diagnostics", initial_diagnostics)
        t0 = time.perf_counter()
        self._compile = [0.0]
        self.activities: dict = {}  # name -> activity (``activities``): the user's; ``run`` adds its own
        # single-threaded BLAS, as in ``run``: the ∇⁴'s power iteration (``build.check_hyperviscosity``)
        # takes 40 norms, and OpenBLAS's threads spinning on a busy machine made them 0.3 s of CPU
        with _compile_timer(self._compile), threadpool_limits(limits=1, user_api="blas"):
            build(self, scene, backend, progress, comm, start, initial, initial_diagnostics)
        self._graphed = GraphedSteps(backend, self.model.graph_guard, graphs)
        self.setup_time = time.perf_counter() - t0
        if inputs:
            self.inputs = inputs

    # -- restarts and branches (``restart``), driven from Python (``drive``) ----------
    from_checkpoint = classmethod(restart.from_checkpoint)
    restore = restart.restore
    restore_history = restart.restore_history
    write_checkpoint = restart.write_checkpoint
    fit_dt = drive.fit_dt
    every = drive.every
    add_callback = drive.add_callback
    time = property(drive.time)
    event_day = property(drive.event_day)
    advance = drive.advance
    steps = drive.steps
    state = drive.state

    # -- the state's diagnostics (``state_diagnostics``) --------------------------
    def fields(self, x=None):
        """``StateDiagnostics.fields``: u, v, h of the whole grid on rank 0."""
        return self.diagnostics.fields(x)

    def divergence(self, x=None):
        """``StateDiagnostics.divergence``: the wind's divergence on rank 0."""
        return self.diagnostics.divergence(x)

    def courant(self, whole=None) -> dict:
        """``StateDiagnostics.courant``: the Courant numbers of the current state."""
        return self.diagnostics.courant(whole)

    def stability_warning(self) -> str | None:
        """``StateDiagnostics.stability_warning``: a line when Δt exceeds the stepper's limit."""
        return self.diagnostics.stability_warning()

    def largest_dt_within_limit(self) -> float | None:
        """``StateDiagnostics.largest_dt_within_limit``: the Δt at the stepper's limit."""
        return self.diagnostics.largest_dt_within_limit()

    # -- the step --------------------------------------------------------------
    @property
    def graphs(self) -> str:
        """The graph mode: "auto", "on" or "off" (set also as True, False; see the class)."""
        return self._graphed.mode

    @graphs.setter
    def graphs(self, value) -> None:
        self._graphed.mode = value

    @property
    def graphs_kept(self) -> int:
        """The step graphs checked and kept so far, each replayed by the later steps of its key
        (``graphs.GraphedSteps.kept``); 0 where steps run plain."""
        return self._graphed.kept

    @property
    def graphs_checked(self) -> int:
        """The step graphs compared bit for bit with the same step launched plainly so far
        (``graphs.GraphedSteps``: each key's first, or a ``Stepper.graph_family``'s)."""
        return self._graphed.checked

    def try_step(self, x):
        """One step of the stepper on x (3, N) in place, replayed as a graph where ``graphs``
        lets it (``graphs.GraphedSteps``; its key holds Δt, so a controlled run's few Δt of
        the controller's grid each keep a graph), the bad-state flag not watched and the
        solvers' counters not read: a controlled run's tries (``adaptive.StepControl``). Its
        ``StepStats``."""
        return self._graphed.step(self.stepper, self.model, x, False)

    def _take_step(self, watch: bool):
        """One step of the stepper on x and, with ``watch``, the bad-state flag's launch
        (``ShallowWater.watch``; the solvers' device counters left for the block's
        read), else with its solvers' counters read (``Stepper.counts``: raises
        ``StepFailure``); its ``StepStats``. With ``graphs``, steps replay as
        graphs (``graphs.GraphedSteps``)."""
        stats = self._graphed.step(self.stepper, self.model, self.x, watch)
        return stats if watch else StepStats(stats.rhs_evals, {**stats.iterations, **self.stepper.counts()})

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

        Blocks of steps, each checked by the guard (``guard.Guard``; under step control
        ``adaptive.steer``'s), then the activities due (``activities``): the run file and its
        ``[[output.streams]]``, the restart file, the callbacks and writers, the log.

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
            ``notify(line)`` (rank 0): a note of a wall time estimated above a day, or a cells build.
        log : callable, optional
            ``log(line)`` (rank 0) with ``log_line`` every ``scene.log_every_steps``
            steps since t = 0 (given on every rank alike, or on none).
        until_step : int, optional
            Stop after this step (default: the scene's last; ``advance``; not under step control).

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
        _check_run_arguments(output, overwrite, restart_every, restart_file, compress, catch_signals)
        files, ckp, start, courant = self._open(
            output, overwrite, restart_every, restart_file, compress, history, on_output, notify
        )
        ledger = Ledger(self.counters, self.scene, self.step, notify if self.root else None)
        stop, signals = self._integrate(files, ckp, start, ledger, log, catch_signals, until_step)
        if stop.signum is None and stop.blowup is None:  # a signal after the last step's check: the output is whole
            stop.signum = signals.asked() or None
        result = ledger.result(
            self.step, files.history, courant, output, stop.blowup, ckp.written, self.setup_time, self._compile[0]
        )
        return self._outcome(stop, result, output, ckp)

    def _integrate(self, files, ckp, start, ledger, log, catch_signals, until_step) -> tuple:
        """``run``'s loop with its files (``RunFiles``, ``Checkpointer``) and signals: the fixed
        step's (``_loop``) or, under ``scene.control``, the step control's (``adaptive.steer``);
        (why it stopped, ``summary.Stop``; the ``StopSignals``). The files closed, or dropped
        on an exception."""
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
                        if self.control is None:
                            last = self.scene.nsteps if until_step is None else until_step
                            stop = self._loop(Guard(self, last, ledger), signals, ledger, bar)
                        elif until_step is None:
                            stop = steer(self, signals, ledger, lambda: self._after_steps(self.step, 1, bar))
                        else:
                            raise ValueError("until_step is a fixed dt's: under step control a run goes to its end")
                    self._stopped(stop, files, ckp)
                files.close()  # under this run's handlers: a signal now waits, and is answered below
            except BaseException:
                files.abort()
                raise
        return stop, signals

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
            start = self.diagnostics.gather_fields(
                divergence=files.divergence
            )  # the first output time's, on every rank
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
            if is_due(activity.schedule, self):
                activity(self)
        bar.update(done)
        if n % 50 < done or n == self.scene.nsteps:  # a multiple of 50 in the steps done
            bar.set_postfix(
                day=f"{self.time:.2f}",
                sim_days_per_s=f"{(self.time - self.scene.start_day) / max(self.counters['wall_time'], 1e-9):.3g}",
            )

    def _stopped(self, stop: Stop, files: RunFiles, ckp: Checkpointer) -> None:
        """Close the files of a run that stopped early: after a blow-up with the last good
        state (``step`` is the last good step again), after a signal with the current one
        and its restart file."""
        if stop.blowup is not None:
            files.end(self.step, self.last_good, blowup=stop.blowup)
        elif stop.signum is not None:
            name, day = signal.Signals(stop.signum).name, self.time
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
            line = interruption(name, self.step, self.time, self.scene, output, ckp.kept, ckp.written, stop.abandoned)
            err = Interrupted(line)
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


def _check_run_arguments(output, overwrite, restart_every, restart_file, compress, catch_signals) -> None:
    """``Simulation.run``'s arguments, before anything is opened: ``OutputError`` for an output
    or restart file that is not a path, ``SceneError`` for a flag that is not a bool or a
    restart interval that is not a number of days > 0; each names the argument."""
    for name, path in (("output", output), ("restart_file", restart_file)):
        if path is not None:
            path_argument(name, path, "a file's path (str or os.PathLike)", OutputError)
    for name, value in (("overwrite", overwrite), ("compress", compress), ("catch_signals", catch_signals)):
        flag_argument(name, value, SceneError)
    if restart_every is not None:
        number_argument("restart_every", restart_every, "days", positive=True, error=SceneError)
