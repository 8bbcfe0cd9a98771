"""Tests of the cubed-sphere grid (swe_sphere.grid.cubed_sphere.CubedSphere)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial import cKDTree

from swe_sphere.grid.cubed_sphere import CubedSphere
from swe_sphere.mesh.cube import reference_to_sphere

from helpers import cached_grid
from numpy_ops import NumpyOps


@pytest.mark.parametrize("ne", [1, 2, 3])
@pytest.mark.parametrize("np_", range(2, 9))
def test_unique_node_count(ne, np_):
    g = cached_grid(ne, np_)
    expected = 6 * ne * ne * (np_ - 1) ** 2 + 2
    assert g.nunique == expected
    assert g.nnodes == 6 * ne * ne * np_ * np_
    assert np.unique(g.gid).size == expected
    assert g.gid.min() == 0 and g.gid.max() == expected - 1
    assert g.first.size == expected and g.area.size == expected
    # distinct unique nodes are distinct points on the sphere
    pts = g.xyz[:, g.first].T
    dmin = cKDTree(pts).query(pts, k=2)[0][:, 1].min()
    assert dmin > 1e-6 / ne


@pytest.mark.parametrize("ne", [1, 2, 3, 7])
@pytest.mark.parametrize("np_", [2, 4, 8])
def test_total_area(ne, np_):
    g = cached_grid(ne, np_)
    exact = 4 * math.pi * g.radius**2
    assert abs(g.area.sum() - exact) <= 1e-12 * exact
    assert abs(g.spheremp.sum() - exact) <= 1e-12 * exact
    assert abs(g.integrate(np.ones(g.nnodes)) - exact) <= 1e-12 * exact
    assert np.all(g.area > 0)


@pytest.mark.parametrize("ne,np_", [(1, 2), (2, 4), (3, 5), (2, 8)])
def test_copies_share_coordinates(ne, np_):
    g = cached_grid(ne, np_)
    rep = g.first[g.gid]  # the representative copy of every node
    for name in ("xyz", "east", "north"):
        a = getattr(g, name)
        assert np.array_equal(a, a[:, rep]), name
    assert np.array_equal(g.lat, g.lat[rep])
    assert np.array_equal(g.lon, g.lon[rep])
    assert np.all(g.first[g.gid[g.first]] == g.first)
    # lat/lon are those of xyz
    assert np.allclose(np.sin(g.lat), g.xyz[2], atol=1e-15)
    c = np.cos(g.lat)
    assert np.allclose(c * np.cos(g.lon), g.xyz[0], atol=1e-15)
    assert np.allclose(c * np.sin(g.lon), g.xyz[1], atol=1e-15)
    assert np.all((g.lon >= 0) & (g.lon < 2 * math.pi))


@pytest.mark.parametrize("ne,np_", [(2, 4), (3, 8)])
def test_positions_are_their_first_copies_computed_alone_bit_for_bit(ne, np_):
    """Every node's position is the one computed from its first copy's own angles,
    in one batch here: the metric reuses a first copy's position from the batch
    of all copies rather than computing it twice, with the same bits."""
    g = cached_grid(ne, np_)
    e, p = np.divmod(g.dss_table[:, 0].astype(np.int64), np_ * np_)
    j, i = np.divmod(p, np_)
    xyz = reference_to_sphere(ne, e, g.rule.points[i], g.rule.points[j])
    xyz[np.abs(xyz) < 1e-15] = 0.0
    xyz /= np.linalg.norm(xyz, axis=1)[:, None]
    assert np.array_equal(g.xyz, xyz.T)


@pytest.mark.parametrize("ne,np_", [(1, 3), (2, 4), (3, 7)])
def test_dss_lists(ne, np_):
    g = cached_grid(ne, np_)
    table = g.dss_table
    counts = np.sum(table >= 0, axis=1)
    # every row lists the copies of its node, ascending, itself among them
    assert np.all(np.any(table == np.arange(g.nnodes)[:, None], axis=1))
    rows = np.where(table >= 0, table, g.nnodes)
    assert np.array_equal(np.sort(rows, axis=1), rows)
    assert np.array_equal(g.gid[np.where(table >= 0, table, 0)][table >= 0], np.repeat(g.gid, counts))
    assert np.array_equal(np.bincount(g.gid), counts[g.first])  # a row for each copy: the node's copy count
    assert np.array_equal(table[:, 0], g.first[g.gid])  # the first copy leads
    # interior nodes have 1 copy, edge nodes 2, element corners 3 (cube corners) or 4
    assert set(np.unique(counts)) <= {1, 2, 3, 4}
    assert np.sum(counts[g.first] == 3) == 8
    mass = np.bincount(g.gid, weights=g.spheremp)
    assert np.allclose(g.area, mass, rtol=1e-14, atol=0)
    assert np.allclose(g.rspheremp, 1 / mass[g.gid], rtol=1e-14, atol=0)


@pytest.mark.parametrize("ne,np_", [(1, 2), (2, 4), (3, 5), (4, 8)])
def test_part_is_the_whole_grid_at_its_nodes_bit_for_bit(ne, np_):
    """A grid built from some elements only (an MPI rank's) holds the whole grid's
    values at its nodes, bit for bit; its unique nodes (``first``, ``area``) are
    those whose first copy it holds; its halo lists the other elements' copies."""
    g = cached_grid(ne, np_)
    rng = np.random.default_rng(ne * 10 + np_)
    for size in (1, g.nelem // 3 + 1, g.nelem - 1):
        elements = np.sort(rng.choice(g.nelem, size=size, replace=False))
        part = CubedSphere(ne, np_, elements=elements)
        nodes = (elements[:, None] * np_**2 + np.arange(np_**2)).ravel()
        assert np.array_equal(part.nodes, nodes) and part.nelem == size and part.nnodes == nodes.size
        for name in ("xyz", "lat", "lon", "east", "north", "D", "Dinv", "metdet", "spheremp", "rspheremp", "dx", "gid"):
            a = getattr(part, name)
            assert a.shape[-1] == nodes.size, name  # sized by the elements held
            assert np.array_equal(a, getattr(g, name)[..., nodes]), name
        assert np.array_equal(part.dss_table, g.dss_table[nodes])
        held = np.isin(g.first, nodes)
        assert np.array_equal(part.nodes[part.first], g.first[held])
        assert np.array_equal(part.area, g.area[held])
        copies = np.unique(g.dss_table[nodes])
        assert np.array_equal(part.halo, np.setdiff1d(copies[copies >= 0], nodes))
        assert np.array_equal(part.halo_spheremp, g.spheremp[part.halo])


def test_area_correction_is_the_quadrature_of_the_metric():
    """The area correction takes the quadrature area from the analytic Jacobian
    (so that every part computes the same factor); it equals Σ metdet·w of the
    computed metric to round-off: Σ spheremp = 4πa² to a few ulps."""
    for ne, np_ in ((1, 4), (3, 3), (8, 6)):
        g = cached_grid(ne, np_)
        exact = 4 * math.pi * g.radius**2
        assert abs(float(np.sum(g.spheremp)) - exact) <= 4e-15 * exact


def test_bad_element_lists_raise():
    for elements in ([3, 2], [0, 0], [-1], [24], [[0, 1]]):
        with pytest.raises(ValueError, match="elements must be ascending distinct"):
            CubedSphere(2, 4, elements=elements)


@pytest.mark.parametrize("ne,np_", [(1, 2), (2, 4), (3, 6), (2, 8)])
def test_metric_terms(ne, np_):
    g = cached_grid(ne, np_)
    D = g.D.T.reshape(-1, 2, 2)
    Dinv = g.Dinv.T.reshape(-1, 2, 2)
    eye = np.broadcast_to(np.eye(2), D.shape)
    assert np.allclose(D @ Dinv, eye, rtol=0, atol=1e-13)
    assert np.allclose(Dinv @ D, eye, rtol=0, atol=1e-13)
    assert np.all(g.metdet > 0)
    assert np.allclose(np.linalg.det(D), g.metdet, rtol=1e-13, atol=0)
    w2 = np.outer(g.rule.weights, g.rule.weights).ravel()
    assert np.allclose(g.spheremp, g.metdet * np.tile(w2, g.nelem), rtol=1e-14, atol=0)
    assert np.all(g.dx > 0) and np.all(np.isfinite(g.dx))


@pytest.mark.parametrize("ne,np_", [(1, 2), (2, 4), (3, 7)])
def test_tangent_basis(ne, np_):
    g = cached_grid(ne, np_)
    e, n, r = g.east, g.north, g.xyz
    dot = lambda a, b: np.sum(a * b, axis=0)  # noqa: E731
    for a, b, v in ((e, e, 1), (n, n, 1), (r, r, 1), (e, n, 0), (e, r, 0), (n, r, 0)):
        assert np.allclose(dot(a, b), v, rtol=0, atol=1e-14)
    # right-handed: east × north = outward normal
    assert np.allclose(np.cross(e, n, axis=0), r, rtol=0, atol=1e-14)


def test_D_is_the_jacobian():
    """D's columns are the (east, north) components of ∂X/∂ξ, ∂X/∂η, checked
    against the spectral derivative of the node positions X = a·xyz (the
    per-element area correction only rescales D by 1 + O(quadrature error))."""
    g = cached_grid(2, 8)
    ops = NumpyOps(g)
    X = ops.el(g.radius * g.xyz)
    dXi, dEta = ops.flat(ops.d_xi(X)), ops.flat(ops.d_eta(X))
    approx = np.stack(
        [
            np.sum(g.east * dXi, 0),
            np.sum(g.east * dEta, 0),
            np.sum(g.north * dXi, 0),
            np.sum(g.north * dEta, 0),
        ]
    )
    scale = np.abs(g.D).max()
    assert np.abs(approx - g.D).max() < 1e-5 * scale
    # the normal part of ∂X/∂ξ vanishes to the same accuracy
    assert np.abs(np.sum(g.xyz * dXi, 0)).max() < 1e-5 * scale


@pytest.mark.parametrize("ne,np_", [(0, 4), (-1, 4), (2, 1), (2, 9), (2, 0), (1.5, 4)])
def test_bad_sizes_raise(ne, np_):
    with pytest.raises(ValueError):
        CubedSphere(ne, np_)
