"""Conforming quadrilateral meshes of the unit sphere: the uniform cube, and Exodus II ``.g`` files.

A ``Mesh`` is what HOMME's ``mesh_mod`` reads from a ``.g`` file (``ne = 0``, ``mesh_file``; meshes
made by SQuadGen, TempestRemap or CUBIT): corner nodes on the unit sphere and quadrilateral
elements given by their four corner nodes, counter-clockwise seen from outside. ``check``
verifies what the spectral-element grid built on it needs (unit radius, orientation, a conforming
cover of the sphere, node valence 3 to 7); ``read_exodus`` and ``write_exodus`` carry meshes in and
out through netCDF4 (the Exodus II layout HOMME reads: ``coord (num_dim, num_nodes)`` or
``coordx/coordy/coordz``, ``connect1 (num_el_in_blk1, 4)`` 1-based, one element block).
Elements and nodes are named in messages by their 1-based numbers, as in the file.
"""

from __future__ import annotations

import hashlib
import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..core.errors import OutputError, SceneError
from ..core.files import replaced

RADIUS_TOLERANCE = 1e-10  # |‖x‖ − 1| allowed of a node (files hold float64 unit vectors)
AREA_TOLERANCE = 1e-8  # relative difference allowed between the elements' total area and 4π
VALENCE = (3, 7)  # elements a node may be shared by (HOMME's mesh_mod)


@dataclass(frozen=True, eq=False)
class Mesh:
    """A quadrilateral mesh of the unit sphere.

    coords (V, 3) float64 : node positions, unit vectors
    quads (F, 4) int64 : each element's corner nodes (0-based), counter-clockwise seen from
        outside; corner k sits at reference point (−1, −1), (1, −1), (1, 1), (−1, 1) of the
        element-local map (HOMME ``corners3D``)
    name : where the mesh came from (a file name, or ``"ne<k> cube"``), for messages
    map : how a grid places its GLL points between an element's corners: ``"element_local"``
        (HOMME's ``cubed_sphere_map = 2``, ``element_local``) or ``"equiangular"``
        (``cubed_sphere_map = 0`` element by element, in the angles of its cube face: ``face_map``)
    """

    coords: np.ndarray
    quads: np.ndarray
    name: str = "mesh"
    map: str = "element_local"

    @property
    def nelem(self) -> int:
        """Elements F."""
        return int(self.quads.shape[0])

    @property
    def nnodes(self) -> int:
        """Corner nodes V."""
        return int(self.coords.shape[0])

    def corners(self) -> np.ndarray:
        """(F, 4, 3) the elements' corner positions, in ``quads`` order."""
        return self.coords[self.quads]

    def edges(self) -> tuple[np.ndarray, np.ndarray]:
        """(edge_nodes (E, 2) int64, element_edges (F, 4) int64): the distinct element edges as
        node pairs (smaller node first, ascending), and the edge k of each element (from corner
        k to corner k+1 mod 4)."""
        a, b = self.quads, np.roll(self.quads, -1, axis=1)
        pairs = np.stack([np.minimum(a, b), np.maximum(a, b)], axis=-1).reshape(-1, 2)
        edge_nodes, inverse = np.unique(pairs, axis=0, return_inverse=True)
        return edge_nodes, inverse.reshape(self.quads.shape)

    def sha256(self) -> str:
        """SHA-256 (hex) of the mesh's content: ``coords`` as little-endian float64 and ``quads`` as
        little-endian int64, with their shapes (what a grid built on it is a function of; the name
        is left out)."""
        h = hashlib.sha256()
        for a in (np.ascontiguousarray(self.coords, dtype="<f8"), np.ascontiguousarray(self.quads, dtype="<i8")):
            h.update(f"{a.dtype.str}{a.shape};".encode())
            h.update(a.tobytes())
        return h.hexdigest()

    def centroids(self) -> np.ndarray:
        """(F, 3) unit vectors: the normalised mean of each element's corners."""
        c = self.corners().mean(axis=1)
        return c / np.linalg.norm(c, axis=1)[:, None]


def corner_weights(a: np.ndarray, b: np.ndarray):
    """The bilinear weights q_k of an element's corners k = 0..3 (at (−1, −1), (1, −1), (1, 1),
    (−1, 1)) at reference points (a, b) (n,), and 4 ∂q_k/∂a, 4 ∂q_k/∂b: three (n, 4) arrays
    (HOMME ``ref2sphere``)."""
    q = np.stack([(1 - a) * (1 - b), (1 + a) * (1 - b), (1 + a) * (1 + b), (1 - a) * (1 + b)], axis=1) / 4
    dq_da = np.stack([-(1 - b), 1 - b, 1 + b, -(1 + b)], axis=1)
    dq_db = np.stack([-(1 - a), -(1 + a), 1 + a, 1 - a], axis=1)
    return q, dq_da, dq_db


def _triangle_area(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Signed areas (sr) of the spherical triangles with unit-vector corners a, b, c (n, 3):
    positive counter-clockwise seen from outside (Van Oosterom & Strackee 1983)."""
    numerator = np.einsum("ni,ni->n", a, np.cross(b, c))
    denominator = 1 + np.einsum("ni,ni->n", a, b) + np.einsum("ni,ni->n", b, c) + np.einsum("ni,ni->n", c, a)
    return 2 * np.arctan2(numerator, denominator)


def element_areas(corners: np.ndarray) -> np.ndarray:
    """(F,) areas (sr) of spherical quadrilaterals with corners (F, 4, 3), counter-clockwise:
    the triangles (1, 2, 3) and (1, 3, 4), as HOMME's ``set_area_correction_map2``."""
    c = [corners[:, k] for k in range(4)]
    return _triangle_area(c[0], c[1], c[2]) + _triangle_area(c[0], c[2], c[3])


def check(mesh: Mesh) -> Mesh:
    """``mesh`` itself once it is a conforming, counter-clockwise quadrilateral cover of the
    unit sphere (neighbours running along their shared edge in opposite directions, V − E + F
    = 2, total area 4π) with node valence 3 to 7. Raises ``SceneError`` with one line naming the mesh
    and the first offending element or node (1-based) otherwise."""
    name, x, q = mesh.name, mesh.coords, mesh.quads
    if x.ndim != 2 or x.shape[1] != 3 or q.ndim != 2 or q.shape[1] != 4 or not q.size:
        raise SceneError(f"{name}: needs node coordinates (V, 3) and quadrilaterals (F, 4)")
    bad = np.flatnonzero(~np.isfinite(x).all(axis=1) | (np.abs(np.linalg.norm(x, axis=1) - 1) > RADIUS_TOLERANCE))
    if bad.size:
        raise SceneError(
            f"{name}: node {bad[0] + 1} is not on the unit sphere (|x| = {float(np.linalg.norm(x[bad[0]])):.17g})"
        )
    bad = np.flatnonzero((q < 0).any(axis=1) | (q >= len(x)).any(axis=1))
    if bad.size:
        raise SceneError(f"{name}: element {bad[0] + 1} names a node outside 1..{len(x)}")
    repeated = np.sort(q, axis=1)
    bad = np.flatnonzero((repeated[:, 1:] == repeated[:, :-1]).any(axis=1))
    if bad.size:
        raise SceneError(f"{name}: element {bad[0] + 1} repeats a corner node")
    c = mesh.corners()
    turns = np.stack(  # each corner's turn, seen from outside: > 0 where the boundary turns left
        [
            np.einsum("ni,ni->n", np.cross(c[:, k] - c[:, k - 1], c[:, (k + 1) % 4] - c[:, k]), c[:, k])
            for k in range(4)
        ],
        axis=1,
    )
    bad = np.flatnonzero((turns <= 0).any(axis=1))
    if bad.size:
        how = "clockwise" if (turns[bad[0]] <= 0).all() else "not convex"
        raise SceneError(
            f"{name}: element {bad[0] + 1} is {how} seen from outside (corners must run counter-clockwise)"
        )
    edge_nodes, element_edges = mesh.edges()
    count = np.bincount(element_edges.ravel(), minlength=len(edge_nodes))
    bad = np.flatnonzero(count != 2)
    if bad.size:
        a, b = edge_nodes[bad[0]] + 1
        owners = np.flatnonzero((element_edges == bad[0]).any(axis=1)) + 1
        raise SceneError(
            f"{name}: the edge from node {a} to node {b} is in {count[bad[0]]} element(s) "
            f"({', '.join(map(str, owners))}), not 2: the mesh is not conforming"
        )
    forward = np.bincount(
        element_edges.ravel(), weights=(q < np.roll(q, -1, axis=1)).ravel(), minlength=len(edge_nodes)
    )
    bad = np.flatnonzero(forward != 1)  # counter-clockwise neighbours run along a shared edge in opposite directions
    if bad.size:
        a, b = edge_nodes[bad[0]] + 1
        owners = np.flatnonzero((element_edges == bad[0]).any(axis=1)) + 1
        raise SceneError(
            f"{name}: elements {owners[0]} and {owners[1]} run the same way along the edge from node {a} to node {b}: "
            "they overlap"
        )
    valence = np.bincount(q.ravel(), minlength=len(x))
    bad = np.flatnonzero((valence < VALENCE[0]) | (valence > VALENCE[1]))
    if bad.size:
        raise SceneError(
            f"{name}: node {bad[0] + 1} is shared by {valence[bad[0]]} elements ({VALENCE[0]} to {VALENCE[1]} allowed)"
        )
    euler = len(x) - len(edge_nodes) + len(q)
    if euler != 2:
        raise SceneError(f"{name}: V − E + F = {euler}, not 2: the elements do not make one sphere")
    area = float(np.sum(element_areas(c)))
    if abs(area / (4 * math.pi) - 1) > AREA_TOLERANCE:
        raise SceneError(f"{name}: the elements cover {area / math.pi:.6g}π sr, not 4π: they overlap")
    return mesh


def read_exodus(path: str | os.PathLike) -> Mesh:
    """The checked ``Mesh`` (``check``) of an Exodus II file: ``coord (num_dim, num_nodes)`` or
    ``coordx``/``coordy``/``coordz``, one element block ``connect1 (num_el_in_blk1, 4)`` of
    1-based node numbers. Raises ``SceneError``, one line naming the file, for a missing or
    unreadable file, not netCDF, a layout other than that, or a mesh ``check`` refuses."""
    import netCDF4
    import scipy.io

    path = Path(path)
    name = path.name
    if path.is_dir():
        raise SceneError(f"mesh file {path} is a directory, not an Exodus II file")
    if not path.is_file():
        raise SceneError(f"mesh file {path} not found")
    try:
        with open(path, "rb") as f:
            magic = f.read(8)
        classic = magic[:3] == b"CDF"
        if not classic and magic != b"\x89HDF\r\n\x1a\n":  # neither netCDF-3 nor netCDF-4 (HDF5)
            raise SceneError(f"{name} is not a netCDF file: an Exodus II mesh (.g) is one")
        if classic:  # netCDF-C reads a truncated netCDF-3 file's missing bytes as zeros: scipy's reader refuses it
            scipy.io.netcdf_file(path, mmap=False).close()
        with netCDF4.Dataset(path) as f:
            dims, variables = f.dimensions, f.variables
            blocks = len(dims["num_el_blk"]) if "num_el_blk" in dims else 1
            if blocks != 1:
                raise SceneError(f"{name}: {blocks} element blocks; one block of quadrilaterals is supported")
            if "connect1" not in variables:
                raise SceneError(f"{name}: no element block connect1")
            connect = variables["connect1"]
            if connect.ndim != 2 or connect.shape[1] != 4:
                raise SceneError(f"{name}: elements of {connect.shape[-1]} nodes; quadrilaterals (4) are needed")
            if "coord" in variables:
                coords = np.asarray(variables["coord"][:], dtype=np.float64).T
            elif all(f"coord{a}" in variables for a in "xyz"):
                coords = np.stack([np.asarray(variables[f"coord{a}"][:], dtype=np.float64) for a in "xyz"], axis=1)
            else:
                raise SceneError(f"{name}: no node coordinates (coord or coordx, coordy, coordz)")
            quads = np.asarray(connect[:], dtype=np.int64) - 1
    except SceneError:
        raise
    except (OSError, RuntimeError, IndexError, ValueError):  # netCDF4's, scipy's and numpy's wordings
        raise SceneError(f"{name}: its arrays cannot be read in full (a truncated or damaged netCDF file)") from None
    return check(Mesh(np.ascontiguousarray(coords), np.ascontiguousarray(quads), name))


def write_exodus(path: str | os.PathLike, mesh: Mesh, title: str | None = None) -> Path:
    """Write ``mesh`` as an Exodus II file HOMME reads (netCDF-3, ``coord``, one block
    ``connect1`` of 1-based ``SHELL4`` elements), whole or not at all: written to a temporary
    name beside ``path`` and renamed. Returns the path. Raises ``OutputError`` (one line) where
    ``path``'s folder cannot be written."""
    path = Path(path)
    try:
        with replaced(path) as tmp:  # 0644: a mesh is for others to read, as a run file
            _write_exodus(tmp, mesh, title)
    except OSError as err:
        raise OutputError(f"cannot write {path}: {err.strerror}") from None
    return path


def _write_exodus(tmp: Path, mesh: Mesh, title: str | None) -> None:
    """The Exodus II variables of ``write_exodus`` into the new file ``tmp``."""
    import netCDF4

    with netCDF4.Dataset(tmp, "w", format="NETCDF3_64BIT_OFFSET") as f:
        f.title = title or f"swe_sphere: {mesh.name}"
        f.api_version = f.version = np.float32(4.98)
        f.floating_point_word_size = np.int32(8)
        f.file_size = np.int32(1)
        for dim, size in (
            ("len_string", 33),
            ("len_line", 81),
            ("four", 4),
            ("time_step", None),
            ("num_dim", 3),
            ("num_nodes", mesh.nnodes),
            ("num_elem", mesh.nelem),
            ("num_el_blk", 1),
            ("num_el_in_blk1", mesh.nelem),
            ("num_nod_per_el1", 4),
        ):
            f.createDimension(dim, size)
        f.createVariable("time_whole", "f8", ("time_step",))
        f.createVariable("eb_status", "i4", ("num_el_blk",))[:] = 1
        prop = f.createVariable("eb_prop1", "i4", ("num_el_blk",))
        prop.setncattr("name", "ID")
        prop[:] = 1
        names = f.createVariable("coor_names", "S1", ("num_dim", "len_string"))
        names[:] = netCDF4.stringtochar(np.array(["x", "y", "z"], dtype="S33"))
        connect = f.createVariable("connect1", "i4", ("num_el_in_blk1", "num_nod_per_el1"))
        connect.elem_type = "SHELL4"
        connect[:] = mesh.quads + 1
        f.createVariable("coord", "f8", ("num_dim", "num_nodes"))[:] = mesh.coords.T
