"""The UGRID description in every run file: the sub-cell mesh of quads between GLL
nodes (``swe_sphere.io.ugrid``), its topology and the attributes that tools read (the fields
live on the control volumes of the dual mesh: test_dual.py)."""

from __future__ import annotations

import math
from collections import Counter

import netCDF4
import numpy as np
import pytest
import xarray as xr

from swe_sphere.io.ugrid import orientation, subcell_quads

GRIDS = [(1, 2), (2, 4), (3, 2), (2, 8), (4, 3)]


def unique_xyz(grid):
    return grid.xyz.T[grid.first]


@pytest.mark.parametrize("ne,np_", GRIDS)
def test_subcell_quads_cover_every_node_once_per_corner(grid_factory, ne, np_):
    grid = grid_factory(ne, np_)
    quads = subcell_quads(grid)
    nface = 6 * ne**2 * (np_ - 1) ** 2
    assert quads.shape == (nface, 4) and quads.dtype == np.int32
    assert np.array_equal(np.unique(quads), np.arange(grid.nunique))  # every GLL node used, no other id
    assert all(len(set(q)) == 4 for q in quads.tolist())  # no degenerate quad
    # a closed surface: every edge shared by exactly two quads, and V − E + F = 2 (a sphere)
    edges = Counter()
    for q in quads.tolist():
        for k in range(4):
            a, b = q[k], q[(k + 1) % 4]
            edges[(min(a, b), max(a, b))] += 1
    assert set(edges.values()) == {2}
    assert grid.nunique - len(edges) + nface == 2


@pytest.mark.parametrize("ne,np_", GRIDS)
def test_subcells_are_counter_clockwise_seen_from_outside(grid_factory, ne, np_):
    grid = grid_factory(ne, np_)
    quads = subcell_quads(grid)
    xyz = unique_xyz(grid)
    o = orientation(xyz, quads)
    assert (o > 0).all(), f"{(o <= 0).sum()} quads clockwise or degenerate"
    # the same test by hand on the first triangle of every quad: ((b − a) × (c − a)) · a > 0
    a, b, c = xyz[quads[:, 0]], xyz[quads[:, 1]], xyz[quads[:, 2]]
    assert (np.einsum("ij,ij->i", np.cross(b - a, c - a), a) > 0).all()
    # and every directed edge appears once: consistently oriented neighbours
    directed = Counter((q[k], q[(k + 1) % 4]) for q in quads.tolist() for k in range(4))
    assert max(directed.values()) == 1
    # the flat quads tile the sphere: their area is 4π less a chord-sag deficit that
    # shrinks with the sub-cell size (2/π for the inscribed cube at ne=1 np=2)
    d = xyz[quads[:, 3]]
    flat = 0.5 * np.linalg.norm(np.cross(c - a, d - b), axis=1)
    ratio = flat.sum() / (4 * math.pi)
    assert 0.63 < ratio < 1.0
    if (ne, np_) == (1, 2):
        assert ratio == pytest.approx(2 / math.pi, rel=1e-12)


@pytest.fixture
def run_file(tc5_run_file):
    return tc5_run_file


def test_run_file_carries_the_mesh_topology(run_file, grid_factory):
    grid = grid_factory(2, 4)
    with netCDF4.Dataset(run_file) as nc:
        mesh = nc["mesh_topology"]
        assert mesh.cf_role == "mesh_topology"
        assert int(mesh.topology_dimension) == 2
        assert mesh.node_coordinates == "lon lat"
        assert mesh.face_node_connectivity == "subcell_face_nodes"
        assert "node_dimension" not in mesh.ncattrs() and "units" not in mesh.ncattrs()  # not UGRID-1.0 attributes
        assert nc.Conventions == "CF-1.8 UGRID-1.0"
        conn = nc["subcell_face_nodes"]
        assert conn.cf_role == "face_node_connectivity"
        assert int(conn.start_index) == 0
        assert conn.dimensions == ("nface", "nmax_face")
        assert nc.dimensions["nface"].size == 6 * 2**2 * 3**2 == 216
        assert nc.dimensions["nmax_face"].size == 4
        assert np.array_equal(conn[:], subcell_quads(grid))
        for name in ("h", "u", "v", "hs", "vorticity"):  # the fields live on the control volumes (test_dual.py)
            assert nc[name].mesh == "mesh_dual" and nc[name].location == "face", name
    with xr.open_dataset(run_file, decode_times=False) as ds:  # xarray still opens it; the mesh adds no data on ncol
        assert ds["subcell_face_nodes"].dims == ("nface", "nmax_face")
        assert ds["h"].dims == ("time", "ncol")
        conn = ds["subcell_face_nodes"].values
        assert conn.min() == 0 and conn.max() == ds.sizes["ncol"] - 1
        # corners in the file's own lat/lon are counter-clockwise too
        lat, lon = np.radians(ds.lat.values), np.radians(ds.lon.values)
        xyz = np.stack([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)], axis=1)
        assert (orientation(xyz, conn) > 0).all()
