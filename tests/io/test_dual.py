"""The GLL dual mesh (``swe_sphere.io.dual``): one control volume a unique node, its area the
node's assembled spheremp; written into every run file as the UGRID mesh the fields live
on and as CF cell bounds. Then the tools that read them: uxarray and CDO, each test
skipping only where its tool is absent (the CF checkers and cf_xarray: test_cf.py)."""

from __future__ import annotations

import ctypes
import dataclasses
import json
import math
import sys
from collections import Counter

import netCDF4
import numpy as np
import pytest
import xarray as xr

from swe_sphere.cli import main
from swe_sphere.core.constants import EARTH
from swe_sphere.grid.cubed_sphere import CubedSphere
from swe_sphere.grid.gll import gll
from swe_sphere.grid.refine import Box, refined_cube
from swe_sphere.io import dual
from swe_sphere.io.dual import (
    RTOL,
    cache_key,
    cells,
    checkerboard,
    control_points,
    convex,
    dual_mesh,
    spherical_areas,
    star_shaped,
    unit_dual_mesh,
)
from swe_sphere.io.dual_solve import PR_GET_THP_DISABLE, small_pages
from swe_sphere.io.ugrid import subcell_quads
from swe_sphere.mesh.cube import cube_mesh
from swe_sphere.mesh.mesh import read_exodus
from swe_sphere.mesh.records import from_json, mesh_of
from swe_sphere.mesh.schmidt import schmidt_cube

from cf_checks import cdo
from helpers import cli_one_line
from meshes import MOUNTAIN

GRIDS = [(1, 2), (2, 4), (3, 2), (2, 8), (4, 3), (1, 6), (1, 3), (2, 2)]
NOT_CONVEX = {(2, 2): 2}  # at most so many cells star-shaped but not convex, on the coarsest grid


@pytest.mark.parametrize("np_", range(2, 9))
def test_control_points_interleave_the_gll_points(np_):
    """HOMME's check: t_k = −1 + Σ_{m<k} w_m lies between GLL points k−1 and k, so each
    sub-cell holds one dual vertex; the intervals' lengths are the weights, to round-off: t_k is
    k roundings of numbers of size ≤ 2 (k ε at most), so a difference is off by 2 np ε at most."""
    rule = gll(np_)
    t = control_points(rule)
    assert t[0] == -1 and t[-1] == 1 and t.size == np_ + 1
    assert (rule.points[:-1] < t[1:-1]).all() and (t[1:-1] < rule.points[1:]).all()
    assert np.max(np.abs(np.diff(t) - rule.weights)) <= 2 * np_ * np.finfo(float).eps


@pytest.mark.parametrize("ne,np_", GRIDS)
def test_every_node_is_one_cell_of_a_closed_mesh(grid_factory, ne, np_):
    grid = grid_factory(ne, np_)
    corners = cells(grid)
    nsub = 6 * ne**2 * (np_ - 1) ** 2
    assert corners.shape == (grid.nunique, 4) and corners.dtype == np.int32
    triangles = corners[:, 3] < 0
    assert triangles.sum() == 8  # the cube corners, 3 elements round them; every other cell 4 vertices
    assert (corners[:, :3] >= 0).all() and corners.max() == nsub - 1
    # each dual vertex (a sub-cell) is a corner of its sub-cell's 4 nodes' cells
    assert Counter(corners[corners >= 0].tolist()) == Counter({q: 4 for q in range(nsub)})
    # each directed edge once: neighbouring cells oriented alike; V − E + F = 2 (a sphere)
    directed = Counter()
    for row in corners.tolist():
        row = [v for v in row if v >= 0]
        directed.update((row[k], row[(k + 1) % len(row)]) for k in range(len(row)))
    assert max(directed.values()) == 1 and all((b, a) in directed for a, b in directed)
    assert nsub - len(directed) // 2 + grid.nunique == 2


@pytest.mark.parametrize("ne,np_", GRIDS + [(8, 4)])
def test_cells_are_convex_counter_clockwise_with_the_spheremp_areas(grid_factory, ne, np_):
    grid = grid_factory(ne, np_)
    verts, corners, error = dual_mesh(grid)
    target = grid.area / grid.radius**2
    assert error <= RTOL
    node = np.stack([grid.to_unique(x) for x in grid.xyz], axis=1)
    # counter-clockwise and simple: every fan triangle from the node turns left, seen from outside
    assert star_shaped(node, verts, corners).all()
    assert (~convex(verts, corners)).sum() <= NOT_CONVEX.get((ne, np_), 0)  # convex: every turn left
    area = spherical_areas(node, verts, corners)
    assert np.max(np.abs(area / target - 1)) == error
    # the same areas fanned from each cell's first vertex instead of its node
    again = spherical_areas(verts[corners[:, 0]], verts, corners)
    assert np.max(np.abs(again / target - 1)) <= RTOL + 1e-13
    assert area.sum() == pytest.approx(4 * math.pi, rel=1e-13)


def test_the_octant_has_a_quarter_hemisphere_and_a_nan_vertex_makes_a_cell_neither_star_shaped_nor_convex():
    verts = np.eye(3)  # the octant x, y, z > 0: a spherical triangle of three right angles, area π/2
    corners = np.array([[0, 1, 2, -1]], dtype=np.int32)
    centre = np.full((1, 3), 1 / math.sqrt(3))
    assert spherical_areas(centre, verts, corners)[0] == pytest.approx(math.pi / 2, rel=1e-14)
    assert star_shaped(centre, verts, corners).all() and convex(verts, corners).all()
    assert not convex(verts, corners[:, [0, 2, 1, 3]]).any()  # clockwise: every turn right
    bad = verts.copy()
    bad[1] = np.nan
    assert not star_shaped(centre, bad, corners).any() and not convex(bad, corners).any()


BOX = Box(20.0, 40.0, 255.0, 285.0)  # over TC5's mountain, within one face of the ne4 cube with its transitions
# (name, mesh, ne, np, {cell vertices: cells}): the cube through the element-local map, a stretched cube,
# and the cube refined 2x and 4x (transitions: mesh corners shared by 3, 5 and 6 elements)
MESHES = {
    "element-local ne2": (lambda: cube_mesh(2), 2, 4, {3: 8, 4: 210}),
    "stretched ne3 c2": (lambda: schmidt_cube(3, 2.0, 40.0, 90.0), 3, 4, {3: 8, 4: 480}),
    "refined ne4 x2": (lambda: refined_cube(4, BOX, 1), 0, 4, {3: 16, 4: 1094, 5: 8}),
    "refined ne6 x4": (lambda: refined_cube(6, BOX, 2), 0, 3, {3: 40, 4: 1442, 5: 16, 6: 8}),
    # HOMME's test mesh made by CUBIT paving, where ../shared has it: its convexity rule stalls the
    # worst cells' fit, and the global fit starts again from the start itself
    "mountain_10_x2.g": (lambda: read_exodus(MOUNTAIN), 0, 4, {3: 30, 4: 6975, 5: 12, 6: 5}),
}


@pytest.fixture(scope="module", params=list(MESHES))
def mesh_grid(request):
    make, ne, np_, valence = MESHES[request.param]
    if request.param == MOUNTAIN.name and not MOUNTAIN.is_file():
        pytest.skip(f"{MOUNTAIN} is not there")
    return CubedSphere(ne, np_, mesh=make()), valence


def test_cells_on_a_mesh_have_a_vertex_an_element_and_the_spheremp_areas(mesh_grid):
    """Any conforming quadrilateral mesh: a cell has as many vertices as its node has elements
    round it (3 to 6 here; the table as wide as the largest), every dual vertex is a corner of
    4 cells, each cell is convex and counter-clockwise, its area is spheremp to RTOL and the
    cells sum to 4π."""
    grid, valence = mesh_grid
    verts, corners, error = dual_mesh(grid)
    count = (corners >= 0).sum(axis=1)
    assert corners.shape == (grid.nunique, max(valence)) and dict(Counter(count.tolist())) == valence
    assert verts.shape[0] == grid.nelem_total * (grid.np - 1) ** 2
    assert np.array_equal(np.bincount(corners[corners >= 0]), np.full(verts.shape[0], 4))
    node = np.stack([grid.to_unique(x) for x in grid.xyz], axis=1)
    assert star_shaped(node, verts, corners).all() and convex(verts, corners).all()
    area = spherical_areas(node, verts, corners)
    assert error <= RTOL and np.max(np.abs(area * grid.radius**2 / grid.area - 1)) == pytest.approx(error, abs=1e-15)
    assert area.sum() == pytest.approx(4 * math.pi, rel=1e-13)


@pytest.mark.parametrize("ne,np_", [(8, 4), (1, 3), (4, 3)])
def test_the_multigrid_preconditioned_fit_reaches_the_areas_with_the_same_bits_each_build(
    grid_factory, monkeypatch, ne, np_
):
    """The fit with every system preconditioned by smoothed aggregation (from ``AMG_CELLS``
    cells on, ne120 and finer: lowered here), ne = 1 np = 3's twisted restart included: the
    areas to RTOL, the cells convex, and each build the same bits (pyamg's own weighting
    estimates a spectral radius from a random start). Not ne = 2 np = 2, whose twisted restart
    stalls with the V-cycle's nearly exact steps (its 26 cells: the cycle is a direct solve)."""
    monkeypatch.setattr(dual, "AMG_CELLS", 0)
    grid = grid_factory(ne, np_)
    verts, corners, error = dual_mesh(grid)
    node = np.stack([grid.to_unique(x) for x in grid.xyz], axis=1)
    area = spherical_areas(node, verts, corners)
    assert error <= RTOL and np.max(np.abs(area / (grid.area / grid.radius**2) - 1)) == error
    assert star_shaped(node, verts, corners).all() and convex(verts, corners).all()
    again = dual_mesh(grid)
    assert np.array_equal(again[0], verts) and np.array_equal(again[1], corners)


def test_the_multigrid_preconditioned_fit_on_a_mesh(mesh_grid, monkeypatch):
    """Each mesh of ``MESHES`` fitted with the multigrid preconditioner (``AMG_CELLS`` lowered):
    its convexity rule and restarts as with Jacobi's."""
    monkeypatch.setattr(dual, "AMG_CELLS", 0)
    grid, _ = mesh_grid
    verts, corners, error = dual_mesh(grid)
    node = np.stack([grid.to_unique(x) for x in grid.xyz], axis=1)
    assert error <= RTOL and star_shaped(node, verts, corners).all() and convex(verts, corners).all()


def test_a_fit_that_stops_at_its_floor_keeps_what_it_reached_after_a_few_solves(grid_factory, monkeypatch):
    """A tolerance below what the fit can reach on a grid (RTOL 1e-16; ne8 np4 stops near 1e-13):
    the fit ends at its floor, within ``FLOOR_ERROR``, its cells star-shaped and convex and their
    areas off spheremp by the error it returns, after a few more linear solves than the fit to
    the real RTOL, not started again from two more starts (before the floor rule: 113 solves,
    then ``ArithmeticError``; ne240 at RTOL 1e-10 took over 25 minutes that way)."""
    import scipy.sparse.linalg as spla

    grid = grid_factory(8, 4)
    solves, cg = [], spla.cg
    monkeypatch.setattr(spla, "cg", lambda *args, **kwargs: solves.append(1) or cg(*args, **kwargs))
    _, _, reached = dual_mesh(grid)
    to_rtol = len(solves)
    solves.clear()
    monkeypatch.setattr(dual, "RTOL", 1e-16)
    verts, corners, error = dual_mesh(grid)
    assert reached <= RTOL and 1e-16 < error <= dual.FLOOR_ERROR
    node = np.stack([grid.to_unique(x) for x in grid.xyz], axis=1)
    assert star_shaped(node, verts, corners).all() and convex(verts, corners).all()
    area = spherical_areas(node, verts, corners)
    assert np.max(np.abs(area / (grid.area / grid.radius**2) - 1)) == pytest.approx(error, abs=1e-15)
    assert to_rtol < len(solves) <= 3 * to_rtol + 2 * dual.FLOOR_TRIALS, (to_rtol, len(solves))


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="prctl(2) is Linux's")
def test_the_build_faults_its_memory_in_small_pages_and_restores_the_setting():
    """``small_pages``: the process's transparent huge pages off inside (prctl's
    PR_GET_THP_DISABLE reads 1), on again after, where they were on before."""
    prctl = ctypes.CDLL(None).prctl
    before = prctl(PR_GET_THP_DISABLE, 0, 0, 0, 0)
    if before != 0:  # inherited from the parent (prctl's flag passes through fork and exec)
        pytest.skip("transparent huge pages already off for this process")
    with small_pages():
        inside = prctl(PR_GET_THP_DISABLE, 0, 0, 0, 0)
    assert inside == 1 and prctl(PR_GET_THP_DISABLE, 0, 0, 0, 0) == 0


@pytest.mark.parametrize("ne,np_", [(1, 2), (3, 4)])
def test_the_checkerboard_alternates_along_every_edge(grid_factory, ne, np_):
    """``checkerboard``: ±1 on the unique nodes, opposite at the two ends of every sub-cell edge."""
    quads = subcell_quads(grid_factory(ne, np_))
    colour = checkerboard(quads)
    assert colour.shape == (quads.max() + 1,) and set(np.unique(colour)) == {-1.0, 1.0}
    assert (colour[quads] == -colour[np.roll(quads, -1, axis=1)]).all()


def test_a_meshs_cells_are_cached_by_its_content_and_map(tmp_path, monkeypatch):
    """The cells' cache key: the uniform cube's as it was (no hash); a mesh's names its content's
    SHA-256 and its map, so the cube through the element-local map, the same mesh read again
    (one entry), the same mesh through the equiangular map and a stretched cube each have their own entry, built once and then read."""
    monkeypatch.setenv("SWE_SPHERE_CACHE_DIR", str(tmp_path))
    assert cache_key(2, 4) == {
        "mesh": "cubed_sphere",
        "map": "equiangular",
        "ne": 2,
        "np": 4,
        "radius": EARTH.a,
        "build": cache_key(2, 4)["build"],
    }
    assert cache_key(2, 4, radius=1.0) == {**cache_key(2, 4), "radius": 1.0}
    cube, again, stretched = cube_mesh(2), cube_mesh(2), schmidt_cube(2, 1.5)
    assert cache_key(2, 4, cube) == cache_key(2, 4, again) != cache_key(2, 4, stretched)
    assert cache_key(2, 4, cube)["map"] == "element_local" and cache_key(2, 4, cube)["mesh"] == cube.sha256()
    by_face = dataclasses.replace(cube, map="equiangular")  # the same mesh through the equiangular map
    assert cache_key(2, 4, by_face) == {**cache_key(2, 4, cube), "map": "equiangular"}
    build = dual.cached_cells  # past the process's memo
    first, read = build(2, 4, cube), build(2, 4, again)
    assert first[3] is not None and read[3] is None and all(np.array_equal(a, b) for a, b in zip(first[:2], read[:2]))
    assert build(2, 4, stretched)[3] is not None and len(list(tmp_path.iterdir())) == 2


def test_the_cells_are_built_on_one_blas_thread(tmp_path, monkeypatch):
    """The cells' fit runs with BLAS at one thread (issue 83: OpenBLAS's threads spun through
    its CG's inner products, 423 s of CPU at ne120 on 16 cores, and set the cells' bits by the
    host's core count)."""
    from threadpoolctl import threadpool_info, threadpool_limits

    monkeypatch.setenv("SWE_SPHERE_CACHE_DIR", str(tmp_path))
    seen, fit = [], dual.dual_mesh

    def watched(grid):
        seen.extend(p["num_threads"] for p in threadpool_info() if p["user_api"] == "blas")
        return fit(grid)

    monkeypatch.setattr(dual, "dual_mesh", watched)
    with threadpool_limits(limits=2, user_api="blas"):
        built = dual.cached_cells(1, 3)
    assert built[3] is not None and seen and set(seen) == {1}


@pytest.mark.parametrize("ne,np_", [(2, 4), (3, 8), (30, 4)])
def test_the_run_grids_targets_are_the_unit_grids_to_round_off(grid_factory, ne, np_):
    """The cells are fitted on the run's grid (radius a), not a second one of radius 1: the
    same unit vectors bit for bit (P/|P|, no radius), and spheremp / a² within round-off of
    the unit grid's. The two chains part at a·factor/|P|: some 30 roundings a side from there
    (the tangents, D's dot products, its determinant, the area factor, the weights, the
    copies' sum, / a²), 30 ε in all, doubled for the determinant's cancellation where the map
    skews (cube corners): 64 ε (largest seen 24.5 ε, ne120)."""
    run, unit = grid_factory(ne, np_), CubedSphere(ne, np_, radius=1.0)
    assert np.array_equal(run.xyz, unit.xyz)
    assert np.max(np.abs(run.area / run.radius**2 / unit.area - 1)) <= 64 * np.finfo(float).eps


def test_the_cells_from_the_run_grid_are_those_of_a_grid_built_for_them(tmp_path, monkeypatch, grid_factory):
    """Given the run's whole grid, the cells are fitted on it; given none, or a rank's part, a
    grid of the same arguments is built (an MPI rank 0 writes from a ``GatheredGrid``): the
    same bits either way, one key."""
    grid = grid_factory(2, 4)
    got = []
    for folder, given in (("run", grid), ("none", None), ("part", grid.part(np.arange(3)))):
        monkeypatch.setenv("SWE_SPHERE_CACHE_DIR", str(tmp_path / folder))
        got.append(dual.cached_cells(2, 4, radius=grid.radius, grid=given))
    assert all(g[3] is not None for g in got)
    for other in got[1:]:
        assert all(np.array_equal(a, b) for a, b in zip(got[0][:3], other[:3], strict=True))
    # a grid of another radius than the cells' is not theirs: a grid of that radius is built
    monkeypatch.setenv("SWE_SPHERE_CACHE_DIR", str(tmp_path / "unit"))
    unit = dual.cached_cells(2, 4, radius=1.0, grid=grid)
    monkeypatch.setenv("SWE_SPHERE_CACHE_DIR", str(tmp_path / "unit_none"))
    assert all(np.array_equal(a, b) for a, b in zip(unit[:3], dual.cached_cells(2, 4, radius=1.0)[:3], strict=True))


@pytest.fixture(scope="module")
def tc5_ne4(tmp_path_factory):
    """``swe-sphere run tc5_mountain`` at ne = 4 np = 4, 1 day (outputs at days 0 and 1)."""
    out = tmp_path_factory.mktemp("dual") / "tc5.nc"
    args = ["run", "tc5_mountain", "--ne", "4", "--np", "4", "--days", "1", "--device", "cpu", "--no-progress"]
    assert main([*args, "--output", str(out)]) == 0
    return out


@pytest.fixture(scope="module")
def tc2_meshes(tmp_path_factory):
    """TC2 for 2 hours on a mesh ``swe-sphere mesh`` writes (the ne4 cube refined 2x over
    ``BOX``) and on the ne3 cube stretched 2x toward (40°N, 90°E): {name: run file}."""
    folder = tmp_path_factory.mktemp("dual_meshes")
    mesh = folder / "refined.g"
    box = [str(x) for x in (BOX.lat_min, BOX.lat_max, BOX.lon_min, BOX.lon_max)]
    assert main(["mesh", "--ne", "4", "--refine-box", *box, "--output", str(mesh)]) == 0
    args = ["run", "tc2_steady", "--dt", "600", "--days", "0.0833333333333333", "--device", "cpu", "--no-progress"]
    stretch = ["--ne", "3", "-s", "grid.stretch_factor=2.0", "-s", "grid.target_lat=40.0", "-s", "grid.target_lon=90.0"]
    runs = {"refined": ["--mesh", str(mesh)], "stretched": stretch}
    for name, grid in runs.items():
        assert main([*args, *grid, "--output", str(folder / f"{name}.nc")]) == 0
    return {name: folder / f"{name}.nc" for name in runs}


@pytest.fixture(scope="module", params=["cube", "refined", "stretched"])
def run_file(request, tc5_ne4, tc2_meshes):
    """A run file and its grid (Earth radius, rebuilt from the file's scene): the ne4 cube's
    TC5 and the two meshes' TC2 (``tc2_meshes``)."""
    path = tc5_ne4 if request.param == "cube" else tc2_meshes[request.param]
    with netCDF4.Dataset(path) as nc:
        scene = json.loads(nc.scene)
    return path, CubedSphere(
        scene["ne"], scene["np"], mesh=mesh_of(scene["ne"], from_json(scene["ne"], scene.get("mesh"))).build()
    )


def file_mean(path, name="h"):
    """The run file's own spheremp-weighted mean of ``name`` at each output time."""
    with xr.open_dataset(path, decode_times=False) as ds:
        return (ds[name] * ds.area).sum("ncol").values / float(ds.area.sum())


def test_run_file_carries_the_dual_mesh_and_cell_bounds(run_file):
    """On the cube and on meshes: the UGRID dual mesh the fields live on, the writer's cells (the
    file's corners give spheremp to RTOL), and CF bounds that repeat a short cell's last vertex."""
    path, grid = run_file
    verts, corners, error, _ = unit_dual_mesh(grid.ne, grid.np, grid.mesh)  # the writer's
    with netCDF4.Dataset(path) as nc:
        mesh = nc["mesh_dual"]
        assert (mesh.cf_role, int(mesh.topology_dimension)) == ("mesh_topology", 2)
        assert mesh.max_relative_area_error == error <= RTOL  # the fit's, as the file says it
        assert (mesh.node_coordinates, mesh.face_coordinates, mesh.face_dimension) == (
            "dual_lon dual_lat",
            "lon lat",
            "ncol",
        )
        conn = nc[mesh.face_node_connectivity]
        assert conn.dimensions == ("ncol", "nv") and int(conn.start_index) == 0 and conn._FillValue == -1
        assert np.array_equal(conn[:].filled(-1), corners) and nc.dimensions["nv"].size == corners.shape[1]
        assert nc.dimensions["ndual_node"].size == grid.nelem_total * (grid.np - 1) ** 2
        for name in ("h", "u", "v", "hs", "vorticity", "divergence"):
            assert (nc[name].mesh, nc[name].location) == ("mesh_dual", "face"), name
        assert "cells" not in nc.ncattrs()
        assert (nc["lon"].bounds, nc["lat"].bounds) == ("lon_bnds", "lat_bnds")
        assert nc["lon_bnds"].dimensions == ("ncol", "nv") and not nc["lon_bnds"].ncattrs()
        lat, lon = np.radians(nc["dual_lat"][:]), np.radians(nc["dual_lon"][:])
        xyz = np.stack([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)], axis=1)
        assert np.allclose(xyz, verts, rtol=0, atol=1e-14)  # through degrees
        # the file's own corners (degrees) give its own areas: spheremp/a², to the tolerance
        node_lat, node_lon = np.radians(nc["lat"][:]), np.radians(nc["lon"][:])
        node = np.stack(
            [np.cos(node_lat) * np.cos(node_lon), np.cos(node_lat) * np.sin(node_lon), np.sin(node_lat)], axis=1
        )
        area = spherical_areas(node, xyz, conn[:].filled(-1))
        assert np.max(np.abs(area * grid.radius**2 / nc["area"][:] - 1)) <= RTOL
        # the bounds are those corners, a short cell's last repeated, longitudes within 180° of the node's
        last = corners[np.arange(len(corners)), (corners >= 0).sum(axis=1) - 1]
        padded = np.where(corners < 0, last[:, None], corners)
        assert np.array_equal(nc["lat_bnds"][:], nc["dual_lat"][:][padded])
        dlon = nc["lon_bnds"][:] - nc["lon"][:][:, None]
        assert np.abs(dlon).max() <= 180 and np.allclose(
            np.mod(dlon + nc["lon"][:][:, None] - nc["dual_lon"][:][padded] + 1, 360), 1
        )


def test_uxarray_averages_integrates_and_takes_zonal_means_of_the_run(run_file):
    ux = pytest.importorskip("uxarray")
    path = run_file[0]
    uxds = ux.open_dataset(path, path)
    grid = uxds.uxgrid
    with xr.open_dataset(path, decode_times=False) as ds:
        area = ds.area.values / 6.37122e6**2
        ncol, ndual = ds.sizes["ncol"], ds.sizes["ndual_node"]
    assert (grid.n_face, grid.n_node) == (ncol, ndual) and grid.validate()
    # uxarray's own spherical face areas are spheremp/a² to the fit's RTOL (its Gaussian quadrature of
    # order 10 adds 4e-14 on the cube)
    areas = np.asarray(grid.compute_face_areas(quadrature_rule="gaussian", order=10))
    assert np.max(np.abs(areas / area - 1)) < RTOL + 1e-13
    h = uxds["h"]
    assert h.sizes["n_face"] == ncol
    # its area-weighted mean is the file's spheremp-weighted mean but for its default face areas' error ε
    # (6e-8 a cell): h > 0, so the weights' relative errors move the mean by 2 max|ε| / (1 − max|ε|) at most
    eps = np.max(np.abs(np.asarray(grid.face_areas) / area - 1))
    mine = file_mean(path)
    means = [float(h.isel(time=t).weighted_mean()) for t in range(2)]
    assert np.allclose(means, mine, rtol=2 * eps / (1 - eps), atol=0)
    # its integral: Σ area·h with its default quadrature's areas, off by ε each (the file's areas sum to 4π)
    assert float(h.isel(time=-1).integrate().values) == pytest.approx(mine[-1] * 4 * math.pi, rel=eps + 1e-13)
    zonal = h.isel(time=-1).zonal_mean(lat=(-90, 90, 10))
    assert zonal.shape == (19,) and np.isfinite(zonal.values).all()
    assert h.isel(time=-1).min() <= zonal.min() and zonal.max() <= h.isel(time=-1).max()
    # one conservative band over the whole sphere is the global mean
    band = h.isel(time=-1).zonal_mean(lat=(-90, 90, 180), conservative=True)
    assert float(band.values[0]) == pytest.approx(mine[-1], rel=1e-6)


def test_uxarray_draws_the_cells(tc5_ne4):
    ux = pytest.importorskip("uxarray")
    h = ux.open_dataset(tc5_ne4, tc5_ne4)["h"].isel(time=-1)
    ncol = h.sizes["n_face"]
    try:  # drawing needs cartopy, an optional dependency of uxarray itself
        pc = h.to_polycollection()
    except ImportError as exc:  # uxarray's OptionalDependencyNotFoundError is one; any other error fails
        pytest.skip(f"uxarray cannot draw without its optional dependency: {exc}")
    assert 0.9 * ncol <= len(pc.get_paths()) <= ncol  # it leaves out the few cells it splits at the antimeridian


@pytest.fixture(scope="module")
def members_file(tmp_path_factory):
    """``swe-sphere run tc5_mountain --members 2`` at ne = 2 np = 4, 6 hours: fields (time, member, ncol)."""
    out = tmp_path_factory.mktemp("dual_members") / "members.nc"
    args = ["run", "tc5_mountain", "--ne", "2", "--np", "4", "--days", "0.25", "--device", "cpu", "--no-progress"]
    assert main([*args, "--members", "2", "--perturbation", "1", "--output", str(out)]) == 0
    return out


@pytest.fixture(params=["cube", "refined", "stretched", "members"])
def cdo_file(request, tc5_ne4, tc2_meshes, members_file):
    """A run file as written: the ne4 cube's TC5, the two meshes' TC2, an ensemble's TC5."""
    return {"cube": tc5_ne4, "members": members_file, **tc2_meshes}[request.param]


def checked_cdo(*args) -> None:
    done = cdo(*args)
    assert done.returncode == 0, done.stderr


def test_cdo_measures_averages_and_remaps_the_file_as_written(cdo_file, tmp_path):
    """``cdo gridarea``, ``cdo fldmean`` and ``cdo remapcon,r360x180`` on the whole file, no variable
    selected first: CDO takes the cells from lon_bnds/lat_bnds, and the meshes' connectivity and vertex
    tables (kept for uxarray) are no fields of their own grids to it (it aborted on them)."""
    path = cdo_file
    checked_cdo("gridarea", path, tmp_path / "area.nc")
    with xr.open_dataset(tmp_path / "area.nc") as a, xr.open_dataset(path, decode_times=False) as ds:
        ratio = a.cell_area.values / ds.area.values  # spheremp in CDO's own Earth radius
    assert np.ptp(ratio) < 1e-12 * ratio.mean()
    mine = file_mean(path).ravel()  # (time,) or (time, member), as CDO's records
    checked_cdo("fldmean", path, tmp_path / "mean.nc")
    with xr.open_dataset(tmp_path / "mean.nc", decode_times=False) as ds:
        assert np.allclose(ds.h.values.ravel(), mine, rtol=1e-13, atol=0)
    # conservative remapping to a 1° grid keeps the mean: CDO's own remap weights move it by 2.8e-5 (TC5),
    # 1.35e-4 (TC2 on the refined mesh and the stretched cube)
    checked_cdo("remapcon,r360x180", path, tmp_path / "ll.nc")
    checked_cdo("fldmean", "-selname,h", tmp_path / "ll.nc", tmp_path / "ll_mean.nc")
    with xr.open_dataset(tmp_path / "ll.nc", decode_times=False) as ll:
        assert (ll.sizes["lat"], ll.sizes["lon"]) == (180, 360) and np.isfinite(ll.h.values).all()
    with xr.open_dataset(tmp_path / "ll_mean.nc", decode_times=False) as ds:
        assert np.allclose(ds.h.values.ravel(), mine, rtol=2e-4, atol=0)


@pytest.mark.parametrize("np_", range(2, 9))
@pytest.mark.parametrize("ne", [1, 2, 3])
def test_the_writers_build_reaches_the_areas_on_every_small_grid(grid_factory, ne, np_):
    """``unit_dual_mesh``, the build the run file takes (unit sphere), on each grid the command
    line accepts up to ne = 3: ne = 2 np = 2 stalled at a mirror-symmetric point there."""
    verts, corners, error, _ = unit_dual_mesh(ne, np_)
    grid = grid_factory(ne, np_)
    node = np.stack([grid.to_unique(x) for x in grid.xyz], axis=1)
    area = spherical_areas(node, verts, corners)
    assert error <= RTOL and np.max(np.abs(area * grid.radius**2 / grid.area - 1)) <= RTOL  # the Earth's spheremp
    assert star_shaped(node, verts, corners).all()
    assert area.sum() == pytest.approx(4 * math.pi, rel=1e-13)


def test_a_run_whose_cells_cannot_be_fitted_is_written_without_them_and_says_so(tmp_path, monkeypatch, capsys):
    """A fit that fails (``dual_mesh``'s ``ArithmeticError``) costs the run its cells, not the run:
    one line says so, the file is the one ``--no-cells`` writes, its ``cells`` attribute naming the
    failure; the grid is not fitted again in the process. An ensemble's run (``--members``) the
    same."""
    monkeypatch.setenv("SWE_SPHERE_CACHE_DIR", str(tmp_path / "cache"))
    fits = []

    def stalled(grid):
        fits.append(grid.ne)
        raise ArithmeticError("dual mesh: no step lowers the cell-area error 1.4e-10")

    monkeypatch.setattr(dual, "dual_mesh", stalled)
    out, ensemble = tmp_path / "o.nc", tmp_path / "members.nc"
    args = ["run", "tc5_mountain", "--ne", "2", "--np", "2", "--days", "0.25", "--device", "cpu", "--no-progress"]
    dual.clear_memo()
    lines = []
    try:
        for path, extra in ((out, []), (ensemble, ["--members", "2", "--perturbation", "1"])):
            assert main([*args, "--output", str(path), *extra]) == 0
            lines.append([line for line in capsys.readouterr().err.splitlines() if "cells" in line])
        with pytest.raises(ArithmeticError, match="no step lowers"):
            dual.unit_dual_mesh(2, 2)
    finally:
        dual.clear_memo()
    assert fits == [2]
    for said in lines:  # the single run's and the ensemble's
        assert len(said) == 1 and "could not be fitted" in said[0] and "no step lowers" in said[0], said
    for path in (out, ensemble):
        with netCDF4.Dataset(path) as ds:
            assert "mesh_dual" not in ds.variables and "their fit failed: dual mesh" in ds.cells
            assert (ds["h"].mesh, ds["h"].location) == ("mesh_topology", "node") and np.isfinite(ds["h"][:]).all()


def test_a_run_says_when_it_built_its_cells_and_runs_without_them(tmp_path, monkeypatch, capsys):
    """ne = 2 np = 2 runs; the first run of a grid says in one line what its cells cost
    (every build, with the threshold lowered), the next reads them quietly; ``--no-cells``
    leaves them out and the file says what is missing."""
    from swe_sphere.io import run_file

    monkeypatch.setenv("SWE_SPHERE_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setattr(run_file, "CELLS_NOTE_SECONDS", 0.0)
    dual.clear_memo()  # the process's own copy: this test's cache starts empty
    args = ["run", "tc5_mountain", "--ne", "2", "--np", "2", "--days", "0.25", "--device", "cpu", "--no-progress"]
    notes = []
    for name, extra in (("first", ["--restart-every", "0.25"]), ("second", []), ("bare", ["--no-cells"])):
        dual.clear_memo()
        assert main([*args, "--output", str(tmp_path / f"{name}.nc"), *extra]) == 0
        notes.append([line for line in capsys.readouterr().err.splitlines() if "cells" in line])
    assert len(notes[0]) == 1 and "ne=2 np=2" in notes[0][0] and str(tmp_path / "cache") in notes[0][0]
    assert notes[1:] == [[], []]
    with netCDF4.Dataset(tmp_path / "first.nc") as full, netCDF4.Dataset(tmp_path / "bare.nc") as bare:
        assert "mesh_dual" in full.variables and "lon_bnds" in full.variables
        assert not {"mesh_dual", "lon_bnds", "lat_bnds", "dual_lon"} & set(bare.variables)
        assert "no mesh_dual" in bare.cells and "remapcon" in bare.cells
        assert not hasattr(bare["lon"], "bounds")
        for name in ("h", "hs", "u"):
            assert (bare[name].mesh, bare[name].location) == ("mesh_topology", "node")
            assert np.array_equal(bare[name][:], full[name][:])
    assert json.loads(netCDF4.Dataset(tmp_path / "bare.nc").scene)["output_cells"] is False
    # a continuation keeps its scene's choice: --no-cells cannot change it
    restart = tmp_path / "first.restart.nc"
    cli_one_line(capsys, ["run", "--continue", restart, "--days", "0.5", "--no-cells"], 2, "--no-cells", "output.cells")
