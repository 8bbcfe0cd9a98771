"""Equiangular gnomonic cubed-sphere spectral-element grid (numpy, built once).

Mirrors HOMME's ``element_t`` metric terms (``cube_mod``, ``coordinate_systems_mod``):
per GLL node ``D``, ``Dinv``, ``metdet``, ``spheremp``, ``rspheremp``, ``lat``,
``lon``; plus the global numbering of unique nodes used by the DSS.

Storage is element-local and flat: node ``(e, i, j)`` (element e, GLL index i
along the element's first reference coordinate ξ, j along η) lives at
``p = e*np*np + j*np + i``; ``N = nelem*np*np``. Element ``e = face*ne*ne +
jb*ne + ia``. Sources: Sadourny (1972) and Ronchi et al. (1996) for the
equiangular map; Taylor, Tribbia & Iskandarani (1997) and Dennis et al. (2012)
for the spectral-element metric terms.
"""

from __future__ import annotations

import math

import numpy as np

from ..core.arguments import integer_argument, number_argument
from ..core.constants import EARTH
from ..core.errors import ArgumentError
from ..mesh.cube import EquiangularMap, Numbering, reference_to_sphere
from ..mesh.element_local import ElementLocalMap, MeshNumbering, epsilon_bubble, mesh_point
from ..mesh.face_map import FaceMap, gnomonic_jacobian
from ..mesh.mesh import Mesh
from .gll import gll


class CubedSphere:
    """Cubed-sphere SE grid with ``ne`` × ``ne`` elements per face and ``np`` GLL points,
    or the part of it made of ``elements`` (an MPI rank's: only those are built and stored).

    With ``mesh`` (a checked ``Mesh``), the grid of that quadrilateral mesh through its map
    (``mesh.map``): the element-local map (HOMME ``cubed_sphere_map = 2``, ``element_local``),
    np ≥ 3, or the equiangular map in each element's cube face (``cubed_sphere_map = 0``,
    ``face_map``); ``ne = 0`` for a mesh from a file (HOMME's ``ne = 0`` with ``mesh_file``), or
    the cube's ne when ``mesh`` is ``cube_mesh(ne)`` (its elements are then the cube's, and so is
    its partition). Without, the cube's equiangular map (HOMME ``cubed_sphere_map = 0``).

    ne, np, radius (m), rule (``GLL``), mesh (the ``Mesh`` or None), nelem_total (elements of
    the whole grid: 6·ne² on the cube, ``mesh.nelem``), elements (E,) int64 (those held).

    Arrays (float64 unless said; N = nelem·np² element-local nodes held, those of
    ``elements`` in order; "global" indices are those of the whole grid)::

      nodes (N,) int64   global element-local index of each node held
      xyz (3, N)       unit position vectors
      lat, lon (N,)    radians; lon in [0, 2π); lon = 0 at the poles
      east, north (3, N)  unit tangent basis of the (u, v) wind components; one
                       basis per unique node, so all copies of a node agree
      D, Dinv (4, N)   2×2 maps reference contravariant ↔ (east, north)
                       components, row-major [D11, D12, D21, D22]; units m
                       (D includes the radius a) and 1/m
      metdet (N,)      det D (m²), with one global factor so that GLL quadrature
                       of it gives 4πa² (HOMME's area correction, map0; also on a mesh
                       through the equiangular map); on a mesh through the element-local
                       map, a factor per element on its interior nodes so that its
                       quadrature gives the element's spherical area (HOMME's epsilon
                       bubble, map2)
      spheremp (N,)    GLL weight × metdet (m²): the element mass matrix
      rspheremp (N,)   1 / (DSS-summed spheremp): inverse assembled mass
      dx (N,)          distance to the nearest neighbouring GLL node (m), for CFL
      gid (N,) int32   global unique-node id; there are nelem_total·(np−1)² + 2 ids,
                       numbered in the order of their first copies
      dss_table (N, C) int32  the global indices of all copies of node p's unique
                       node, ascending (the DSS's summation order), padded with −1
                       (C = most copies of a node: 4, 3 at ne = 1; a mesh's largest
                       node valence, up to 7)
      first (n,) int32  local index of the first copy of each unique node whose
                       first copy is held, ascending gid (all nunique of them when whole)
      area (n,)        assembled spheremp of those unique nodes (m²); sums to 4πa² when whole
      halo (H,) int64, halo_spheremp (H,)  the other elements' copies of the nodes
                       held (global indices, ascending) and their spheremp (m²)

    A part's arrays are the whole grid's at its nodes, bit for bit: every value is
    computed per node, the numbering from the cube's (or mesh's) topology, and the area
    correction from the analytic Jacobian (or per element: the same for any part).
    Raises ``ArgumentError`` (a ValueError) naming the argument for ne not an integer >= 1
    (>= 0 with a mesh, or ne > 0 not the mesh's 6·ne² elements), ``np_`` not an integer in 2..8,
    a radius (m) not finite and > 0, a mesh not a ``Mesh``, elements not ascending distinct
    indices of the grid; ``ValueError`` for np 2 with a mesh through the element-local map, or
    a mesh element the map folds
    (metdet ≤ 0 at a node: its corners span too much of the sphere, one line naming it);
    ``SceneError`` for a mesh through the equiangular map with an element in no one cube face.
    """

    def __init__(self, ne: int, np_: int, radius: float = EARTH.a, elements=None, mesh: Mesh | None = None):
        ne = integer_argument("ne", ne, 0 if mesh is not None else 1)
        np_ = integer_argument("np_", np_, 2)
        if np_ > 8:
            raise ArgumentError(f"np_ must be in 2..8 (got {np_})")
        radius = number_argument("radius", radius, "m", positive=True)
        if mesh is not None and not isinstance(mesh, Mesh):
            raise ArgumentError(f"mesh must be a Mesh or None (got {mesh!r:.60})")
        if mesh is not None and ne and mesh.nelem != 6 * ne * ne:
            raise ArgumentError(f"ne={ne} needs a mesh of {6 * ne * ne} elements ({mesh.name} has {mesh.nelem})")
        self.ne, self.np, self.radius, self.mesh = int(ne), int(np_), float(radius), mesh
        self.rule = gll(self.np)  # validates np
        self.nelem_total = 6 * self.ne * self.ne if mesh is None else mesh.nelem
        self.elements = _elements(self.nelem_total, elements)
        for name, value in _build(self.ne, self.rule, self.radius, self.elements, mesh).items():
            setattr(self, name, value)

    @property
    def map(self) -> str:
        """The reference map: ``"equiangular"`` (the cube's, or ``mesh``'s in its faces) or
        ``"element_local"`` (``mesh.map``)."""
        return "equiangular" if self.mesh is None else self.mesh.map

    def reference_to_sphere(self, e: np.ndarray, xi: np.ndarray, eta: np.ndarray) -> np.ndarray:
        """Unit position vectors (n, 3) of the points (ξ, η) ∈ [−1, 1]² (n,) of elements ``e``
        (n,) (global indices) through the grid's map (equiangular, or ``mesh``'s own)."""
        if self.mesh is None:
            return reference_to_sphere(self.ne, e, xi, eta)
        xi, eta = np.asarray(xi, dtype=np.float64), np.asarray(eta, dtype=np.float64)
        p = mesh_point(self.mesh)(np.asarray(e), xi, eta)[0]
        return p / np.linalg.norm(p, axis=1)[:, None]

    def part(self, elements) -> CubedSphere:
        """The same grid built for ``elements`` only (ascending global indices)."""
        return CubedSphere(self.ne, self.np, self.radius, elements=elements, mesh=self.mesh)

    @property
    def nelem(self) -> int:
        """Elements held (nelem_total, 6·ne² on the cube, for the whole grid)."""
        return self.elements.size

    @property
    def nnodes(self) -> int:
        """Element-local nodes held N = nelem·np²."""
        return self.nelem * self.np * self.np

    @property
    def nunique(self) -> int:
        """Unique nodes of the whole grid: F(np−1)² + 2 for any quadrilateral mesh of the
        sphere with F elements (V = F + 2 corners, E = 2F edges)."""
        return self.nelem_total * (self.np - 1) ** 2 + 2

    def integrate(self, f: np.ndarray) -> float:
        """Area integral ∫ f dA (m² × units of f) of a continuous element-local field f (N,)."""
        return float(np.sum(self.spheremp * f))  # not np.dot: the same bits whatever BLAS's threads

    def to_unique(self, f: np.ndarray) -> np.ndarray:
        """Element-local (..., N) → the unique nodes of ``first`` (..., n)."""
        return f[..., self.first]


def _elements(nelem: int, elements) -> np.ndarray:
    """The element indices a grid holds: all, or ``elements`` checked ascending and distinct."""
    if elements is None:
        return np.arange(nelem)
    e = np.asarray(elements, dtype=np.int64)
    if e.ndim != 1 or (e.size and (e[0] < 0 or e[-1] >= nelem or np.any(np.diff(e) <= 0))):
        raise ArgumentError(f"elements must be ascending distinct indices in 0..{nelem - 1}")
    return e


def _quadrature_area(ne: int, rule, radius: float) -> float:
    """GLL quadrature of the sphere's area (m²) with the analytic Jacobian of the
    equiangular map, a²(Δα/2)²(1 + tan²α)(1 + tan²β)/(1 + tan²α + tan²β)^(3/2),
    the same on the six faces: what Σ metdet·w gives up to round-off, computed
    alike by every process whatever elements it holds."""
    dalpha = math.pi / 2 / ne
    edges = np.linspace(-math.pi / 4, math.pi / 4, ne + 1)
    t2 = np.tan((edges[:-1, None] + (rule.points[None, :] + 1) * dalpha / 2).ravel()) ** 2
    w = np.tile(rule.weights, ne)
    J = gnomonic_jacobian(t2[:, None], t2[None, :])
    return 6 * radius**2 * (dalpha / 2) ** 2 * float(np.sum(J * w[:, None] * w[None, :]))


_CHUNK = 1 << 14  # nodes per piece of the metric's computation


def lat_lon(xyz: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Latitude in [−π/2, π/2] and longitude in [0, 2π) (radians) of unit vectors xyz (..., 3)."""
    return np.arcsin(np.clip(xyz[..., 2], -1, 1)), np.mod(np.arctan2(xyz[..., 1], xyz[..., 0]), 2 * math.pi)


def _metric(reference_map, radius: float, copies: np.ndarray, rep: np.ndarray):
    """(xyz, lat, lon, east, north, D) of element-local nodes ``copies`` (global
    indices) whose unique nodes' first copies are ``rep``: the position and
    (east, north) basis are the first copy's, so every copy's agree bit for bit;
    D (n, 2, 2) is the Jacobian of X = a P/|P| w.r.t. the element reference
    coordinates (ξ, η) in that basis, before the area correction, with P and its
    derivatives from ``reference_map.at`` (``EquiangularMap``, ``ElementLocalMap`` or
    ``FaceMap``)."""
    P, t_xi, t_eta, factor = reference_map.at(copies)
    rP = np.linalg.norm(P, axis=1)
    xhat = P / rP[:, None]
    xyz = xhat.copy()
    moved = rep != copies  # most copies are their node's first: only the others need their first's position
    P_rep = reference_map.at(rep[moved])[0]
    xyz[moved] = P_rep / np.linalg.norm(P_rep, axis=1)[:, None]  # the same bits as computed there (per node)
    xyz[np.abs(xyz) < 1e-15] = 0.0
    xyz /= np.linalg.norm(xyz, axis=1)[:, None]
    lat, lon = lat_lon(xyz)
    east = np.stack([-np.sin(lon), np.cos(lon), np.zeros_like(lon)], axis=1)
    north = np.stack([-np.sin(lat) * np.cos(lon), -np.sin(lat) * np.sin(lon), np.cos(lat)], axis=1)
    proj = np.eye(3)[None] - xhat[:, :, None] * xhat[:, None, :]
    scale = radius * factor / rP
    dX_dxi = scale[:, None] * np.einsum("nij,nj->ni", proj, t_xi)
    dX_deta = scale[:, None] * np.einsum("nij,nj->ni", proj, t_eta)
    D = np.empty((copies.size, 2, 2))
    D[:, 0, 0] = np.einsum("ni,ni->n", east, dX_dxi)
    D[:, 0, 1] = np.einsum("ni,ni->n", east, dX_deta)
    D[:, 1, 0] = np.einsum("ni,ni->n", north, dX_dxi)
    D[:, 1, 1] = np.einsum("ni,ni->n", north, dX_deta)
    return xyz, lat, lon, east, north, D


def _build(ne: int, rule, radius: float, elements: np.ndarray, mesh: Mesh | None) -> dict:
    np_ = rule.np
    npe = np_ * np_
    nodes = (elements[:, None] * npe + np.arange(npe)).ravel()
    if mesh is None:
        gid, table = Numbering(ne, np_).rows(elements)
        reference_map = EquiangularMap(ne, rule)
    else:
        gid, table = MeshNumbering(mesh, np_).rows(elements)
        reference_map = (FaceMap if mesh.map == "equiangular" else ElementLocalMap)(mesh, rule)
    ext, rep = held_nodes(table)
    xyz, lat, lon, east, north, D = held_metric(reference_map, radius, ext, rep)
    here = np.searchsorted(ext, nodes)
    metdet = area_corrected(np.linalg.det(D), D, ne, rule, radius, elements, mesh, reference_map, ext, here)
    spheremp = metdet * np.outer(rule.weights, rule.weights).ravel()[ext % npe]  # weights at index j*np + i

    mass = np.zeros(nodes.size)  # Σ over the copies in table order, one add at a time
    for column in table.T:
        ok = column >= 0
        mass[ok] += spheremp[np.searchsorted(ext, column[ok])]
    first = np.flatnonzero(table[:, 0] == nodes)  # first copies held: ascending gid
    halo = np.setdiff1d(ext, nodes, assume_unique=True)

    D = D[here]
    return dict(
        nodes=nodes,
        xyz=np.ascontiguousarray(xyz[here].T),
        lat=lat[here],
        lon=lon[here],
        east=np.ascontiguousarray(east[here].T),
        north=np.ascontiguousarray(north[here].T),
        D=np.ascontiguousarray(D.reshape(-1, 4).T),
        Dinv=np.ascontiguousarray(np.linalg.inv(D).reshape(-1, 4).T),
        metdet=metdet[here],
        spheremp=spheremp[here],
        rspheremp=1.0 / mass,
        dx=_spacing(radius * xyz[here].reshape(elements.size, np_, np_, 3)).ravel(),
        gid=gid.astype(np.int32),
        dss_table=table.astype(np.int32),
        first=first.astype(np.int32),
        area=mass[first],
        halo=halo,
        halo_spheremp=spheremp[np.searchsorted(ext, halo)],
    )


def held_nodes(table: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(ext, rep), int64 (n,) each: the element-local nodes held and the other elements' copies of
    them (for the assembled mass), distinct and ascending, and for each the first copy in the rows
    of ``table`` (rows of element-local node ids, −1 for none): every copy gets the coordinates of
    its first copy, so lat/lon/basis agree bit for bit. Shared with ``refine.WorstDistortion``."""
    valid = table >= 0
    ext = np.sort(table[valid])
    ext = ext[
        np.concatenate(([True], ext[1:] != ext[:-1]))
    ]  # distinct, ascending (np.unique's hashing is 10x slower here)
    rep = np.empty(ext.size, dtype=np.int64)
    rep[np.searchsorted(ext, table[valid])] = np.broadcast_to(table[:, :1], table.shape)[valid]
    return ext, rep


def held_metric(reference_map, radius: float, ext: np.ndarray, rep: np.ndarray):
    """(xyz (n, 3) in units of ``radius``, lat, lon (n,) radians, east, north (n, 3) unit
    vectors, D (n, 2, 2)) at the n nodes ``ext`` (their first copies ``rep``, ``held_nodes``) of
    ``reference_map``, in pieces of ``_CHUNK`` nodes to bound the temporaries."""
    n = ext.size
    xyz, east, north, lat, lon = np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3)), np.empty(n), np.empty(n)
    D = np.empty((n, 2, 2))
    for a in range(0, n, _CHUNK):
        part = slice(a, a + _CHUNK)
        xyz[part], lat[part], lon[part], east[part], north[part], D[part] = _metric(
            reference_map, radius, ext[part], rep[part]
        )
    return xyz, lat, lon, east, north, D


def area_corrected(metdet, D, ne: int, rule, radius: float, elements, mesh, reference_map, ext, here) -> np.ndarray:
    """The metric determinant ``metdet`` (n,) with the area correction (HOMME's
    ``set_area_correction_map0`` on the cube), ``D`` (n, 2, 2) scaled to match in place.
    Raises ValueError where the map folds (metdet ≤ 0 at a node)."""
    np_ = rule.np
    if np.any(metdet <= 0):  # an element-local element whose corners span too much of the sphere: p/|p| folds
        e = int(ext[np.argmax(metdet <= 0)] // (np_ * np_))
        where = f"element {e + 1} of {mesh.name}" if mesh is not None else f"element {e}"
        raise ValueError(
            f"the map folds in {where} (metdet <= 0 at a GLL node): its corners span too much of the sphere; "
            "use smaller elements (a larger ne, a smaller stretch_factor)"
        )
    if mesh is None or mesh.map == "equiangular":
        # Area correction (HOMME geometry_mod::set_area_correction_map0): one global
        # factor on the metric so that the GLL-quadrature area of the sphere is 4πa².
        # A single factor keeps element-edge fluxes consistent, hence mass
        # conservation to round-off; a per-element factor would not.
        quadrature = _quadrature_area(ne, rule, radius) if mesh is None else radius**2 * reference_map.quadrature_area()
        s = math.sqrt(4 * math.pi * radius**2 / quadrature)
        D *= s
        return metdet * s**2
    # HOMME's epsilon bubble (set_area_correction_map2): a factor per element on
    # its interior nodes only, which no other element shares, so the edge
    # fluxes still cancel; the copies of shared nodes held for the mass keep theirs.
    alpha = epsilon_bubble(mesh, rule, radius, elements, metdet[here].reshape(-1, np_, np_))
    p = here.reshape(-1, np_, np_)[:, 1:-1, 1:-1]
    a = np.broadcast_to(alpha[:, None, None], p.shape)
    D[p.ravel()] *= np.sqrt(a.ravel())[:, None, None]
    metdet[p.ravel()] *= a.ravel()
    return metdet


def _spacing(X: np.ndarray) -> np.ndarray:
    """Nearest-neighbour spacing along both element directions, (nelem, np, np), of the node
    positions ``X`` (nelem, np, np, 3)."""
    dist_i = np.linalg.norm(np.diff(X, axis=2), axis=3)  # (nelem, j, np-1)
    dist_j = np.linalg.norm(np.diff(X, axis=1), axis=3)  # (nelem, np-1, i)
    dx = np.full(X.shape[:3], np.inf)
    dx[:, :, :-1] = np.minimum(dx[:, :, :-1], dist_i)
    dx[:, :, 1:] = np.minimum(dx[:, :, 1:], dist_i)
    dx[:, :-1, :] = np.minimum(dx[:, :-1, :], dist_j)
    dx[:, 1:, :] = np.minimum(dx[:, 1:, :], dist_j)
    return dx
