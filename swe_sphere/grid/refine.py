"""The meshes ``swe-sphere mesh`` writes (``make_mesh``): the cube, the stretched cube, and the
cube refined over a latitude-longitude box by levels of 2×, with conforming quadrilateral
transitions and smoothing (``refined_cube``), as E3SM's regionally refined meshes (RRM) made by
SQuadGen (Ullrich; ``--refine_rect``, ``--refine_type CUBIT``, ``--smooth_type SPRING``).

The cube is turned so that the centre of its face 4 lies on the box's centre (SQuadGen's
``--lon_ref``/``--lat_ref``). On that face, level k (1..levels) splits every element of a
rectangle R_k into 2×2, and the ring of elements along R_k's four sides takes the 2-refinement
transition template used by CUBIT paving (Schneiders 1996, "Refining quadrilateral and hexahedral
element meshes"): two neighbours along a side each become 3 quadrilaterals through their centre,
the midpoint of their side toward R_k and the midpoint of the edge they share; the ring's corner
elements touch R_k at a node only and stay whole. R_levels is the box's elements at the finest
level; each coarser R_k holds the finer one and its ring. Then the nodes about the
refined region are smoothed (Laplacian: each moves to the normalised mean of its edge
neighbours) so that HOMME's Dinv-based distortion (``quality``) stays near that of the cube.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..mesh.cube import cube_mesh, reference_to_sphere
from ..mesh.element_local import ElementLocalMap, MeshNumbering
from ..mesh.face_map import FaceMap
from ..mesh.mesh import Mesh, check
from ..mesh.schmidt import rotation_to, schmidt_cube
from .cubed_sphere import area_corrected, held_metric, held_nodes
from .gll import gll
from .quality import dinv_singular_values

FACE = 4  # the cube face turned onto the box (its centre is the north pole before the turn)
SMOOTHING = 100  # Laplacian smoothing iterations (SQuadGen's --smooth_iter)
SMOOTH_REACH = 2  # edges from the new nodes to the farthest node the smoothing moves (SQuadGen's --smooth_dist)


@dataclass(frozen=True)
class Box:
    """A latitude-longitude box (degrees): lat_min < lat_max in [−90, 90], lon_min < lon_max
    (east, any turn: lon_max − lon_min ≤ 360)."""

    lat_min: float
    lat_max: float
    lon_min: float
    lon_max: float

    def __post_init__(self):
        values = (self.lat_min, self.lat_max, self.lon_min, self.lon_max)
        if not all(math.isfinite(v) for v in values):
            raise ValueError(f"the refinement box must be finite numbers (got {values})")
        if not -90 <= self.lat_min < self.lat_max <= 90:
            raise ValueError(
                f"the refinement box needs -90 <= lat_min < lat_max <= 90 (got {self.lat_min}, {self.lat_max})"
            )
        if not 0 < self.lon_max - self.lon_min <= 360:
            raise ValueError(
                f"the refinement box needs lon_min < lon_max <= lon_min + 360 (got {self.lon_min}, {self.lon_max})"
            )

    def centre(self) -> tuple[float, float]:
        """(lat, lon) degrees: the middle of the box's latitudes and longitudes."""
        return (self.lat_min + self.lat_max) / 2, (self.lon_min + self.lon_max) / 2

    def holds(self, xyz: np.ndarray) -> np.ndarray:
        """(n,) bool: which unit vectors xyz (n, 3) lie in the box."""
        lat = np.degrees(np.arcsin(np.clip(xyz[:, 2], -1, 1)))
        east = np.mod(np.degrees(np.arctan2(xyz[:, 1], xyz[:, 0])) - self.lon_min, 360)
        return (lat >= self.lat_min) & (lat <= self.lat_max) & (east <= self.lon_max - self.lon_min)


def _square(x: int, y: int, h: int) -> tuple:
    """The corners of the square of side h at (x, y), counter-clockwise."""
    return ((x, y), (x + h, y), (x + h, y + h), (x, y + h))


def _mid(a: tuple, b: tuple) -> tuple:
    return ((a[0] + b[0]) // 2, (a[1] + b[1]) // 2)


def _transition(corners: tuple, toward: int, pair_next: bool) -> list:
    """The 3 quadrilaterals of the 2-refinement template of a square (``corners``
    counter-clockwise) whose edge ``toward`` (from corner k to k+1) faces the refined side:
    through its centre, that edge's midpoint and the midpoint of the edge it shares with its
    pair, the next square along the refined side (``pair_next``: across the edge after
    ``toward``) or the one before (across the edge before it)."""
    p0, p1, p2, p3 = (corners[(toward + k) % 4] for k in range(4))
    m, c = _mid(p0, p1), _mid(p0, p2)
    if pair_next:
        s = _mid(p1, p2)
        return [(p0, m, c, p3), (m, p1, s, c), (c, s, p2, p3)]
    s = _mid(p3, p0)
    return [(m, p1, p2, c), (p0, m, c, s), (s, c, p2, p3)]


def _rectangles(inside: np.ndarray, ne: int, levels: int) -> list:
    """[R_1, ..., R_levels], each (x0, y0, x1, y1) in units of the finest element (the coarse
    element is 2^levels): R_levels the bounding rectangle of the finest cells ``inside`` (bool,
    (ne·2^levels,)² indexed [y, x]), each R_k aligned to level k − 1's elements with an even
    number of them along each side (the transition pairs), R_(k−1) ⊇ R_k with its ring.
    Raises ``ValueError`` when the box holds no cell's centre, or when R_1 and its
    ring leave the face."""
    rows, cols = np.nonzero(inside)
    if not rows.size:
        raise ValueError(f"the refinement box holds no element centre of the ne{ne} cube at {2**levels}x")
    rect = (int(cols.min()), int(rows.min()), int(cols.max()) + 1, int(rows.max()) + 1)
    rects, size, coarse = [], ne * 2**levels, 2**levels
    for k in range(levels, 0, -1):
        h = 2 ** (levels - k + 1)  # level k − 1's element
        x0, y0 = (h * math.floor(v / h) for v in rect[:2])
        x1, y1 = (h * math.ceil(v / h) for v in rect[2:])
        if (x1 - x0) // h % 2:  # an even number of elements a side: one more, where the face has more room
            x0, x1 = (x0 - h, x1) if x0 > size - x1 else (x0, x1 + h)
        if (y1 - y0) // h % 2:
            y0, y1 = (y0 - h, y1) if y0 > size - y1 else (y0, y1 + h)
        rects.append((x0, y0, x1, y1))
        rect = (x0 - h, y0 - h, x1 + h, y1 + h)  # R_(k−1) holds R_k's ring
    x0, y0, x1, y1 = rects[-1]
    if x0 < coarse or y0 < coarse or x1 + coarse > size or y1 + coarse > size:
        raise ValueError(
            f"the refinement box and its transitions do not fit in one face of the ne{ne} cube "
            f"(about {90 / ne:.3g} degrees an element): use a smaller box or a larger ne"
        )
    return rects[::-1]


def _refine_face(ne: int, rects: list, levels: int) -> list:
    """The quadrilaterals (corner keys (x, y) in finest-element units, counter-clockwise) of
    the face refined in ``rects`` [R_1..R_levels]."""
    h = 2**levels
    quads = [_square(i * h, j * h, h) for j in range(ne) for i in range(ne)]
    for k, (x0, y0, x1, y1) in enumerate(rects, start=1):
        h = 2 ** (levels - k + 1)
        out = []
        for q in quads:
            x, y = q[0]
            if q != _square(x, y, h):  # coarser, or a transition element made before
                out.append(q)
            elif x0 <= x < x1 and y0 <= y < y1:
                g = h // 2
                out += [_square(x + a, y + b, g) for b in (0, g) for a in (0, g)]
            elif x0 <= x < x1 and y in (y0 - h, y1):  # below (edge 2 faces R) or above (edge 0)
                out += _transition(q, 2 if y < y0 else 0, ((x - x0) // h) % 2 == (0 if y > y0 else 1))
            elif y0 <= y < y1 and x in (x0 - h, x1):  # left (edge 1 faces R) or right (edge 3)
                out += _transition(q, 1 if x < x0 else 3, ((y - y0) // h) % 2 == (0 if x < x0 else 1))
            else:
                out.append(q)
        quads = out
    return quads


def smooth(mesh: Mesh, free: np.ndarray, iterations: int = SMOOTHING) -> Mesh:
    """``mesh`` with its nodes ``free`` (indices) moved each to the normalised mean of its edge
    neighbours (Laplacian smoothing on the sphere, Jacobi sweeps; SQuadGen's spring smoothing is
    its damped form), after as many sweeps up to ``iterations`` as leave the elements that hold
    a free node the smallest largest Dinv-based distortion (``quality.element_sizes`` at np =
    4): more sweeps even out the sizes across the transitions, but pull the fine region's
    edge nodes outward and the transition elements out of shape."""
    edges, _ = mesh.edges()
    moving = np.flatnonzero(np.isin(mesh.quads, free).any(axis=1))
    count = np.bincount(edges.ravel(), minlength=mesh.nnodes)[free, None]
    distortion = WorstDistortion(mesh, moving)
    coords, best, least = mesh.coords.copy(), mesh.coords, distortion(mesh)
    for _ in range(iterations):
        total = np.zeros_like(coords)
        np.add.at(total, edges[:, 0], coords[edges[:, 1]])
        np.add.at(total, edges[:, 1], coords[edges[:, 0]])
        moved = total[free] / count
        coords[free] = moved / np.linalg.norm(moved, axis=1)[:, None]
        worst = distortion(Mesh(coords, mesh.quads))
        if worst < least:
            best, least = coords.copy(), worst
    return Mesh(best, mesh.quads, mesh.name)


class WorstDistortion:
    """The largest Dinv-based distortion of ``elements`` of a mesh with ``mesh``'s quads at
    np = 4 (inf for a folded element): ``element_sizes(CubedSphere(0, 4, 1.0,
    elements=elements, mesh=m)).distortion.max()`` bit for bit (the same ``cubed_sphere``
    steps: the metric of the nodes held and their copies, the fold check and the area
    correction, D⁻¹ of the nodes held), with the numbering of the nodes, which the quads
    alone set, built once for all the sweeps, and none of the grid's other fields."""

    def __init__(self, mesh: Mesh, elements: np.ndarray):
        self.rule, self.elements = gll(4), np.asarray(elements, dtype=np.int64)
        npe = self.rule.np**2
        _, table = MeshNumbering(mesh, self.rule.np).rows(self.elements)
        self.ext, self.rep = held_nodes(table)
        self.here = np.searchsorted(self.ext, (self.elements[:, None] * npe + np.arange(npe)).ravel())

    def __call__(self, mesh: Mesh) -> float:
        reference_map = (FaceMap if mesh.map == "equiangular" else ElementLocalMap)(mesh, self.rule)
        D = held_metric(reference_map, 1.0, self.ext, self.rep)[5]
        try:
            area_corrected(
                np.linalg.det(D), D, 0, self.rule, 1.0, self.elements, mesh, reference_map, self.ext, self.here
            )
        except ValueError:  # a folded map: a sweep that folds an element is never the best
            return math.inf
        large, small = dinv_singular_values(np.ascontiguousarray(np.linalg.inv(D[self.here]).reshape(-1, 4).T))
        per_element = (self.elements.size, self.rule.np**2)
        return float((large.reshape(per_element).max(axis=1) / small.reshape(per_element).min(axis=1)).max())


def refined_cube(ne: int, box: Box, levels: int, iterations: int = SMOOTHING) -> Mesh:
    """The ne cube (``cube_mesh``) turned so that its face 4 is centred on ``box`` and refined
    there by ``levels`` levels of 2× (elements 2^levels times smaller across than the cube's
    in the box), with conforming transitions and ``iterations`` Laplacian smoothing sweeps of
    the nodes within two coarse elements of the refined region; checked (``mesh.check``).
    Raises ``ValueError`` for ne < 1, levels < 1, iterations < 0, or a box that holds no
    element centre or does not fit in one face with its transitions."""
    if isinstance(levels, bool) or int(levels) != levels or levels < 1:
        raise ValueError(f"refinement levels must be an integer >= 1 (got {levels})")
    if isinstance(iterations, bool) or int(iterations) != iterations or iterations < 0:
        raise ValueError(f"smoothing iterations must be an integer >= 0 (got {iterations})")
    cube, levels = cube_mesh(ne), int(levels)
    turn = rotation_to(*box.centre())
    n, h = ne * 2**levels, 2**levels
    # the finest cells of face 4, their centres turned onto the box
    cell = (np.arange(n) + 0.5) / h
    x, y = np.meshgrid(cell, cell)
    inside = box.holds(_face_points(ne, x.ravel(), y.ravel()) @ turn.T).reshape(n, n)
    rects = _rectangles(inside, ne, levels)
    face_quads = _refine_face(ne, rects, levels)

    # face 4's corner nodes keep their cube numbers; the new nodes follow
    first = FACE * ne * ne
    node = {}
    for e, corners in enumerate(cube.quads[first : first + ne * ne]):
        for key, number in zip(_square((e % ne) * h, (e // ne) * h, h), corners, strict=True):
            node[key] = int(number)
    keys = sorted({k for q in face_quads for k in q} - node.keys())
    node.update({key: cube.nnodes + i for i, key in enumerate(keys)})
    new = np.array(keys, dtype=np.float64).reshape(-1, 2) / h
    coords = np.vstack([cube.coords, _face_points(ne, new[:, 0], new[:, 1])]) @ turn.T
    quads = np.vstack(
        [cube.quads[:first], np.array([[node[k] for k in q] for q in face_quads]), cube.quads[first + ne * ne :]]
    )
    name = (
        f"ne{ne} cube refined {2**levels}x over lat {box.lat_min:g}..{box.lat_max:g}, "
        f"lon {box.lon_min:g}..{box.lon_max:g}"
    )
    mesh = Mesh(coords, quads, name)
    free = np.zeros(mesh.nnodes, dtype=bool)
    free[cube.nnodes :] = True
    edges, _ = mesh.edges()
    for _ in range(SMOOTH_REACH):  # and the nodes up to SMOOTH_REACH edges away, on any face
        free[edges[free[edges].any(axis=1)]] = True
    return check(smooth(mesh, np.flatnonzero(free), iterations))


def make_mesh(
    ne: int,
    *,
    stretch_factor: float | None = None,
    target_lat: float | None = None,
    target_lon: float | None = None,
    box: Box | None = None,
    levels: int | None = None,
    smoothing: int | None = None,
) -> Mesh:
    """The checked mesh ``swe-sphere mesh`` writes: the ne cube (``cube_mesh``); with
    ``stretch_factor`` the Schmidt-stretched cube (``schmidt.schmidt_cube``, toward
    (target_lat, target_lon), degrees, default the north pole); with ``box`` the cube refined
    there by ``levels`` (default 1) levels of 2× with ``smoothing`` sweeps (default
    ``SMOOTHING``; ``refined_cube``). Raises ``ValueError`` (one line naming the option) for a
    target without a stretch, a stretch with a box, levels or smoothing without a box, and
    what ``cube_mesh``, ``schmidt_cube``, ``refined_cube`` or ``mesh.check`` refuse."""
    if stretch_factor is None and (target_lat is not None or target_lon is not None):
        raise ValueError("target_lat and target_lon place a stretch: they need stretch_factor")
    if box is None and (levels is not None or smoothing is not None):
        raise ValueError("levels and smoothing refine a box: they need a refinement box")
    if box is not None:
        if stretch_factor is not None:
            raise ValueError("a refinement box refines the uniform cube: it cannot be stretched too")
        return refined_cube(ne, box, 1 if levels is None else levels, SMOOTHING if smoothing is None else smoothing)
    if stretch_factor is not None:
        lat, lon = 90.0 if target_lat is None else target_lat, 0.0 if target_lon is None else target_lon
        return check(schmidt_cube(ne, stretch_factor, lat, lon))
    return check(cube_mesh(ne))


def _face_points(ne: int, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Unit vectors (n, 3) of the points (x, y) ∈ [0, ne]² (element units) of face 4 of the
    ne cube through its equiangular map."""
    ia, jb = np.minimum(np.floor(x), ne - 1), np.minimum(np.floor(y), ne - 1)
    e = (FACE * ne * ne + jb * ne + ia).astype(np.int64)
    return reference_to_sphere(ne, e, 2 * (x - ia) - 1, 2 * (y - jb) - 1)
