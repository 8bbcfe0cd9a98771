"""The equiangular cube as a mesh: its elements e = face·ne² + jb·ne + ia, their corners and
edge neighbours, the unique-node numbering of its GLL nodes from the cube's topology in exact
integer arithmetic (``Numbering``), the equiangular gnomonic map of its elements
(``reference_to_sphere``; Sadourny 1972, Ronchi et al. 1996) and the cube as a ``Mesh``
(``cube_mesh``)."""

from __future__ import annotations

import math

import numpy as np

from .face_map import FACES
from .mesh import Mesh


def _lattice_groups(ne: int, np_: int, elements: np.ndarray, positions: np.ndarray):
    """The coincident copies among nodes ``positions`` (p = j·np + i) of ``elements``
    (ascending), from the cube's topology in exact integer arithmetic (no search
    over coordinates): (group (E, P) of each node, members (groups, most copies)
    global indices e·np² + p ascending and −1-padded, lead (E, P): the node is its
    group's first (smallest) copy).

    Node (i, j) of element (face, jb, ia) sits at lattice point (k, l) =
    (ia·(np−1) + i, jb·(np−1) + j) of its face, 0 ≤ k, l ≤ M = ne·(np−1),
    and at the integer point M·c + (2k − M)·ea + (2l − M)·eb on the cube
    scaled by M (c, ea, eb the face's axis vectors). The lattice coordinate of
    an angle is odd about the face centre (the element edges and the GLL points
    are symmetric), so every copy of a node on a cube edge or corner, seen from
    any face, lands on the same integer point, and only those do."""
    M, P = ne * (np_ - 1), positions.size
    face, rest = np.divmod(elements, ne * ne)
    jb, ia = np.divmod(rest, ne)
    k = ia[:, None] * (np_ - 1) + positions % np_
    l = jb[:, None] * (np_ - 1) + positions // np_
    F, key = FACES.astype(np.int64), np.zeros(k.shape, dtype=np.int64)
    for d in range(3):  # the point's coordinates Q_d in [0, 2M], one at a time (memory)
        key = key * (2 * M + 1) + (
            M * F[face, 0, d, None] + (2 * k - M) * F[face, 1, d, None] + (2 * l - M) * F[face, 2, d, None] + M
        )
    key = key.ravel()
    order = np.argsort(key, kind="stable")  # by point, then ascending global index
    sk = key[order]
    starts = np.concatenate(([True], sk[1:] != sk[:-1]))
    sorted_group = np.cumsum(starts) - 1
    pos = np.arange(order.size) - np.flatnonzero(starts)[sorted_group]  # place among its point's copies
    group, lead = np.empty(order.size, dtype=np.int64), np.empty(order.size, dtype=bool)
    group[order], lead[order] = sorted_group, starts
    members = np.full((int(sorted_group[-1]) + 1, int(pos.max()) + 1), -1, dtype=np.int64)
    members[sorted_group, pos] = elements[order // P] * np_ * np_ + positions[order % P]
    return group.reshape(-1, P), members, lead.reshape(-1, P)


_EDGE_CORNERS = ((0, 1), (1, 3), (2, 3), (0, 2))  # edges j = 0, i = np−1, j = np−1, i = 0 by corner c = 2·[j>0] + [i>0]


class Numbering:
    """The cube's unique nodes for ne, np, numbered in the order of their first
    copies (smallest global index e·np² + p), from the cube's topology.

    An element's nodes first seen there are its (np−2)² interior nodes, the
    inner nodes of each edge it shares with a higher-numbered element, and the
    corners where it is the lowest-numbered element: so the count per element,
    hence (prefix sum) the number of any node, comes from the element corners'
    coincidences (``_lattice_groups`` at np = 2) alone, arrays of 6·ne²·4 entries.
    The copies of the nodes of some elements come from the lattice points of
    those elements and of their corner neighbours only.
    """

    def __init__(self, ne: int, np_: int):
        self.ne, self.np = ne, np_
        nelem, last = 6 * ne * ne, np_ - 1
        i, j = np.tile(np.arange(np_), np_), np.repeat(np.arange(np_), np_)  # node p = j·np + i
        interior = (i > 0) & (i < last) & (j > 0) & (j < last)
        self.ring = ring = np.flatnonzero(~interior)  # ascending p
        ri, rj = i[ring], j[ring]
        self.ring_corner = np.where(
            ((ri == 0) | (ri == last)) & ((rj == 0) | (rj == last)), 2 * (rj > 0) + (ri > 0), -1
        )
        self.ring_edge = np.select([rj == 0, ri == last, rj == last, ri == 0], [0, 1, 2, 3])  # where not a corner
        self.before = np.cumsum(interior) - interior  # interior nodes before each p
        elements = np.arange(nelem)
        self.vertex, vmembers, self.corner_first = _lattice_groups(ne, 2, elements, np.arange(4))
        self.vertex_elements = np.where(vmembers >= 0, vmembers // 4, -1)
        nbr = np.full((nelem, 4), -1)
        for k, (a, b) in enumerate(_EDGE_CORNERS):  # the other element at both corners of edge k
            A, B = self.vertex_elements[self.vertex[:, a]], self.vertex_elements[self.vertex[:, b]]
            both = np.any(A[:, :, None] == B[:, None, :], axis=2) & (A >= 0) & (A != elements[:, None])
            nbr[:, k] = np.where(both, A, -1).max(axis=1)
        if np.any(nbr < 0):
            raise RuntimeError(f"an element edge without a neighbour (ne={ne})")
        self.edge_neighbours = nbr
        count = (
            int(interior.sum()) + (np_ - 2) * np.sum(elements[:, None] < nbr, axis=1) + self.corner_first.sum(axis=1)
        )
        self.offset = np.concatenate(([0], np.cumsum(count)[:-1]))
        if int(count.sum()) != 6 * ne * ne * (np_ - 1) ** 2 + 2:
            raise RuntimeError(f"grid has {int(count.sum())} unique nodes, expected {6 * ne * ne * (np_ - 1) ** 2 + 2}")
        self.width = 3 if ne == 1 else 4  # most copies of a node

    def _ring_first(self, elements: np.ndarray) -> np.ndarray:
        """(E, ring) bool: the ring node is first seen in its element."""
        corner, edge = self.ring_corner, self.ring_edge
        return np.where(
            corner >= 0,
            self.corner_first[elements][:, np.maximum(corner, 0)],
            elements[:, None] < self.edge_neighbours[elements][:, edge],
        )

    def rows(self, elements: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(gid (N,), table (N, C)) int64 of the nodes of ``elements`` (ascending):
        unique-node ids and the global indices of every copy, ascending, −1-padded."""
        npe, ring = self.np * self.np, self.ring
        near = np.unique(self.vertex_elements[self.vertex[elements]])  # the elements and their corner neighbours
        near = near[near >= 0]
        group, members, _ = _lattice_groups(self.ne, self.np, near, ring)
        held = members[group[np.searchsorted(near, elements)]]  # (E, ring, copies): complete for these nodes
        f, p = np.divmod(held[..., 0], npe)  # each ring node's first copy
        uf, inverse = np.unique(f, return_inverse=True)
        rank = np.cumsum(self._ring_first(uf), axis=1) - 1  # among first-seen ring nodes of the element
        ring_index = np.zeros(npe, dtype=np.int64)
        ring_index[ring] = np.arange(ring.size)
        ring_gid = self.offset[f] + self.before[p] + rank[inverse.reshape(f.shape), ring_index[p]]
        mask = np.ones((elements.size, npe), dtype=bool)
        mask[:, ring] = self._ring_first(elements)
        gid = self.offset[elements][:, None] + np.cumsum(mask, axis=1) - 1
        gid[:, ring] = ring_gid
        table = np.full((elements.size, npe, self.width), -1, dtype=np.int64)
        table[:, :, 0] = elements[:, None] * npe + np.arange(npe)
        table[:, ring, : held.shape[2]] = held
        return gid.ravel(), table.reshape(elements.size * npe, -1)


def element_neighbours(ne: int) -> np.ndarray:
    """(6·ne², 4) int64: the four edge neighbours of each element (the elements
    sharing two element corners with it), ascending."""
    return np.sort(Numbering(ne, 2).edge_neighbours, axis=1)


class EquiangularMap:
    """The equiangular gnomonic map of the ne cube at the GLL points of ``rule``, for
    ``_metric``: ``at(copies)`` of global element-local node indices gives (P = c + tan α ea +
    tan β eb (n, 3), ∂P/∂ξ and ∂P/∂η (n, 3) each divided by ``factor`` = Δα/2)."""

    def __init__(self, ne: int, rule):
        self.ne, self.rule = ne, rule
        self.factor = math.pi / 2 / ne / 2

    def at(self, copies: np.ndarray):
        np_ = self.rule.np
        e, p = np.divmod(copies, np_ * np_)
        j, i = np.divmod(p, np_)
        alpha, beta, face, P = _equiangular(self.ne, e, self.rule.points[i], self.rule.points[j])
        return (
            P,
            FACES[face, 1] / np.cos(alpha)[:, None] ** 2,
            FACES[face, 2] / np.cos(beta)[:, None] ** 2,
            self.factor,
        )


def _equiangular(ne: int, e: np.ndarray, xi: np.ndarray, eta: np.ndarray):
    """The equiangular angles α, β, the face and P = c + tan α ea + tan β eb of the points
    with reference coordinates (ξ, η) ∈ [−1, 1]² in elements ``e`` (global indices)."""
    face, rest = np.divmod(e, ne * ne)
    jb, ia = np.divmod(rest, ne)
    edges = np.linspace(-math.pi / 4, math.pi / 4, ne + 1)
    dalpha = math.pi / 2 / ne
    alpha = edges[ia] + (xi + 1) * dalpha / 2
    beta = edges[jb] + (eta + 1) * dalpha / 2
    c, ea, eb = FACES[face, 0], FACES[face, 1], FACES[face, 2]
    return alpha, beta, face, c + np.tan(alpha)[:, None] * ea + np.tan(beta)[:, None] * eb


def reference_to_sphere(ne: int, e: np.ndarray, xi: np.ndarray, eta: np.ndarray) -> np.ndarray:
    """Unit position vectors (n, 3) of the points (ξ, η) ∈ [−1, 1]² (n,) of the reference
    square of elements ``e`` (n,) of the ne grid, through the equiangular gnomonic map."""
    P = _equiangular(ne, np.asarray(e), np.asarray(xi), np.asarray(eta))[-1]
    return P / np.linalg.norm(P, axis=1)[:, None]


def cube_element(ne: int, xyz: np.ndarray) -> np.ndarray:
    """(n,) int64: the element e = face·ne² + jb·ne + ia of the ne equiangular cube that
    holds each point xyz (n, 3) (unit or not; on an element edge, either side)."""
    face = np.argmax(xyz @ FACES[:, 0].T, axis=1)
    c, ea, eb = (np.einsum("ni,ni->n", xyz, FACES[face, k]) for k in range(3))
    cell = [
        np.clip(np.floor((np.arctan2(t, c) / (math.pi / 2) + 0.5) * ne), 0, ne - 1).astype(np.int64) for t in (ea, eb)
    ]
    return face * ne * ne + cell[1] * ne + cell[0]


def cube_mesh(ne: int) -> Mesh:
    """The uniform equiangular cube with ``ne``×``ne`` elements a face as a ``Mesh``: element
    e = face·ne² + jb·ne + ia of ``CubedSphere`` with corners (ia, jb), (ia+1, jb), (ia+1,
    jb+1), (ia, jb+1) of its face (counter-clockwise), the corner nodes numbered in the order
    of their first copies. Raises ``ValueError`` for ne < 1."""
    if isinstance(ne, bool) or int(ne) != ne or ne < 1:
        raise ValueError(f"ne must be an integer >= 1 (got {ne})")
    numbering = Numbering(int(ne), 2)
    corner = np.array([0, 1, 3, 2])  # counter-clockwise corner k → node p = 2·[j > 0] + [i > 0]
    quads = numbering.rows(np.arange(6 * ne * ne))[0].reshape(-1, 4)[:, corner]
    copies = np.arange(quads.size)
    first = np.zeros(int(quads.max()) + 1, dtype=np.int64)
    first[quads.ravel()[::-1]] = copies[::-1]  # each node's first copy (reverse: the smallest wins)
    e, k = np.divmod(first, 4)
    xi, eta = np.array([-1.0, 1, 1, -1]), np.array([-1.0, -1, 1, 1])
    return Mesh(reference_to_sphere(ne, e, xi[k], eta[k]), quads.astype(np.int64), f"ne{ne} cube")
