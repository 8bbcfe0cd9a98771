"""The grid layer: the assembled spectral-element grid on a mesh (``swe_sphere.mesh``, the layer
below): GLL points, the cubed sphere's nodes and metric terms, the rank partition, and the
topology (DSS, assembly and reductions on one rank or over MPI); mesh quality and refinement,
which measure and make meshes through the assembled grid.

``cubed_sphere.CubedSphere`` (``D``, ``Dinv``, ``metdet``, ``spheremp``, lat/lon per node, as
HOMME's ``element_t``), ``gll.gll``, ``partition.partition`` (a space-filling curve),
``topology.Topology`` (the one seam for DSS and global sums), ``refine.refined_cube`` (the cube
refined over a latitude-longitude box; ``refine.make_mesh``, what ``swe-sphere mesh`` writes),
``quality.element_sizes`` (HOMME's Dinv-based length scales and distortion), ``levels`` (element
levels of local time stepping).

May import: ``mesh``, ``core``, ``kernels``.
"""

__all__ = ["cubed_sphere", "gll", "partition", "quality", "refine", "topology"]
