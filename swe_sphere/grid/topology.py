"""Assembly over the elements a process holds: DSS, unique-node vectors and global reductions.

The model, the steppers and the Krylov solvers reach the grid's connectivity
only through a ``Topology``: the direct stiffness summation (HOMME
``bndry_exchangeV`` with ``rspheremp`` scaling), ``assemble``/``scatter``
between element-local fields and vectors on unique nodes (what Krylov solvers
iterate on), and area integrals, norms and maxima (``reductions.RankReductions``).

Over MPI (``comm`` with several ranks) each rank holds a contiguous piece of
the elements' space-filling curve (``swe_sphere.grid.partition``). A DSS is then
HOMME's ``edgeVpack`` → ``bndry_exchangeV`` → ``edgeVunpack``: the copies of
shared nodes that neighbouring ranks need are packed (``kernels.dss.pack``),
exchanged by nonblocking point-to-point messages into a ghost buffer
(through host memory on any device: ``grid.halo``), and the DSS kernel sums local and ghost copies in the grid's one
global order (``CubedSphere.dss_table``). Every copy is summed individually
(not a neighbour's partial sum), so the result has the same bits on any
number of ranks and explicit runs do too. A topology over the whole sphere
has no neighbours: no pack, no exchange, and its reductions are over its own
nodes, so the same model code runs on one process and on many.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from ..core.backend import Backend
from ..core.errors import ArgumentError
from ..core.parallel import record
from ..kernels import dss
from ..kernels.operators import row_vectors
from .cubed_sphere import CubedSphere
from .halo import MAX_ROWS, Exchange, Halo
from .partition import level_chunks, mesh_order, mesh_partition, partition, sfc_order
from .reductions import RankReductions, SerialComm, reduction_ops

f64 = wp.float64


class GatheredGrid:
    """The whole grid as rank 0 diagnoses and writes it, gathered from the ranks'
    parts rather than built (no metric, no DSS tables): ne, np, radius, rule, mesh,
    nelem (= nelem_total), nnodes, nunique; lat, lon, spheremp, dx (nnodes,) and gid (nnodes,) int32;
    first (nunique,) int32 and area (nunique,); ``integrate``, ``to_unique``, ``map`` and
    ``reference_to_sphere`` as ``CubedSphere``'s, whose values these are, bit for bit."""

    nunique = CubedSphere.nunique
    integrate = CubedSphere.integrate
    to_unique = CubedSphere.to_unique
    map = CubedSphere.map
    reference_to_sphere = CubedSphere.reference_to_sphere

    def __init__(self, part, fields: np.ndarray, first: np.ndarray, area: np.ndarray):
        self.ne, self.np, self.radius, self.rule, self.mesh = part.ne, part.np, part.radius, part.rule, part.mesh
        self.nelem = self.nelem_total = part.nelem_total
        self.nnodes = fields.shape[1]
        self.lat, self.lon, self.spheremp, self.dx = fields[:4]
        self.gid = fields[4].astype(np.int32)
        self.first, self.area = first.astype(np.int32), area


def rank_parts(ne: int, size: int, mesh=None, level: np.ndarray | None = None) -> list[np.ndarray]:
    """The elements of each of ``size`` ranks, ascending: all of them on one rank,
    else the chunks of ``partition.partition`` (the cube's for ne ≥ 1, else of ``mesh``'s
    elements along the curve through their centroids, ``partition.mesh_partition``); with
    ``level`` (one int an element), each rank's share of every level along that curve
    (``partition.level_chunks``: local time stepping's levels)."""
    if size == 1:  # skip the curve: one part in natural order is the whole grid
        return [np.arange(6 * ne * ne if ne else mesh.nelem)]
    if level is not None:
        return [np.sort(p) for p in level_chunks(sfc_order(ne) if ne else mesh_order(mesh), np.asarray(level), size)]
    return [np.sort(p) for p in (partition(ne, size) if ne else mesh_partition(mesh, size))]


def on_ranks(
    ne: int,
    np_: int,
    radius: float,
    comm,
    backend: Backend,
    mesh=None,
    level=None,
    rows: int = MAX_ROWS,
    threads: int | None = None,
) -> Topology:
    """This rank's ``Topology`` of the grid (``ne``, ``np_``, ``radius`` m; ``mesh`` a ``Mesh``
    where ``ne`` is 0) split over ``comm``'s ranks (None: one process) by ``rank_parts``
    (``level``: an element's level, as there): its part of the elements as a ``CubedSphere``,
    assembled with the others' (HOMME's ``prim_init1`` decomposition); ``rows`` the most rows an
    exchange carries (``Topology``'s); ``threads`` its CPU threads (None: ``Backend.threads``)."""
    size, rank = (1, 0) if comm is None else (comm.size, comm.rank)
    parts = rank_parts(ne, size, mesh, level)
    local = CubedSphere(ne, np_, radius, elements=parts[rank], mesh=mesh)  # this rank's only
    threads = backend.threads() if threads is None else threads
    return Topology(local, backend, threads, comm, parts=parts, rows=rows)


def _lookup(keys: np.ndarray, values: np.ndarray) -> np.ndarray:
    """The position in ``keys`` (distinct, not empty) of each of ``values``, −1 where absent."""
    order = np.argsort(keys)
    at = np.minimum(np.searchsorted(keys[order], values), keys.size - 1)
    return np.where(keys[order][at] == values, order[at], -1)


class Topology(RankReductions):
    """The assembly of ``grid``'s elements on ``device``, for rank ``comm.rank`` of ``comm.size``.

    Parameters
    ----------
    grid : CubedSphere: the whole sphere, or this rank's part of it
        (``CubedSphere(..., elements=rank_parts(ne, size)[rank])``); given the
        whole sphere with several ranks, the rank builds its own part.
    device : the run's ``core.backend.Backend``, or a Warp device name (looked up once).
    threads : CPU threads a launch is split over (``swe_sphere.core.parallel``).
    comm : an mpi4py communicator, or None (``SerialComm()``: all elements here).
        With several ranks, rank k holds chunk k of ``partition.partition``.
    parts : ``rank_parts(grid.ne, comm.size, grid.mesh)`` when the caller has it already.
    rows : the most rows an exchange with the neighbours carries (at least ``halo.MAX_ROWS``, the
        ∇⁴'s four; a state's 3 + K with K passive tracers): its halo buffers' size.

    Unique-node vectors (what the Krylov solvers iterate on) are distributed:
    a unique node belongs to the rank of its first copy in the grid's order,
    each rank's vectors hold its own nodes (``nunique``), ``dot``/``norm`` sum
    over ranks, and ``scatter`` receives the values of the nodes its elements
    touch from their owners (a second halo, owner → touching ranks).

    Attributes (device arrays unless said)
    --------------------------------------
    elements (nelem_local,) numpy : the global element indices held, ascending
    nodes (N,) numpy : their element-local nodes' global indices
    N : element-local nodes held (int); nunique : unique nodes owned (int)
    nnodes_total : element-local nodes of the whole grid (int)
    distributed : whether the elements are spread over several ranks (bool)
    spheremp (N + ghosts,) rspheremp (N,) : element mass (local copies, then
        the DSS ghosts) and inverse assembled mass (m², m⁻²)
    table (N, C) int32 : the copies of each node's unique node in the global
        summation order, −1-padded; c < N local, c ≥ N the ghost c − N
    gid (N,) int32 : each node's index in the unique-node vectors: < nunique
        owned here, else nunique + its place in the unique-node halo
    first (nunique,) int32 : one local copy of each owned unique node
    area (nunique,) numpy : assembled spheremp of the owned unique nodes (m²)
    total_area : Σ area over the sphere (m²; 4πa²)
    copies, owned : the DSS's halo and the unique-node halo (``halo.Halo``: what goes
        to and comes from each neighbour); neighbours : ranks sharing nodes with
        this one; ghost : the DSS's receive buffer; halo_copies : copies received per DSS
    edges : ``kernels.dss.Edges`` of the DSS by element on GLL rows (``by_element``), on
        the CPU where ``element_rows`` (a class attribute, True) and the mesh allows; else None
        and the DSS is the node gather (CUDA's form): the same bits either way

    Over several ranks on CUDA each rank's arrays live on its own device (``core.backend.pick_device``:
    rank r of a node on cuda:(r mod its GPUs)), and the exchanges go through host memory (``halo``).
    """

    # False: the node gather on the CPU too (what benchmarks/archive/replaced_paths.py dss_by_element compares the rows
    # with, and how tests/core/test_cuda_compile.py finds the DSS kernels CUDA launches)
    element_rows = True

    def __init__(self, grid, device: str | Backend = "cpu", threads: int = 1, comm=None, parts=None, rows=MAX_ROWS):
        self.backend = device if isinstance(device, Backend) else Backend.of(device)
        self.device = device = self.backend.device  # the name
        self.threads = int(threads)
        self.comm = comm if comm is not None else SerialComm()
        # the most rows an exchange carries: the ∇⁴'s four, or a state's with its tracers' masses
        self.max_rows = max(MAX_ROWS, int(rows))
        self._sum, self._max, self._min = reduction_ops(self.comm)
        rank, size = self.comm.rank, self.comm.size
        self.distributed = size > 1
        self.parts = parts = rank_parts(grid.ne, size, grid.mesh) if parts is None else parts
        if not np.array_equal(grid.elements, parts[rank]):
            grid = grid.part(parts[rank])
        self.grid = grid
        self.elements, self.nodes = grid.elements, grid.nodes
        self.N, self.nnodes_total = grid.nnodes, grid.nelem_total * grid.np**2
        self._build_halos(parts, rank)

        def up(a, dtype=f64):
            return wp.array(np.ascontiguousarray(a), dtype=dtype, device=device)

        self.spheremp = up(np.concatenate([grid.spheremp, grid.halo_spheremp[np.searchsorted(grid.halo, self.recv)]]))
        self.rspheremp = up(grid.rspheremp)
        self.table = up(self._table, wp.int32)
        self.gid, self.first = up(self._gid, wp.int32), up(grid.first, wp.int32)
        self.area = grid.area
        self.nunique = grid.first.size
        self.total_area = self.sum(float(np.sum(self.area)))
        c = self.copies  # the DSS's pattern
        self.neighbours, self.ghost, self.halo_copies = c.neighbours, c.recv_buffer, c.size
        self.dss_copies = d = dss.Copies()  # the DSS kernels' view of the above
        d.table, d.nlocal, d.ghost, d.spheremp, d.rspheremp = (
            self.table,
            self.N,
            self.ghost,
            self.spheremp,
            self.rspheremp,
        )
        self.edges = self._element_edges() if self.backend.host and self.element_rows else None
        if self.edges is not None:  # what the element-row kernels read beside x: spheremp and rspheremp as rows
            self._mass_rows = row_vectors(self.spheremp[: self.N], grid.np), row_vectors(self.rspheremp, grid.np)

    def _build_halos(self, parts, rank):
        """Local tables from the rank's own nodes' rows of the global DSS table and
        the element → rank map (no arrays over the whole grid's nodes): the DSS
        table in local/ghost indices; for each neighbour, the element copies it
        sends and receives (``copies``), and the owned unique-node values it sends
        and receives (``owned``), both in global order."""
        grid = self.grid
        table, gid = grid.dss_table.astype(np.int64), grid.gid.astype(np.int64)
        elem_rank = np.empty(sum(map(len, parts)), dtype=np.int64)
        for k, p in enumerate(parts):
            elem_rank[p] = k
        valid = table >= 0
        copy_rank = np.where(valid, elem_rank[np.where(valid, table, 0) // grid.np**2], -1)
        owner = copy_rank[:, 0]  # a unique node belongs to the rank of its first copy
        owned_gid = gid[grid.first]  # ascending
        recv, send, unique_nbrs, unique_send, unique_recv = [], [], [], [], []
        neighbours = np.unique(copy_rank[valid & (copy_rank != rank)])
        for s in neighbours:
            theirs = copy_rank == s
            touched = np.any(theirs, axis=1)  # the nodes held here that s holds copies of
            recv.append(np.unique(table[theirs]))  # ascending: the global order
            send.append(np.flatnonzero(touched))
            out = np.unique(gid[touched & (owner == rank)])
            into = np.unique(gid[owner == s])
            if out.size or into.size:
                unique_nbrs.append(s), unique_send.append(np.searchsorted(owned_gid, out)), unique_recv.append(into)
        self.copies = Halo(neighbours, send, recv, self.backend, self.max_rows)
        self.owned = Halo(unique_nbrs, unique_send, unique_recv, self.backend, self.max_rows)
        self.recv = np.concatenate(recv) if recv else np.zeros(0, dtype=np.int64)
        self._table = np.where(valid, _lookup(np.concatenate([grid.nodes, self.recv]), np.where(valid, table, -1)), -1)
        if np.any(valid & (self._table < 0)):
            raise RuntimeError("a copy of a shared node is neither local nor received")
        self._gid = _lookup(np.concatenate([owned_gid, *unique_recv]), gid)
        if np.any(self._gid < 0):
            raise RuntimeError("a node's unique value is neither owned nor received")

    def _element_edges(self) -> dss.Edges | None:
        """The element-row DSS's ``dss.Edges`` (the CPU's form of ``dss`` and ``dss_update``)
        from the DSS table: for each node inside an element's edge the one other copy, and the
        neighbour rows that run lane for lane beside the south and north edges. None where a
        node inside an edge has other than two copies (np < 3, or a mesh that is not a
        conforming one): there the node gather stays."""
        NP, nelem = self.grid.np, self.grid.nelem
        if NP < 3:
            return None
        inner = np.arange(1, NP - 1)
        local = np.concatenate([inner, (NP - 1) * NP + inner, inner * NP, inner * NP + NP - 1])
        nodes = np.arange(nelem)[:, None] * NP * NP + local[None, :]
        table = self._table[nodes]  # (nelem, 4(np − 2), copies)
        valid = table >= 0
        if not np.all(valid.sum(axis=-1) == 2):
            return None
        other = np.where(valid & (table != nodes[..., None]), table, -1).max(axis=-1)
        aligned = np.full((nelem, 2), -1, dtype=np.int64)
        for side in (0, 1):
            o = other[:, side * (NP - 2) : (side + 1) * (NP - 2)]
            start = o[:, 0] - 1  # the neighbour's row's first node, if the lanes line up
            ok = (start >= 0) & (o[:, -1] < self.N) & (start % NP == 0) & np.all(o == start[:, None] + inner, axis=1)
            aligned[ok, side] = start[ok] // NP
        g = dss.Edges()
        g.other = wp.array(other.astype(np.int32), dtype=wp.int32, device=self.device)
        g.aligned = wp.array(aligned.astype(np.int32), dtype=wp.int32, device=self.device)
        return g

    def by_element(self, x: wp.array2d, kernel, args, lanes: int = 1, per_part=None, rest=None) -> list:
        """Launches for a kernel that sums the DSS of x (rows, N) by element on GLL rows
        itself (``kernels.dss.gather_rows``; where ``edges`` is not None: the CPU), the form of
        ``gathering`` there: ``kernel(rows, copies, ghosts, np)`` builds it; it takes (xr, x,
        ``dss_copies``, ``edges``, wr, rsr, *args, offset), xr x's rows, wr and rsr spheremp's
        first N and rspheremp as rows (``args`` as the kernel reads them: its arrays of nodes as
        ``kernels.operators.row_vectors``); dim nelem. The neighbours'
        copies are exchanged first. ``lanes`` > 1: the kernel takes that many consecutive
        elements an index (``kernels.hyperviscosity_across.laplacian_across``; dim ⌊nelem/lanes⌋,
        ``per_part`` as ``core.parallel.record``'s), and ``rest`` = (a builder, its args) as
        ``kernel`` and ``args`` one element an index, launched over the elements past the last
        whole block (with their offset)."""
        NP, nelem, lanes = self.grid.np, self.grid.nelem, int(lanes)
        build = (x.shape[0], self.table.shape[1], bool(len(self.neighbours)), NP)
        head = [row_vectors(x, NP), x, self.dss_copies, self.edges, *self._mass_rows]
        launches, blocks = self._exchange(x), nelem // lanes
        if blocks:
            launches.append(
                record(
                    kernel(*build),
                    blocks,
                    [*head, *args],
                    device=self.backend,
                    threads=self.threads,
                    nodes_per_index=NP * NP * lanes,
                    per_part=per_part,
                )
            )
        if blocks * lanes < nelem:
            tail, tail_args = rest
            first = blocks * lanes
            launches.append(
                record(
                    tail(*build),
                    nelem - first,
                    [*head, *tail_args],
                    device=self.backend,
                    threads=self.threads,
                    nodes_per_index=NP * NP,
                    start=first,
                )
            )
        return launches

    def _record(self, kernel, dim, inputs):
        return record(kernel, dim, inputs, device=self.backend, threads=self.threads, block=self.grid.np**2)

    def _exchange(self, x: wp.array2d, halo: Halo | None = None) -> list:
        """Launches that fill ``halo``'s receive buffer (default the DSS ghosts)
        with the neighbours' entries of x's rows (pack, then exchange); none
        without neighbours."""
        halo = self.copies if halo is None else halo
        if not len(halo.neighbours):
            return []
        rows = x.shape[0]
        if rows > self.max_rows:
            raise ValueError(f"an exchange of more than {self.max_rows} rows (got {rows})")
        exchange = halo.exchanges.get(rows)
        if exchange is None:
            tag = rows if halo is self.copies else self.max_rows + rows
            exchange = halo.exchanges[rows] = Exchange(self.comm, halo, rows, tag, self.backend)
        if not halo.send_index_np.size:  # only receives from its neighbours
            return [exchange]
        return [self._record(dss.pack, halo.send_index_np.size, [x, rows, halo.send_index, halo.send_buffer]), exchange]

    def exchange(self, x: wp.array2d, unique: bool = False) -> list:
        """Launches that fill the DSS's ghost buffer ``ghost`` (or, ``unique``, the
        unique-node halo ``owned.recv_buffer``) with the neighbours' entries of x's
        rows, in ``dss.pack``'s layout; none without neighbours. For kernels that
        gather over copies themselves (``kernels.helmholtz``)."""
        return self._exchange(x, self.owned if unique else None)

    # -- assembly (recorded launch lists: run each item's ``launch()`` in order) --
    def dss(self, x: wp.array2d, weighted: bool, out: wp.array2d) -> list:
        """Launches for out = DSS(x), (rows, N) each: out[r, p] = rspheremp[p] ·
        Σ over the copies c of p's node of (spheremp[c] if ``weighted`` else 1)·x[r, c]
        (``kernels.dss.dss_rows``), the neighbours' copies exchanged first.
        Weighted for a strong-form field (continuous result, integral kept),
        unweighted for a weak form. ``out`` must not alias ``x``. On the CPU by element
        on GLL rows (``kernels.dss.dss_update_elements``, the same bits)."""
        if self.edges is not None:
            return self.dss_update(x, [(out, [(1.0, None)])], weighted=weighted)
        return self.gathering(
            x,
            lambda rows, copies, ghosts: dss.dss_rows(rows, bool(weighted), copies, ghosts=ghosts, dtype=x.dtype),
            [out],
        )

    def part_copies(self, elements: np.ndarray, whole: np.ndarray | None = None) -> tuple[wp.array, dss.Copies]:
        """What a DSS over part of the elements (indices ``elements``, held here) gathers:
        (nodes, copies): the element-local nodes whose unique node one of the part's elements
        touches, here or on another rank (every copy, int32 device array), and a
        ``dss.Copies`` whose table keeps only the part's copies (the others −1): their DSS
        is M⁻¹ Σ over the part's copies, whatever the other elements' entries hold.
        ``whole`` (nelem_total,) bool: the part over the whole grid's elements, which says
        which received copies are the part's; needed with neighbours (ValueError without,
        or when it disagrees with ``elements`` here)."""
        per = self.grid.np**2
        mine = np.zeros(self.grid.nelem, dtype=bool)
        mine[elements] = True
        member = mine[np.arange(self.N) // per]  # each copy's: local copies, then the received ones
        if len(self.neighbours):
            if whole is None or not np.array_equal(np.asarray(whole, dtype=bool)[self.elements], mine):
                raise ValueError("an assembly over part of the elements on several ranks needs the whole part")
            member = np.concatenate([member, np.asarray(whole, dtype=bool)[self.recv // per]])
        table = self._table
        kept = np.where((table >= 0) & member[np.maximum(table, 0)], table, -1)
        nodes = np.flatnonzero((kept >= 0).any(axis=1))
        copies = dss.Copies()
        copies.table = wp.array(kept.astype(np.int32), dtype=wp.int32, device=self.device)
        copies.nlocal, copies.ghost = self.N, self.ghost
        copies.spheremp, copies.rspheremp = self.spheremp, self.rspheremp
        return wp.array(nodes.astype(np.int32), dtype=wp.int32, device=self.device), copies

    def dss_at(self, x: wp.array2d, weighted: bool, out: wp.array2d, nodes: wp.array, copies: dss.Copies) -> list:
        """Launches for out = DSS(x) over ``copies`` (``part_copies``) at the element-local
        ``nodes`` only, out's other nodes left as they are (``kernels.dss.dss_rows_at``): what
        a part of the elements contributes, assembled over the nodes it touches. The
        neighbours' copies are exchanged first (all of them: the table picks the part's)."""
        ghosts = bool(len(self.neighbours))
        kernel = dss.dss_rows_at(x.shape[0], bool(weighted), self.table.shape[1], ghosts, x.dtype)
        launch = record(kernel, nodes.shape[0], [x, copies, nodes, out], device=self.backend, threads=self.threads)
        return [*self._exchange(x), launch]

    def dss_update(self, x: wp.array2d, updates, weighted: bool = True, rkl: bool = False, assembled: int = 0) -> list:
        """Launches for the weighted DSS k of x (rows, N) (``weighted`` False: the unweighted
        one, of a weak form), not stored but used by
        one or two ``updates`` (out, terms) in order: out = Σ a·src over the
        terms (a, src), src an array of x's shape or None for k
        (``kernels.dss.dss_update``: summed left to right, the bits of
        ``blas.axpby``/``axpbypcz`` on a stored k). Outputs may alias terms, not x. The terms
        and outputs float64, or all float32 (the float32 state's stages). ``rkl``: each update's
        terms (1, s0), (ν, s1), (coef, k) formed as an RKL1 stage (``kernels.dss.rkl_stage``).
        ``assembled`` A: the last A rows of the one update's out take k itself (x's rows there
        the terms of a weighted DSS: a limited stage's tracers, ``kernels.dss.dss_update``'s)."""
        patterns, coefs, arrays = [], [], []
        for out, terms in updates:
            patterns.append("rkl" if rkl else "".join("k" if src is None else "a" for _, src in terms))
            coefs += [a for a, _ in terms] + [0.0] * (3 - len(terms))
            srcs = [src for _, src in terms if src is not None]
            arrays += [*(srcs + [out] * (2 - len(srcs))), out]  # unused slots: any array of the shape
        coefs += [0.0] * (6 - len(coefs))
        arrays += arrays[-3:] * (2 - len(updates))
        if self.edges is not None:
            return self.by_element(
                x,
                lambda rows, copies, ghosts, np_: dss.dss_update_elements(
                    rows, copies, tuple(patterns), ghosts, bool(weighted), np_, x.dtype, arrays[0].dtype, assembled
                ),
                [dss.vec6(*coefs), *(row_vectors(a, self.grid.np) for a in arrays)],
            )
        return self.gathering(
            x,
            lambda rows, copies, ghosts: dss.dss_update(
                rows,
                copies,
                tuple(patterns),
                ghosts=ghosts,
                weighted=bool(weighted),
                dtype=x.dtype,
                state=arrays[0].dtype,
                assembled=assembled,
            ),
            [dss.vec6(*coefs), *arrays],
        )

    def gathering(self, x: wp.array2d, kernel, args) -> list:
        """Launches for a kernel that sums the DSS of x (rows, N) itself
        (``kernels.dss.gather``) and uses it node by node: ``kernel(rows,
        copies, ghosts)`` builds it for x's rows, the table's columns and
        whether there are neighbours; it takes (x, ``dss_copies``, *args,
        block, offset), dim N/block: np² consecutive nodes a thread on the CPU,
        where Warp's cost per thread is a fifth of a DSS's (0.52 → 0.42 ms at
        ne30), one on CUDA. The neighbours' copies are exchanged first."""
        kernel = kernel(x.shape[0], self.table.shape[1], bool(len(self.neighbours)))
        block = self.backend.nodes_per_thread(self.grid.np)
        launch = record(
            kernel,
            self.N // block,
            [x, self.dss_copies, *args, block],
            device=self.backend,
            threads=self.threads,
            nodes_per_index=block,
        )
        return [*self._exchange(x), launch]

    def assemble(self, x: wp.array2d, row: int, out: wp.array) -> list:
        """Launches for the unique-node out (nunique,) = M x[row]: Σ over the copies
        (the neighbours' exchanged first, all of x's rows) of spheremp·x[row]
        (assembled mass times a continuous field, m² × units of x)."""
        args = [x, self.ghost, self.N, int(row), self.spheremp, self.table, self.first, out]
        return [*self._exchange(x), self._record(dss.assemble, self.nunique, args)]

    def scatter(self, y: wp.array, out: wp.array2d, row: int, rows: int = 1) -> list:
        """Launches for the element-local out[row : row + rows] (rows, N) from the
        unique-node vector y (rows·nunique, row r at r·nunique …): every copy of a
        node gets its value, those owned elsewhere received from their owners."""
        y2 = y.reshape((rows, self.nunique))
        return [
            *self._exchange(y2, self.owned),
            self._record(dss.scatter, self.N, [y2, self.owned.recv_buffer, self.gid, int(row), out]),
        ]

    # -- between the whole grid and this rank's part (numpy) ------------------------
    def _part_nodes(self, k: int) -> np.ndarray:
        """The whole-grid element-local indices of rank k's nodes, in its order."""
        npe = self.grid.np**2
        return (self.parts[k][:, None] * npe + np.arange(npe)).ravel()

    def gather(self, a: np.ndarray) -> np.ndarray | None:
        """The whole-grid field (..., nnodes_total) from every rank's part (..., N), on
        rank 0 (``Gatherv``; call on every rank); None on the other ranks. On one
        process, ``a`` itself."""
        if not self.distributed:
            return a
        a = np.ascontiguousarray(a, dtype=np.float64)
        counts = [a.size // self.N * p.size * self.grid.np**2 for p in self.parts]
        flat = np.empty(sum(counts)) if self.comm.rank == 0 else None
        self.comm.Gatherv(a, [flat, counts] if flat is not None else None, root=0)
        if flat is None:
            return None
        out = np.empty(a.shape[:-1] + (self.nnodes_total,))
        for k, piece in enumerate(np.split(flat, np.cumsum(counts)[:-1])):
            out[..., self._part_nodes(k)] = piece.reshape(a.shape[:-1] + (-1,))
        return out

    def distribute(self, whole, rows: int, what: str) -> np.ndarray:
        """This rank's part (rows, N) of a whole-grid field ``whole`` (rows,
        nnodes_total; one row also (nnodes_total,)) given on rank 0 (``Scatterv``; call on every rank; ``whole``
        is read on rank 0 only, the others may pass None). On one process,
        ``whole`` itself as float64. Raises ValueError on every rank, one line
        naming ``what``, when rank 0's ``whole`` has another shape or is not finite
        (``ArgumentError``): "<what> has shape S, the grid needs (rows, nnodes_total)"."""
        root, want = self.comm.rank == 0, (rows, self.nnodes_total)  # rank 0's ``whole``: it hands the field out
        shape, finite = self.bcast((np.shape(whole), bool(np.isfinite(whole).all())) if root else None)
        if rows == 1 and shape == want[1:]:  # one row given as (nnodes_total,)
            whole, shape = np.reshape(whole, want) if root else None, want
        if shape != want:
            raise ArgumentError(f"{what} has shape {shape}, the grid needs {want}")
        if not finite:
            raise ArgumentError(f"{what} holds a NaN or an infinity")
        if not self.distributed:
            return np.asarray(whole, dtype=np.float64)
        counts = [rows * p.size * self.grid.np**2 for p in self.parts]
        flat = None
        if self.comm.rank == 0:
            flat = np.concatenate(
                [np.asarray(whole, dtype=np.float64)[:, self._part_nodes(k)].ravel() for k in range(len(self.parts))]
            )
        out = np.empty((rows, self.N))
        self.comm.Scatterv([flat, counts] if flat is not None else None, out, root=0)
        return out

    def whole_grid(self):
        """The whole grid on rank 0 (None elsewhere; call on every rank): the grid
        itself on one process, else a ``GatheredGrid`` of the ranks' parts."""
        if not self.distributed:
            return self.grid
        g = self.grid
        fields = self.gather(np.stack([g.lat, g.lon, g.spheremp, g.dx, g.gid]))
        owned = self.comm.gather((g.nodes[g.first], g.area), root=0)  # each unique node from its first copy's rank
        if fields is None:
            return None
        first, area = (np.concatenate(a) for a in zip(*owned))
        order = np.argsort(first)  # the first copies' order is the unique nodes' (gid) order
        return GatheredGrid(g, fields, first[order], area[order])

    def bcast(self, value):
        """Rank 0's ``value`` (any picklable object) on every rank."""
        return self.comm.bcast(value, root=0)

    def standard_normal(self, rng: np.random.Generator, rows: int) -> np.ndarray:
        """This rank's part (rows, N) of ``rng.standard_normal((rows, nnodes_total))``:
        the stream drawn in pieces (numpy's generators give the same numbers
        however a stream is split), so no rank holds the whole array."""
        wanted = (np.arange(rows)[:, None] * self.nnodes_total + self.nodes).ravel()  # ascending
        out, start, chunk = np.empty(wanted.size), 0, 1 << 16
        for lo in range(0, rows * self.nnodes_total, chunk):
            draw = rng.standard_normal(min(chunk, rows * self.nnodes_total - lo))
            stop = np.searchsorted(wanted, lo + draw.size)
            out[start:stop] = draw[wanted[start:stop] - lo]
            start = stop
        return out.reshape(rows, self.N)

    def first_node(self, local: int | None) -> int | None:
        """The smallest whole-grid node index over all ranks of a local node index
        (None: none here); None if no rank has one."""
        g = int(self.nodes[local]) if local is not None else self.nnodes_total
        g = int(self.comm.allreduce(g, self._min))
        return None if g == self.nnodes_total else g

    def whole_sums(self, rows) -> np.ndarray:
        """Σ of each row of ``rows`` ((k, N), or k arrays (N,): this rank's element-local
        nodes) over every rank's nodes, added on rank 0 in the whole grid's element-local
        order (the one-process array: the same bits on any rank count, unlike ``sums``),
        every rank getting the k sums (call on every rank)."""
        if not self.distributed:
            return np.array([np.sum(r) for r in rows])
        whole = self.gather(np.stack(rows))
        return self.bcast(None if whole is None else np.array([np.sum(r) for r in whole]))
