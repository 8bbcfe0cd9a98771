"""Assembly over the elements a process holds: DSS, unique-node vectors and global reductions.

The model, the steppers and the Krylov solvers reach the grid's connectivity
only through a ``Topology``: the direct stiffness summation (HOMME
``bndry_exchangeV`` with ``rspheremp`` scaling), ``assemble``/``scatter``
between element-local fields and vectors on unique nodes (what Krylov solvers
iterate on), and area integrals, norms and maxima.

Over MPI (``comm`` with several ranks) each rank holds a contiguous piece of
the elements' space-filling curve (``swe_sphere.partition``). A DSS is then
HOMME's ``edgeVpack`` → ``bndry_exchangeV`` → ``edgeVunpack``: the copies of
shared nodes that neighbouring ranks need are packed (``kernels.dss.pack``),
exchanged by persistent nonblocking point-to-point messages into a ghost
buffer, and the DSS kernel sums local and ghost copies in the grid's one
global order (``CubedSphere.dss_table``). Every copy is summed individually
(not a neighbour's partial sum), so the result has the same bits on any
number of ranks and explicit runs do too. A topology over the whole sphere
has no neighbours: no pack, no exchange, and its reductions are over its own
nodes, so the same model code runs on one process and on many.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from .kernels import dss
from .parallel import record

f64 = wp.float64
MAX_ROWS = 4  # most rows a DSS assembles at once (the hyperviscosity's Cartesian wind + h)


class SerialComm:
    """What a topology needs of an MPI communicator, for one process (no MPI needed)."""

    rank, size = 0, 1

    def allreduce(self, value, op=None):
        return value

    def allgather(self, value):
        return [value]


def _ops(comm):
    """(SUM, MAX, MIN) reduction operations of ``comm``."""
    if isinstance(comm, SerialComm):
        return None, None, None
    from mpi4py import MPI

    return MPI.SUM, MPI.MAX, MPI.MIN


class GridPart:
    """The elements of a ``CubedSphere`` one rank holds: ne, np, radius, rule, and
    the per-node arrays of ``NODE_ARRAYS`` for its nodes only (N = nelem·np²)."""

    NODE_ARRAYS = ("xyz", "lat", "lon", "east", "north", "D", "Dinv", "metdet", "spheremp", "rspheremp", "dx")

    def __init__(self, grid, elements, nodes):
        self.ne, self.np, self.radius, self.rule = grid.ne, grid.np, grid.radius, grid.rule
        self.nelem, self.npts = len(elements), len(nodes)
        for name in self.NODE_ARRAYS:
            setattr(self, name, getattr(grid, name)[..., nodes])


class _Exchange:
    """One exchange of packed copies with the neighbouring ranks (HOMME
    ``bndry_exchangeV``): nonblocking receives into the ghost buffer and sends
    from the pack buffer, all completed before ``launch()`` returns (run like a
    recorded launch)."""

    def __init__(self, topo, rows: int):
        send, ghost = topo.send_buffer.numpy(), topo.ghost.numpy()  # CPU: zero-copy views
        self.comm, self.tag = topo.comm, rows
        self.recvs = [(ghost[a * rows : b * rows], int(s)) for s, (a, b) in zip(topo.neighbours, topo.recv_ranges)]
        self.sends = [(send[a * rows : b * rows], int(s)) for s, (a, b) in zip(topo.neighbours, topo.send_ranges)]
        self.kernel = type("exchange", (), {"key": "exchange"})  # named like a launch in launch lists

    def launch(self) -> None:
        from mpi4py import MPI

        requests = [self.comm.Irecv(buf, source=s, tag=self.tag) for buf, s in self.recvs]
        requests += [self.comm.Isend(buf, dest=s, tag=self.tag) for buf, s in self.sends]
        MPI.Request.Waitall(requests)


class Topology:
    """The assembly of ``grid``'s elements on ``device``, for rank ``comm.rank`` of ``comm.size``.

    Parameters
    ----------
    grid : CubedSphere (the whole sphere)
    device : Warp device name.
    threads : CPU threads a launch is split over (``swe_sphere.parallel``).
    comm : an mpi4py communicator, or None (``SerialComm()``: all elements here).
        With several ranks, rank k holds chunk k of ``partition.partition``.

    Attributes (device arrays unless said)
    --------------------------------------
    elements (nelem_local,) numpy : the global element indices held, ascending
    nodes (N,) numpy : their element-local nodes' global indices
    N : element-local nodes held (int); nunique : unique nodes owned (int)
    npts_total : element-local nodes of the whole grid (int)
    spheremp (N,) rspheremp (N,) : element mass and inverse assembled mass (m², m⁻²)
    table (N, C) int32 : the copies of each node's unique node in the global
        summation order, −1-padded; c < N local, c ≥ N the ghost c − N
    gid (N,) int32 : each node's index in the unique-node vectors
    first (nunique,) int32 : one local copy of each owned unique node
    area (nunique,) numpy : assembled spheremp of the owned unique nodes (m²)
    total_area : Σ area over the sphere (m²; 4πa²)
    neighbours : ranks sharing nodes with this one; halo_copies, halo_bytes_per_row:
        copies received per DSS and their bytes per assembled row

    Raises ValueError on a CUDA device with more than one rank (CPU only so far).
    """

    def __init__(self, grid, device: str = "cpu", threads: int = 1, comm=None):
        self.grid, self.device, self.threads = grid, device, int(threads)
        self.comm = comm if comm is not None else SerialComm()
        self._sum, self._max, self._min = _ops(self.comm)
        rank, size = self.comm.rank, self.comm.size
        npe = grid.np**2
        if size == 1:  # skip the curve: one part in natural order is the whole grid
            parts = [np.arange(grid.nelem)]
        else:
            if not wp.get_device(device).is_cpu:
                raise ValueError("runs over several MPI ranks are CPU-only so far (use --device cpu)")
            from .partition import partition

            parts = [np.sort(p) for p in partition(grid, size)]
        self.parts = parts
        self.elements = parts[rank]
        self.nodes = (self.elements[:, None] * npe + np.arange(npe)).ravel()
        self.N, self.npts_total = self.nodes.size, grid.npts
        self._build_halo(parts, rank, size, npe)

        def up(a, dtype=f64):
            return wp.array(np.ascontiguousarray(a), dtype=dtype, device=device)

        self.spheremp_np = grid.spheremp[self.nodes]
        self.spheremp = up(np.concatenate([self.spheremp_np, grid.spheremp[self.recv]]))
        self.rspheremp = up(grid.rspheremp[self.nodes])
        self.table = up(self._table, wp.int32)
        self.gid, self.first = up(self._gid, wp.int32), up(self._first, wp.int32)
        self.nunique = self._first.size
        self.complete = self.max(float(np.any(self._gid < 0))) == 0.0  # on every rank, every node's unique value is held
        self.total_area = self.sum(float(np.sum(self.area)))
        self.send_index = up(self._send_index, wp.int32)
        self.send_buffer = wp.zeros(max(1, self._send_index.size) * MAX_ROWS, dtype=f64, device=device)
        self.ghost = wp.zeros(max(1, self.recv.size) * MAX_ROWS, dtype=f64, device=device)
        self.halo_copies = int(self.recv.size)
        self.halo_bytes_per_row = 8 * self.halo_copies
        self._exchanges: dict[int, _Exchange] = {}

    def _build_halo(self, parts, rank, size, npe):
        """Local tables: which copies each neighbour sends and receives, in global
        order, and the DSS table in local/ghost indices."""
        grid = self.grid
        gid, nodes = grid.gid, self.nodes
        elem_rank = np.empty(grid.nelem, dtype=np.int64)
        for k, p in enumerate(parts):
            elem_rank[p] = k
        copy_rank = np.repeat(elem_rank, npe)
        loc = np.full(grid.npts, -1, dtype=np.int64)
        loc[nodes] = np.arange(nodes.size)
        touched = np.unique(gid.astype(np.int64) * size + copy_rank)  # (unique node, rank) pairs
        t_node, t_rank = np.divmod(touched, size)
        mine = np.zeros(grid.nunique, dtype=bool)
        mine[gid[nodes]] = True
        self.neighbours = np.unique(t_rank[mine[t_node] & (t_rank != rank)])
        recv, send, self.recv_ranges, self.send_ranges = [], [], [], []
        for s in self.neighbours:
            shared = np.zeros(grid.nunique, dtype=bool)
            shared[t_node[t_rank == s]] = True
            shared &= mine
            r = np.flatnonzero((copy_rank == s) & shared[gid])  # ascending: the global order
            m = nodes[shared[gid[nodes]]]
            self.recv_ranges.append((sum(map(len, recv)), sum(map(len, recv)) + r.size))
            self.send_ranges.append((sum(map(len, send)), sum(map(len, send)) + m.size))
            recv.append(r)
            send.append(m)
        self.recv = np.concatenate(recv) if recv else np.zeros(0, dtype=np.int64)
        self._send_index = loc[np.concatenate(send)] if send else np.zeros(0, dtype=np.int64)
        index = loc.copy()
        index[self.recv] = nodes.size + np.arange(self.recv.size)
        rows = grid.dss_table[nodes]
        self._table = np.where(rows >= 0, index[np.maximum(rows, 0)], -1)
        if np.any((rows >= 0) & (self._table < 0)):
            raise RuntimeError("a copy of a shared node is neither local nor received")
        owner = copy_rank[grid.first]  # a unique node belongs to the rank of its first copy
        owned = np.flatnonzero(owner == rank)
        self._first = loc[grid.first[owned]]
        self.area = grid.area[owned]
        unique_index = np.full(grid.nunique, -1, dtype=np.int64)
        unique_index[owned] = np.arange(owned.size)
        self._gid = unique_index[gid[nodes]]  # −1: owned elsewhere (no halo of unique nodes yet)

    def _record(self, kernel, dim, inputs):
        return record(kernel, dim, inputs, device=self.device, threads=self.threads, block=self.grid.np**2)

    def _exchange(self, x: wp.array2d) -> list:
        """Launches that fill the ghost buffer with the neighbours' copies of x's rows
        (pack, then exchange); none without neighbours."""
        if not len(self.neighbours):
            return []
        rows = x.shape[0]
        if rows > MAX_ROWS:
            raise ValueError(f"a DSS over more than {MAX_ROWS} rows (got {rows})")
        exchange = self._exchanges.get(rows)
        if exchange is None:
            exchange = self._exchanges[rows] = _Exchange(self, rows)
        return [self._record(dss.pack, self._send_index.size, [x, rows, self.send_index, self.send_buffer]), exchange]

    # -- assembly (recorded launch lists: run each item's ``launch()`` in order) --
    def dss(self, x: wp.array2d, weighted: bool, out: wp.array2d) -> list:
        """Launches for out = DSS(x), (rows, N) each: out[r, p] = rspheremp[p] ·
        Σ over the copies c of p's node of (spheremp[c] if ``weighted`` else 1)·x[r, c]
        (``kernels.dss.dss_rows``), the neighbours' copies exchanged first.
        Weighted for a strong-form field (continuous result, integral kept),
        unweighted for a weak form. ``out`` must not alias ``x``."""
        ghosts = bool(len(self.neighbours))
        kernel = dss.dss_rows(x.shape[0], bool(weighted), self.table.shape[1], ghosts)
        args = [x, self.ghost, self.N, self.spheremp, self.rspheremp, self.table, out]
        return [*self._exchange(x), self._record(kernel, self.N, args)]

    def _unique_vectors(self):
        if not self.complete:
            raise NotImplementedError("unique-node vectors (implicit and semi-implicit steppers) run on one MPI rank only so far")

    def assemble(self, x: wp.array2d, row: int, out: wp.array) -> list:
        """Launches for the unique-node out (nunique,) = M x[row]: Σ over the copies
        of spheremp·x[row] (assembled mass times a continuous field, m² × units of x)."""
        self._unique_vectors()
        return [self._record(dss.assemble, self.nunique, [x, row, self.spheremp, self.table, self.first, out])]

    def scatter(self, y: wp.array, out: wp.array2d, row: int) -> list:
        """Launches for the element-local out[row] (N,) = y[gid] from a unique-node vector."""
        self._unique_vectors()
        return [self._record(dss.scatter, self.N, [y, self.gid, row, out])]

    # -- between the whole grid and this rank's part (numpy) ------------------------
    def local_grid(self):
        """The grid of this rank's elements (``GridPart``; the grid itself when whole)."""
        return self.grid if self.N == self.npts_total else GridPart(self.grid, self.elements, self.nodes)

    def local(self, f: np.ndarray) -> np.ndarray:
        """This rank's part (..., N) of a whole-grid element-local field (..., npts_total)."""
        return f[..., self.nodes] if self.N != self.npts_total else f

    def gather(self, a: np.ndarray) -> np.ndarray:
        """The whole-grid field (..., npts_total) from every rank's part (..., N), on every rank."""
        if self.N == self.npts_total:
            return a
        npe = self.grid.np**2
        out = np.empty(a.shape[:-1] + (self.npts_total,), dtype=a.dtype)
        for elements, part in zip(self.parts, self.comm.allgather(a)):
            out[..., (elements[:, None] * npe + np.arange(npe)).ravel()] = part
        return out

    def first_node(self, local: int | None) -> int | None:
        """The smallest whole-grid node index over all ranks of a local node index
        (None: none here); None if no rank has one."""
        g = int(self.nodes[local]) if local is not None else self.npts_total
        g = int(self.comm.allreduce(g, self._min))
        return None if g == self.npts_total else g

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
