"""The element-local map of a quadrilateral mesh and the numbering of its GLL nodes.

HOMME's ``cubed_sphere_map = 2`` (``cube_mod::dmap_elementlocal``, ``ref2sphere``; Guba, Taylor,
Ullrich, Overfelt & Levy 2014, GMD 7:2803): the point (a, b) ∈ [−1, 1]² of an element with
corners c₁..c₄ (counter-clockwise, at (−1, −1), (1, −1), (1, 1), (−1, 1)) is
p = Σ q_k(a, b) c_k, bilinear in Cartesian space, projected onto the sphere, x = p/|p|. Two
elements sharing an edge place the same points on it (p is linear along the edge in both), so
the GLL nodes of a shared edge coincide whichever way the elements run along it. The area
correction is HOMME's "epsilon bubble" (``geometry_mod::set_area_correction_map2``): each
element's interior metric is scaled so that its GLL area is the exact area of the spherical
quadrilateral; the boundary metric is left alone, so neighbours' edge fluxes still cancel.
"""

from __future__ import annotations

import functools

import numpy as np

from .face_map import FaceMap
from .mesh import Mesh, corner_weights, element_areas


def bilinear(mesh: Mesh, e: np.ndarray, a: np.ndarray, b: np.ndarray):
    """The element-local map before projection at the points (a, b) ∈ [−1, 1]² (n,) of elements
    ``e`` (n,) of ``mesh``: (p (n, 3), 4 ∂p/∂a (n, 3), 4 ∂p/∂b (n, 3)); x = p/|p| is the point on
    the unit sphere (HOMME ``ref2sphere`` with ``cubed_sphere_map = 2``)."""
    c = mesh.coords[mesh.quads[e]]  # (n, 4, 3)
    q, dq_da, dq_db = corner_weights(a, b)
    return np.einsum("nk,nki->ni", q, c), np.einsum("nk,nki->ni", dq_da, c), np.einsum("nk,nki->ni", dq_db, c)


def mesh_point(mesh: Mesh):
    """The map of ``mesh`` (``mesh.map``) as a function (e, a, b) → (P, 4 ∂P/∂a, 4 ∂P/∂b)
    (each (n, 3); x = P/|P|): ``bilinear`` (element-local) or ``face_map.FaceMap.point``
    (equiangular in each element's cube face)."""
    return FaceMap(mesh).point if mesh.map == "equiangular" else functools.partial(bilinear, mesh)


class ElementLocalMap:
    """The element-local map of ``mesh`` at the GLL points of ``rule``, for the grid's
    ``_metric``: ``at(copies)`` of global element-local node indices e·np² + j·np + i gives
    (p (n, 3) the unnormalised point, ∂p/∂a and ∂p/∂b (n, 3) each divided by ``factor``,
    factor = 1/4)."""

    factor = 0.25

    def __init__(self, mesh: Mesh, rule):
        self.mesh, self.rule = mesh, rule

    def at(self, copies: np.ndarray):
        np_ = self.rule.np
        e, p = np.divmod(copies, np_ * np_)
        j, i = np.divmod(p, np_)
        return (*bilinear(self.mesh, e, self.rule.points[i], self.rule.points[j]), self.factor)


def locate(mesh: Mesh, xyz: np.ndarray, candidates: int = 8, tolerance: float = 1e-10):
    """The element and reference point (e, a, b) (n,) each of points xyz (n, 3) on the unit
    sphere: the inverse of the mesh's map (``mesh_point``: element-local or equiangular), by
    Newton's method on the part of p(a, b) across x (p ∥ x, p·x > 0) in each of the ``candidates`` elements with the nearest
    centroids, keeping the first whose (a, b) lies in [−1, 1]² (to ``tolerance``). A point on
    an element edge gets one of its elements. Raises ``ValueError`` naming the first point no
    candidate holds (a mesh whose elements are far larger than their neighbours': raise
    ``candidates``)."""
    from scipy.spatial import cKDTree

    xyz = np.asarray(xyz, dtype=np.float64)
    point = mesh_point(mesh)
    n = xyz.shape[0]
    k = min(candidates, mesh.nelem)
    near = cKDTree(mesh.centroids()).query(xyz, k=k)[1].reshape(n, k)
    # a tangent basis (t1, t2) at each point, from the axis it is least aligned with
    axis = np.eye(3)[np.argmin(np.abs(xyz), axis=1)]
    t1 = np.cross(xyz, axis)
    t1 /= np.linalg.norm(t1, axis=1)[:, None]
    t2 = np.cross(xyz, t1)
    found = np.full(n, -1, dtype=np.int64)
    out_a, out_b = np.zeros(n), np.zeros(n)
    for column in range(k):
        todo = np.flatnonzero(found < 0)
        if not todo.size:
            break
        e, x, u, v = near[todo, column], xyz[todo], t1[todo], t2[todo]
        a, b = np.zeros(todo.size), np.zeros(todo.size)
        for _ in range(30):  # quadratic convergence from the centre; bounded for elements that do not hold x
            p, pa, pb = point(e, a, b)
            f = np.stack([np.einsum("ni,ni->n", p, u), np.einsum("ni,ni->n", p, v)], axis=1)
            J = (
                np.stack(
                    [
                        np.stack([np.einsum("ni,ni->n", pa, u), np.einsum("ni,ni->n", pb, u)], axis=1),
                        np.stack([np.einsum("ni,ni->n", pa, v), np.einsum("ni,ni->n", pb, v)], axis=1),
                    ],
                    axis=1,
                )
                / 4
            )
            step = np.linalg.solve(J, f[..., None])[..., 0]
            a, b = np.clip(a - step[:, 0], -3, 3), np.clip(b - step[:, 1], -3, 3)
            if np.max(np.abs(step)) < 1e-15:
                break
        inside = (np.abs(a) <= 1 + tolerance) & (np.abs(b) <= 1 + tolerance)
        inside &= np.einsum("ni,ni->n", point(e, a, b)[0], x) > 0
        hit = todo[inside]
        found[hit], out_a[hit], out_b[hit] = e[inside], np.clip(a[inside], -1, 1), np.clip(b[inside], -1, 1)
    if np.any(found < 0):
        raise ValueError(f"point {int(np.flatnonzero(found < 0)[0])} lies in none of its {k} nearest elements")
    return found, out_a, out_b


def epsilon_bubble(mesh: Mesh, rule, radius: float, elements: np.ndarray, metdet: np.ndarray) -> np.ndarray:
    """(E,) the factor α of each of ``elements`` by which its interior nodes' metdet is
    multiplied (and D by √α) so that Σ w_i w_j metdet over the element is the area
    a²·(spherical quadrilateral of its corners) (HOMME ``set_area_correction_map2``);
    ``metdet`` (E, np, np) before the correction (m²). Raises ``ValueError`` for np < 3
    (no interior node to carry the correction)."""
    if rule.np < 3:
        raise ValueError(
            f"the element-local map needs np >= 3 (got {rule.np}): its area correction moves interior nodes"
        )
    w2 = np.outer(rule.weights, rule.weights)  # [j, i]
    exact = radius**2 * element_areas(mesh.coords[mesh.quads[elements]])
    numerical = np.sum(w2 * metdet, axis=(1, 2))
    interior = np.sum((w2 * metdet)[:, 1:-1, 1:-1], axis=(1, 2))
    return 1 + (exact - numerical) / interior


class MeshNumbering:
    """The unique GLL nodes of ``mesh`` at ``np_`` points, numbered in the order of their first
    copies (smallest global index e·np² + p), as ``cubed_sphere.Numbering`` numbers the cube's.

    A node is a mesh corner (shared by its 3 to 7 elements), the inner point t of a mesh edge
    (shared by its two elements, counted from the edge's smaller-numbered node so that the two
    elements agree whichever way they run along it: the GLL points are symmetric), or an
    element's interior point; the copies of each are found by sorting these integer keys.

    width : most copies of a node (the DSS table's columns)
    """

    def __init__(self, mesh: Mesh, np_: int):
        self.np = np_
        last, inner = np_ - 1, np_ - 2
        i, j = np.tile(np.arange(np_), np_), np.repeat(np.arange(np_), np_)  # node p = j·np + i
        corner = np.select(
            [(i == 0) & (j == 0), (i == last) & (j == 0), (i == last) & (j == last), (i == 0) & (j == last)],
            [0, 1, 2, 3],
            -1,
        )
        edge = np.select([j == 0, i == last, j == last, i == 0], [0, 1, 2, 3], -1)  # where not a corner
        along = np.select([edge == 0, edge == 1, edge == 2, edge == 3], [i, j, last - i, last - j])  # from corner k
        interior = (corner < 0) & (edge < 0)
        edge_nodes, element_edges = mesh.edges()
        V, E, F = mesh.nnodes, len(edge_nodes), mesh.nelem
        key = np.empty((F, np_ * np_), dtype=np.int64)
        at = corner >= 0
        key[:, at] = mesh.quads[:, corner[at]]
        at = (corner < 0) & (edge >= 0)
        k = edge[at]
        forward = mesh.quads[:, k] < mesh.quads[:, (k + 1) % 4]  # the element runs along the edge from its smaller node
        t = np.where(forward, along[at], last - along[at])
        key[:, at] = V + element_edges[:, k] * inner + t - 1
        key[:, interior] = V + E * inner + np.arange(F)[:, None] * inner**2 + np.arange(inner**2)
        key = key.ravel()
        order = np.argsort(key, kind="stable")  # by key, then ascending global index
        sk = key[order]
        starts = np.concatenate(([True], sk[1:] != sk[:-1]))
        group = np.cumsum(starts) - 1
        place = np.arange(order.size) - np.flatnonzero(starts)[group]
        first = order[starts]  # each group's first (smallest) copy
        gid_of_group = np.empty(first.size, dtype=np.int64)
        gid_of_group[np.argsort(first)] = np.arange(first.size)
        group_of = np.empty(key.size, dtype=np.int64)
        group_of[order] = group
        self.gid = gid_of_group[group_of]
        self.width = int(place.max()) + 1
        members = np.full((first.size, self.width), -1, dtype=np.int64)
        members[group, place] = order
        self.table = members[group_of]  # each node's row: its group's copies, ascending
        self.nunique = first.size

    def rows(self, elements: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(gid (N,), table (N, width)) int64 of the nodes of ``elements`` (ascending), as
        ``Numbering.rows``: unique-node ids and the global indices of every copy, ascending,
        −1-padded."""
        nodes = (elements[:, None] * self.np**2 + np.arange(self.np**2)).ravel()
        return self.gid[nodes], self.table[nodes]
