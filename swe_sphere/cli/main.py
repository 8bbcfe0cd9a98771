"""The console script's entry point: parse, run the command, and turn a failure into
its one line and exit status (``swe_sphere.cli``'s docstring lists them)."""

from __future__ import annotations

import errno
import os
import sys
import time
import traceback

from ..core import mpi
from ..core.errors import BlowUp, Interrupted, ResourceError, StepFailure
from . import frontier, mesh, plot, remap, run, stability, sweep
from . import list as list_
from .exits import EXIT_BAD_INPUT, EXIT_BLOWUP, EXIT_INTERNAL, exit_process, hold_signals, on_sigterm
from .parser import parser

# each command's function and the module it imports first, the one that brings Warp, numpy
# and the rest (``_import_uncollected``)
COMMANDS = {
    "list": (list_.command, "config.scene"),
    "stability": (stability.command, "studies.stability"),
    "sweep": (sweep.command, "studies.sweep"),
    "frontier": (frontier.command, "studies.frontier"),
    "plot": (plot.command, "studies.plotting"),
    "remap": (remap.command, "io.remap"),
    "run": (run.command, "simulation.simulation"),
    "mesh": (mesh.command, "grid.refine"),
}
# the commands one process runs: under mpiexec rank 0 alone runs them (each rank drew, wrote and
# printed the same files; two mesh writers met each other's file)
SERIAL = ("list", "plot", "remap", "mesh")


def _import_uncollected(module: str) -> None:
    """Import ``module`` (of this package) with the cyclic garbage collector off, then
    freeze what exists: the imports make objects that live to the end, none of them
    garbage, and the collector's passes over them cost a tenth of a second of CPU at every
    start; frozen, later collections skip them too. For the console script only: a
    caller's process would keep its own cyclic garbage of the moment forever."""
    import gc
    import importlib

    gc.disable()
    try:
        importlib.import_module(f"..{module}", __package__)
    finally:
        gc.enable()
        gc.freeze()


def classify(err: BaseException, command: str | None = None) -> tuple[int, str]:
    """(exit status, one-line message) of a failure, as the command line reports it (and the
    benchmark scripts, benchmarks/results.py); ``command`` the subcommand it met (an interrupt
    names it, but for ``run``, whose interrupt outside its loop is outside the time loop)."""
    import signal

    if isinstance(err, Interrupted):
        return 128 + err.signum, str(err)
    if isinstance(err, KeyboardInterrupt):  # outside the time loop (its handler stops after a step)
        signum = getattr(err, "signum", signal.SIGINT)
        where = "outside the time loop" if command in (None, "run") else f"in swe-sphere {command}"
        return 128 + signum, f"interrupted by {signal.Signals(signum).name} {where}; no output was written"
    if isinstance(err, (BlowUp, StepFailure, ResourceError)):  # BlowUp: a sweep's reference run
        return EXIT_BLOWUP, str(err)
    if isinstance(err, MemoryError):
        return EXIT_BLOWUP, "out of memory" + (f" ({err})" if str(err) else "")
    if isinstance(err, (FileNotFoundError, IsADirectoryError, NotADirectoryError, PermissionError)) or (
        isinstance(err, OSError) and err.errno in (errno.EROFS, errno.ENAMETOOLONG)
    ):  # a folder to make on a read-only file system, a name longer than the file system takes
        return EXIT_BAD_INPUT, f"{err.filename}: {err.strerror}" if err.filename else str(err)
    if isinstance(err, OSError):
        return EXIT_BLOWUP, f"{err.filename + ': ' if err.filename else ''}{err.strerror or err}"
    if isinstance(err, ValueError):
        return EXIT_BAD_INPUT, str(err)
    return EXIT_INTERNAL, f"internal error: {type(err).__name__}: {err} (run with --debug for the traceback)"


def main(argv=None) -> int:
    import _signal  # built in, nothing to import: SIGTERM as SIGINT from the first instruction on

    console = argv is None and _signal.getsignal(_signal.SIGTERM) == _signal.SIG_DFL  # not a caller's process
    if console:
        _signal.signal(_signal.SIGTERM, on_sigterm)
    debug, args = os.environ.get("SWE_SPHERE_DEBUG", "") not in ("", "0"), None
    try:  # start-up (the imports of Warp and the rest) included: a signal there is one line too
        args = parser().parse_args(argv)
        args.argv, args.console = argv, console
        debug = debug or args.debug
        command, module = COMMANDS[args.command]
        if args.command in SERIAL and mpi.launched_rank() != 0:
            return 0
        if console:
            _import_uncollected(module)
        code = command(args)
    except (Exception, KeyboardInterrupt) as err:
        if debug:
            if classify(err)[0] != EXIT_BAD_INPUT:
                raise
            traceback.print_exc()  # the traceback asked for, and bad input's own exit status below
        if console:
            hold_signals()  # a second Ctrl-C does not break the report
        code = _report(err, args)
    if console and mpi.launched_size() == 1:  # an MPI rank's teardown finalises MPI
        exit_process(code)
    return code


def _report(err: BaseException, args) -> int:
    """Print the one line of a failure (rank 0 for what every rank meets alike) and
    return its exit status; under MPI, end the job when one rank may have failed alone."""
    code, message = classify(err, None if args is None else args.command)
    comm = (
        mpi.world() if args is not None and args.command == "run" and not isinstance(err, mpi.MPIUnavailable) else None
    )  # one run over several MPI ranks
    # every rank refuses it, stops at one step, or finds too little memory, alike
    alike = code == EXIT_BAD_INPUT or isinstance(err, Interrupted) or getattr(err, "on_every_rank", False)
    # another command under mpiexec (a sweep's workers) refuses bad input on every rank too: rank 0 says it
    rank = comm.rank if comm is not None else mpi.launched_rank()
    if rank == 0 or not alike:
        where = f"rank {comm.rank} of {comm.size}: " if comm is not None and comm.rank else ""
        print(
            f"swe-sphere: {where}{'error: ' if code in (EXIT_BAD_INPUT, EXIT_INTERNAL) else ''}{message}",
            file=sys.stderr,
        )
    if comm is not None and comm.rank != 0 and not alike and code < 128:
        # perhaps this rank alone (a signal stops every rank at the same step): the others
        # cannot meet it again, so rank 0 closes its files and ends the job (mpi.watch_failures)
        sys.stderr.flush()
        mpi.report_failure(comm, code, f"{where}{message}")
    if comm is not None and comm.rank == 0 and not alike:
        # rank 0, the writer, may fail alone (its output): the others would wait for it
        # forever, so it ends the job, with its exit status, once its files are closed.
        # The process manager forwards stderr on its own time: aborting at once lost
        # the line now and then (exit 3, empty stderr), so give it a moment.
        sys.stderr.flush()
        time.sleep(0.5)
        comm.Abort(code)
    return code
