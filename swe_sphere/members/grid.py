"""An ensemble's grid: N disjoint copies of one whole ``CubedSphere``, member after member (member
k's elements, element-local and unique nodes the k-th block of each). Every per-node array is the
grid's repeated, every index the grid's offset by its member's block, and each node's DSS copies
are those of its own member, in the grid's order. A ``Topology`` and a ``ShallowWater`` built on
it therefore compute each member as the grid alone would: element-local kernels see the same
numbers, and the DSS sums the same copies in the same order (the same bits). What is global over
the grid (a spectral radius, a mean, a norm) is the ensemble's over all members, not a member's:
the caller takes those from the one grid (``members.members.Members``).
"""

from __future__ import annotations

import numpy as np

from ..core.arguments import instance_argument, integer_argument
from ..core.errors import ArgumentError
from ..grid.cubed_sphere import CubedSphere

# per-node arrays (..., n) and the unique nodes' areas (u,) repeated member after member
_REPEATED = ("xyz", "lat", "lon", "east", "north", "D", "Dinv", "metdet", "spheremp", "rspheremp", "dx", "area")


class MemberGrid(CubedSphere):
    """``members`` copies of the whole grid ``grid`` (a ``CubedSphere`` of every element): a
    ``CubedSphere`` of N·E elements on N spheres, built from the grid's arrays (not by its
    constructor), whose attributes a ``grid.topology.Topology`` and a
    ``model.shallow_water.ShallowWater`` read as ``CubedSphere`` documents them:

    ne, np, radius, rule, mesh : the grid's; single : the grid itself; members : N.
    nelem_total = elements = N·E (``elements`` (N·E,) int64, all held); nnodes = N·n.
    nodes (N·n,) int64 : 0 … N·n − 1. gid (N·n,) int32 : the grid's + k·u in member k.
    dss_table (N·n, C) int32 : the grid's + k·n in member k (−1 padding kept).
    first (N·u,) int32 : the grid's + k·n; area (N·u,) : the grid's repeated (m²).
    xyz, lat, lon, east, north, D, Dinv, metdet, spheremp, rspheremp, dx : the grid's
    repeated along their last axis. halo, halo_spheremp : empty (no other elements).
    nunique : N·u. ``integrate`` and ``to_unique`` are over all members; ``part`` raises
    ValueError (the copies are held whole, by one process).

    Raises ``ArgumentError`` for ``grid`` not a ``CubedSphere`` of the whole sphere, or
    ``members`` not an integer ≥ 1."""

    def __init__(self, grid: CubedSphere, members: int):
        instance_argument("grid", grid, CubedSphere, "a CubedSphere")
        members = integer_argument("members", members, 1)
        if grid.nelem != grid.nelem_total:
            raise ArgumentError(f"grid must be the whole sphere (it holds {grid.nelem} of {grid.nelem_total} elements)")
        self.single, self.members = grid, members
        self.ne, self.np, self.radius, self.rule, self.mesh = grid.ne, grid.np, grid.radius, grid.rule, grid.mesh
        n, u = grid.nnodes, grid.first.size
        self.nelem_total = members * grid.nelem
        self.elements = np.arange(self.nelem_total)
        self.nodes = np.arange(members * n)
        for name in _REPEATED:  # np.tile repeats the last axis of a 2-d or 3-d array
            setattr(self, name, np.ascontiguousarray(np.tile(getattr(grid, name), members)))
        k = np.arange(members)
        self.gid = (grid.gid[None, :] + (k * u)[:, None]).ravel().astype(np.int32)
        table = grid.dss_table[None]  # its copies offset in int64 (k·n), then int32 as the grid's
        self.dss_table = np.vstack(np.where(table >= 0, table + (k * n)[:, None, None], -1)).astype(np.int32)
        self.first = (grid.first[None, :] + (k * n)[:, None]).ravel().astype(np.int32)
        self.halo, self.halo_spheremp = np.zeros(0, dtype=np.int64), np.zeros(0)

    @property
    def nunique(self) -> int:
        """Unique nodes of all members (N·u)."""
        return self.members * self.single.nunique

    def part(self, elements) -> CubedSphere:
        """Refused (ValueError): an ensemble's copies are held whole, by one process."""
        raise ValueError("an ensemble's member grid is held whole (no MPI parts yet)")

    def reference_to_sphere(self, e: np.ndarray, xi: np.ndarray, eta: np.ndarray) -> np.ndarray:
        """As ``CubedSphere``'s, element e being element e mod E of its member's sphere."""
        return self.single.reference_to_sphere(np.asarray(e) % self.single.nelem, xi, eta)

    def member(self, a: np.ndarray, k: int) -> np.ndarray:
        """Member k's part (..., n) of an array (..., N·n) over the copies' nodes (a view)."""
        return a[..., k * self.single.nnodes : (k + 1) * self.single.nnodes]
