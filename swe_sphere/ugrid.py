"""UGRID description of the GLL nodes: the sub-cell mesh of quads between nodes.

Each element's ``np``×``np`` GLL nodes span ``(np−1)²`` quadrilateral sub-cells;
over the sphere that is ``nface = 6·ne²·(np−1)²`` quads on the ``nunique``
unique nodes (the ``ncol`` of the run file), every node a corner of at least one
quad. Corners are ordered counter-clockwise as seen from outside the sphere
(the face axes of ``grid._FACES`` satisfy c × ea = eb, so increasing ξ then η
turns counter-clockwise). Written into every run file by ``output.RunWriter``
as a UGRID-1.0 ``mesh_topology`` (Jacobsen et al., UGRID conventions), which
uxarray and other unstructured-grid tools read.
"""

from __future__ import annotations

import numpy as np

from .grid import CubedSphere

MESH = "mesh_topology"
CONNECTIVITY = "face_node_connectivity"
FACE_DIM, MAX_DIM = "nface", "nmax_face"


def subcell_quads(grid: CubedSphere) -> np.ndarray:
    """Corner node ids (unique ids = ``ncol`` indices), int32 (nface, 4), counter-clockwise
    from outside: (i, j), (i+1, j), (i+1, j+1), (i, j+1) in each element's GLL indices."""
    n = grid.np
    gid = grid.gid.reshape(grid.nelem, n, n)  # [e, j, i]
    quads = np.stack([gid[:, :-1, :-1], gid[:, :-1, 1:], gid[:, 1:, 1:], gid[:, 1:, :-1]], axis=-1)
    return np.ascontiguousarray(quads.reshape(-1, 4), dtype=np.int32)


def orientation(xyz_unique: np.ndarray, quads: np.ndarray) -> np.ndarray:
    """Signed orientation of each quad seen from outside: ((b−a)×(c−a))·a for its two
    triangles (a, b, c) and (a, c, d), the smaller of the two; > 0 means counter-clockwise.

    ``xyz_unique``: (nunique, 3) unit vectors of the nodes."""
    a, b, c, d = (xyz_unique[quads[:, k]] for k in range(4))
    t1 = np.einsum("ij,ij->i", np.cross(b - a, c - a), a)
    t2 = np.einsum("ij,ij->i", np.cross(c - a, d - a), a)
    return np.minimum(t1, t2)


def write_mesh(ds, grid: CubedSphere) -> None:
    """Add the UGRID mesh variables to an open ``netCDF4.Dataset`` ``ds`` whose node
    coordinates are ``lon``/``lat`` on the unique nodes (their dimension UGRID takes
    from the coordinates)."""
    quads = subcell_quads(grid)
    ds.createDimension(FACE_DIM, quads.shape[0])
    ds.createDimension(MAX_DIM, 4)
    mesh = ds.createVariable(MESH, "i4", ())
    mesh.setncatts(
        dict(
            cf_role="mesh_topology",
            long_name="sub-cell mesh of quadrilaterals between the GLL nodes",
            topology_dimension=np.int32(2),
            node_coordinates="lon lat",
            face_node_connectivity=CONNECTIVITY,
            face_dimension=FACE_DIM,
        )
    )
    mesh.assignValue(0)
    conn = ds.createVariable(CONNECTIVITY, "i4", (FACE_DIM, MAX_DIM), fill_value=False)
    conn.setncatts(
        dict(
            cf_role="face_node_connectivity",
            long_name="corner nodes (ncol indices) of each sub-cell, counter-clockwise from outside",
            start_index=np.int32(0),
        )
    )
    conn[:] = quads
