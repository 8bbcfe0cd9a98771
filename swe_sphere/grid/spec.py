"""The mesh a run's grid is built on, as a record of plain JSON values (``Scene.mesh``), so that
run and restart files carry it and a continuation rebuilds the same mesh, or refuses.

A record is one of:

- ``None``: the uniform cube of ne, through the equiangular map (HOMME ``cubed_sphere_map = 0``);
- ``{"map": "element_local"}``: the same cube through the element-local map
  (``cubed_sphere_map = 2``);
- ``{"map": "element_local", "stretch_factor": c, "target_lat": φ, "target_lon": λ}`` (degrees):
  the Schmidt-stretched cube of ne (``schmidt.schmidt_cube``; FV3's ``stretch_fac``,
  ``target_lat``, ``target_lon``);
- ``{"map": m, "cube": "equidistant"}``: the gnomonic equidistant cube of ne
  (``equidistant.equidistant_cube``; pySEs's grid with m = ``"element_local"``);
- ``{"map": m, "file": path, "sha256": hex, "nelem": F}``: an Exodus II ``.g`` file
  (``mesh.read_exodus``; HOMME's ``ne = 0`` with ``mesh_file``), its absolute path, the SHA-256
  of its bytes and its element count, through the map m: ``"element_local"`` (the default, as
  E3SM runs its meshes) or ``"equiangular"`` (each element in its cube face: ``face_map``).
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
from pathlib import Path

from ..core.errors import SceneError
from .cubed_sphere import cube_mesh
from .equidistant import equidistant_cube
from .face_map import face_corners
from .mesh import Mesh, read_exodus
from .schmidt import schmidt_cube

MAPS = ("equiangular", "element_local")  # HOMME's cubed_sphere_map = 0 and 2
CUBES = ("equiangular", "equidistant")  # where the cube's element corners lie: equal angles or equal tangents


def file_sha256(path) -> str:
    """SHA-256 (hex) of the bytes of the file ``path``."""
    with open(path, "rb") as f:
        return hashlib.file_digest(f, "sha256").hexdigest()


def file_record(path, map_: str = "element_local") -> dict:
    """The record of the Exodus II file ``path`` (made absolute) through ``map_`` (one of
    ``MAPS``), read and checked. Raises ``SceneError`` (one line) for what ``read_exodus``
    refuses, and on the equiangular map for an element in no one cube face
    (``face_map.face_corners``)."""
    path = Path(path).expanduser().absolute()
    mesh = _mapped(read_exodus(path), map_)
    return {"map": map_, "file": str(path), "sha256": file_sha256(path), "nelem": mesh.nelem}


def _mapped(mesh: Mesh, map_: str) -> Mesh:
    """``mesh`` to be built through ``map_``, checked that it can be (``face_corners``)."""
    mesh = dataclasses.replace(mesh, map=map_)
    if map_ == "equiangular":
        face_corners(mesh)
    return mesh


def build_mesh(ne: int, record: dict | None) -> Mesh | None:
    """The ``Mesh`` of ``record`` for ``CubedSphere(ne, np, mesh=...)`` (None: the equiangular
    cube, no mesh). A file is read again and must hold the bytes recorded: ``SceneError`` (one
    line) when it is gone, unreadable or changed, so a run never continues on another mesh."""
    if record is None:
        return None
    if "file" in record:
        path = Path(record["file"])
        if not path.is_file():
            raise SceneError(f"mesh file {path} not found")
        if file_sha256(path) != record["sha256"]:
            raise SceneError(
                f"mesh file {path} is not the mesh this run was made on (sha256 {record['sha256'][:12]}...): "
                "a run does not continue on another mesh"
            )
        return _mapped(read_exodus(path), record["map"])
    if "stretch_factor" in record:
        return schmidt_cube(ne, record["stretch_factor"], record["target_lat"], record["target_lon"])
    if record.get("cube") == "equidistant":
        return _mapped(equidistant_cube(ne), record["map"])
    return cube_mesh(ne)


def nelem(ne: int, record: dict | None) -> int:
    """Elements of the mesh: 6·ne² on a cube, the file's own count."""
    return int(record["nelem"]) if record is not None and "file" in record else 6 * ne * ne


def mean_ne(ne: int, record: dict | None) -> float:
    """The ne of the uniform cube with as many elements (the same mean element spacing): ne on
    a cube (stretched or not), √(F/6) for a file mesh of F elements."""
    return math.sqrt(nelem(ne, record) / 6) if record is not None and "file" in record else ne


def label(ne: int, record: dict | None) -> str:
    """The grid's part of a default file name: ``ne4``, ``ne4map2`` (the element-local map,
    HOMME's ``cubed_sphere_map = 2``), ``ne4c2.5`` (stretched by 2.5), ``ne4ed`` (the equidistant
    cube; ``ne4edmap0`` through the equiangular map), a mesh file's stem, or
    its stem and ``map0`` through the equiangular map (``cubed_sphere_map = 0``)."""
    if record is not None and "file" in record:
        return Path(record["file"]).stem + ("map0" if record["map"] == "equiangular" else "")
    if record is not None and "stretch_factor" in record:
        return f"ne{ne}c{record['stretch_factor']:g}"
    if record is not None and record.get("cube") == "equidistant":
        return f"ne{ne}ed" + ("map0" if record["map"] == "equiangular" else "")
    return f"ne{ne}" if record is None else f"ne{ne}map2"


def describe(ne: int, np_: int, record: dict | None) -> str:
    """The grid in words for headers and messages: ``ne=4 np=4``, ``ne=4 np=4 element-local``,
    ``ne=4 np=4 stretched 2.5x toward (40, 270)``, ``ne=4 np=4 equidistant cube element-local``,
    ``mesh x.g np=4`` or ``mesh x.g np=4 equiangular``."""
    if record is None:
        return f"ne={ne} np={np_}"
    if "file" in record:
        return f"mesh {Path(record['file']).name} np={np_}" + (" equiangular" if record["map"] == "equiangular" else "")
    if "stretch_factor" in record:
        return (
            f"ne={ne} np={np_} stretched {record['stretch_factor']:g}x toward "
            f"({record['target_lat']:g}, {record['target_lon']:g})"
        )
    if record.get("cube") == "equidistant":
        return f"ne={ne} np={np_} equidistant cube " + record["map"].replace("_", "-")
    return f"ne={ne} np={np_} element-local"
