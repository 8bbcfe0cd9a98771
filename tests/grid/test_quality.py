"""Element sizes and shapes as HOMME reports them (Dinv-based length scales and distortion)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from swe_sphere.grid.cubed_sphere import CubedSphere
from swe_sphere.grid.quality import REGIONS, dinv_singular_values, element_regions, element_sizes
from swe_sphere.grid.refine import Box, make_mesh
from swe_sphere.mesh.mesh import read_exodus
from swe_sphere.mesh.schmidt import schmidt_cube

from meshes import MOUNTAIN


def test_the_closed_form_singular_values_are_numpys(rng):
    m = rng.standard_normal((500, 2, 2))
    large, small = dinv_singular_values(m.reshape(500, 4).T)
    s = np.linalg.svd(m, compute_uv=False)
    assert np.allclose(large, s[:, 0], rtol=1e-13, atol=0)
    assert np.allclose(small, s[:, 1], rtol=1e-12, atol=0)


@pytest.mark.parametrize("ne", [2, 5])
def test_the_equiangular_cubes_worst_distortion_is_sqrt3_at_its_corners(ne):
    """At a cube corner the equiangular map's two reference directions meet at 120°
    (three faces share the corner): D's singular values differ by √3 there, and nowhere more."""
    sizes = element_sizes(CubedSphere(ne, 4))
    assert sizes.summary()["distortion_max"] == pytest.approx(math.sqrt(3), rel=1e-13)
    assert sizes.distortion[0] == pytest.approx(math.sqrt(3), rel=1e-13)  # element 0 holds a cube corner
    assert sizes.area.sum() == pytest.approx(4 * math.pi * 6.37122e6**2, rel=1e-13)


def test_a_stretched_cubes_spacing_follows_the_stretch():
    """The elements at the target (around face 4's centre) are about c times finer than the
    cube's same elements, those at its antipode about c times coarser (the map's scale varies
    across them, more across the larger ones: 2.1 % and 8.7 % from c at ne8, c = 2)."""
    c, ne = 2.0, 8
    plain = element_sizes(CubedSphere(ne, 4, mesh=schmidt_cube(ne, 1.0))).dx_short
    stretched = element_sizes(CubedSphere(ne, 4, mesh=schmidt_cube(ne, c))).dx_short
    mid = ne // 2
    at = [face * ne * ne + jb * ne + ia for face in (4, 5) for jb in (mid - 1, mid) for ia in (mid - 1, mid)]
    ratio = plain[at] / stretched[at]
    assert np.all(np.abs(ratio[:4] / c - 1) < 0.05)  # face 4: the target
    assert np.all(np.abs(ratio[4:] * c - 1) < 0.1)  # face 5: the antipode


@pytest.mark.skipif(not MOUNTAIN.is_file(), reason="mountain_10_x2.g (E3SM's HOMME test mesh) not present")
def test_the_mountain_mesh_figures():
    """mountain_10_x2.g at np4: its transition elements are distorted past HOMME's warning (4),
    its smallest element sets the step 3.1 times below its ne10 base's (σ_max ratio)."""
    mesh = element_sizes(CubedSphere(0, 4, mesh=read_exodus(MOUNTAIN))).summary()
    base = element_sizes(CubedSphere(10, 4)).summary()
    assert mesh["distortion_max"] == pytest.approx(5.449, abs=1e-3)
    assert mesh["norm_dinv_max"] / base["norm_dinv_max"] == pytest.approx(3.103, abs=1e-3)
    assert mesh["dx_short_max"] == pytest.approx(base["dx_short_max"], rel=0.01)  # the coarse region is ne10's


def _distance_from(grid, lat: float, lon: float) -> np.ndarray:
    """Each element's mean node's great-circle distance (degrees) from (lat, lon) (degrees)."""
    x = np.stack([np.cos(grid.lat) * np.cos(grid.lon), np.cos(grid.lat) * np.sin(grid.lon), np.sin(grid.lat)])
    c = x.reshape(3, grid.nelem, -1).mean(axis=2)
    t = np.radians([lat, lon])
    target = np.array([np.cos(t[0]) * np.cos(t[1]), np.cos(t[0]) * np.sin(t[1]), np.sin(t[0])])
    return np.degrees(np.arccos(np.clip(target @ c / np.linalg.norm(c, axis=0), -1, 1)))


def test_the_regions_of_a_stretched_cube_are_rings_about_its_target():
    """c = 2.5 toward (30°N, 270°E) at ne4: the finest third of the resolution range nearest the
    target, the coarsest third farthest (the Schmidt map's scale grows with the distance); the
    uniform cube has no regions (its sizes spread 1.17x, below UNIFORM_RATIO)."""
    assert REGIONS == ("refined", "transition", "coarse")
    assert element_regions(element_sizes(CubedSphere(4, 4))) is None
    grid = CubedSphere(0, 4, 1.0, mesh=make_mesh(4, stretch_factor=2.5, target_lat=30.0, target_lon=270.0))
    regions = element_regions(element_sizes(grid))
    assert np.bincount(regions).tolist() == [48, 36, 12]
    far = _distance_from(grid, 30.0, 270.0)
    assert far[regions == 0].max() < far[regions == 1].min() + 10 and far[regions == 0].max() < far[regions == 2].min()
    assert far[regions == 1].max() < far[regions == 2].max()


def test_the_regions_of_a_refined_cube_are_its_levels():
    """ne4 refined 2x over TC5's mountain box (10..50°N, 246.7..293.3°E): the refined region's
    elements are the box's (centroids within 45° of the mountain at 30°N, 270°E), about a quarter
    of a coarse element's area each (2.89x less in the median: the smoothing moves their nodes),
    the coarse region's the cube's elsewhere."""
    grid = CubedSphere(0, 4, 1.0, mesh=make_mesh(4, box=Box(10, 50, 246.7, 293.3), levels=1))
    sizes = element_sizes(grid)
    regions = element_regions(sizes)
    assert np.bincount(regions).tolist() == [40, 12, 72]
    assert _distance_from(grid, 30.0, 270.0)[regions == 0].max() < 45
    ratio = np.median(sizes.area[regions == 2]) / np.median(sizes.area[regions == 0])
    assert 2.8 < ratio < 3.0
