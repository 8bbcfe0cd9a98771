"""The mesh a run's grid is built on, as a small frozen record (``Scene.mesh``) that run and
restart files carry as plain JSON, so that a continuation rebuilds the same mesh, or refuses.

A scene's mesh is one of (None: the uniform cube of ne through the equiangular map, HOMME's
``cubed_sphere_map = 0``; JSON ``null``, left out of the scene's record):

- ``CubeMesh(ne, map, cube)``: the cube of ne through ``map`` (``"element_local"``,
  ``cubed_sphere_map = 2``), its element corners at equal angles or, ``cube = "equidistant"``,
  at equal tangents (``equidistant.equidistant_cube``; pySEs's grid). JSON ``{"map": m}`` or
  ``{"map": m, "cube": "equidistant"}``;
- ``StretchedCube(ne, factor, lat, lon)``: the Schmidt-stretched cube of ne through the
  element-local map (``schmidt.schmidt_cube``; FV3's ``stretch_fac``, ``target_lat``,
  ``target_lon``, degrees). JSON ``{"map": "element_local", "stretch_factor": c,
  "target_lat": φ, "target_lon": λ}``;
- ``MeshFile(path, sha256, map, nelem)``: an Exodus II ``.g`` file (``mesh.read_exodus``;
  HOMME's ``ne = 0`` with ``mesh_file``), its absolute path, the SHA-256 of its bytes and its
  element count, through ``map``: ``"element_local"`` (the default, as E3SM runs its meshes) or
  ``"equiangular"`` (each element in its cube face: ``face_map``). JSON ``{"map": m, "file":
  path, "sha256": hex, "nelem": F}``.

Each has ``build()`` (the ``Mesh`` for ``CubedSphere(ne, np, mesh=...)``), ``nelem``,
``mean_ne``, ``label`` (a default file name's part) and ``description(np)`` (words for
messages). A mesh file is read and hashed once a process while its size and modification time
stay the same (``read_mesh_file``), however many records name it and builds ask for it.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import math
import os
from pathlib import Path

from ..core.errors import SceneError
from .cube import cube_mesh
from .equidistant import equidistant_cube
from .face_map import face_corners
from .mesh import Mesh, read_exodus
from .schmidt import schmidt_cube

MAPS = ("equiangular", "element_local")  # HOMME's cubed_sphere_map = 0 and 2
CUBES = ("equiangular", "equidistant")  # where the cube's element corners lie: equal angles or equal tangents


class _OnTheCube:
    """What a record of the cube of ``ne`` elements an edge knows of its size."""

    ne: int

    @property
    def nelem(self) -> int:
        return 6 * self.ne * self.ne

    @property
    def mean_ne(self) -> float:
        return self.ne


@dataclasses.dataclass(frozen=True)
class CubeMesh(_OnTheCube):
    """The cube of ``ne`` elements an edge through ``map`` (``MAPS``), its corners at equal
    angles or equal tangents (``cube``, one of ``CUBES``)."""

    ne: int
    map: str = "equiangular"
    cube: str = "equiangular"

    def as_json(self) -> dict | None:
        """The record as plain values (None: the equiangular cube through its own map)."""
        if self.cube == "equidistant":
            return {"map": self.map, "cube": self.cube}
        return None if self.map == "equiangular" else {"map": self.map}

    def build(self) -> Mesh | None:
        """The ``Mesh``; None for the equiangular cube (``CubedSphere``'s own numbering)."""
        if self.cube == "equidistant":
            return _mapped(equidistant_cube(self.ne), self.map)
        return None if self.map == "equiangular" else cube_mesh(self.ne)

    @property
    def label(self) -> str:
        """``ne4``, ``ne4map2`` (element-local), ``ne4ed`` (equidistant), ``ne4edmap0``."""
        if self.cube == "equidistant":
            return f"ne{self.ne}ed" + ("map0" if self.map == "equiangular" else "")
        return f"ne{self.ne}" + ("map2" if self.map == "element_local" else "")

    def description(self, np_: int) -> str:
        """``ne=4 np=4``, ``ne=4 np=4 element-local``, ``ne=4 np=4 equidistant cube element-local``."""
        words = f"ne={self.ne} np={np_}"
        if self.cube == "equidistant":
            return f"{words} equidistant cube " + self.map.replace("_", "-")
        return words + (" element-local" if self.map == "element_local" else "")


@dataclasses.dataclass(frozen=True)
class StretchedCube(_OnTheCube):
    """The cube of ``ne`` stretched by ``factor`` ≥ 1 toward (``lat``, ``lon``) (degrees),
    through the element-local map (``schmidt.schmidt_cube``)."""

    ne: int
    factor: float
    lat: float = 90.0
    lon: float = 0.0
    map = "element_local"  # the one map a stretched cube is built through

    def as_json(self) -> dict:
        return {"map": self.map, "stretch_factor": self.factor, "target_lat": self.lat, "target_lon": self.lon}

    def build(self) -> Mesh:
        """The ``Mesh``; ``ValueError`` for a stretch that folds an element."""
        return schmidt_cube(self.ne, self.factor, self.lat, self.lon)

    @property
    def label(self) -> str:
        """``ne4c2.5``."""
        return f"ne{self.ne}c{self.factor:g}"

    def description(self, np_: int) -> str:
        """``ne=4 np=4 stretched 2.5x toward (40, 270)``."""
        return f"ne={self.ne} np={np_} stretched {self.factor:g}x toward ({self.lat:g}, {self.lon:g})"


@dataclasses.dataclass(frozen=True)
class MeshFile:
    """An Exodus II file: its absolute ``path``, the ``sha256`` of its bytes, the ``map`` it is
    built through (``MAPS``) and its element count ``nelem``."""

    path: str
    sha256: str
    map: str = "element_local"
    nelem: int = 0

    @classmethod
    def of(cls, path, map_: str = "element_local") -> MeshFile:
        """The record of the file ``path`` (made absolute) through ``map_``, read and checked.
        Raises ``SceneError`` (one line) for what ``read_exodus`` refuses, and on the
        equiangular map for an element in no one cube face (``face_map.face_corners``)."""
        path = Path(path).expanduser().absolute()
        mesh, sha256 = read_mesh_file(path, map_)
        return cls(str(path), sha256, map_, mesh.nelem)

    def as_json(self) -> dict:
        return {"map": self.map, "file": self.path, "sha256": self.sha256, "nelem": self.nelem}

    def build(self) -> Mesh:
        """The file's ``Mesh`` through ``map``. ``SceneError`` (one line) when the file is
        gone, unreadable or holds other bytes than recorded, so a run never continues on
        another mesh."""
        path = Path(self.path)
        if not path.is_file():
            raise SceneError(f"mesh file {path} not found")
        mesh, sha256 = read_mesh_file(path, self.map)
        if sha256 != self.sha256:
            raise SceneError(
                f"mesh file {path} is not the mesh this run was made on (sha256 {self.sha256[:12]}...): "
                "a run does not continue on another mesh"
            )
        return mesh

    @property
    def mean_ne(self) -> float:
        """√(F/6): the ne of the uniform cube with as many elements (the same mean spacing)."""
        return math.sqrt(self.nelem / 6)

    @property
    def label(self) -> str:
        """The file's stem, and ``map0`` through the equiangular map."""
        return Path(self.path).stem + ("map0" if self.map == "equiangular" else "")

    def description(self, np_: int) -> str:
        """``mesh x.g np=4`` or ``mesh x.g np=4 equiangular``."""
        return f"mesh {Path(self.path).name} np={np_}" + (" equiangular" if self.map == "equiangular" else "")


MeshRecord = CubeMesh | StretchedCube | MeshFile


def file_sha256(path) -> str:
    """SHA-256 (hex) of the bytes of the file ``path``."""
    with open(path, "rb") as f:
        return hashlib.file_digest(f, "sha256").hexdigest()


def read_mesh_file(path, map_: str) -> tuple[Mesh, str]:
    """(the checked ``Mesh`` of the Exodus II file ``path`` through ``map_``, the SHA-256 of its
    bytes): read and hashed once a process while the file keeps its size and modification
    time. Raises ``SceneError`` as ``MeshFile.of``."""
    if not Path(path).is_file():
        read_exodus(path)  # its one-line refusal: not found, or a folder
    stat = os.stat(path)
    return _read_mesh_file(str(path), stat.st_size, stat.st_mtime_ns, map_)


@functools.lru_cache(maxsize=8)
def _read_mesh_file(path: str, size: int, mtime_ns: int, map_: str) -> tuple[Mesh, str]:
    mesh, sha256 = _read_and_hash(path, size, mtime_ns)
    return _mapped(mesh, map_), sha256


@functools.lru_cache(maxsize=4)
def _read_and_hash(path: str, size: int, mtime_ns: int) -> tuple[Mesh, str]:
    return read_exodus(path), file_sha256(path)  # size and mtime_ns: the key only


def _mapped(mesh: Mesh, map_: str) -> Mesh:
    """``mesh`` to be built through ``map_``, checked that it can be (``face_corners``)."""
    mesh = dataclasses.replace(mesh, map=map_)
    if map_ == "equiangular":
        face_corners(mesh)
    return mesh


def mesh_of(ne: int, record: MeshRecord | None) -> MeshRecord:
    """The record of a grid of ``ne`` and ``record`` (None: the equiangular cube of ne)."""
    return CubeMesh(ne) if record is None else record


def from_json(ne: int, d: dict | None) -> MeshRecord | None:
    """The record of ``as_json``'s plain values ``d`` for a grid of ``ne`` (a scene's ``ne``
    and ``mesh``, read back from a run or restart file); None for None."""
    if d is None:
        return None
    if "file" in d:
        return MeshFile(d["file"], d["sha256"], d["map"], int(d["nelem"]))
    if "stretch_factor" in d:
        return StretchedCube(ne, d["stretch_factor"], d["target_lat"], d["target_lon"])
    return CubeMesh(ne, d["map"], d.get("cube", "equiangular"))


def with_ne(record: MeshRecord | None, ne: int) -> MeshRecord | None:
    """``record`` on a cube of ``ne`` (a scene's ne replaced); a file's mesh is its own."""
    return record if record is None or isinstance(record, MeshFile) else dataclasses.replace(record, ne=ne)
