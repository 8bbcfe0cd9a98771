"""The Schmidt-stretched cube (FV3's do_schmidt): the cube at c = 1, conformal stretching toward
the target with a resolution ratio c² between the target and its antipode, and a valid mesh."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from swe_sphere.grid.cubed_sphere import CubedSphere
from swe_sphere.mesh.cube import cube_mesh
from swe_sphere.mesh.mesh import check, element_areas
from swe_sphere.mesh.schmidt import rotation_to, schmidt_cube

import roundoff
from meshes import tc2_l2_by_np

GRID_ARRAYS = ("xyz", "lat", "lon", "D", "Dinv", "metdet", "spheremp", "rspheremp", "dx", "gid", "dss_table")


def test_no_stretch_toward_the_north_pole_is_the_cube_bit_for_bit():
    stretched = CubedSphere(3, 4, mesh=schmidt_cube(3, 1.0, 90.0, 0.0))
    cube = CubedSphere(3, 4, mesh=cube_mesh(3))
    for name in GRID_ARRAYS:
        assert np.array_equal(getattr(stretched, name), getattr(cube, name)), name


@pytest.mark.roundoff
def test_no_stretch_toward_any_target_is_the_cube_turned():
    """At c = 1 the mesh is the cube turned onto the target: every node's metdet (a rotation
    invariant) is the cube's to the roundings of the turn and the map."""
    stretched = CubedSphere(3, 4, mesh=schmidt_cube(3, 1.0, -20.0, 30.0))
    cube = CubedSphere(3, 4, mesh=cube_mesh(3))
    roundoff.within(np.max(np.abs(stretched.metdet / cube.metdet - 1)), roundoff.bound(64), "metdet")
    turn = rotation_to(-20.0, 30.0)
    roundoff.within(np.max(np.abs(turn @ cube.xyz - stretched.xyz)), roundoff.bound(16), "positions")


@pytest.mark.parametrize("target", [(90.0, 0.0), (40.0, 270.0), (-20.0, 30.0)])
@pytest.mark.parametrize("c", [2.0, 4.0])
def test_the_elements_at_the_target_are_c4_times_smaller_than_at_its_antipode(c, target):
    """The Schmidt map's local scale is 1/c at the target and c at the antipode: the elements
    around the two points differ in area by c⁴, up to the variation of the scale across
    them (3.5 % at ne8 c = 2, 0.9 % at ne16, shrinking as the elements do)."""
    ratios = []
    for ne in (8, 16):
        mesh = check(schmidt_cube(ne, c, *target))
        t = rotation_to(*target)[:, 2]
        areas = element_areas(mesh.corners())
        at_target, at_antipode = np.argmax(mesh.coords @ t), np.argmin(mesh.coords @ t)
        assert mesh.coords[at_target] @ t == pytest.approx(1, abs=roundoff.bound(4))  # face 4's centre node
        near = areas[(mesh.quads == at_target).any(axis=1)].mean()
        far = areas[(mesh.quads == at_antipode).any(axis=1)].mean()
        ratios.append(far / near / c**4)
    assert 0 < 1 - ratios[1] < (1 - ratios[0]) / 3  # converges to c⁴ (second order in the element size)
    assert 1 - ratios[1] < 0.06


def test_a_stretched_grid_keeps_the_sphere_area_and_the_mass_matrix_positive():
    g = CubedSphere(6, 4, mesh=schmidt_cube(6, 2.5, 45.0, 260.0))
    assert math.fsum(g.area) == pytest.approx(4 * math.pi * g.radius**2, rel=roundoff.bound(50))
    assert np.all(g.metdet > 0)
    assert g.dx.max() / g.dx.min() > 2.5**2  # the spacing ratio includes c² and the cube's own


@pytest.mark.parametrize(
    "args, message",
    [
        ((0.5, 0.0, 0.0), "stretch_factor must be a number >= 1"),
        ((float("nan"), 0.0, 0.0), "stretch_factor must be a number >= 1"),
        ((2.0, 91.0, 0.0), "target_lat must be in"),
    ],
)
def test_a_bad_stretch_is_refused(args, message):
    with pytest.raises(ValueError, match=message):
        schmidt_cube(2, *args)


@pytest.mark.parametrize("c", [1e9, 1e200, 1.7976931348623157e308])
def test_a_huge_stretch_is_refused_as_a_fold_without_warnings(c):
    """`swe-sphere mesh --ne 4 --stretch-factor 1e9`: three numpy RuntimeWarnings (c² + 1 rounded to
    c², a division by 0 at the antipode) before "node 94 is not on the unit sphere (|x| = nan)"."""
    with warnings.catch_warnings(), pytest.raises(ValueError, match="is (not convex|clockwise) seen from outside"):
        warnings.simplefilter("error")
        check(schmidt_cube(4, c, 90.0, 0.0))


def test_tc2_on_a_stretched_cube_converges_spectrally_in_np_and_keeps_its_mass():
    """TC2 (steady, exact) 12 minutes on the ne6 cube stretched by 2.5 toward (45°, 260°):
    the normalized l2 error of h falls by ≥ 3 per np from 3 to 6 (measured 4.4 to 6.0),
    and mass is kept to round-off."""
    errors = tc2_l2_by_np(schmidt_cube(6, 2.5, 45.0, 260.0), (3, 4, 5, 6), ne=6)
    print("TC2 l2(h) by np 3..6:", errors)
    assert all(b < a / 3 for a, b in zip(errors[:-1], errors[1:]))
