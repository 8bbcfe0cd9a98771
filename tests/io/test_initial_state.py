"""An initial state of one's own: ``[case] name = "file"`` with a
netCDF file on the model's nodes or on a lat-lon grid, and ``initial=`` a function.

Written from TC2's initial state, each reproduces it: a node file bit for bit (the
values are taken as they are), a lat-lon file to the bicubic spline's accuracy,
a function bit for bit. Bad files are refused in one line (exit 2 from the CLI,
``SceneError`` from the API)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import xarray as xr

import swe_sphere
from swe_sphere.cases.library import make_case
from swe_sphere.config.scene import list_scenes, load_scene
from swe_sphere.core.errors import SceneError
from swe_sphere.io.initial_state import SCENE_CASES
from swe_sphere.simulation.simulation import Simulation

from helpers import TINY, cached_grid, cli_main, cli_one_line

ALPHA = math.pi / 4  # the flow crosses the poles: the winds' interpolation there is tested
TC2 = make_case("tc2_steady", {"alpha": ALPHA})
SCENE = """terms = ["continuity", "momentum_advection", "coriolis", "pressure_gradient"]
[case]
name = "file"
path = "{path}"
[grid]
ne = {ne}
np = 4
[time]
stepper = "ssprk3"
dt = 1800.0
days = 0.125
[output]
every_days = 0.125
"""


def scene_file(tmp_path, path, ne=2):
    f = tmp_path / "mine.toml"
    f.write_text(SCENE.format(path=path, ne=ne))
    return f


def tc2_sim(ne=2):
    return Simulation(load_scene("tc2_steady_alpha_pi4", ne=ne, dt=1800.0, days=0.125), "cpu", progress=False)


def latlon_file(path, lat, lon, **change):
    """TC2 (α = π/4) on the lat-lon grid lat, lon (degrees), fields changed by ``change``."""
    la, lo = np.meshgrid(np.radians(lat), np.radians(lon), indexing="ij")
    u, v, h = TC2.initial(la, lo)
    ds = xr.Dataset(
        {
            "h": (("lat", "lon"), h, {"units": "m"}),
            "u": (("lat", "lon"), u, {"units": "m s-1"}),
            "v": (("lat", "lon"), v, {"units": "m/s"}),
        },
        coords={"lat": ("lat", lat, {"units": "degrees_north"}), "lon": ("lon", lon, {"units": "degrees_east"})},
    )
    for name, value in change.items():
        if value is None:
            ds = ds.drop_vars(name)
        else:
            ds[name] = value(ds[name]) if callable(value) else value
    ds.to_netcdf(path)
    return path


def test_node_file_is_tc2_bitwise(tmp_path, capsys):
    """TC2's state written by ``Simulation.state`` (a run file's layout) starts a file
    run with TC2's element-local state bit for bit; through the CLI, the run file's
    first output is TC2's run file's."""
    tc2 = tc2_sim()
    tc2.state().to_netcdf(tmp_path / "tc2_state.nc")
    mine = Simulation(load_scene(scene_file(tmp_path, tmp_path / "tc2_state.nc")), "cpu", progress=False)
    assert np.array_equal(mine.x.numpy(), tc2.x.numpy())
    assert np.array_equal(mine.hs, tc2.hs)

    # a run file of the CLI (two output times; case.time picks the first) through the CLI
    args = ("--device", "cpu", "--no-progress")
    assert (
        cli_main(
            capsys,
            "run",
            "tc2_steady_alpha_pi4",
            "--ne",
            2,
            "--dt",
            1800,
            "--days",
            0.125,
            "--output",
            tmp_path / "tc2.nc",
            *args,
        )[0]
        == 0
    )
    scene = scene_file(tmp_path, tmp_path / "tc2.nc")
    scene.write_text(scene.read_text().replace("[grid]", "time = 0.0\n[grid]"))
    assert cli_main(capsys, "run", scene, "--output", tmp_path / "mine.nc", *args)[0] == 0
    cli_one_line(
        capsys,
        ["run", scene, "-s", "case.time=0.1", *args],
        2,
        "case.time = 0.1 is not one of the file's times (0, 0.125)",
    )
    with (
        xr.open_dataset(tmp_path / "tc2.nc", decode_times=False) as a,
        xr.open_dataset(tmp_path / "mine.nc", decode_times=False) as b,
    ):
        for name in ("h", "u", "v"):
            assert np.array_equal(a[name].isel(time=0).values, b[name].isel(time=0).values), name
        assert b.attrs["case"] == "file"


def test_restart_file_starts_a_run(tmp_path):
    """A restart file of the same grid is a node state: its state, bit for bit."""
    sim = tc2_sim()
    sim.advance(days=1800.0 / 86400.0)
    sim.write_checkpoint(tmp_path / "r.restart.nc")
    scene = scene_file(tmp_path, tmp_path / "r.restart.nc")
    mine = Simulation(load_scene(scene), "cpu", progress=False)
    assert np.array_equal(mine.x.numpy(), sim.x.numpy())
    with pytest.raises(SceneError, match="a restart file holds one state"):
        load_scene(scene, overrides={"case.time": 0.0})


@pytest.mark.parametrize(
    "lat, lon",
    [
        (np.linspace(-90.0, 90.0, 181), np.arange(360.0)),  # 1 degree, both poles
        (
            np.linspace(89.5, -89.5, 180),
            np.arange(360.0) - 180.0,
        ),  # no poles (as a Gaussian grid), north first, from -180
    ],
)
def test_latlon_file_interpolates_tc2(tmp_path, lat, lon):
    """A 1-degree lat-lon file of TC2 (α = π/4, the jet over the poles) gives TC2's
    state at the ne = 4 nodes within 1e-8 of each field's largest value (measured:
    1.5e-9 for h, 4e-10 for the winds; the bicubic spline's error ~ Δ⁴), continuous:
    every copy of a node holds the same value."""
    mine = Simulation(
        load_scene(scene_file(tmp_path, latlon_file(tmp_path / "ll.nc", lat, lon), ne=4)), "cpu", progress=False
    )
    x, truth = mine.x.numpy(), tc2_sim(ne=4).x.numpy()
    for row, name in enumerate("uvh"):
        err = np.max(np.abs(x[row] - truth[row])) / np.max(np.abs(truth[row]))
        assert err < 1e-8, (name, err)
    grid = cached_grid(4, 4)
    copies = grid.dss_table  # each node's copies (global indices, -1 padded)
    for row in x:
        values = np.where(copies >= 0, row[np.maximum(copies, 0)], row[copies[:, :1]])
        assert np.all(values == values[:, :1])


def test_function_is_tc2_bitwise():
    """``initial=fn(lat, lon) -> (h, u, v)`` with TC2's formula starts from TC2's state, bit for bit."""

    def tc2(lat, lon):
        u, v, h = TC2.initial(lat, lon)
        return h, u, v

    mine = Simulation(
        load_scene("tc2_steady_alpha_pi4", ne=2, dt=1800.0, days=0.125), "cpu", progress=False, initial=tc2
    )
    assert np.array_equal(mine.x.numpy(), tc2_sim().x.numpy())
    ds = swe_sphere.run("tc2_steady_alpha_pi4", device="cpu", ne=2, dt=1800.0, days=0.125, initial=tc2)
    assert ds.l2_h.values[0] == 0.0  # against TC2's exact solution: the start is it


@pytest.mark.parametrize(
    "fn, words",
    [
        (lambda lat, lon: (lat, lat, lat), ["h <= 0"]),
        (lambda lat, lon: (np.full(3, 1e3), lat, lat), ["h has shape (3,)"]),
        (lambda lat, lon: (1e3 + 0 * lat, lat * np.nan, lat), ["u has", "non-finite"]),
        (lambda lat, lon: (1e3, 0.0), ["must return (h, u, v)"]),
    ],
)
def test_bad_function_refused(fn, words):
    with pytest.raises(SceneError) as err:
        Simulation(load_scene("tc2_steady", ne=2), "cpu", progress=False, initial=fn)
    for word in words:
        assert word in str(err.value)


LL = (np.linspace(-90.0, 90.0, 19), np.arange(36) * 10.0)


def fitting_terms(scene, case: str) -> dict:
    """The ``terms`` override that ``case`` needs on ``scene`` (its terms but a forcing,
    with the case's required terms added), or {} when the scene's terms fit."""
    need = SCENE_CASES[case][0].required_terms
    terms = [t for t in scene.terms if t != "forcing"] + sorted(need - set(scene.terms))
    return {} if terms == list(scene.terms) else {"terms": terms}


@pytest.mark.parametrize("name", [p.stem for p in list_scenes()])
def test_case_switch_on_every_bundled_scene(tmp_path, capsys, name):
    """``-s case.name=X`` on each bundled scene drops the scene file's parameters of its
    own case (e.g. tc2_steady's alpha, which ``file`` does not know): to ``file`` the
    case holds just the path given, to ``galewsky`` just ``-s case.perturbed``; a
    ``-s case.alpha`` that galewsky does not know is refused in one line, exit 2.
    (Terms the new case needs, or its lack of a forcing, are still the scene's to
    fit: ``fitting_terms``.)"""
    base = load_scene(name)
    path = latlon_file(tmp_path / "ll.nc", *LL)
    over = {"case.name": "file", "case.path": str(path), **fitting_terms(base, "file")}
    scene = load_scene(name, ne=2, overrides=over)
    assert (scene.case, scene.case_params) == ("file", {"path": str(path)})
    assert (scene.ne, scene.np, scene.stepper) == (2, base.np, base.stepper)  # the rest is the scene's
    over = {"case.name": "galewsky", "case.perturbed": False, **fitting_terms(base, "galewsky")}
    assert load_scene(name, ne=2, overrides=over).case_params == {"perturbed": False}
    cli_one_line(
        capsys,
        [
            "run",
            name,
            "-s",
            "case.name=galewsky",
            "-s",
            "case.alpha=0.3",
            "--device",
            "cpu",
            "--output",
            tmp_path / "out.nc",
        ],
        2,
        "unknown parameter case.alpha for galewsky",
    )
    assert not (tmp_path / "out.nc").exists()


def test_tc2_switched_to_a_file_runs(tmp_path, capsys):
    """A user's command (tc2_steady switched to a file of TC2's state, α = π/4,
    which the scene's alpha = 0 would have been refused by) runs, from that state."""
    tc2 = tc2_sim()
    tc2.state().to_netcdf(tmp_path / "run.nc")
    code, _, err = cli_main(
        capsys,
        "run",
        "tc2_steady",
        "-s",
        "case.name=file",
        "-s",
        f"case.path={tmp_path / 'run.nc'}",
        "--ne",
        2,
        "--dt",
        1800,
        "--days",
        0.125,
        "--device",
        "cpu",
        "--no-progress",
        "--output",
        tmp_path / "out.nc",
    )
    assert code == 0, err
    with xr.open_dataset(tmp_path / "out.nc", decode_times=False) as ds:
        assert ds.attrs["case"] == "file"
        assert np.array_equal(ds.h.isel(time=0).values, tc2.state().h.values)


BAD = {
    "missing": (dict(v=None), ["no variable v"]),
    "nan": (dict(h=lambda h: h.where(h.lat < 60)), ["h has", "non-finite"]),
    "shape": (dict(u=(("lon", "lat"), np.zeros((36, 19)))), ["u has dimensions ('lon', 'lat')"]),
    "depth": (dict(h=lambda h: h - 2500.0), ["h <= 0"]),
    "units": (dict(u=lambda u: u.assign_attrs(units="km/h")), ["u has units 'km/h'"]),
    "depth units": (dict(h=lambda h: h.assign_attrs(units="km")), ["h has units 'km'"]),
}


@pytest.mark.parametrize("kind", BAD)
def test_bad_file_refused(tmp_path, capsys, kind):
    """Each defect: one line naming the file's variable, exit 2 from the CLI and no
    output; ``SceneError`` from ``swe_sphere.run``."""
    change, words = BAD[kind]
    scene = scene_file(tmp_path, latlon_file(tmp_path / "bad.nc", *LL, **change))
    cli_one_line(
        capsys,
        ["run", scene, "--device", "cpu", "--no-progress", "--output", tmp_path / "out.nc"],
        2,
        "case.path",
        *words,
    )
    assert not (tmp_path / "out.nc").exists()
    with pytest.raises(SceneError) as err:
        swe_sphere.run(scene, device="cpu")
    for word in words:
        assert word in str(err.value)


def test_node_file_of_another_grid_refused(tmp_path):
    tc2_sim(ne=2).state().to_netcdf(tmp_path / "ne2.nc")
    with pytest.raises(SceneError, match="not those of this run's grid"):
        Simulation(load_scene(scene_file(tmp_path, tmp_path / "ne2.nc", ne=3)), "cpu", progress=False)


def test_the_initial_state_file_is_never_replaced(tmp_path, capsys, monkeypatch):
    """``--output`` naming the file ``case.path`` reads: refused even with --overwrite."""
    monkeypatch.chdir(tmp_path)
    state = latlon_file(tmp_path / "state.nc", *LL)
    before = state.read_bytes()
    cli_one_line(
        capsys,
        ["run", scene_file(tmp_path, state), "--device", "cpu", "--no-progress", "--output", "state.nc", "--overwrite"],
        2,
        "would replace the input",
        "state.nc",
    )
    assert state.read_bytes() == before


@pytest.mark.parametrize(
    "lat, lon, words",
    [
        (np.arange(-30.0, 30.0), np.arange(360.0), ["lat covers -30 to 29 degrees, not the globe"]),
        (np.radians(np.linspace(-90.0, 90.0, 19)), np.radians(np.arange(36) * 10.0), ["not the globe", "radians?"]),
    ],
)
def test_an_initial_state_not_covering_the_globe_is_refused(tmp_path, capsys, lat, lon, words, monkeypatch):
    """A regional lat-lon file was extrapolated to the poles; one in radians was read as
    a tiny regional one. Both: one line, exit 2, no output."""
    monkeypatch.chdir(tmp_path)
    scene = scene_file(tmp_path, latlon_file(tmp_path / "part.nc", lat, lon))
    cli_one_line(
        capsys, ["run", scene, "--device", "cpu", "--no-progress", "--output", "out.nc"], 2, "case.path", *words
    )
    assert not (tmp_path / "out.nc").exists()


def test_a_switched_case_is_named_in_header_title_and_file_name(tmp_path, capsys, monkeypatch):
    """``-s case.name=file`` on tc2_steady: the header, the run file's title and its
    default name say the case that ran, not the scene file's own."""
    monkeypatch.chdir(tmp_path)
    state = latlon_file(tmp_path / "state.nc", *LL)
    code, out, err = cli_main(
        capsys,
        "run",
        "tc2_steady",
        *TINY,
        "--dt",
        "1800",
        "--days",
        "0.125",
        "-s",
        "case.name=file",
        "-s",
        f"case.path={state}",
        "-s",
        "output.every_days=0.125",
    )
    assert code == 0, err
    assert "scene       file_in_tc2_steady: case file with scene tc2_steady's grid, terms and stepping" in out
    with xr.open_dataset(tmp_path / "file_in_tc2_steady_ne2np4_ssprk3_0.125d_dt1800.nc") as ds:
        assert ds.attrs["title"] == "swe_sphere run of scene file_in_tc2_steady" and ds.attrs["case"] == "file"
