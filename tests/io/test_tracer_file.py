"""Tracers' initial fields from a netCDF file (issue 125): a scene's ``[tracers]`` ``file``,
whose variables the ``initial`` entries that are not bundled fields name, on a lat-lon grid
(interpolated) or on the model's nodes (a run file's q, taken as it is); bad input refused in
one line naming the file and the variable."""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr

from swe_sphere.cases.tracers import TRACER_FIELDS
from swe_sphere.config.scene import load_scene
from swe_sphere.core.errors import SceneError

from helpers import cli_one_line, make_sim
from roundoff import bound

SHORT = {"ne": 2, "np_": 4, "days": 0.125, "output": {"every_days": 0.125}}


def latlon_file(path, **fields):
    """A 1° regular grid (cell centres, -89.5..89.5, 0.5..359.5) holding each of ``fields``
    (name → function of (lat, lon) in rad), with a time dimension of two (the last is read:
    the first holds zeros)."""
    lat, lon = np.arange(-89.5, 90), np.arange(0.5, 360)
    la, lo = np.meshgrid(np.radians(lat), np.radians(lon), indexing="ij")
    data = {n: (("time", "lat", "lon"), np.stack([np.zeros(la.shape), f(la, lo)])) for n, f in fields.items()}
    xr.Dataset(data, coords={"time": [0.0, 1.0], "lat": lat, "lon": lon}).to_netcdf(path)
    return path


def tracers(path, *initial) -> dict:
    names = [f"t{k}" for k in range(len(initial))]
    return {"names": names, "initial": list(initial), "file": str(path)}


def test_a_lat_lon_files_field_is_interpolated_to_the_nodes(tmp_path):
    """A file's variable beside the bundled field it samples: at the nodes the two agree to the
    splines' error on a 1° grid (the hills' curvature: < 1e-5 of their 0.95 peak), and the run
    carries it as it carries the bundled one."""
    path = latlon_file(tmp_path / "q.nc", hills=TRACER_FIELDS["gaussian_hills"])
    scene = load_scene("galewsky", **SHORT, tracers=tracers(path, "gaussian_hills", "hills"))
    assert scene.tracer_file == str(path.absolute()) and scene.as_dict()["tracer_file"] == str(path.absolute())
    make_sim(scene).run(tmp_path / "run.nc")
    with xr.open_dataset(tmp_path / "run.nc", decode_times=False) as ds:
        start = np.abs(ds.t1.isel(time=0) - ds.t0.isel(time=0)).max()
        assert 0 < start < 1e-5
        assert np.abs(ds.t1.isel(time=-1) - ds.t0.isel(time=-1)).max() < 2e-5  # the flow moved both alike
        assert np.abs(ds.t0.isel(time=-1) - ds.t0.isel(time=0)).max() > 1e-3  # and it did move them
    assert (
        "tracer_file"
        not in load_scene("galewsky", **SHORT, tracers={"names": ["a"], "initial": ["constant"]}).as_dict()
    )


def test_a_run_files_tracer_starts_another_run_as_it_ended(tmp_path, monkeypatch):
    """A run file on the model's nodes, named relative to the working folder: the next run's q
    at its start is the last q of the first to the roundings of h q and q = h q / h (the nodes
    matched, no interpolation)."""
    first = load_scene("galewsky", **SHORT, tracers={"names": ["dye"], "initial": ["cosine_bells"]})
    make_sim(first).run(tmp_path / "first.nc")
    monkeypatch.chdir(tmp_path)
    second = load_scene("galewsky", **SHORT, tracers={"names": ["again"], "initial": ["dye"], "file": "first.nc"})
    assert second.tracer_file == str(tmp_path / "first.nc")
    make_sim(second).run(tmp_path / "second.nc")
    with xr.open_dataset(tmp_path / "first.nc") as a, xr.open_dataset(tmp_path / "second.nc") as b:
        q, again = a.dye.isel(time=-1).values, b.again.isel(time=0).values
        # the run carries h q with the new run's h, and writes (h q) / h: two roundings of q
        assert np.abs(again - q).max() <= bound(2, np.abs(q).max())


@pytest.mark.parametrize(
    "table, words",
    [
        ({"initial": ["ozone"]}, ["tracers.file", "no variable ozone", "the file's: hills"]),
        ({"initial": ["constant"]}, ["tracers.file", "no tracers.initial names a variable"]),
        ({"initial": ["hills"], "file": "nowhere.nc"}, ["tracers.file", "nowhere.nc", "not found"]),
        ({"initial": ["ozone"], "file": None}, ["tracers.initial", "unknown field 'ozone'", "tracers.file"]),
    ],
)
def test_bad_tracer_files_are_refused_in_one_line(tmp_path, capsys, table, words):
    """A missing variable (the file's own listed), a file nothing reads, a missing file, an
    unknown field without a file: ``SceneError`` at load, and from the command line one line,
    exit 2, no run file."""
    path = latlon_file(tmp_path / "q.nc", hills=TRACER_FIELDS["gaussian_hills"])
    t = {"names": ["a"], "file": str(path), **table}
    if t["file"] is None:
        del t["file"]
    with pytest.raises(SceneError) as err:
        load_scene("galewsky", **SHORT, tracers=t)
    for word in words:
        assert word in str(err.value)
    scene = tmp_path / "scene.toml"
    listed = lambda xs: "[" + ", ".join(f'"{x}"' for x in xs) + "]"  # noqa: E731
    extra = f'file = "{t["file"]}"\n' if "file" in t else ""
    scene.write_text(
        _galewsky_text() + f"\n[tracers]\nnames = {listed(t['names'])}\ninitial = {listed(t['initial'])}\n{extra}"
    )
    cli_one_line(capsys, ["run", scene, "--ne", "2", "--days", "0.125", "--output", tmp_path / "out.nc"], 2, *words)
    assert not (tmp_path / "out.nc").exists()


def _galewsky_text() -> str:
    from swe_sphere.config.scene import scene_dir

    return (scene_dir() / "galewsky.toml").read_text()


def test_a_node_file_of_another_grid_is_refused_in_one_line(tmp_path, capsys):
    """A run file of ne2 read by an ne3 run: its nodes are not the run's, said in one line
    (when the run builds its start), exit 2, no run file."""
    make_sim(load_scene("galewsky", **SHORT, tracers={"names": ["dye"], "initial": ["cosine_bells"]})).run(
        tmp_path / "ne2.nc"
    )
    table = {"names": ["again"], "initial": ["dye"], "file": str(tmp_path / "ne2.nc")}
    with pytest.raises(SceneError, match="not those of this run's grid"):
        make_sim(load_scene("galewsky", **{**SHORT, "ne": 3}, tracers=table))
    scene = tmp_path / "scene.toml"
    scene.write_text(
        _galewsky_text() + f'\n[tracers]\nnames = ["again"]\ninitial = ["dye"]\nfile = "{tmp_path / "ne2.nc"}"\n'
    )
    cli_one_line(
        capsys,
        ["run", scene, "--ne", "3", "--np", "4", "--days", "0.125", "--output", tmp_path / "out.nc"],
        2,
        "tracers.file",
        "not those of this run's grid",
    )
    assert not (tmp_path / "out.nc").exists()
