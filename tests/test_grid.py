"""Tests of the cubed-sphere grid (swe_sphere.grid.CubedSphere)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial import cKDTree

from swe_sphere.grid import CubedSphere

from conftest import cached_grid
from numpy_ops import NumpyOps


@pytest.mark.parametrize("ne", [1, 2, 3])
@pytest.mark.parametrize("np_", range(2, 9))
def test_unique_node_count(ne, np_):
    g = cached_grid(ne, np_)
    expected = 6 * ne * ne * (np_ - 1) ** 2 + 2
    assert g.nunique == expected
    assert g.npts == 6 * ne * ne * np_ * np_
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
    assert abs(g.integrate(np.ones(g.npts)) - exact) <= 1e-12 * exact
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


@pytest.mark.parametrize("ne,np_", [(1, 3), (2, 4), (3, 7)])
def test_dss_lists(ne, np_):
    g = cached_grid(ne, np_)
    counts = np.diff(g.dss_offsets)
    assert g.dss_offsets[0] == 0 and g.dss_offsets[-1] == g.npts
    assert np.array_equal(np.sort(g.dss_copies), np.arange(g.npts))
    assert np.array_equal(np.repeat(np.arange(g.nunique), counts), g.gid[g.dss_copies])
    # interior nodes have 1 copy, edge nodes 2, element corners 3 (cube corners) or 4
    assert set(np.unique(counts)) <= {1, 2, 3, 4}
    assert np.sum(counts == 3) == 8
    mass = np.bincount(g.gid, weights=g.spheremp)
    assert np.allclose(g.area, mass, rtol=1e-14, atol=0)
    assert np.allclose(g.rspheremp, 1 / mass[g.gid], rtol=1e-14, atol=0)


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
