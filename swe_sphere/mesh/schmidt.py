"""The Schmidt-stretched cube (FV3's ``do_schmidt``; Schmidt 1977; Harris, Lin & Tu 2016, J.
Climate 29:4293, §2a).

The cube is turned so that the centre of its north face (face 4) lies on the target, then
every node is moved along its great circle through the target, from angular distance θ to θ'
with tan(θ'/2) = tan(θ/2)/c: a conformal map (a scaling by 1/c of the stereographic
projection from the target's antipode) that keeps the topology and refines the elements
near the target by c and coarsens those at its antipode by c, a resolution ratio of c².
The stretched corners make a ``Mesh`` for the element-local map, as a ``.g`` file of the same
mesh would in HOMME.
"""

from __future__ import annotations

import math

import numpy as np

from .cube import cube_mesh
from .mesh import Mesh


def rotation_to(target_lat: float, target_lon: float) -> np.ndarray:
    """(3, 3) the rotation taking the north pole to (target_lat, target_lon) (degrees) along
    its meridian: about y by the target's colatitude, then about z by its longitude; the
    identity, exactly, for the north pole itself at longitude 0."""
    colat, lon = math.pi / 2 - math.radians(target_lat), math.radians(target_lon)
    about_y = np.array([[math.cos(colat), 0, math.sin(colat)], [0, 1, 0], [-math.sin(colat), 0, math.cos(colat)]])
    about_z = np.array([[math.cos(lon), -math.sin(lon), 0], [math.sin(lon), math.cos(lon), 0], [0, 0, 1]])
    return about_z @ about_y


def schmidt(xyz: np.ndarray, stretch_factor: float, target: np.ndarray) -> np.ndarray:
    """Unit vectors xyz (n, 3) moved toward the unit vector ``target`` (3,) by the Schmidt
    transform with factor c: cos θ' = ((c² − 1) + (c² + 1) cos θ) / ((c² + 1) + (c² − 1) cos θ)
    and the component across the target scaled by sin θ'/sin θ = 2c / ((c² + 1) + (c² − 1) cos θ)
    (θ the angle from the target; no division by sin θ, so the target and its antipode are
    regular). xyz itself for c = 1."""
    c = float(stretch_factor)
    if c == 1:  # the identity: kept exact, so that c = 1 is the unstretched cube bit for bit
        return xyz
    z = xyz @ target
    # those over 2c, in cos²(θ/2) and sin²(θ/2): no c² to lose the 1 of c² ± 1 (c = 1e9) or overflow
    near, far = c * (0.5 + 0.5 * z), (0.5 - 0.5 * z) / c
    cos_new = (near - far) / (near + far)
    across = (xyz - z[:, None] * target) / (near + far)[:, None]
    out = cos_new[:, None] * target + across
    return out / np.linalg.norm(out, axis=1)[:, None]


def schmidt_cube(ne: int, stretch_factor: float, target_lat: float = 90.0, target_lon: float = 0.0) -> Mesh:
    """The ne cube (``cube_mesh``) with the centre of its face 4 turned onto (target_lat,
    target_lon) (degrees) and stretched toward it by ``stretch_factor`` c ≥ 1 (FV3's
    ``stretch_fac``): element spacing about 1/c of the cube's at the target and c times it at
    the antipode. The cube's elements and corner numbering, so ``CubedSphere(ne, np,
    mesh=...)`` partitions it as the cube. Raises ``ValueError`` for c < 1 or not finite, a
    latitude outside [−90, 90] or a longitude not finite."""
    c = float(stretch_factor)
    if not math.isfinite(c) or c < 1:
        raise ValueError(f"stretch_factor must be a number >= 1 (got {stretch_factor})")
    if not -90 <= float(target_lat) <= 90 or not math.isfinite(float(target_lon)):
        raise ValueError(f"target_lat must be in [-90, 90] and target_lon finite (got {target_lat}, {target_lon})")
    cube = cube_mesh(ne)
    turn = rotation_to(target_lat, target_lon)
    coords = cube.coords @ turn.T
    name = f"ne{ne} cube stretched by {c:g} toward ({float(target_lat):g}, {float(target_lon):g})"
    return Mesh(schmidt(coords, c, turn[:, 2]), cube.quads, name)
