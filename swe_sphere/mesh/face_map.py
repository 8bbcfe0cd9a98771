"""The equiangular map element by element, for a quadrilateral mesh whose elements each lie in
one face of a cube: HOMME's ``cubed_sphere_map = 0`` on a mesh file (``cube_mod``:
``ref2sphere_equiangular``, with the corners' face coordinates of ``mesh_mod``).

Each element's face is the cube face its corners' mean points into. Its corners' equiangular
coordinates in that face are (α, β) = (atan(x·ea / x·c), atan(x·eb / x·c)) (Ronchi et al. 1996);
the point (a, b) ∈ [−1, 1]² is (α, β) bilinear between the corners (``mesh.corner_weights``),
carried onto the sphere by the face's gnomonic map, x = P/|P| with P = c + tan α ea + tan β eb.
On the uniform cube that is the built-in equiangular map (``cubed_sphere.EquiangularMap``).
Two elements sharing an edge place the same points on it: (α, β) is linear along the edge in
both, and on a cube edge both faces measure it by the same angle.

The cube's faces are ``FACES`` turned by a rotation: the identity where every element fits in
them (E3SM's files, the project's cube), else the frame of an element left as the cube made it,
the farthest from the mesh's smallest (``refine.refined_cube`` turns the cube onto its
refinement box). An element whose corners reach beyond its face's edges (a smoothing that moved
nodes across a cube edge) has no such map: ``face_corners`` refuses it.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from ..core.errors import SceneError
from .mesh import Mesh, corner_weights, element_areas

# Face k: centre c, in-face axes (ea, eb) with c × ea = eb, so every face is
# seen counter-clockwise from outside and metdet > 0 in the (east, north) basis.
# FACES[k] = (c, ea, eb) (6, 3, 3): the equiangular map's faces, for those that invert it (remap).
FACES = np.array(
    [
        [[1, 0, 0], [0, 1, 0], [0, 0, 1]],
        [[0, 1, 0], [-1, 0, 0], [0, 0, 1]],
        [[-1, 0, 0], [0, -1, 0], [0, 0, 1]],
        [[0, -1, 0], [1, 0, 0], [0, 0, 1]],
        [[0, 0, 1], [0, 1, 0], [-1, 0, 0]],
        [[0, 0, -1], [0, 1, 0], [1, 0, 0]],
    ],
    dtype=float,
)

FIT_TOLERANCE = 1e-10  # radians a corner may lie beyond its face's edge: the round-off of float64 nodes and of a frame
CANDIDATES = 4  # elements whose frames are tried for a turned cube


def gnomonic_jacobian(t2a, t2b):
    """|∂x/∂α × ∂x/∂β| of the unit sphere's gnomonic equiangular map at tan²α, tan²β (arrays
    that broadcast): (1 + tan²α)(1 + tan²β) / (1 + tan²α + tan²β)^(3/2) (Rančić, Purser &
    Mesinger 1996)."""
    return (1 + t2a) * (1 + t2b) / (1 + t2a + t2b) ** 1.5


def _fit(corners: np.ndarray, frame: np.ndarray):
    """Each element's face of the cube ``FACES`` turned by ``frame`` (3, 3): (axes (F, 3, 3)
    its face's rows c, ea, eb; angles (F, 4, 2) its corners' (α, β) there; excess (F,) how far
    (radians) its corners reach beyond the face's edges, ≤ 0 inside) for ``corners`` (F, 4, 3)."""
    faces = FACES @ frame.T
    axes = faces[np.argmax(corners.sum(axis=1) @ faces[:, 0].T, axis=1)]
    c, ta, tb = (np.einsum("fki,fi->fk", corners, axes[:, k]) for k in range(3))
    angles = np.stack([np.arctan2(ta, c), np.arctan2(tb, c)], axis=2)
    return axes, angles, np.max(np.abs(angles), axis=(1, 2)) - math.pi / 4


def _element_frame(corners: np.ndarray) -> np.ndarray:
    """The rotation (3, 3) taking face 0's axes to those of the face of a cube element with
    ``corners`` (4, 3): its edges from corner 0 to 1 and from 3 to 2 lie on great circles of
    constant β, which meet on the face's ea axis; its other two on circles of constant α, which
    meet on eb."""
    c0, c1, c2, c3 = corners
    ea = np.cross(np.cross(c0, c1), np.cross(c3, c2))
    eb = np.cross(np.cross(c0, c3), np.cross(c1, c2))
    ea, eb = ea * np.sign(ea @ (c1 - c0)), eb * np.sign(eb @ (c3 - c0))
    columns = np.stack([np.cross(ea, eb), ea, eb], axis=1)
    u, _, vt = np.linalg.svd(columns / np.linalg.norm(columns, axis=0))
    return u @ vt  # the nearest rotation: the three axes exactly orthonormal


@functools.lru_cache(maxsize=8)
def face_corners(mesh: Mesh) -> tuple[np.ndarray, np.ndarray]:
    """(axes (F, 3, 3): the rows c, ea, eb of each element's cube face; angles (F, 4, 2): its
    corners' equiangular coordinates (α, β) there, radians) of ``mesh``, in the cube's own
    frame (the module's note). Raises ``SceneError`` (one line naming the first element, 1-based)
    where no frame holds every element in one face to ``FIT_TOLERANCE``."""
    corners = mesh.corners()
    best = _fit(corners, np.eye(3))
    if np.any(best[2] > FIT_TOLERANCE):
        centroids = mesh.centroids()
        smallest = int(np.argmin(element_areas(corners)))
        for e in np.argsort(centroids @ centroids[smallest], kind="stable")[:CANDIDATES]:
            fit = _fit(corners, _element_frame(corners[e]))
            if np.count_nonzero(fit[2] > FIT_TOLERANCE) < np.count_nonzero(best[2] > FIT_TOLERANCE):
                best = fit
    axes, angles, excess = best
    bad = np.flatnonzero(excess > FIT_TOLERANCE)
    if bad.size:
        raise SceneError(
            f"{mesh.name}: element {bad[0] + 1} does not lie in one face of a cube (a corner "
            f"{math.degrees(excess[bad[0]]):.3g} degrees beyond its face's edge; {bad.size} such elements): "
            'the equiangular map needs each element in one face; use map = "element_local"'
        )
    return axes, angles


class FaceMap:
    """The equiangular map of ``mesh``'s elements in their cube faces at the GLL points of
    ``rule``, for the grid's ``_metric``: ``at(copies)`` of global element-local node indices
    e·np² + j·np + i gives (P (n, 3) the point before projection, ∂P/∂a and ∂P/∂b (n, 3) each
    divided by ``factor`` = 1/4). Raises ``SceneError`` as ``face_corners``."""

    factor = 0.25

    def __init__(self, mesh: Mesh, rule=None):
        self.mesh, self.rule = mesh, rule
        self.axes, self.angles = face_corners(mesh)

    def _angles(self, e: np.ndarray, a: np.ndarray, b: np.ndarray):
        """(α, β, 4 ∂(α, β)/∂a, 4 ∂(α, β)/∂b), each (2, n) but α, β (n,), at (a, b) (n,) of
        elements ``e`` (n,)."""
        q, dq_da, dq_db = corner_weights(a, b)
        corner = self.angles[e]  # (n, 4, 2)
        alpha, beta = np.einsum("nk,nkd->dn", q, corner)
        return alpha, beta, np.einsum("nk,nkd->dn", dq_da, corner), np.einsum("nk,nkd->dn", dq_db, corner)

    def point(self, e: np.ndarray, a: np.ndarray, b: np.ndarray):
        """(P (n, 3), 4 ∂P/∂a (n, 3), 4 ∂P/∂b (n, 3)) at the points (a, b) ∈ [−1, 1]² (n,) of
        elements ``e`` (n,); x = P/|P| is the point on the unit sphere."""
        alpha, beta, d_da, d_db = self._angles(e, a, b)
        axes = self.axes[e]
        sec2a, sec2b = 1 / np.cos(alpha) ** 2, 1 / np.cos(beta) ** 2  # d tan/dα
        P = axes[:, 0] + np.tan(alpha)[:, None] * axes[:, 1] + np.tan(beta)[:, None] * axes[:, 2]
        Pa = (sec2a * d_da[0])[:, None] * axes[:, 1] + (sec2b * d_da[1])[:, None] * axes[:, 2]
        Pb = (sec2a * d_db[0])[:, None] * axes[:, 1] + (sec2b * d_db[1])[:, None] * axes[:, 2]
        return P, Pa, Pb

    def at(self, copies: np.ndarray):
        np_ = self.rule.np
        e, p = np.divmod(copies, np_ * np_)
        j, i = np.divmod(p, np_)
        return (*self.point(e, self.rule.points[i], self.rule.points[j]), self.factor)

    def quadrature_area(self) -> float:
        """GLL quadrature (sr) of the unit sphere's area over every element of the mesh with the
        map's analytic Jacobian, ``gnomonic_jacobian`` × det ∂(α, β)/∂(a, b): what Σ metdet·w
        gives up to round-off, the same whatever elements a process holds."""
        np_, F = self.rule.np, self.mesh.nelem
        a, b = np.tile(self.rule.points, np_ * F), np.tile(np.repeat(self.rule.points, np_), F)
        alpha, beta, d_da, d_db = self._angles(np.repeat(np.arange(F), np_ * np_), a, b)
        det = (d_da[0] * d_db[1] - d_db[0] * d_da[1]) / 16
        w = np.tile(np.outer(self.rule.weights, self.rule.weights).ravel(), F)
        return float(np.sum(gnomonic_jacobian(np.tan(alpha) ** 2, np.tan(beta) ** 2) * det * w))
