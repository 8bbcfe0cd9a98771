"""The equiangular map element by element on a mesh (HOMME ``cubed_sphere_map = 0`` on a mesh
file; ``face_map``): the cube written as a ``.g`` file and read through it is the built-in
equiangular cube to round-off; on a refined mesh neighbours place the same GLL points on their
shared edges, across cube edges too, and TC2 is as accurate as on the uniform cube; an element
in no one cube face is refused in one line (``test_element_local`` locates points through it)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from swe_sphere.core.errors import SceneError
from swe_sphere.grid.cubed_sphere import CubedSphere
from swe_sphere.grid.partition import mesh_partition
from swe_sphere.grid.refine import Box, make_mesh
from swe_sphere.mesh.cube import cube_mesh
from swe_sphere.mesh.face_map import FIT_TOLERANCE, face_corners
from swe_sphere.mesh.mesh import read_exodus, write_exodus

import roundoff
from meshes import MOUNTAIN, TC2_TERMS, TC6_TERMS, equiangular, icosahedral_mesh, refined_equiangular, run_steps

METRIC = ("xyz", "lat", "lon", "D", "Dinv", "metdet", "spheremp", "rspheremp", "dx", "area")
TABLES = ("gid", "dss_table", "first", "halo")


@pytest.fixture(scope="module")
def refined():
    return refined_equiangular()


@pytest.mark.roundoff
@pytest.mark.parametrize("ne", [2, 3])
def test_the_cube_read_from_its_g_file_through_the_map_is_the_built_in_cube(ne, tmp_path):
    """The ne cube written by the project and read back through the equiangular map: the
    built-in equiangular cube's numbering exactly, its metric terms (metdet, D, Dinv,
    spheremp: the same map, its angles interpolated from the corners' rather than laid out)
    to a few roundings, and the state after 6 TC6 steps (with ∇⁴) to the roundings they take."""
    built_in = CubedSphere(ne, 4)
    from_file = CubedSphere(0, 4, mesh=equiangular(read_exodus(write_exodus(tmp_path / "cube.g", cube_mesh(ne)))))
    assert from_file.map == built_in.map == "equiangular"
    for name in TABLES:
        assert np.array_equal(getattr(from_file, name), getattr(built_in, name)), name
    for name in METRIC:
        a, b = getattr(built_in, name), getattr(from_file, name)
        roundoff.within(np.max(np.abs(b - a)), roundoff.bound(64, np.max(np.abs(a))), name)
    steps = 6
    nu = dict(nu=1e15, nu_div=1e15, nu_s=1e15)
    a = run_steps(built_in, "tc6_rossby_haurwitz", TC6_TERMS, steps, 300.0, **nu)[0]
    b = run_steps(from_file, "tc6_rossby_haurwitz", TC6_TERMS, steps, 300.0, **nu)[0]
    for row, what in enumerate(("u", "v", "h")):
        bound = roundoff.bound(steps * 3 * roundoff.operator_roundings(4, 2), np.max(np.abs(a[row])))
        roundoff.within(np.max(np.abs(b[row] - a[row])), bound, f"TC6 {what} after {steps} steps")


def test_neighbours_place_the_same_gll_points_on_their_shared_edges(refined):
    """Every copy of every node of the refined mesh, placed by its own element's map: the copies
    of a node coincide to a few roundings (the turned cube's frame adds its own), on edges
    inside a face and on cube edges alike; and the elements cover the sphere (Σ area = 4πa²)."""
    g = CubedSphere(0, 5, mesh=refined)
    npe = g.np**2
    e, p = np.divmod(np.arange(g.nnodes), npe)
    j, i = np.divmod(p, g.np)
    own = g.reference_to_sphere(e, g.rule.points[i], g.rule.points[j])  # each copy by its own element
    table = g.dss_table.astype(np.int64)
    worst = 0.0
    for k in range(1, table.shape[1]):
        have = table[:, k] >= 0
        worst = max(worst, np.max(np.abs(own[table[have, k]] - own[table[have, 0]])))
    roundoff.within(worst, roundoff.bound(64), "|x| between the copies of a node")
    # the nodes whose copies lie in more than one face are those on the cube's edges
    axes = face_corners(refined)[0]
    centre = axes[:, 0][table.clip(0) // npe]  # (N, copies, 3): each copy's face
    across = np.any((table >= 0) & np.any(centre != centre[:, :1], axis=2), axis=1)
    c, ta, tb = (np.einsum("ni,ni->n", own, axes[e, k]) for k in range(3))
    on_edge = np.maximum(np.abs(np.arctan2(ta, c)), np.abs(np.arctan2(tb, c))) > math.pi / 4 - 1e-12
    assert np.array_equal(across, on_edge) and np.count_nonzero(across) >= 12 * 4 * (g.np - 1) * 2
    assert math.fsum(g.area) == pytest.approx(4 * math.pi * g.radius**2, rel=roundoff.bound(4 * g.np**2))


def test_a_part_of_the_grid_is_the_whole_at_its_nodes_bit_for_bit(refined):
    """An MPI rank's part (the mesh's curve partition): the area correction comes from the whole
    mesh's analytic quadrature, so every array is the whole grid's at the part's nodes."""
    whole = CubedSphere(0, 4, mesh=refined)
    for elements in mesh_partition(refined, 3):
        part = whole.part(np.sort(elements))
        for name in (*METRIC[:-1], "gid"):
            assert np.array_equal(getattr(part, name), getattr(whole, name)[..., part.nodes]), name


def test_the_turned_cube_of_a_refined_mesh_is_found(refined):
    """``refine`` turns the cube onto its box: no element fits in the unturned faces as a
    whole, yet every element's corners lie in one face of the frame found, to round-off."""
    axes, angles = face_corners(refined)
    assert not np.allclose(np.abs(axes[:, 0]).max(axis=1), 1)  # the faces are not the unturned cube's
    assert np.max(np.abs(angles)) <= math.pi / 4 + FIT_TOLERANCE
    assert len(np.unique(np.round(axes[:, 0], 6), axis=0)) == 6


def test_an_element_in_no_one_face_is_refused_in_one_line():
    """The icosahedral quadrilaterals (no cube) and a smoothed refined mesh (nodes moved across
    a cube edge): SceneError naming the first element, on one line."""
    for mesh in (icosahedral_mesh(0), make_mesh(4, box=Box(20.0, 40.0, 260.0, 280.0), levels=1)):
        with pytest.raises(SceneError, match=r"element \d+ does not lie in one face of a cube") as err:
            CubedSphere(0, 4, mesh=equiangular(mesh))
        assert "\n" not in str(err.value)


def test_tc2_on_a_refined_mesh_is_no_worse_through_the_equiangular_map(refined):
    """TC2 (steady, exact, no ∇⁴) for 30 minutes: the normalized l2 error of h on the refined
    mesh through the equiangular map (2.5e-5) is below the same mesh's through the element-local
    map (4.5e-5) and the uniform ne4 equiangular cube's (2.8e-5); mass to round-off."""
    steps, errors = 12, {}
    for name, grid in (
        ("refined map0", CubedSphere(0, 4, mesh=refined)),
        ("refined map2", CubedSphere(0, 4, mesh=dataclasses.replace(refined, map="element_local"))),
        ("ne4 cube", CubedSphere(4, 4)),
    ):
        x, start = run_steps(grid, "tc2_steady", TC2_TERMS, steps, 150.0)
        h, h0 = x[2], start[2]
        roundoff.within(
            abs(grid.integrate(h) / grid.integrate(h0) - 1), roundoff.mass_change_bound(3 * steps, grid.nnodes), name
        )
        errors[name] = math.sqrt(grid.integrate((h - h0) ** 2) / grid.integrate(h0**2))
    print(", ".join(f"{k} {v:.3e}" for k, v in errors.items()))
    assert errors["refined map0"] < 0.7 * errors["refined map2"]
    assert errors["refined map0"] <= errors["ne4 cube"]


@pytest.mark.skipif(not MOUNTAIN.is_file(), reason="E3SM's mesh not present")
def test_e3sms_mountain_mesh_lies_in_the_unturned_cubes_faces():
    axes, _ = face_corners(equiangular(read_exodus(MOUNTAIN)))
    assert np.array_equal(np.abs(axes[:, 0]).max(axis=1), np.ones(len(axes)))
