"""Quadrilateral meshes of the sphere: the cube as a mesh, Exodus II files in and out, and the
checks a mesh must pass on reading (one line naming the element or node)."""

from __future__ import annotations

import math

import netCDF4
import numpy as np
import pytest

from swe_sphere.core.errors import OutputError, SceneError
from swe_sphere.mesh.cube import cube_mesh
from swe_sphere.mesh.mesh import Mesh, check, element_areas, read_exodus, write_exodus

from meshes import MOUNTAIN, TEMPEST_NE2, bipyramid_mesh, icosahedral_mesh


@pytest.mark.parametrize("ne", [1, 2, 5])
def test_the_cube_is_a_conforming_mesh_of_the_sphere(ne):
    mesh = check(cube_mesh(ne))
    assert mesh.nelem == 6 * ne * ne
    assert mesh.nnodes == 6 * ne * ne + 2  # V = F + 2 for a quadrilateral mesh of the sphere
    valence = np.bincount(mesh.quads.ravel())
    assert np.count_nonzero(valence == 3) == 8  # the cube's corners
    assert np.all(valence[valence != 3] == 4)
    # Every element covers the same share of the sphere at ne = 1; the areas sum to 4π.
    assert math.fsum(element_areas(mesh.corners())) == pytest.approx(4 * math.pi, rel=1e-14)


def test_a_written_mesh_reads_back_bit_for_bit(tmp_path):
    mesh = cube_mesh(3)
    path = write_exodus(tmp_path / "ne3.g", mesh)
    back = read_exodus(path)
    assert np.array_equal(back.coords, mesh.coords)
    assert np.array_equal(back.quads, mesh.quads)
    assert [p.name for p in tmp_path.iterdir()] == ["ne3.g"]  # no temporary left behind
    with netCDF4.Dataset(path) as f:  # the layout HOMME's mesh_mod reads
        assert f["coord"].shape == (3, mesh.nnodes)
        assert f["connect1"].getncattr("elem_type") == "SHELL4"
        assert int(f["connect1"][:].min()) == 1
        assert len(f.dimensions["num_el_blk"]) == 1


def test_a_mesh_with_nodes_of_3_to_6_elements_passes_its_checks_and_reads_back(tmp_path):
    mesh = icosahedral_mesh(1)
    assert sorted(set(np.bincount(mesh.quads.ravel()))) == [3, 4, 5, 6]
    back = read_exodus(write_exodus(tmp_path / "ico.g", mesh))
    assert np.array_equal(back.coords, mesh.coords) and np.array_equal(back.quads, mesh.quads)


def test_a_mesh_is_written_readable_by_others_or_refused_in_one_line(tmp_path):
    path = write_exodus(tmp_path / "ne1.g", cube_mesh(1))
    assert path.stat().st_mode & 0o777 == 0o644
    with pytest.raises(OutputError, match=r"^cannot write .*/nowhere/ne1.g: No such file or directory$"):
        write_exodus(tmp_path / "nowhere" / "ne1.g", cube_mesh(1))


def test_coordx_coordy_coordz_are_read_like_coord(tmp_path):
    mesh = cube_mesh(2)
    path = tmp_path / "split.g"
    with netCDF4.Dataset(path, "w", format="NETCDF3_CLASSIC") as f:
        f.createDimension("num_nodes", mesh.nnodes)
        f.createDimension("num_el_in_blk1", mesh.nelem)
        f.createDimension("num_nod_per_el1", 4)
        for k, a in enumerate("xyz"):
            f.createVariable(f"coord{a}", "f8", ("num_nodes",))[:] = mesh.coords[:, k]
        f.createVariable("connect1", "i4", ("num_el_in_blk1", "num_nod_per_el1"))[:] = mesh.quads + 1
    back = read_exodus(path)
    assert np.array_equal(back.coords, mesh.coords) and np.array_equal(back.quads, mesh.quads)


@pytest.mark.skipif(not TEMPEST_NE2.is_file(), reason="TEMPEST_NE2.g (E3SM's HOMME test mesh) not present")
def test_tempest_ne2_is_the_ne2_cube():
    mesh = read_exodus(TEMPEST_NE2)
    cube = cube_mesh(2)
    assert (mesh.nelem, mesh.nnodes) == (24, 26)
    # The same corner nodes (to round-off), in another order.
    ours = {tuple(np.round(x, 12)) for x in cube.coords}
    assert {tuple(np.round(x, 12)) for x in mesh.coords} == ours


@pytest.mark.skipif(not MOUNTAIN.is_file(), reason="mountain_10_x2.g (E3SM's HOMME test mesh) not present")
def test_the_refined_mountain_mesh_passes_its_checks():
    mesh = read_exodus(MOUNTAIN)
    assert (mesh.nelem, mesh.nnodes) == (780, 782)
    assert sorted(set(np.bincount(mesh.quads.ravel()))) == [3, 4, 5, 6]


def bad(mesh: Mesh, **change) -> Mesh:
    return Mesh(change.get("coords", mesh.coords), change.get("quads", mesh.quads), "bad.g")


def clockwise():
    mesh = cube_mesh(2)
    quads = mesh.quads.copy()
    quads[4] = quads[4, ::-1]
    return bad(mesh, quads=quads)


def off_sphere():
    mesh = cube_mesh(2)
    coords = mesh.coords.copy()
    coords[6] *= 1 + 1e-6
    return bad(mesh, coords=coords)


def non_conforming():
    """Element 8 uses a copy of node 1 (same place, another number): its two edges there are in one element each."""
    mesh = cube_mesh(2)
    coords = np.vstack([mesh.coords, mesh.coords[:1]])
    quads = mesh.quads.copy()
    e, k = np.argwhere(quads == 0)[-1]
    quads[e, k] = mesh.nnodes
    return bad(mesh, coords=coords, quads=quads)


def two_spheres():
    mesh = cube_mesh(1)
    return bad(mesh, coords=np.vstack([mesh.coords] * 2), quads=np.vstack([mesh.quads, mesh.quads + mesh.nnodes]))


def doubled():
    """One square about the north pole, twice: every edge in two elements, run the same way."""
    lon = np.pi / 2 * np.arange(4)
    coords = np.stack([0.5 * np.cos(lon), 0.5 * np.sin(lon), np.full(4, np.sqrt(0.75))], axis=1)
    return Mesh(coords, np.array([[0, 1, 2, 3], [0, 1, 2, 3]]), "bad.g")


def repeated_corner():
    mesh = cube_mesh(2)
    quads = mesh.quads.copy()
    quads[3, 2] = quads[3, 1]
    return bad(mesh, quads=quads)


@pytest.mark.parametrize(
    "make, message",
    [
        (clockwise, r"^bad.g: element 5 is clockwise seen from outside"),
        (off_sphere, r"^bad.g: node 7 is not on the unit sphere"),
        (non_conforming, r"^bad.g: the edge from node \d+ to node \d+ is in 1 element\(s\) \(\d+\), not 2"),
        (two_spheres, r"^bad.g: V − E \+ F = 4, not 2"),
        (repeated_corner, r"^bad.g: element 4 repeats a corner node"),
        (doubled, r"^bad.g: elements 1 and 2 run the same way along the edge from node 1 to node 2: they overlap$"),
    ],
)
def test_a_bad_mesh_is_refused_in_one_line_naming_the_element_or_node(make, message):
    with pytest.raises(SceneError, match=message) as err:
        check(make())
    assert "\n" not in str(err.value)


def test_a_node_of_8_elements_is_refused():
    with pytest.raises(
        SceneError, match=r"^8-gonal bipyramid quads: node 1 is shared by 8 elements \(3 to 7 allowed\)$"
    ):
        bipyramid_mesh(8)


def write_raw(path, coords, blocks, nodes_per_element=4):
    """A netCDF file in the Exodus layout with the element blocks ``blocks`` (1-based connectivity)."""
    with netCDF4.Dataset(path, "w", format="NETCDF3_CLASSIC") as f:
        f.createDimension("num_dim", 3)
        f.createDimension("num_nodes", coords.shape[0])
        f.createDimension("num_el_blk", len(blocks))
        f.createDimension("num_nod_per_el1", nodes_per_element)
        f.createVariable("coord", "f8", ("num_dim", "num_nodes"))[:] = coords.T
        for b, quads in enumerate(blocks, 1):
            f.createDimension(f"num_el_in_blk{b}", quads.shape[0])
            if b > 1:
                f.createDimension(f"num_nod_per_el{b}", quads.shape[1])
            f.createVariable(f"connect{b}", "i4", (f"num_el_in_blk{b}", f"num_nod_per_el{b}"))[:] = quads
    return path


def five_nodes(tmp_path):
    mesh = cube_mesh(2)
    return write_raw(tmp_path / "bad.g", mesh.coords, [np.hstack([mesh.quads, mesh.quads[:, :1]]) + 1], 5)


def two_blocks(tmp_path):
    mesh = cube_mesh(2)
    return write_raw(tmp_path / "bad.g", mesh.coords, [mesh.quads[:12] + 1, mesh.quads[12:] + 1])


def truncated(tmp_path):
    path = write_exodus(tmp_path / "bad.g", cube_mesh(2))
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    return path


def not_netcdf(tmp_path):
    path = tmp_path / "bad.g"
    path.write_text("ne = 2\n")
    return path


def missing(tmp_path):
    return tmp_path / "bad.g"


def a_folder(tmp_path):
    (tmp_path / "bad.g").mkdir()
    return tmp_path / "bad.g"


@pytest.mark.parametrize(
    "make, message",
    [
        (five_nodes, r"^bad.g: elements of 5 nodes; quadrilaterals \(4\) are needed$"),
        (two_blocks, r"^bad.g: 2 element blocks; one block of quadrilaterals is supported$"),
        (truncated, r"^bad.g: its arrays cannot be read in full \(a truncated or damaged netCDF file\)$"),
        (not_netcdf, r"^bad.g is not a netCDF file: an Exodus II mesh \(.g\) is one$"),
        (missing, r"^mesh file .*bad.g not found$"),
        (a_folder, r"^mesh file .*bad.g is a directory, not an Exodus II file$"),
    ],
)
def test_a_bad_mesh_file_is_refused_in_one_line(tmp_path, make, message):
    path = make(tmp_path)
    with pytest.raises(SceneError, match=message) as err:
        read_exodus(path)
    assert "\n" not in str(err.value)


def test_a_meshs_sha256_is_its_content(tmp_path):
    """``Mesh.sha256`` (the key of its cached cells): the same for the same nodes and elements
    whatever the name, the integer width or a round trip through a .g file; another for a node
    moved by one unit in the last place."""
    cube = cube_mesh(2)
    again = Mesh(cube.coords.copy(), cube.quads.astype(np.int32), "another name")
    assert again.sha256() == cube.sha256() == read_exodus(write_exodus(tmp_path / "c.g", cube)).sha256()
    moved = cube.coords.copy()
    moved[5, 0] = np.nextafter(moved[5, 0], 2.0)
    assert Mesh(moved, cube.quads).sha256() != cube.sha256()
