"""Independent runs spread over processes (``sweep`` and ``stability --workers``).

``executor(workers)`` yields a ``concurrent.futures`` executor:

* under ``mpiexec -n N`` (N > 1): mpi4py's ``MPICommExecutor`` over
  COMM_WORLD, rank 0 handing runs to the N − 1 others (one node or many);
  on those other ranks it yields None once rank 0 is done, and the caller
  just returns;
* else with ``workers`` > 1: a local process pool (spawned processes: Warp
  and its CPU thread pools are not fork-safe);
* else ``InProcess()``: each run in this process when submitted.

Each worker's CPU threads (``SWE_SPHERE_THREADS`` and BLAS) are set to the
node's CPUs divided among the workers on the node, so that concurrent runs
do not oversubscribe the cores; a ``SWE_SPHERE_THREADS`` set by the user wins.
A pool's workers start Warp quietly (``runtime.init_warp``: no banner, no
module-load lines) and ignore SIGINT (a Ctrl-C reaches the whole process
group): the main process answers it. When an error or a signal leaves
``executor``'s block, the workers are sent SIGTERM, which ends a worker's run
after its step (``Simulation.run``) or, outside the time loop, at once, and
every task still queued as it starts; the block then ends when they have, their
unfinished runs written nowhere (the caller cancels what it can).
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import signal
from concurrent.futures import Future, ProcessPoolExecutor

from . import mpi
from .errors import Interrupted
from .runtime import init_warp


def cpus() -> int:
    """CPUs this process may run on."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:
        return max(1, os.cpu_count() or 1)


def limit_threads(threads: int) -> None:
    """Use ``threads`` CPU threads in this process (unless SWE_SPHERE_THREADS is set)."""
    # threadpoolctl limits only the BLAS libraries already loaded: numpy's and scipy's
    # own OpenBLAS load on import, and a spawned worker has imported neither yet (it
    # then ran the Helmholtz CG's inner products on every core, spinning under load)
    import numpy  # noqa: F401
    import scipy.linalg  # noqa: F401
    from threadpoolctl import threadpool_limits

    os.environ.setdefault("SWE_SPHERE_THREADS", str(threads))
    threadpool_limits(int(os.environ["SWE_SPHERE_THREADS"]))


_BUSY = [False]  # a worker: whether it is running a task
_STOPPING = [False]  # a worker: SIGTERM came; the tasks still queued end at once


def _on_sigterm(signum, frame):
    _STOPPING[0] = True
    if _BUSY[0]:  # idle, the worker waits for its next task or the pool's end
        raise KeyboardInterrupt


def _task(fn, /, *args, **kwargs):
    """``fn(*args, **kwargs)`` in a pool worker, ended by SIGTERM (``_on_sigterm``;
    in a time loop, ``Simulation.run``'s own handler, after the step), as is
    every task after it."""
    if _STOPPING[0]:
        raise KeyboardInterrupt
    _BUSY[0] = True
    try:
        return fn(*args, **kwargs)
    except (KeyboardInterrupt, Interrupted):
        _STOPPING[0] = True
        raise
    finally:
        _BUSY[0] = False


def start_worker(threads: int) -> None:
    """A pool worker's start: SIGINT left to the main process, SIGTERM ending its
    tasks (``_task``), ``threads`` CPU threads (``limit_threads``), Warp initialised quietly."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, _on_sigterm)
    limit_threads(threads)
    init_warp()


class _Pool(ProcessPoolExecutor):
    """A process pool whose tasks end on SIGTERM (``_task``)."""

    def submit(self, fn, /, *args, **kwargs):
        return super().submit(_task, fn, *args, **kwargs)


@contextlib.contextmanager
def executor(workers: int = 1):
    """The executor for independent runs (see the module docstring); ValueError for workers < 1."""
    if workers < 1:
        raise ValueError(f"--workers must be >= 1 (got {workers})")
    comm = mpi.world()
    if comm is not None:
        from mpi4py.futures import MPICommExecutor

        limit_threads(max(1, cpus() // mpi.node_local_size(comm)))
        with MPICommExecutor(comm, root=0) as pool:
            yield pool
        return
    if workers == 1:
        yield InProcess()
        return
    threads = max(1, cpus() // workers)
    before = set(multiprocessing.active_children())
    with _Pool(
        workers, mp_context=multiprocessing.get_context("spawn"), initializer=start_worker, initargs=(threads,)
    ) as pool:
        try:
            yield pool
        except BaseException:  # end the runs under way and those queued, not wait for them
            for worker in set(multiprocessing.active_children()) - before:  # this pool's
                worker.terminate()
            raise


class InProcess:
    """An executor that runs ``fn`` here and now when submitted (its exceptions
    propagate at once) and hands back its result as a done Future."""

    def submit(self, fn, /, *args, **kwargs) -> Future:
        future: Future = Future()
        future.set_result(fn(*args, **kwargs))
        return future
