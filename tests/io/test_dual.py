"""The GLL dual mesh (``swe_sphere.io.dual``): one control volume a unique node, its area the
node's assembled spheremp; written into every run file as the UGRID mesh the fields live
on and as CF cell bounds. Then the tools that read them: uxarray and CDO, each test
skipping only where its tool is absent (the CF checkers and cf_xarray: test_cf.py)."""

from __future__ import annotations

import json
import math
import shutil
import subprocess
from collections import Counter

import netCDF4
import numpy as np
import pytest
import xarray as xr

from swe_sphere.cli import main
from swe_sphere.grid.gll import gll
from swe_sphere.io.dual import (
    RTOL,
    cells,
    control_points,
    convex,
    dual_mesh,
    spherical_areas,
    star_shaped,
    unit_dual_mesh,
)

from helpers import cli_one_line

GRIDS = [(1, 2), (2, 4), (3, 2), (2, 8), (4, 3), (1, 6), (1, 3), (2, 2)]
NOT_CONVEX = {(1, 3): 3, (2, 2): 3}  # at most so many cells star-shaped but not convex, on the two coarsest grids


@pytest.mark.parametrize("np_", range(2, 9))
def test_control_points_interleave_the_gll_points(np_):
    """HOMME's check: t_k = −1 + Σ_{m<k} w_m lies between GLL points k−1 and k, so each
    sub-cell holds one dual vertex; the intervals' lengths are the weights."""
    rule = gll(np_)
    t = control_points(rule)
    assert t[0] == -1 and t[-1] == 1 and t.size == np_ + 1
    assert (rule.points[:-1] < t[1:-1]).all() and (t[1:-1] < rule.points[1:]).all()
    assert np.allclose(np.diff(t), rule.weights, rtol=0, atol=4e-16)


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


@pytest.fixture(scope="module")
def tc5_ne4(tmp_path_factory):
    """``swe-sphere run tc5_mountain`` at ne = 4 np = 4, 1 day (outputs at days 0 and 1)."""
    out = tmp_path_factory.mktemp("dual") / "tc5.nc"
    assert (
        main(
            [
                "run",
                "tc5_mountain",
                "--ne",
                "4",
                "--np",
                "4",
                "--days",
                "1",
                "--device",
                "cpu",
                "--no-progress",
                "--output",
                str(out),
            ]
        )
        == 0
    )
    return out


def file_mean(path, name="h"):
    """The run file's own spheremp-weighted mean of ``name`` at each output time."""
    with xr.open_dataset(path, decode_times=False) as ds:
        return (ds[name] * ds.area).sum("ncol").values / float(ds.area.sum())


def test_run_file_carries_the_dual_mesh_and_cell_bounds(tc5_ne4, grid_factory):
    grid = grid_factory(4, 4)
    verts, corners, _, _ = unit_dual_mesh(4, 4)  # the writer's
    with netCDF4.Dataset(tc5_ne4) as nc:
        mesh = nc["mesh_dual"]
        assert (mesh.cf_role, int(mesh.topology_dimension)) == ("mesh_topology", 2)
        assert (mesh.node_coordinates, mesh.face_coordinates, mesh.face_dimension) == (
            "dual_lon dual_lat",
            "lon lat",
            "ncol",
        )
        conn = nc[mesh.face_node_connectivity]
        assert conn.dimensions == ("ncol", "nv") and int(conn.start_index) == 0 and conn._FillValue == -1
        assert np.array_equal(conn[:].filled(-1), corners)
        assert nc.dimensions["ndual_node"].size == 6 * 4**2 * 3**2
        for name in ("h", "u", "v", "hs", "vorticity", "divergence"):
            assert (nc[name].mesh, nc[name].location) == ("mesh_dual", "face"), name
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
        # the bounds are those corners, the triangles' last repeated, longitudes within 180° of the node's
        padded = np.where(corners < 0, corners[:, 2:3], corners)
        assert np.array_equal(nc["lat_bnds"][:], nc["dual_lat"][:][padded])
        dlon = nc["lon_bnds"][:] - nc["lon"][:][:, None]
        assert np.abs(dlon).max() <= 180 and np.allclose(
            np.mod(dlon + nc["lon"][:][:, None] - nc["dual_lon"][:][padded] + 1, 360), 1
        )


def test_uxarray_averages_integrates_and_takes_zonal_means_of_the_run(tc5_ne4):
    ux = pytest.importorskip("uxarray")
    uxds = ux.open_dataset(tc5_ne4, tc5_ne4)
    grid = uxds.uxgrid
    with xr.open_dataset(tc5_ne4, decode_times=False) as ds:
        area = ds.area.values / 6.37122e6**2
        ncol = ds.sizes["ncol"]
    assert (grid.n_face, grid.n_node) == (ncol, 6 * 4**2 * 3**2) and grid.validate()
    # uxarray's own spherical face areas are spheremp/a² (Gaussian quadrature of order 10: measured 4e-14)
    areas = np.asarray(grid.compute_face_areas(quadrature_rule="gaussian", order=10))
    assert np.max(np.abs(areas / area - 1)) < 1e-12
    h = uxds["h"]
    assert h.sizes["n_face"] == ncol
    # its area-weighted mean is the file's spheremp-weighted mean (default face areas: 6e-8 off)
    mine = file_mean(tc5_ne4)
    assert np.allclose([float(h.isel(time=t).weighted_mean()) for t in range(2)], mine, rtol=1e-10, atol=0)
    # its integral: Σ area·h with its default quadrature's areas (measured 2e-8 relative)
    assert float(h.isel(time=-1).integrate().values) == pytest.approx(mine[-1] * 4 * math.pi, rel=1e-6)
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


def cdo(*args) -> str:
    return subprocess.run(["cdo", "-s", *map(str, args)], check=True, capture_output=True, text=True).stdout


@pytest.mark.skipif(shutil.which("cdo") is None, reason="CDO is not installed (apt-get install cdo)")
def test_cdo_fldmean_and_remapcon_of_the_native_file(tc5_ne4, tmp_path):
    # CDO reads the cells from lon_bnds/lat_bnds: its cell areas are spheremp in its own Earth radius
    cdo("gridarea", tc5_ne4, tmp_path / "area.nc")
    with xr.open_dataset(tmp_path / "area.nc") as a, xr.open_dataset(tc5_ne4, decode_times=False) as ds:
        ratio = a.cell_area.values / ds.area.values
    assert np.ptp(ratio) < 1e-12 * ratio.mean()
    mine = file_mean(tc5_ne4)
    means = np.array(cdo("outputf,%.17g", "-fldmean", "-selname,h", tc5_ne4).split(), dtype=float)
    assert np.allclose(means, mine, rtol=1e-13, atol=0)
    # conservative remapping to a 5° grid keeps the mean (measured 2.8e-5 relative: CDO's own remap weights)
    cdo("remapcon,r72x36", "-selname,h", tc5_ne4, tmp_path / "ll.nc")
    remapped = np.array(cdo("outputf,%.17g", "-fldmean", tmp_path / "ll.nc").split(), dtype=float)
    assert np.allclose(remapped, mine, rtol=1e-4, atol=0)


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


def test_a_run_says_when_it_built_its_cells_and_runs_without_them(tmp_path, monkeypatch, capsys):
    """ne = 2 np = 2 runs; the first run of a grid says in one line what its cells cost
    (every build, with the threshold lowered), the next reads them quietly; ``--no-cells``
    leaves them out and the file says what is missing."""
    from swe_sphere.simulation import writers

    monkeypatch.setenv("SWE_SPHERE_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setattr(writers, "NOTE_SECONDS", 0.0)
    unit_dual_mesh.cache_clear()  # the process's own copy: this test's cache starts empty
    args = ["run", "tc5_mountain", "--ne", "2", "--np", "2", "--days", "0.25", "--device", "cpu", "--no-progress"]
    notes = []
    for name, extra in (("first", ["--restart-every", "0.25"]), ("second", []), ("bare", ["--no-cells"])):
        unit_dual_mesh.cache_clear()
        assert main([*args, "--output", str(tmp_path / f"{name}.nc"), *extra]) == 0
        notes.append([line for line in capsys.readouterr().err.splitlines() if "cells" in line])
    assert len(notes[0]) == 1 and "ne 2 np 2" in notes[0][0] and str(tmp_path / "cache") in notes[0][0]
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
