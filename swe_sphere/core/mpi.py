"""Whether this process was started by ``mpiexec``, and its MPI world.

mpi4py is imported (and MPI initialised) only in a process that a process
manager started as one of several ranks, so a plain ``swe-sphere`` command
never needs MPI. Hydra (MPICH, Intel MPI), Open MPI and Slurm announce the
job size in the environment before ``MPI_Init``.
"""

from __future__ import annotations

import contextlib
import os
import sys
import threading
import time

from .errors import MPIUnavailable

_SIZE_VARIABLES = ("PMI_SIZE", "OMPI_COMM_WORLD_SIZE", "PMIX_SIZE", "SLURM_NTASKS")
_RANK_VARIABLES = ("PMI_RANK", "OMPI_COMM_WORLD_RANK", "PMIX_RANK", "SLURM_PROCID")


def launched_size() -> int:
    """The number of ranks the process manager started (1 outside ``mpiexec``)."""
    for name in _SIZE_VARIABLES:
        value = os.environ.get(name, "").strip()
        if value.isdigit():
            return int(value)
    return 1


def launched_rank() -> int:
    """This process's rank as the process manager announced it (0 outside ``mpiexec``), known
    without initialising MPI."""
    if launched_size() <= 1:
        return 0
    for name in _RANK_VARIABLES:
        value = os.environ.get(name, "").strip()
        if value.isdigit():
            return int(value)
    return 0


def world():
    """``mpi4py``'s COMM_WORLD under ``mpiexec`` with more than one rank, else None.
    Raises ``MPIUnavailable`` (one line) when mpi4py cannot be imported there."""
    if launched_size() <= 1:
        return None
    try:
        from mpi4py import MPI
    except ImportError as err:
        raise MPIUnavailable(
            f"started by mpiexec as one of {launched_size()} ranks, but mpi4py cannot be imported ({err}): "
            "pip install 'swe-sphere[mpi]' (mpich and mpi4py)"
        ) from None
    return MPI.COMM_WORLD


@contextlib.contextmanager
def _node(comm):
    """The ranks of ``comm`` on this node as a communicator of their own (an MPI shared-memory
    split, collective, ordered as in ``comm``), freed after."""
    from mpi4py import MPI

    local = comm.Split_type(MPI.COMM_TYPE_SHARED)
    try:
        yield local
    finally:
        local.Free()


def node_rank(comm) -> tuple[int, int]:
    """(this rank's place among the ranks of ``comm`` on its node, their number): an MPI
    shared-memory split (collective), ordered as in ``comm``."""
    with _node(comm) as local:
        return local.Get_rank(), local.Get_size()


def node_local_size(comm) -> int:
    """Ranks of ``comm`` on this node (``node_rank``)."""
    return node_rank(comm)[1]


def node_peers(comm, key) -> int:
    """Ranks of ``comm`` on this node, this one included, whose ``key`` (any picklable value:
    their device) equals this rank's (collective)."""
    with _node(comm) as local:
        return local.allgather(key).count(key)


def processor_name() -> str:
    """The node this rank runs on, as MPI names it (for messages)."""
    from mpi4py import MPI

    return MPI.Get_processor_name()


# A failure on one rank alone: the others would wait for it in their next collective
# forever, and that rank cannot rejoin them (they may be anywhere inside a step). It
# reports to rank 0 on this tag (above the halo exchanges' tags, below MPI's 32767
# minimum TAG_UB); rank 0, the writer, closes its files with what they hold and ends the
# job. The failing rank ends the job itself should rank 0 not answer.
FAILURE_TAG = 32000
FAILURE_GRACE_S = 60.0  # rank 0 may be finishing a large restart file first


def report_failure(comm, code: int, message: str) -> None:
    """On a rank > 0 that failed alone: tell rank 0 (``watch_failures``) and wait for
    it to end the job with ``MPI_Abort(code)``; abort it from here after ``FAILURE_GRACE_S``."""
    comm.send((code, message), dest=0, tag=FAILURE_TAG)  # a few bytes: sent eagerly, returns at once
    time.sleep(FAILURE_GRACE_S)  # sleeping, not in an MPI wait (which spins on a core)
    comm.Abort(code)


class watch_failures:
    """``with watch_failures(comm, finish):`` on rank 0, a thread listens for
    ``report_failure``; on a report it calls ``finish(message)`` (closing the open
    files with every completed output time) and ends the job with ``MPI_Abort`` and
    the failing rank's status. Needs ``MPI_THREAD_MULTIPLE`` (mpi4py's default).
    Does nothing on other ranks (or with ``comm`` None)."""

    POLL_S = 0.1  # test for a report this often: a blocking receive would spin a core

    def __init__(self, comm, finish):
        self.comm, self.finish = comm, finish
        self.active = comm is not None and comm.rank == 0
        if self.active:  # without threads, the failing rank ends the job after FAILURE_GRACE_S
            from mpi4py import MPI

            self.active = MPI.Query_thread() == MPI.THREAD_MULTIPLE

    def __enter__(self):
        if self.active:
            self.stop = threading.Event()
            self.thread = threading.Thread(target=self._listen, name="swe-sphere-failures", daemon=True)
            self.thread.start()
        return self

    def _listen(self) -> None:
        from mpi4py import MPI

        request = self.comm.irecv(source=MPI.ANY_SOURCE, tag=FAILURE_TAG)
        while True:
            done, report = request.test()
            if done:
                break
            if self.stop.wait(self.POLL_S):
                request.Cancel()
                request.Wait()
                return
        code, message = report
        try:
            self.finish(message)
        finally:
            sys.stderr.flush()
            time.sleep(0.5)  # the failing rank's line is still on its way through the process manager
            self.comm.Abort(code)

    def __exit__(self, *exc):
        if self.active:
            self.stop.set()
            self.thread.join()


class RankMax:
    """Ranks as ``core.interrupts.StopSignals`` asks of a run's topology: their communicator
    ``comm`` and the largest of a value over them (``max``, collective); an ensemble's, whose
    members' ranks share no topology."""

    def __init__(self, comm):
        self.comm = comm

    def max(self, value):
        return max(self.comm.allgather(value))


def from_root(comm, make, refused: type[BaseException] = Exception):
    """``make()`` on rank 0 of ``comm`` (None: this process alone), what it raises of ``refused``
    raised on every rank (else the others would wait for rank 0 forever): its value on rank 0,
    None on the others (collective)."""
    value = error = None
    if comm is None or comm.rank == 0:
        try:
            value = make()
        except refused as err:
            error = err
    error = error if comm is None else comm.bcast(error, root=0)
    if error is not None:
        raise error
    return value
