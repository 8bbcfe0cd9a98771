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

from .constants import EARTH
from .gll import gll

# Face k: centre c, in-face axes (ea, eb) with c × ea = eb, so every face is
# seen counter-clockwise from outside and metdet > 0 in the (east, north) basis.
_FACES = np.array(
    [
        [[1, 0, 0], [0, 1, 0], [0, 0, 1]],
        [[0, 1, 0], [-1, 0, 0], [0, 0, 1]],
        [[-1, 0, 0], [0, -1, 0], [0, 0, 1]],
        [[0, -1, 0], [1, 0, 0], [0, 0, 1]],
        [[0, 0, 1], [0, 1, 0], [-1, 0, 0]],
        [[0, 0, -1], [0, 1, 0], [1, 0, 0]],
    ],
    dtype=float,
)


class CubedSphere:
    """Cubed-sphere SE grid with ``ne``×``ne`` elements per face and ``np`` GLL points.

    Arrays (float64 unless said; N = 6·ne²·np² element-local nodes):
      xyz (3, N)       unit position vectors
      lat, lon (N,)    radians; lon in [0, 2π); lon = 0 at the poles
      east, north (3, N)  unit tangent basis of the (u, v) wind components; one
                       basis per unique node, so all copies of a node agree
      D, Dinv (4, N)   2×2 maps reference contravariant ↔ (east, north)
                       components, row-major [D11, D12, D21, D22]; units m
                       (D includes the radius a) and 1/m
      metdet (N,)      det D (m²), with one global factor so that GLL quadrature
                       of it gives 4πa² (HOMME's area correction, map0)
      spheremp (N,)    GLL weight × metdet (m²): the element mass matrix
      rspheremp (N,)   1 / (DSS-summed spheremp): inverse assembled mass
      dx (N,)          distance to the nearest neighbouring GLL node (m), for CFL
      gid (N,) int32   unique-node id; there are 6·ne²·(np−1)² + 2 ids
      dss_offsets (nunique+1,), dss_copies (N,) int32   CSR list of the
                       element-local copies of each unique node
      dss_table (N, C) int32  the copies of node p's unique node, in dss_copies
                       order, padded with −1 (C = most copies of a node: 4,
                       3 at ne = 1): what the DSS gathers, one row per node
      first (nunique,) int32  one element-local index per unique node (output)
      area (nunique,)  assembled spheremp of each unique node (m²); sums to 4πa²

    Raises ``ValueError`` for ne < 1 or np outside 2..8.
    """

    def __init__(self, ne: int, np: int, radius: float = EARTH.a):
        if isinstance(ne, bool) or int(ne) != ne or ne < 1:
            raise ValueError(f"ne must be an integer >= 1 (got {ne})")
        self.ne, self.np, self.radius = int(ne), int(np), float(radius)
        self.rule = gll(self.np)  # validates np
        for name, value in _build(self.ne, self.rule, self.radius).items():
            setattr(self, name, value)

    @property
    def nelem(self) -> int:
        return 6 * self.ne * self.ne

    @property
    def npts(self) -> int:
        """Element-local node count N = nelem·np²."""
        return self.nelem * self.np * self.np

    @property
    def nunique(self) -> int:
        return 6 * self.ne * self.ne * (self.np - 1) ** 2 + 2

    def integrate(self, f: np.ndarray) -> float:
        """Area integral ∫ f dA (m² × units of f) of a continuous element-local field f (N,)."""
        return float(np.sum(self.spheremp * f))  # not np.dot: the same bits whatever BLAS's threads

    def to_unique(self, f: np.ndarray) -> np.ndarray:
        """Element-local (..., N) → unique nodes (..., nunique)."""
        return f[..., self.first]


def _coincident(ne: int, npts: int, face, jb, ia) -> tuple[int, np.ndarray]:
    """(count, label per node) of the coincident element-local nodes, from the
    cube's topology in exact integer arithmetic (no search over coordinates).

    Node (i, j) of element (face, jb, ia) sits at lattice point (k, l) =
    (ia·(np−1) + i, jb·(np−1) + j) of its face, 0 ≤ k, l ≤ M = ne·(np−1),
    and at the integer point M·c + (2k − M)·ea + (2l − M)·eb on the cube
    scaled by M (c, ea, eb the face's axis vectors). The lattice coordinate of
    an angle is odd about the face centre (the element edges and the GLL points
    are symmetric), so every copy of a node on a cube edge or corner, seen from
    any face, lands on the same integer point, and only those do."""
    M = ne * (npts - 1)
    per = npts * npts
    i, j = np.tile(np.arange(npts), npts), np.repeat(np.arange(npts), npts)  # node index j·np + i
    k = (np.repeat(ia, per) * (npts - 1) + np.tile(i, ia.size)).astype(np.int64)
    l = (np.repeat(jb, per) * (npts - 1) + np.tile(j, jb.size)).astype(np.int64)
    F = _FACES.astype(np.int64)[np.repeat(face, per)]
    Q = M * F[:, 0] + (2 * k - M)[:, None] * F[:, 1] + (2 * l - M)[:, None] * F[:, 2] + M  # in [0, 2M]
    key = (Q[:, 0] * (2 * M + 1) + Q[:, 1]) * (2 * M + 1) + Q[:, 2]
    _, labels = np.unique(key, return_inverse=True)
    return int(labels.max()) + 1, labels.ravel()


def _build(ne: int, rule, radius: float) -> dict:
    npts = rule.np
    nelem = 6 * ne * ne
    edges = np.linspace(-math.pi / 4, math.pi / 4, ne + 1)
    dalpha = math.pi / 2 / ne
    ref = rule.points
    # Element-local angles: shapes (nelem, np(j), np(i)) flattened to N.
    face, jb, ia = np.meshgrid(np.arange(6), np.arange(ne), np.arange(ne), indexing="ij")
    face, jb, ia = face.ravel(), jb.ravel(), ia.ravel()
    alpha = edges[ia][:, None, None] + (ref[None, None, :] + 1) * dalpha / 2
    beta = edges[jb][:, None, None] + (ref[None, :, None] + 1) * dalpha / 2
    alpha = np.broadcast_to(alpha, (nelem, npts, npts)).ravel()
    beta = np.broadcast_to(beta, (nelem, npts, npts)).ravel()
    fnode = np.repeat(face, npts * npts)
    c, ea, eb = _FACES[fnode, 0], _FACES[fnode, 1], _FACES[fnode, 2]
    ta, tb = np.tan(alpha), np.tan(beta)
    P = c + ta[:, None] * ea + tb[:, None] * eb
    rP = np.linalg.norm(P, axis=1)
    xhat = P / rP[:, None]

    # Unique nodes: identify coincident copies, then give every copy the
    # coordinates of one representative so lat/lon/basis agree bit for bit.
    n = xhat.shape[0]
    ncomp, labels = _coincident(ne, npts, face, jb, ia)
    expected = 6 * ne * ne * (npts - 1) ** 2 + 2
    if ncomp != expected:
        raise RuntimeError(f"grid has {ncomp} unique nodes, expected {expected}")
    # number unique nodes in order of first appearance
    _, first = np.unique(labels, return_index=True)
    order = np.argsort(first)
    relabel = np.empty(ncomp, dtype=np.int64)
    relabel[order] = np.arange(ncomp)
    gid = relabel[labels]
    first = np.sort(first)
    xyz = xhat[first][gid]
    xyz[np.abs(xyz) < 1e-15] = 0.0
    xyz /= np.linalg.norm(xyz, axis=1)[:, None]
    lat = np.arcsin(np.clip(xyz[:, 2], -1, 1))
    lon = np.mod(np.arctan2(xyz[:, 1], xyz[:, 0]), 2 * math.pi)
    east = np.stack([-np.sin(lon), np.cos(lon), np.zeros_like(lon)], axis=1)
    north = np.stack([-np.sin(lat) * np.cos(lon), -np.sin(lat) * np.sin(lon), np.cos(lat)], axis=1)

    # Jacobian of X = a P/|P| w.r.t. the element reference coordinates (ξ, η).
    proj = np.eye(3)[None] - xhat[:, :, None] * xhat[:, None, :]
    scale = radius * dalpha / 2 / rP
    dX_dxi = scale[:, None] * np.einsum("nij,nj->ni", proj, ea / np.cos(alpha)[:, None] ** 2)
    dX_deta = scale[:, None] * np.einsum("nij,nj->ni", proj, eb / np.cos(beta)[:, None] ** 2)
    D = np.empty((n, 2, 2))
    D[:, 0, 0] = np.einsum("ni,ni->n", east, dX_dxi)
    D[:, 0, 1] = np.einsum("ni,ni->n", east, dX_deta)
    D[:, 1, 0] = np.einsum("ni,ni->n", north, dX_dxi)
    D[:, 1, 1] = np.einsum("ni,ni->n", north, dX_deta)
    metdet = np.linalg.det(D)
    if np.any(metdet <= 0):
        raise RuntimeError("non-positive metric determinant")

    # Area correction (HOMME geometry_mod::set_area_correction_map0): one global
    # factor on the metric so that the GLL-quadrature area of the sphere is 4πa².
    # A single factor keeps element-edge fluxes consistent, hence mass
    # conservation to round-off; a per-element factor would not.
    w2 = np.outer(rule.weights, rule.weights).ravel()  # index j*np + i
    quad_area = float(np.sum(metdet * np.tile(w2, nelem)))
    s = math.sqrt(4 * math.pi * radius**2 / quad_area)
    D *= s
    metdet = metdet * s**2
    Dinv = np.linalg.inv(D)
    spheremp = metdet * np.tile(w2, nelem)

    mass = np.bincount(gid, weights=spheremp, minlength=ncomp)
    rspheremp = 1.0 / mass[gid]
    copies = np.argsort(gid, kind="stable").astype(np.int32)
    counts = np.bincount(gid, minlength=ncomp)
    offsets = np.concatenate(([0], np.cumsum(counts))).astype(np.int32)
    rank = np.arange(n) - offsets[gid[copies]]  # position of each copy in its node's list
    table = np.full((ncomp, counts.max()), -1, dtype=np.int32)
    table[gid[copies], rank] = copies

    # Nearest-neighbour spacing along both element directions.
    X = radius * xyz.reshape(nelem, npts, npts, 3)
    dist_i = np.linalg.norm(np.diff(X, axis=2), axis=3)  # (nelem, j, np-1)
    dist_j = np.linalg.norm(np.diff(X, axis=1), axis=3)  # (nelem, np-1, i)
    dx = np.full((nelem, npts, npts), np.inf)
    dx[:, :, :-1] = np.minimum(dx[:, :, :-1], dist_i)
    dx[:, :, 1:] = np.minimum(dx[:, :, 1:], dist_i)
    dx[:, :-1, :] = np.minimum(dx[:, :-1, :], dist_j)
    dx[:, 1:, :] = np.minimum(dx[:, 1:, :], dist_j)

    return dict(
        xyz=np.ascontiguousarray(xyz.T),
        lat=lat,
        lon=lon,
        east=np.ascontiguousarray(east.T),
        north=np.ascontiguousarray(north.T),
        D=np.ascontiguousarray(D.reshape(n, 4).T),
        Dinv=np.ascontiguousarray(Dinv.reshape(n, 4).T),
        metdet=metdet,
        spheremp=spheremp,
        rspheremp=rspheremp,
        dx=dx.ravel(),
        gid=gid.astype(np.int32),
        dss_offsets=offsets,
        dss_copies=copies,
        dss_table=table[gid],
        first=first.astype(np.int32),
        area=mass,
    )
