"""``Simulation.run``'s loop: blocks of steps checked by the guard (``guard.Guard``), the
activities due after each good step, the progress bar, a stopped run's files closed and its
outcome (``StepLoop``, the object a ``Simulation`` holds); the run's arguments checked
(``check_run_arguments``) and the seconds spent compiling Warp modules (``compile_timer``)."""

from __future__ import annotations

import contextlib
import signal
import sys
import time

from tqdm import tqdm

from ..core.arguments import flag_argument, number_argument, path_argument
from ..core.errors import BlowUp, Interrupted, OutputError, SceneError, StepFailure
from ..core.interrupts import StepAbandoned, StopSignals
from .activities import is_due
from .guard import Guard
from .summary import Ledger, RunResult, Stop, interruption
from .writers import Checkpointer, RunFiles, interrupted_attrs


@contextlib.contextmanager
def compile_timer(acc: list):
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


class StepLoop:
    """The steps of ``Simulation.run`` on ``sim``, each by ``take_step(watch)`` (its ``StepStats``),
    its activities between them, and how it stopped."""

    def __init__(self, sim, take_step):
        self.sim, self.take_step = sim, take_step
        self.lines = None  # a run's ``progress.ProgressLines``, where it was given one

    def watched(self, lines) -> None:
        """Write the run's progress as ``lines`` (a ``progress.ProgressLines``, or None: none) from now on."""
        self.lines = lines
        if lines is not None:
            lines.start(self.sim.time, self.sim.scene.days)

    def progress_bar(self) -> tqdm:
        # disable=None: a bar only on a terminal, not redrawn into a log (or mpiexec's pipe)
        return tqdm(
            initial=self.sim.step,
            total=self.sim.scene.nsteps,
            unit="step",
            disable=None if self.sim.progress else True,
            file=sys.stderr,
            dynamic_ncols=True,
        )

    def blocks(self, guard: Guard, signals: StopSignals, ledger: Ledger, bar) -> Stop:
        """Blocks of steps to ``guard.stop_step``, the activities due called after each good
        step; a block that finds trouble is re-run a checked step at a time. Returns why
        the loop stopped (``summary.Stop``: nothing, a signal, an abandoned step or a blow-up)."""
        rerun_to = self.sim.step  # steps up to here are re-run one at a time: their block found trouble
        while self.sim.step < guard.stop_step:
            if self.sim.step >= rerun_to and (signum := signals.asked()):  # every rank stops at the same step
                return Stop(signum=signum)
            b = self.sim.step
            e = guard.block_end(b) if b >= rerun_to else b + 1  # a re-run goes on to the trouble it looks for
            m, trouble, detail = self.steps(b, e, guard, signals, ledger)
            if trouble is None:  # m > b: a step without trouble was taken
                self.after_steps(m, m - b, bar)
            elif trouble == "abandoned":
                return Stop(signum=detail, abandoned=(b, m))
            elif e > b + 1:  # the block is re-run from b, a checked step at a time
                rerun_to = m + 1 if trouble == "failure" else m  # a failure: in step m + 1
            else:
                return Stop(blowup=guard.message(b + 1, trouble, detail))
        return Stop()

    def after_steps(self, n: int, done: int, bar) -> None:
        """Step n (the last of ``done`` steps) is good: the activities due there, the progress bar."""
        sim = self.sim
        sim.step = n
        for activity in list(sim.activities.values()):
            if is_due(activity.schedule, sim):
                activity(sim)
        bar.update(done)
        if self.lines is not None and sim.root:
            self.lines.tick(n, sim.time)
        if n % 50 < done or n == sim.scene.nsteps:  # a multiple of 50 in the steps done
            bar.set_postfix(
                day=f"{sim.time:.2f}",
                sim_days_per_s=f"{(sim.time - sim.scene.start_day) / max(sim.counters['wall_time'], 1e-9):.3g}",
            )

    def stopped(self, stop: Stop, files: RunFiles, ckp: Checkpointer) -> None:
        """Close the files of a run that stopped early: after a blow-up with the last good
        state (``step`` is the last good step again), after a signal with the current one
        and its restart file."""
        if stop.blowup is not None:
            files.end(self.sim.step, self.sim.last_good, blowup=stop.blowup)
        elif stop.signum is not None:
            files.end(self.sim.step, **interrupted_attrs(stop.signum, self.sim.step, self.sim.time))
            ckp.interrupted(self.sim.step, abandoned=stop.abandoned is not None)

    def outcome(self, stop: Stop, result: RunResult, output, ckp: Checkpointer) -> RunResult:
        """``result``, or ``BlowUp`` or ``Interrupted`` raised with it."""
        if stop.blowup is not None:
            err = BlowUp(stop.blowup)
            err.result = result
            raise err
        if stop.signum is not None:
            name = signal.Signals(stop.signum).name
            line = interruption(
                name, self.sim.step, self.sim.time, self.sim.scene, output, ckp.kept, ckp.written, stop.abandoned
            )
            err = Interrupted(line)
            err.signum, err.result, err.checkpoint = stop.signum, result, ckp.written
            raise err
        return result

    def steps(self, b: int, e: int, guard: Guard, signals: StopSignals, ledger: Ledger):
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
                stats = self.take_step(block)
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
            self.sim.step = m  # the steps x holds (not yet checked)
        trouble, node = guard.end(b, trouble, ledger)
        ledger.account(m if block else b + 1, t0, cpu0)
        return m, trouble, node if trouble == "bad" else detail
