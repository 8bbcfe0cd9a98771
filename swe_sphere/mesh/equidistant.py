"""The gnomonic equidistant cube (Sadourny 1972; Rančić, Purser & Mesinger 1996, Q. J. R.
Meteorol. Soc. 122, 959–982): the cube's element corners equally spaced on the faces of the
cube itself (in tan α), not in angle α as on the equiangular cube. pySEs builds its
"quasi-uniform" grid so (its ``init_cube_topo`` corners, through the element-local map).

The elements are then not uniform: about 7.1° across at a face centre at ne = 16 and 3.8° at a
face edge (atan(2/ne) and π/4 − atan(1 − 2/ne)), so the cube edges and corners get about 1.5×
the equiangular cube's resolution and the face centres about 0.8×. Which is better is a matter
of where a flow's gradients lie (docs/explanation/efficiency/frontier.md, "Which cube for which case"): Galewsky's
jet lies along the cube edges between the equatorial faces and the polar face (35–45° N),
TC2's smooth flow everywhere.
"""

from __future__ import annotations

import math

import numpy as np

from .cube import cube_mesh
from .face_map import FACES
from .mesh import Mesh


def equidistant_cube(ne: int) -> Mesh:
    """The ne cube (``cube_mesh``: its elements, corner numbering and partition) with every
    corner node moved from face angles (α, β) to the point c + (4α/π) ea + (4β/π) eb of its
    cube face (FACES' rows c, ea, eb), projected onto the sphere: corners equally spaced in
    tan α. A node on a cube edge or corner lands on the same point from each of its faces
    (its along-edge angle is the same there, and its across-edge tangent is ±1). For the
    element-local map (pySEs's grid), or the equiangular map between its corners' angles.
    Raises ``ValueError`` for ne < 1."""
    cube = cube_mesh(ne)
    x = cube.coords
    face = np.argmax(x @ FACES[:, 0].T, axis=1)  # a node's face: the centre nearest to it (any one on an edge)
    c, ea, eb = FACES[face, 0], FACES[face, 1], FACES[face, 2]
    xc = np.sum(x * c, axis=1)
    alpha, beta = np.arctan(np.sum(x * ea, axis=1) / xc), np.arctan(np.sum(x * eb, axis=1) / xc)
    p = c + (4 / math.pi) * (alpha[:, None] * ea + beta[:, None] * eb)
    return Mesh(p / np.linalg.norm(p, axis=1)[:, None], cube.quads, f"ne{ne} equidistant cube")
