"""Runs on meshes chosen by a scene's [grid] (or ``--mesh``): a project-written Exodus II cube and
a Schmidt-stretched cube. TC2's error stays that of the uniform cube's size, mass is kept to
round-off, a restart continues bitwise and refuses another mesh, and bad [grid] input is one
line, exit 2, nothing written."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest
import xarray as xr

from swe_sphere.cases.library import make_case
from swe_sphere.cli import main
from swe_sphere.config.scene import efold_nu, load_scene
from swe_sphere.core.constants import DAY
from swe_sphere.core.errors import SceneError
from swe_sphere.core.runtime import run_bytes
from swe_sphere.grid.cubed_sphere import CubedSphere
from swe_sphere.grid.quality import element_sizes, smallest_dx
from swe_sphere.io import restart_file
from swe_sphere.io.remap import Remapper, latlon_grid, remap_dataset
from swe_sphere.mesh.cube import cube_mesh
from swe_sphere.mesh.mesh import read_exodus, write_exodus
from swe_sphere.mesh.records import file_sha256
from swe_sphere.mesh.schmidt import schmidt_cube
from swe_sphere.simulation.simulation import Simulation

import roundoff
from helpers import write_tc2_scene
from meshes import MOUNTAIN, icosahedral_mesh

DT = 600.0  # s: within the gravity-wave limit of the ne2 np4 element-local cube (1838 s) and the stretched ne4
STEPS = 12  # 2 hours
H_L2 = "l2_h"  # the normalized l2 error of h (Williamson 1992) in a run's diagnostics


@pytest.fixture
def cube_file(tmp_path):
    """The ne2 cube written as an Exodus II file by the project."""
    return write_exodus(tmp_path / "cube2.g", cube_mesh(2))


def tc2(**grid):
    """TC2 (no ∇⁴) for ``STEPS`` steps of ``DT`` on the grid ``load_scene`` is given."""
    return load_scene("tc2_steady", dt=DT, days=STEPS * DT / DAY, **grid)


def run(scene):
    sim = Simulation(scene, "cpu", progress=False)
    return sim, sim.run(None)


@pytest.mark.roundoff
def test_tc2_on_a_written_cube_file_is_the_cube_and_keeps_mass(cube_file):
    """TC2 on the ne2 cube read back from the .g file it was written to (ne = 0, element-local
    map): the same grid as the built-in ne2 cube through the element-local map, so the same
    state bit for bit; its h error is within 2x the equiangular ne2 cube's (1.88x: the
    bilinear map's nodes are less even on so coarse a cube), and mass is kept to round-off."""
    on_file, result = run(tc2(mesh=cube_file))
    assert on_file.scene.ne == 0 and on_file.scene.nelem == 24 and on_file.grid.mesh.nelem == 24
    built_in, _ = run(tc2(ne=2, overrides={"grid.map": "element_local"}))
    _, cube = run(tc2(ne=2))
    assert np.array_equal(on_file.x.numpy(), built_in.x.numpy())
    e_file, e_cube = result.diagnostics[H_L2], cube.diagnostics[H_L2]
    assert e_cube < e_file < 2 * e_cube, (e_file, e_cube)
    roundoff.mass_kept(result.history, on_file.grid.nnodes)


@pytest.mark.roundoff
def test_tc2_on_a_stretched_cube(tmp_path):
    """TC2 on the ne4 cube stretched 2x toward (40°N, 90°E): h's l2 error after 2 hours is
    below the uniform ne4 cube's times the coarsest elements' factor (c = 2, error ∝ dx⁴
    at np4: 16); the mass is kept to round-off. c = 1 is the element-local cube."""
    stretched = {"grid.stretch_factor": 2.0, "grid.target_lat": 40.0, "grid.target_lon": 90.0}
    sim, result = run(tc2(ne=4, overrides=stretched))
    assert sim.scene.mesh.factor == 2.0 and sim.grid.map == "element_local"
    _, cube = run(tc2(ne=4))
    e, e_cube = result.diagnostics[H_L2], cube.diagnostics[H_L2]
    assert e_cube < e < 16 * e_cube, (e, e_cube)
    roundoff.mass_kept(result.history, sim.grid.nnodes)
    unstretched, _ = run(tc2(ne=4, overrides={"grid.stretch_factor": 1.0}))
    local, _ = run(tc2(ne=4, overrides={"grid.map": "element_local"}))
    assert np.array_equal(unstretched.x.numpy(), local.x.numpy())


def test_the_efold_rule_and_memory_estimate_on_a_mesh_file(cube_file):
    """ν from efold_hours on a mesh file is the uniform cube's of as many elements (√(F/6))."""
    on_file = load_scene("tc5_mountain", mesh=cube_file)
    assert on_file.nu == efold_nu(3.0, 2, 4, 6.37122e6) == load_scene("tc5_mountain", ne=2).nu
    # and the memory estimate counts the file's 24 elements as the ne2 cube's
    need = run_bytes(on_file.ne, on_file.np, on_file.stepper, nelem=on_file.nelem)
    assert on_file.ne == 0 and need == run_bytes(2, 4, on_file.stepper) > 0


def test_restart_on_a_mesh_file_is_bitwise_and_refuses_another_mesh(cube_file, tmp_path, capsys):
    """6 steps straight against 3 + a restart file + 3 more from it on the .g mesh: the same
    bits. The restart records the mesh (the file and its SHA-256); with the file replaced
    by another mesh, or with --mesh, the continuation is refused in one line."""
    scene = dataclasses.replace(tc2(mesh=cube_file), days=6 * DT / DAY)
    straight, _ = run(scene)
    first, _ = run(dataclasses.replace(scene, days=3 * DT / DAY))
    restart = first.write_checkpoint(tmp_path / "r.restart.nc")
    recorded = restart_file.read(restart)["scene"]["mesh"]
    assert recorded == {"map": "element_local", "file": str(cube_file), "sha256": file_sha256(cube_file), "nelem": 24}
    continued = Simulation.from_checkpoint(restart, "cpu", days=scene.days, progress=False)
    assert continued.scene.mesh == scene.mesh and continued.step == 3
    continued.run(None)
    assert np.array_equal(continued.x.numpy(), straight.x.numpy())

    other = write_exodus(tmp_path / "ico.g", icosahedral_mesh(0))
    code = main(["run", "--continue", str(restart), "--mesh", str(other), "--output", str(tmp_path / "c.nc")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "continues on its own mesh" in err[0], err
    write_exodus(cube_file, icosahedral_mesh(0))  # the file now holds another mesh
    with pytest.raises(SceneError, match="not the mesh this run was made on"):
        Simulation.from_checkpoint(restart, "cpu", progress=False)
    assert not (tmp_path / "c.nc").exists()


def test_a_restart_on_the_equiangular_map_refuses_the_other_map(cube_file, tmp_path, capsys):
    """A run of a scene on the .g cube through the equiangular map records the map in its
    restart; continuing it with the scene changed to the element-local map (and nothing else)
    is refused in one line."""
    scene = write_tc2_scene(tmp_path / "s.toml", ne=0, dt=DT, days=3 * DT / DAY)
    text = scene.read_text()
    scene.write_text(text.replace("ne = 0\n", 'ne = 0\nmesh_file = "cube2.g"\nmap = "equiangular"\n'))
    assert main(["run", str(scene), "--restart-every", str(3 * DT / DAY), "--output", str(tmp_path / "eq.nc")]) == 0
    restart = tmp_path / "eq.restart.nc"
    assert restart_file.read(restart)["scene"]["mesh"]["map"] == "equiangular"
    capsys.readouterr()
    scene.write_text(text.replace("ne = 0\n", 'ne = 0\nmesh_file = "cube2.g"\nmap = "element_local"\n'))
    code = main(["run", "--continue", str(restart), str(scene), "--days", "0.05", "--output", str(tmp_path / "c.nc")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and err[0].endswith("(differs in: mesh)"), err
    assert not (tmp_path / "c.nc").exists()


BAD_GRIDS = [
    ('map = "gnomonic"', "grid.map must be one of"),
    ("stretch_factor = 0.5", "grid.stretch_factor must be >= 1"),
    ("stretch_factor = 2.0\ntarget_lat = 95.0", "grid.target_lat must be in [-90, 90]"),
    ("target_lon = 10.0", "grid.target_lon needs grid.stretch_factor"),
    ('stretch_factor = 2.0\nmap = "equiangular"', 'grid.map = "equiangular" cannot stretch'),
    ('mesh_file = "absent.g"', "absent.g not found"),
    ('mesh_file = "cube2.g"\nstretch_factor = 2.0', "grid.stretch_factor stretches the cube"),
    ('mesh_file = "ico.g"\nmap = "equiangular"', "ico.g: element 2 does not lie in one face of a cube"),
    ('mesh_file = "garbage.g"', "garbage.g is not a netCDF file"),
    ('mesh_file = "cube2.g"\nne_ = 1', "unknown key grid.ne_"),
    ('mesh_file = "cube2.g"\nmap = 2', "grid.map must be str"),
]


@pytest.mark.parametrize("table, message", BAD_GRIDS, ids=[m.split()[0] for _, m in BAD_GRIDS])
def test_bad_grid_input_is_one_line_exit_2(tmp_path, capsys, cube_file, table, message):
    """Each bad [grid] key: one line naming it, exit 2, no output written."""
    (tmp_path / "garbage.g").write_text("not netCDF")
    write_exodus(tmp_path / "ico.g", icosahedral_mesh(0))
    scene = write_tc2_scene(tmp_path / "s.toml", ne=0)
    scene.write_text(scene.read_text().replace("ne = 0\n", table + "\n"))
    code = main(["run", str(scene), "--output", str(tmp_path / "o.nc")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and message in err[0], err
    assert not (tmp_path / "o.nc").exists()


@pytest.mark.parametrize(
    "args, message",
    [
        (("--ne", "2"), "ne = 2 and mesh"),
        (("--np", "2"), "np must be >= 3 on mesh cube2.g"),
    ],
)
def test_bad_mesh_options_are_one_line_exit_2(tmp_path, capsys, cube_file, args, message):
    """--mesh with --ne (a mesh file's elements are its own), or with np = 2 (the
    element-local map's area correction needs interior nodes): one line, exit 2."""
    code = main(["run", "tc2_steady", "--mesh", str(cube_file), *args, "--output", str(tmp_path / "o.nc")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and message in err[0], err
    assert not (tmp_path / "o.nc").exists()


def test_a_mesh_file_needs_ne_0(tmp_path, cube_file):
    scene = write_tc2_scene(tmp_path / "s.toml", ne=2)
    scene.write_text(scene.read_text().replace("ne = 2\n", 'ne = 2\nmesh_file = "cube2.g"\n'))
    with pytest.raises(SceneError, match="grid.ne must be 0 with grid.mesh_file"):
        load_scene(scene)


def test_run_file_on_a_mesh_file_holds_its_cells(tmp_path, capsys, cube_file):
    """`swe-sphere run --mesh`: the run file records the mesh in its scene and holds the nodes,
    the sub-cell mesh and the control volumes the fields live on, as on the cube."""
    out = tmp_path / "run.nc"
    code = main(["run", "tc2_steady", "--mesh", str(cube_file), "--dt", "600", "--days", "0.125", "--output", str(out)])
    assert code == 0
    with xr.open_dataset(out, decode_times=False) as ds:
        assert json.loads(ds.attrs["scene"])["mesh"]["file"] == str(cube_file)
        assert ds.sizes["ncol"] == 24 * 9 + 2 and "mesh_dual" in ds.variables and "cells" not in ds.attrs
        assert (ds.h.attrs["mesh"], ds.h.attrs["location"]) == ("mesh_dual", "face")
        assert ds.sizes["nv"] == 4 and ds.sizes["ndual_node"] == 24 * 9
    # the lat-lon remap locates the points through the element-local map: TC2's initial h to
    # the interpolation error of the ne2 np4 grid (9.8 m, 3.3e-3 of h's largest value; 3.2 m
    # through the equiangular ne2 cube's map; bound 5e-3)
    ds = remap_dataset(out, 10.0)
    lat, lon = np.meshgrid(np.radians(ds.lat.values), np.radians(ds.lon.values), indexing="ij")
    exact = make_case("tc2_steady").initial(lat, lon)[2]
    assert np.max(np.abs(ds.h.isel(time=0).values - exact)) < 5e-3 * exact.max()


def test_a_run_on_a_mesh_prints_homme_print_cfl_figures(tmp_path, capsys):
    """At start, on the ne2 cube stretched 3x toward the north pole: the Dinv-based spacing
    (dx_short min to dx_long max), the largest distortion (21.4: a warning line, above
    HOMME's 4), the area ratio and the worst element's Courant numbers, as
    ``quality.element_sizes`` gives them; a uniform cube prints none of it."""
    args = ["--ne", "2", "--dt", "300", "--days", "0.125", "--no-progress"]
    stretched = ["-s", "grid.stretch_factor=3.0", "--output", str(tmp_path / "s.nc")]
    assert main(["run", "tc2_steady", *args, *stretched]) == 0
    out, err = capsys.readouterr()
    s = element_sizes(CubedSphere(2, 4, mesh=schmidt_cube(2, 3.0))).summary()
    assert s["distortion_max"] == pytest.approx(21.41, abs=0.01)
    mesh_lines = [line for line in out.splitlines() if line.startswith("mesh ")]
    assert mesh_lines[0].endswith(
        f"{s['dx_short_min'] / 1e3:.1f} to {s['dx_long_max'] / 1e3:.1f} km (dx_short mean "
        f"{s['dx_short_mean'] / 1e3:.1f} km), largest distortion {s['distortion_max']:.2f}, area ratio {s['area_ratio']:.2f}"
    )
    assert f"worst element {s['worst'] + 1} " in mesh_lines[1] and "Courant gravity-wave" in mesh_lines[1]
    warnings = [line for line in err.splitlines() if "distorted" in line]
    assert len(warnings) == 1 and f"{s['distortion_max']:.2f}x" in warnings[0]
    assert main(["run", "tc2_steady", *args, "--output", str(tmp_path / "c.nc")]) == 0
    out, err = capsys.readouterr()
    assert "mesh " not in out and "distorted" not in err


def test_a_stretch_that_folds_an_element_is_one_line(tmp_path, capsys):
    """The ne2 cube stretched 5x: the element-local map folds the elements at the antipode
    (their corners span most of a hemisphere): one line naming the element, exit 2."""
    code = main(["run", "tc2_steady", "--ne", "2", "-s", "grid.stretch_factor=5.0", "--output", str(tmp_path / "o.nc")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "the map folds in element 21" in err[0], err
    assert not (tmp_path / "o.nc").exists()


def smooth(x, y, z):
    """A smooth field on the sphere that no element's polynomial holds exactly."""
    return np.exp(x) * (1 + y * z)


@pytest.mark.roundoff
def test_remap_of_a_smooth_field_on_a_stretched_cube():
    """Remapping through the element-local map on the ne4 cube stretched 2x toward (40°N, 90°E):
    at the GLL nodes themselves the nodes' values come back to round-off; on a 7.5° lat-lon
    grid the error of exp(x)(1 + yz) is the GLL interpolation's, and falls spectrally with np:
    6.95e-3 at np4, 2.07e-4 at np6 (the uniform ne4 cube's: 2.6e-4, 1.1e-6; the coarse
    elements at the antipode are 2x as wide)."""
    errors = {}
    for np_ in (4, 6):
        grid = CubedSphere(4, np_, mesh=schmidt_cube(4, 2.0, 40.0, 90.0))
        values = grid.to_unique(smooth(*grid.xyz))
        at_nodes = Remapper(grid, grid.lat[grid.first], grid.lon[grid.first])(values)
        roundoff.within(
            np.max(np.abs(at_nodes - values)), roundoff.bound(4 * np_ * np_, np.abs(values).max()), "at the nodes"
        )
        lat, lon = latlon_grid(7.5)
        lat, lon = np.meshgrid(np.radians(lat), np.radians(lon), indexing="ij")
        exact = smooth(np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat))
        errors[np_] = np.max(np.abs(Remapper(grid, lat, lon)(values) - exact))
    assert errors[4] < 1e-2 and errors[6] < errors[4] / 20, errors


def test_default_file_names_and_headers_say_the_mesh(cube_file):
    """A run's default file name (``Scene.grid_label``) and header (``grid_text``) tell the
    meshes apart; the uniform cube's are as before."""
    scenes = {
        "ne2": load_scene("tc2_steady", ne=2),
        "ne2map2": load_scene("tc2_steady", ne=2, overrides={"grid.map": "element_local"}),
        "ne2c1.5": load_scene("tc2_steady", ne=2, overrides={"grid.stretch_factor": 1.5}),
        "cube2": load_scene("tc2_steady", mesh=cube_file),
        "cube2map0": load_scene("tc2_steady", mesh=cube_file, overrides={"grid.map": "equiangular"}),
    }
    assert {label: s.grid_label for label, s in scenes.items()} == {label: label for label in scenes}
    assert [s.grid_text for s in scenes.values()] == [
        "ne=2 np=4",
        "ne=2 np=4 element-local",
        "ne=2 np=4 stretched 1.5x toward (90, 0)",
        "mesh cube2.g np=4",
        "mesh cube2.g np=4 equiangular",
    ]


MESHES_BESIDE_CUBES = {  # mesh: (its .g, the uniform cube of about as many elements, bound on the l2(h) ratio)
    "icosahedral": (None, 6, 3.5),  # 240 elements, nodes of 3 to 6, against ne6's 216: 2.81x measured
    "mountain_10_x2": (MOUNTAIN, 10, 2.5),  # ne10 refined 2x against its ne10 base: 1.90x (HOMME too is worse)
}


@pytest.mark.roundoff
@pytest.mark.parametrize("name", MESHES_BESIDE_CUBES)
def test_tc2_on_meshes_beyond_the_cube(tmp_path, name):
    """TC2 for 2 hours through ``--mesh``'s path on the project's icosahedral quadrilaterals
    (written to a .g) and on E3SM's mountain_10_x2.g (skipped where absent): mass to
    round-off, and h's l2 error within a bound of the uniform cube's of about as many
    elements (measured: 2.81x ne6's, 1.90x ne10's)."""
    path, ne, bound = MESHES_BESIDE_CUBES[name]
    if path is None:
        path = write_exodus(tmp_path / "ico.g", icosahedral_mesh(1))
    elif not path.is_file():
        pytest.skip(f"{path} is not beside the checkout")
    sim, result = run(tc2(mesh=path))
    _, cube = run(tc2(ne=ne))
    assert result.diagnostics[H_L2] < bound * cube.diagnostics[H_L2], (result.diagnostics[H_L2], cube.diagnostics[H_L2])
    roundoff.mass_kept(result.history, sim.grid.nnodes)


def test_dt_scales_with_the_smallest_dinv_spacing(cube_file):
    """tc2_steady's 300 s at ne16 np4, on the ne2 cube file: scaled by the ratio of the two
    grids' smallest dx_short (HOMME's Dinv-based length), then cut to divide the day."""
    ratio = smallest_dx(0, 4, read_exodus(cube_file)) / smallest_dx(16, 4)
    assert ratio == pytest.approx(6.24, abs=0.01)
    scene = load_scene("tc2_steady", mesh=cube_file)
    assert scene.dt == DAY / math.ceil(DAY / (300 * ratio)) == DAY / 47
