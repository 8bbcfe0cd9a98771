"""The grid layer: GLL points, the cubed sphere's nodes and metric terms, its numbering, the
rank partition, and the topology (DSS, assembly and reductions on one rank or over MPI).

``cubed_sphere.CubedSphere`` (``D``, ``Dinv``, ``metdet``, ``spheremp``, lat/lon per node, as
HOMME's ``element_t``), ``gll.gll``, ``partition.partition`` (a space-filling curve),
``topology.Topology`` (the one seam for DSS and global sums), ``mesh.Mesh`` (any conforming
quadrilateral mesh of the sphere; Exodus II ``.g`` files in and out), ``element_local`` (its map and
numbering), ``face_map`` (the equiangular map in each element's cube face), ``schmidt.schmidt_cube`` (the stretched cube),
``equidistant.equidistant_cube`` (the gnomonic equidistant cube, pySEs's), ``refine.refined_cube`` (the cube
refined over a latitude-longitude box; ``refine.make_mesh``, what ``swe-sphere mesh`` writes),
``quality.element_sizes`` (HOMME's Dinv-based length scales and distortion).

May import: ``core``, ``kernels``.
"""

__all__ = [
    "cubed_sphere",
    "element_local",
    "equidistant",
    "face_map",
    "gll",
    "mesh",
    "partition",
    "quality",
    "refine",
    "schmidt",
    "topology",
]
