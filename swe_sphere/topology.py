"""Assembly over the elements a process holds: DSS, unique-node vectors and global reductions.

The model, the steppers and the Krylov solvers reach the grid's connectivity
only through a ``Topology``: the direct stiffness summation (HOMME
``bndry_exchangeV`` with ``rspheremp`` scaling), ``assemble``/``scatter``
between element-local fields and vectors on unique nodes (what Krylov solvers
iterate on), and area integrals, norms and maxima. The exchange with other
processes is a step of its own in the recorded launch lists (HOMME's
``edgeVpack`` → ``bndry_exchangeV`` → ``edgeVunpack``); a topology over the
whole sphere has nothing to exchange and its reductions are over its own
nodes, so the same model code runs on one process and on many.

Sums over the copies of a node are taken in one fixed global order (that of
the grid's ``dss_table``), so a DSS gives the same bits whatever holds the
copies.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from .kernels import dss
from .parallel import record

f64 = wp.float64


class SerialComm:
    """The reductions of an MPI communicator for one process (no MPI needed)."""

    rank, size = 0, 1

    def allreduce(self, value, op=None):
        return value


SUM, MAX = "sum", "max"  # reduction names (mpi4py's MPI.SUM / MPI.MAX where MPI runs)


class Topology:
    """The assembly of ``grid``'s elements on ``device``.

    Parameters
    ----------
    grid : CubedSphere
    device : Warp device name.
    threads : CPU threads a launch is split over (``swe_sphere.parallel``).
    comm : what global reductions go through (``allreduce(value, op)``);
        ``SerialComm()`` by default.

    Attributes (device arrays unless said)
    --------------------------------------
    N : element-local nodes held (int); nunique : unique nodes owned (int)
    npts_total : element-local nodes of the whole grid (int)
    spheremp, rspheremp (N,) : element mass and inverse assembled mass (m², m⁻²)
    table (N, C) int32 : the element-local copies of each node's unique node,
        in the global summation order, −1-padded (``CubedSphere.dss_table``)
    gid (N,) int32 : each node's index in the unique-node vectors
    first (nunique,) int32 : one element-local copy of each owned unique node
    area (nunique,) numpy : assembled spheremp of the owned unique nodes (m²)
    total_area : Σ area over the sphere (m²; 4πa²)
    """

    def __init__(self, grid, device: str = "cpu", threads: int = 1, comm=None):
        self.grid, self.device, self.threads = grid, device, int(threads)
        self.comm = comm if comm is not None else SerialComm()
        self._sum, self._max = SUM, MAX
        self.N, self.nunique = grid.npts, grid.nunique

        def up(a, dtype=f64):
            return wp.array(np.ascontiguousarray(a), dtype=dtype, device=device)

        self.spheremp_np = grid.spheremp
        self.spheremp, self.rspheremp = up(grid.spheremp), up(grid.rspheremp)
        self.table = up(grid.dss_table, wp.int32)
        self.gid, self.first = up(grid.gid, wp.int32), up(grid.first, wp.int32)
        self.area = grid.area
        self.total_area = self.sum(float(np.sum(self.area)))
        self.npts_total = int(self.sum(self.N))

    def _record(self, kernel, dim, inputs):
        return record(kernel, dim, inputs, device=self.device, threads=self.threads, block=self.grid.np**2)

    # -- assembly (recorded launch lists: run each item's ``launch()`` in order) --
    def dss(self, x: wp.array2d, weighted: bool, out: wp.array2d) -> list:
        """Launches for out = DSS(x), (rows, N) each: out[r, p] = rspheremp[p] ·
        Σ over the copies c of p's node of (spheremp[c] if ``weighted`` else 1)·x[r, c]
        (``kernels.dss.dss_rows``). Weighted for a strong-form field (continuous
        result, integral kept), unweighted for a weak form. ``out`` must not alias ``x``."""
        kernel = dss.dss_rows(x.shape[0], bool(weighted), self.table.shape[1])
        return [self._record(kernel, self.N, [x, self.spheremp, self.rspheremp, self.table, out])]

    def assemble(self, x: wp.array2d, row: int, out: wp.array) -> list:
        """Launches for the unique-node out (nunique,) = M x[row]: Σ over the copies
        of spheremp·x[row] (assembled mass times a continuous field, m² × units of x)."""
        return [self._record(dss.assemble, self.nunique, [x, row, self.spheremp, self.table, self.first, out])]

    def scatter(self, y: wp.array, out: wp.array2d, row: int) -> list:
        """Launches for the element-local out[row] (N,) = y[gid] from a unique-node vector."""
        return [self._record(dss.scatter, self.N, [y, self.gid, row, out])]

    # -- global reductions (numpy in, Python float out) ------------------------------
    def sum(self, value: float) -> float:
        """Σ of a per-process value over all processes."""
        return float(self.comm.allreduce(value, self._sum))

    def max(self, value: float) -> float:
        """Maximum of a per-process value over all processes."""
        return float(self.comm.allreduce(value, self._max))

    def integrate(self, f: np.ndarray) -> float:
        """Area integral ∫ f dA (m² × units of f) of a continuous element-local field f (N,)
        (HOMME ``global_integral``)."""
        return self.sum(float(np.sum(self.spheremp_np * f)))  # not np.dot: the same bits whatever BLAS's threads

    def mean(self, f: np.ndarray) -> float:
        """Area mean of a continuous element-local field f (N,)."""
        return self.integrate(f) / self.total_area

    def dot(self, a: wp.array, b: wp.array) -> float:
        """Σ a·b of two device arrays of one shape over all processes (element-local
        arrays count every copy; unique-node vectors each owned node once): the
        inner product a Krylov solver over the topology's vectors needs."""
        if wp.get_device(self.device).is_cpu:
            local = float(a.numpy().ravel().dot(b.numpy().ravel()))  # as np.linalg.norm
        else:
            local = float(wp.utils.array_inner(a.flatten(), b.flatten()))
        return self.sum(local)

    def norm(self, a: wp.array) -> float:
        """Euclidean norm of a device array over all processes (as ``dot``)."""
        return float(np.sqrt(self.dot(a, a)))
