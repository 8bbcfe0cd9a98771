"""Sums, maxima, integrals and inner products over the ranks a run is split over, with the
same bits on every rank and any rank count where the grid's order allows (``sums``: gathered
and added in rank order, not MPI's reduction tree). ``RankReductions`` is the part of a
``topology.Topology`` that reads only its communicator, grid, backend and total area;
``SerialComm`` stands in for a communicator of one process (no MPI needed)."""

from __future__ import annotations

import numpy as np
import warp as wp

from ..kernels import blas

f64 = wp.float64


class SerialComm:
    """What a topology needs of an MPI communicator, for one process (no MPI needed)."""

    rank, size = 0, 1

    def allreduce(self, value, op=None):
        return value

    def bcast(self, value, root=0):
        return value


def reduction_ops(comm):
    """(SUM, MAX, MIN) reduction operations of ``comm``."""
    if isinstance(comm, SerialComm):
        return None, None, None
    from mpi4py import MPI

    return MPI.SUM, MPI.MAX, MPI.MIN


class RankReductions:
    """Global reductions of a ``Topology`` (numpy in, Python float out, unless said): they read
    its ``comm``, its reduction operations ``_sum``/``_max`` (``reduction_ops``), ``distributed``,
    ``grid`` (spheremp), ``total_area``, ``backend`` and ``device``."""

    def sum(self, value: float) -> float:
        """Σ of a per-process value over all processes (as ``sums``)."""
        return float(self.sums(np.float64(value)))

    def max(self, value: float) -> float:
        """Maximum of a per-process value over all processes."""
        return float(self.comm.allreduce(value, self._max))

    def integrate(self, f: np.ndarray) -> float:
        """Area integral ∫ f dA (m² × units of f) of a continuous element-local field f (N,)
        (HOMME ``global_integral``)."""
        return self.sum(float(np.sum(self.grid.spheremp * f)))  # not np.dot: the same bits whatever BLAS's threads

    def mean(self, f: np.ndarray) -> float:
        """Area mean of a continuous element-local field f (N,)."""
        return self.integrate(f) / self.total_area

    def sums(self, values: np.ndarray) -> np.ndarray:
        """Elementwise Σ of a per-process numpy array over all processes: gathered
        and added in rank order, so every rank gets the same bits whatever MPI's
        reduction algorithm (a Krylov solver's ranks must take the same branches)."""
        values = np.array(values, dtype=np.float64)  # C-contiguous, 0-d stays 0-d
        if self._sum is None:  # one process
            return values
        parts = np.empty((self.comm.size, *values.shape))
        self.comm.Allgather(values, parts)
        total = parts[0].copy()
        for part in parts[1:]:
            total += part
        return total

    def device_sums(self, partial: wp.array2d, rows: int, out: wp.array) -> list:
        """Recorded launches that put the totals of the first ``rows`` rows of per-chunk
        partial sums into the float64 device array ``out`` (rows,), added in index order
        on the device (``blas.row_totals``, one thread): no host read. Where the backend
        says so (``Backend.direct_totals``: CUDA, long rows) they are first added in chunks of
        about √n (``blas.chunk_sums``), so that the one thread adds ≈ 2√n values. The totals are
        this process's: ``allreduce`` adds them over ranks."""
        n, src, launches = partial.shape[1], partial[:rows], []
        if not self.backend.direct_totals(n):
            chunk = int(np.ceil(np.sqrt(n)))
            mid = wp.zeros((rows, (n + chunk - 1) // chunk), dtype=f64, device=self.device)
            launches.append(
                wp.launch(blas.chunk_sums, mid.shape, [src, chunk, mid], device=self.device, record_cmd=True)
            )
            src = mid
        launches.append(wp.launch(blas.row_totals, 1, [src, out], device=self.device, record_cmd=True))
        return launches

    def allreduce(self, out: wp.array) -> None:
        """The float64 device array ``out`` of this process's totals (``device_sums``)
        summed over all ranks in place (``sums``: rank order, the same bits on every
        rank): one host read and write with several ranks; nothing with one, where the
        totals stay on the device."""
        if self.distributed:
            out.assign(self.sums(out.numpy()))

    def dot(self, a, b) -> float:
        """Σ a·b of two arrays of one shape (device or numpy) over all processes
        (element-local arrays count every copy; unique-node vectors each owned
        node once): the inner product a Krylov solver over the topology's vectors needs."""
        if isinstance(a, np.ndarray):
            local = float(a.ravel().dot(b.ravel()))
        else:
            local = self.backend.inner(a, b)
        return self.sum(local)

    def norm(self, a) -> float:
        """Euclidean norm of a device array over all processes (as ``dot``)."""
        return float(np.sqrt(self.dot(a, a)))
