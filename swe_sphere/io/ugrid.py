"""UGRID description of the GLL nodes: the sub-cell mesh of quads between nodes.

Each element's ``np``×``np`` GLL nodes span ``(np−1)²`` quadrilateral sub-cells;
over the sphere that is ``nface = 6·ne²·(np−1)²`` quads on the ``nunique``
unique nodes (the ``ncol`` of the run file), every node a corner of at least one
quad. Corners are ordered counter-clockwise as seen from outside the sphere
(the face axes of ``grid.cubed_sphere.FACES`` satisfy c × ea = eb, so increasing ξ then η
turns counter-clockwise). Written into every run file by ``output.RunWriter``
as a UGRID-1.0 ``mesh_topology`` (Jacobsen et al., UGRID conventions), beside the
dual mesh of control volumes (``dual``) that the fields live on.
"""

from __future__ import annotations

import numpy as np

from ..grid.cubed_sphere import CubedSphere

MESH = "mesh_topology"
CONNECTIVITY = "subcell_face_nodes"  # not uxarray's own name for the variable it reads (it renames to it)
FACE_DIM, MAX_DIM = "nface", "nmax_face"
# CDI's (CDO's netCDF reader's) mark of a variable that is no field: without it CDO takes the mesh's
# integer tables and vertex coordinates for fields on grids of their own ("generic"), the first of which
# ``cdo gridarea`` measures and ``cdo remapcon`` refuses ("Unsupported generic coordinates")
NOT_A_FIELD = {"cdi": "ignore"}


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


def write_topology(
    ds,
    name: str,
    connectivity: str,
    faces: np.ndarray,
    dims: tuple,
    *,
    long_name: str,
    corners: str,
    node_coordinates: str,
    **attrs,
) -> None:
    """Add a 2-D UGRID ``mesh_topology`` variable ``name`` and its face_node_connectivity
    ``connectivity`` (int32 ``faces`` (nface, nmax) on ``dims``, 0-based, −1 padding as
    its _FillValue; ``corners`` its long_name) to an open ``netCDF4.Dataset`` ``ds``;
    ``attrs``: more attributes of the mesh (face_coordinates, ...)."""
    mesh = ds.createVariable(name, "i4", ())
    mesh.setncatts(
        dict(
            cf_role="mesh_topology",
            long_name=long_name,
            topology_dimension=np.int32(2),
            node_coordinates=node_coordinates,
            face_node_connectivity=connectivity,
            face_dimension=dims[0],
            **attrs,
        )
    )
    mesh.assignValue(0)
    padded = bool((faces < 0).any())
    conn = ds.createVariable(
        connectivity, "i4", dims, fill_value=np.int32(-1) if padded else False, zlib=True
    )  # 25× smaller
    conn.setncatts(dict(cf_role="face_node_connectivity", long_name=corners, start_index=np.int32(0), **NOT_A_FIELD))
    conn[:] = faces


def write_mesh(ds, grid: CubedSphere) -> None:
    """Add the UGRID mesh variables to an open ``netCDF4.Dataset`` ``ds`` whose node
    coordinates are ``lon``/``lat`` on the unique nodes (their dimension UGRID takes
    from the coordinates)."""
    quads = subcell_quads(grid)
    ds.createDimension(FACE_DIM, quads.shape[0])
    ds.createDimension(MAX_DIM, 4)
    write_topology(
        ds,
        MESH,
        CONNECTIVITY,
        quads,
        (FACE_DIM, MAX_DIM),
        long_name="sub-cell mesh of quadrilaterals between the GLL nodes",
        node_coordinates="lon lat",
        corners="corner nodes (ncol indices) of each sub-cell, counter-clockwise from outside",
    )
