"""The run loop of ``Simulation.run``, of one member or many: the run wrapper (``integrate``:
its files recorded, signals, progress bar, a stopped run's files closed) and its outcome
(``outcome``), its steps by the integrator (``run_steps``, at a fixed or a controlled Δt) under
the run's hooks (``guard.RunObserver``), the run's own activities (``own_activities``) and the run's
arguments checked (``check_run_arguments``): plain functions of the parts they are given."""

from __future__ import annotations

import contextlib
import signal
import sys

from threadpoolctl import threadpool_limits
from tqdm import tqdm

from ..core.arguments import flag_argument, number_argument, path_argument
from ..core.errors import BlowUp, Interrupted, OutputError, SceneError
from ..core.interrupts import ABANDON_AFTER
from ..core.runtime import compile_timer
from ..integrator.core import Stop
from ..io.output_files import check_distinct, check_target
from .writers import Checkpointer, RunFiles, opening


def check_run_arguments(output, overwrite, restart_every, restart_file, compress, catch_signals) -> None:
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


def run_steps(core, observer, describe, until_step: int | None = None, until_day: float | None = None) -> Stop:
    """The steps of a run (a ``Simulation``'s, of one member or many) by its integrator ``core`` to
    ``until_step`` (None: the scene's last, ``observer.run.scene``) under ``observer`` (a
    ``guard.RunObserver``), each step's Δt the integrator's own policy's at a fixed Δt; under its
    ``control`` (an ``integrator.control.StepControl``; ``until_step`` then refused, ValueError) the
    policy ``observer.steer``'s, which keeps and puts back its steps (each accepted step a block
    checked at once, landed on the days the observer's activities are due at and on ``until_day``,
    default the scene's last) from then on (a controlled run steps by nothing else). Returns why the steps stopped
    (``Stop``: nothing, a signal, an abandoned step, a blow-up with ``describe(bad)`` its line, or
    the controller's Δt below dt_min); after a controlled run's blow-up, the state and the control
    those of the step before."""
    scene = observer.run.scene
    if core.control is None:
        stop = core.advance(scene.nsteps if until_step is None else until_step, observer)
    elif until_step is not None:
        raise ValueError("until_step is a fixed dt's: under step control a run goes to its end")
    else:  # the control's Δt policy from now on, also how a step is put back, each step checked at once
        core.policy = observer.steer(core.control, scene.days if until_day is None else until_day)
        core.lone = True
        try:
            stop = core.advance(sys.maxsize, observer)
        except BlowUp as err:  # the controller's Δt below dt_min: the rejected tries put the state back
            return Stop(blowup=str(err))
        finally:  # a try launched ahead undone: the state the run stops with is the last accepted step's
            core.control.settle(core.units[0].x)
    if stop.bad is not None:
        stop.blowup = describe(stop.bad)
        if core.control is not None:
            core.policy.put_back([], {})
    return stop


def integrate(run, files, ckp, start, signals, blocks, during, ends, diagnosed, *, progress, lines, compiling) -> Stop:
    """The run wrapper of ``Simulation.run``: ``run`` (a
    ``run_state.RunState``) stepped by ``blocks(bar)`` (``run_steps``; a ``Stop``) with
    its files (``writers.RunFiles``, ``Checkpointer``) under ``signals`` (a ``StopSignals``), one
    BLAS thread, ``during`` (a context: the run's own activities), a progress bar and ``lines``
    (``cli.progress.ProgressLines``: ``start``, ``tick``; or None), the seconds compiling added to ``compiling[0]``. The
    first output time recorded first (``start`` its gathered fields, ``diagnosed`` their diagnostics
    where taken), a continuation's not written again: the two files join without a repeat. ``ends``
    the run's members (``members.members.Members``): a single run's blow-up line is the files'
    attribute ``blowup`` and its last good state (the step's start) recorded, and on an exception the
    files are dropped; a run of members' files keep the line, or the exception's, as ``stopped``. A signal's step
    recorded, its attributes (``interrupted``, its name, ``interrupted_at_step`` and
    ``interrupted_at_day``) and its restart file. The files closed with the members dropped
    (``ends.drops``, as ``dropped_members``). Returns why the steps stopped, a signal after the last
    step's check taken as one (the output is whole)."""
    # single-threaded BLAS: the Krylov solvers' vectors are too short for threads to
    # pay, and on a busy machine OpenBLAS's spinning threads made a norm cost 10 ms
    one = ends.members is None  # a single run: a blow-up's files keep its last good state, else its line
    with signals, threadpool_limits(limits=1, user_api="blas"):
        try:
            with during, compile_timer(compiling):
                files.record(whole=start, final=True, write=not run.step, diagnosed=diagnosed)
                if lines is not None:
                    lines.start(run.time, run.scene.days)
                # a bar on a terminal only (disable=None), not redrawn into a log or mpiexec's pipe
                on = {"disable": None if progress else True, "file": sys.stderr, "dynamic_ncols": True}
                with tqdm(initial=run.step, total=run.scene.nsteps, unit="step", **on) as bar:
                    stop = blocks(bar)
                if stop.blowup is not None and one:  # ``run.step`` is the last good step again: its start kept
                    files.end(ends.units[0].start, blowup=stop.blowup)
                elif stop.blowup is not None:
                    files.set_attrs(stopped=stop.blowup)
                elif stop.signum is not None:
                    # the global attributes of a run file stopped by a signal: its name, the step and model day
                    name = signal.Signals(stop.signum).name
                    files.end(interrupted=name, interrupted_at_step=run.step, interrupted_at_day=run.time)
                    ckp.interrupted(abandoned=stop.abandoned is not None)
                drops = ends.drops  # collective
                files.set_attrs(**({"dropped_members": "; ".join(drops)} if drops else {}))
            files.close()  # under this run's handlers: a signal now waits, and is answered below
        except BaseException as err:
            if one:
                files.abort()
            else:
                files.set_attrs(stopped=str(err) or type(err).__name__)
                files.close()
            raise
    if stop.signum is None and stop.blowup is None:  # a signal after the last step's check: the output is whole
        stop.signum = signals.asked() or None
    return stop


def outcome(stop: Stop, run, output, ckp: Checkpointer, result=None):
    """``result`` of ``run`` (a ``run_state.RunState``), or ``BlowUp`` or ``Interrupted`` raised with
    it. The ``Interrupted`` of a run (a ``Simulation``'s) the signal ``stop.signum`` stopped at its
    step says what was kept (``output``, the restart file its ``writers.Checkpointer`` ``ckp`` wrote,
    or an existing one it left alone) and, for ``stop.abandoned`` = (b, m), the step abandoned; with
    ``signum``, ``result`` (the run's ``RunResult``, or None) and ``checkpoint`` (the restart file
    written, or None) on it."""
    if stop.blowup is not None:
        err = BlowUp(stop.blowup)
        err.result = result
        raise err
    if stop.signum is None:
        return result
    day, scene = run.time, run.scene
    if day == scene.days:  # the run had ended (an interruption inside it stops before its last step)
        kept = [f"the output {output} is complete"] if output is not None else []
        when = f"after the last step (model time {day:.4f} days)"
    else:
        kept = [f"output so far in {output}"] if output is not None else []
        if ckp.kept is not None:
            kept.append(f"no restart file: {ckp.kept} exists (--overwrite, or overwrite=True in Python, replaces it)")
        how = ""
        if stop.abandoned:
            b, m = stop.abandoned  # steps b+1..m were taken in a block not yet checked: dropped with m + 1
            before = f" with steps {b + 1}-{m} before it (not yet checked)" if m > b else ""
            how = f"; step {m + 1} abandoned after {ABANDON_AFTER:g} s{before} (no restart file from it)"
        when = f"at step {run.step} (model time {day:.4f} days){how}"
    kept += [f"restart file {ckp.written}"] if ckp.written is not None else []
    err = Interrupted("; ".join([f"interrupted by {signal.Signals(stop.signum).name} {when}", *kept]))
    err.signum, err.result, err.checkpoint = stop.signum, result, ckp.written
    raise err


@contextlib.contextmanager
def own_activities(activities: dict, files: RunFiles, ckp: Checkpointer, deferred=None, **more):
    """A run's own activities in ``activities`` (a ``Simulation``'s, changed
    in place) while its loop runs: the run file and checkpointer before the user's, ``more``
    after; the stepper ``deferred``'s solver counters read with the bad-state check
    (``Stepper.deferred``). The user's alone again after."""
    own, steppers = dict(activities), [] if deferred is None else [deferred]
    activities.clear()
    activities.update({"run_file": files, "checkpointer": ckp, **own, **more})
    for stepper in steppers:
        stepper.deferred = True
    try:
        yield
    finally:
        activities.clear()
        activities.update(own)
        for stepper in steppers:
            stepper.deferred = False


def open_files(sim, output, overwrite, restart_every, restart_file, compress, history, on_output, notify, compiling):
    """The run files and checkpointer of a run of ``sim`` (a ``Simulation``; ``run``'s arguments; paths
    checked, the files created on rank 0), the start's gathered fields, its Courant numbers (a
    single run's) and its members' diagnostics (None for a single run); the seconds compiling
    the diagnostic kernels added to ``compiling[0]``. Checked before any file is opened:
    ValueError for a user's activity under a name the run gives its own (``run_file``,
    ``checkpointer``, ``log``); on rank 0 ``OutputError`` for a file of the run that is one of
    ``sim.inputs`` (``check_distinct``: the scene file, a mesh, a start) or a restart file that
    exists and not ``overwrite``."""
    d, paths = sim.members, (output, restart_every, restart_file, overwrite)
    ckp = Checkpointer(sim.run_state, sim.write_checkpoint, d.bcast, sim.root, *paths)
    files = RunFiles(sim.run_state, d, sim.grid, sim.hs, output, on_output)
    taken = sorted(set(sim.activities) & {"run_file", "checkpointer", "log"})  # the names ``run`` gives its own
    if taken:
        raise ValueError(f"activities {', '.join(taken)}: a run's own names (choose another)")
    if sim.root:
        check_distinct([ckp.path, *(path for path, _, _ in files.streams)], sim.inputs)  # the run file and streams
        if ckp.path is not None:
            check_target(ckp.path, overwrite)
    with compile_timer(compiling):  # a continuation's first use of the diagnostic kernels
        start = d.gather_fields(divergence=files.divergence)  # the first output time's, every rank
    name = f"swe_sphere.{type(sim).__name__}.run"
    courant, first, attrs, more = opening(d, files, start, history, name, sim.dfi, sim.device)
    if output is not None and sim.root:
        files.open(attrs, overwrite=overwrite, compress=compress, notify=notify, **more)
    return files, ckp, start, courant, first
