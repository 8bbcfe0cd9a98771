"""The mesh layer, below the assembled grid (ClimaCore's ``Meshes`` apart from its
``Topologies``): what elements a grid is made of and where their corners lie, before any GLL
node or metric term.

``mesh.Mesh`` (any conforming quadrilateral mesh of the sphere; Exodus II ``.g`` files in and
out), ``cube`` (the equiangular cube: its numbering, map and ``cube_mesh``), ``element_local``
(the element-local map and the numbering of any mesh), ``face_map`` (the equiangular map in each
element's cube face), ``schmidt.schmidt_cube`` (the stretched cube), ``equidistant.equidistant_cube``
(the gnomonic equidistant cube, pySEs's), ``records`` (``CubeMesh``, ``StretchedCube``,
``MeshFile``: a scene's mesh as a frozen record with ``build()``, carried by run files as JSON).

May import: ``core``, ``kernels``.
"""

__all__ = ["cube", "element_local", "equidistant", "face_map", "mesh", "records", "schmidt"]
