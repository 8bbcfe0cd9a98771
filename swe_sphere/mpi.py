"""Whether this process was started by ``mpiexec``, and its MPI world.

mpi4py is imported (and MPI initialised) only in a process that a process
manager started as one of several ranks, so a plain ``swe-sphere`` command
never needs MPI. Hydra (MPICH, Intel MPI), Open MPI and Slurm announce the
job size in the environment before ``MPI_Init``.
"""

from __future__ import annotations

import os

_SIZE_VARIABLES = ("PMI_SIZE", "OMPI_COMM_WORLD_SIZE", "PMIX_SIZE", "SLURM_NTASKS")


def launched_size() -> int:
    """The number of ranks the process manager started (1 outside ``mpiexec``)."""
    for name in _SIZE_VARIABLES:
        value = os.environ.get(name, "").strip()
        if value.isdigit():
            return int(value)
    return 1


def world():
    """``mpi4py``'s COMM_WORLD under ``mpiexec`` with more than one rank, else None.
    Raises RuntimeError (one line) when mpi4py cannot be imported there."""
    if launched_size() <= 1:
        return None
    try:
        from mpi4py import MPI
    except ImportError as err:
        raise RuntimeError(f"started by mpiexec but mpi4py is not importable ({err}); pip install mpich mpi4py") from None
    return MPI.COMM_WORLD


def node_local_size(comm) -> int:
    """Ranks of ``comm`` on this node (MPI shared-memory split)."""
    from mpi4py import MPI

    local = comm.Split_type(MPI.COMM_TYPE_SHARED)
    try:
        return local.Get_size()
    finally:
        local.Free()
