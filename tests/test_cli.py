"""The command line: ``swe-sphere run`` / ``swe-sphere list``, the netCDF file a
run writes, bad input (exit 2) and blow-ups (exit 3).

Runs are in-process (``swe_sphere.cli.main``) on tiny grids (ne = 2, np = 4:
218 unique nodes) on the CPU; one test calls the installed console script in a
subprocess to prove the entry point and the exit status.
"""

from __future__ import annotations

import json
import math
import os
import re
import shutil
import subprocess
from pathlib import Path

import netCDF4
import numpy as np
import pytest
import warp as wp
import xarray as xr

from swe_sphere import __version__
from swe_sphere.cli import main
from swe_sphere.config.scene import efold_nu
from swe_sphere.io.run_file import RunWriter

import roundoff
from helpers import TINY, cached_grid, cli_main, console_script, one_line

REPO = Path(__file__).resolve().parents[1]
TESTCASES = REPO / "testcases"
EARTH_RADIUS = 6.37122e6
STEPPER_NAMES = ("leapfrog", "leapfrog_trapezoidal", "ssprk3", "rk4", "kgu35", "fbrk32", "split_explicit", "mri")
TERM_NAMES = ("continuity", "momentum_advection", "coriolis", "pressure_gradient", "topography", "hyperviscosity")
# tc2_steady at ne=2 with dt = 2 h (gravity-wave Courant number ~1.25) goes
# negative in depth after ~1.4 days: well after the first daily output.
BLOWUP = ("tc2_steady", *TINY, "--dt", "7200", "--days", "5")
BLOWUP_RE = re.compile(
    r"step (?P<step>\d+) \(model time (?P<days>[-+0-9.eE]+) days\).*"
    r"lat (?P<lat>[-+0-9.]+), lon (?P<lon>[-+0-9.]+)"
)


def cuda_available() -> bool:
    return wp.is_cuda_available()


@pytest.fixture(autouse=True)
def _in_tmp(tmp_path, monkeypatch):
    """Every test runs in its own folder, so a default output name lands there."""
    monkeypatch.chdir(tmp_path)


def run_cli(capsys, *args):
    """``main(["run", *args])`` → (exit status, stdout, stderr)."""
    return cli_main(capsys, "run", *args)


def stderr_lines(err: str) -> list[str]:
    return [line for line in err.splitlines() if line.strip()]


def nc_files(folder: Path) -> list[Path]:
    return sorted(p for p in folder.rglob("*") if p.name.endswith((".nc", ".nc.part")))


def edited_scene(tmp_path: Path, edit, source: str = "tc2_steady.toml", name: str = "edited.toml") -> Path:
    """A copy of a bundled scene, rewritten by ``edit(text) -> text``."""
    text = (TESTCASES / source).read_text()
    new = edit(text)
    assert new != text, "the edit did not change the scene"
    path = tmp_path / name
    path.write_text(new)
    return path


# ---------------------------------------------------------------------------
# A successful run and the file it writes
# ---------------------------------------------------------------------------


@pytest.fixture(scope="module")
def tc2_run(tmp_path_factory):
    """tc2_steady, ne=2 np=4, 1 day (dt scaled to 2400 s: 36 ssprk3 steps)."""
    folder = tmp_path_factory.mktemp("tc2")
    out = folder / "tc2.nc"
    code = main(["run", "tc2_steady", *TINY, "--days", "1", "--output", str(out)])
    return code, out


@pytest.mark.parametrize("days, quoted", [(1.25, "(day 1, its last output time T213 stores)"), (0.25, None)])
def test_summary_quotes_the_last_output_time_the_reference_stores(tmp_path, capsys, days, quoted):
    """T213 stores days 0, 1, 2, 5, 10 and 15: a 1.25-day run quotes its day-1 errors (labelled),
    a 0.25-day run says there is none (not "nan"); t = 0 is never quoted."""
    assert (
        main(["run", "tc5_mountain", *TINY, "--dt", "1800", "--days", str(days), "--output", str(tmp_path / "r.nc")])
        == 0
    )
    lines = [line for line in capsys.readouterr().out.splitlines() if "vs T213" in line]
    assert not any("nan" in line for line in lines)
    if quoted is None:
        assert lines == ["  vs T213     none: no output time after t = 0 is one T213 stores (days 0, 1, 2, 5, 10, 15)"]
    else:
        assert len(lines) == 3 and lines[0].endswith(quoted)
        with xr.open_dataset(
            tmp_path / "r.nc", decode_times=False
        ) as ds:  # the quoted l2 is the run file's day-1 value
            assert f"l2 {float(ds.ref_l2_h_surface.sel(time=1.0)):.3e}" in lines[0]


@pytest.mark.parametrize("which", ["tc2", "tc5"])
def test_run_writes_a_complete_netcdf_file(which, tc2_run, tc5_run_file):
    code, out = tc2_run if which == "tc2" else (0, tc5_run_file)
    ne, np_, days = 2, 4, 1
    assert code == 0
    assert out.is_file()
    assert not out.with_name(out.name + ".part").exists()
    with xr.open_dataset(out, decode_times=False) as ds:
        ncol = 6 * ne**2 * (np_ - 1) ** 2 + 2
        assert ds.sizes["ncol"] == ncol == 218
        assert ds.sizes["time"] == days + 1
        for name in ("h", "u", "v"):
            assert ds[name].dims == ("time", "ncol"), name
            assert np.isfinite(ds[name].values).all(), name
        assert ds["hs"].dims in (("ncol",), ("time", "ncol"))
        for name in ("lat", "lon", "area"):
            assert ds[name].dims == ("ncol",), name
        assert (ds.h.values > 0).all()

        # units on every variable but the UGRID meshes' and the cell bounds (time's are in its CF encoding)
        meshes = {v for v in ds.variables if "cf_role" in ds[v].attrs} | {"lat_bnds", "lon_bnds"}
        for name in [v for v in ds.data_vars if v not in meshes] + ["lat", "lon"]:
            assert ds[name].attrs.get("units"), f"{name} has no units"
        assert ds.h.attrs["units"] == "m" and ds.hs.attrs["units"] == "m"
        assert ds.u.attrs["units"] == ds.v.attrs["units"] == "m s-1"
        assert ds.lat.attrs["units"] == "degrees_north"
        assert ds.lon.attrs["units"] == "degrees_east"
        assert ds.area.attrs["units"] == "m2"

        lat, lon, area = ds.lat.values, ds.lon.values, ds.area.values
        assert lat.min() >= -90 and lat.max() <= 90
        assert lat.min() < -80 and lat.max() > 80  # nodes cover the sphere, in degrees
        assert lon.min() >= 0 and lon.max() < 360
        assert lon.max() > 300  # degrees, not radians
        assert (area > 0).all()
        assert abs(area.sum() / (4 * math.pi * EARTH_RADIUS**2) - 1) < 1e-12

        # diagnostics time series
        for name in (
            "mass",
            "total_energy",
            "potential_enstrophy",
            "mass_change",
            "total_energy_change",
            "potential_enstrophy_change",
            "rhs_evals",
            "wall_time",
            "steps",
        ):
            assert ds[name].dims == ("time",), name
            assert np.isfinite(ds[name].values).all(), name
        assert ds.mass_change.values[0] == 0
        roundoff.mass_kept(
            roundoff.run_file_history(ds), cached_grid(2, 4).nnodes, lambda d: 2 * roundoff.operations(d)
        )  # and leapfrog's time filter
        assert (np.diff(ds.rhs_evals.values) > 0).all()
        assert (np.diff(ds.wall_time.values) >= 0).all() and ds.wall_time.values[0] == 0
        assert ds.rhs_evals.values[0] == 0 and ds.steps.values[0] == 0

        # global attributes: the resolved scene (JSON) and the version
        assert ds.attrs["swe_sphere_version"] == __version__
        scene = json.loads(ds.attrs["scene"])
        assert scene["name"] == ("tc2_steady" if which == "tc2" else "tc5_mountain")
        assert (scene["ne"], scene["np"], scene["days"]) == (ne, np_, days)
        assert scene["output_every_days"] == 1.0
        assert round(days * 86400 / scene["dt"]) * scene["dt"] == pytest.approx(days * 86400)
        assert ds.steps.values[-1] == round(days * 86400 / scene["dt"])
        assert "blowup" not in ds.attrs

        if which == "tc2":
            assert scene["stepper"] == "ssprk3" and scene["dt"] == 2400.0  # 300 s scaled from ne=16 to ne=2
            assert ds.rhs_evals.values[-1] == 3 * ds.steps.values[-1]  # ssprk3: 3 stages
            assert (ds.hs.values == 0).all()
            for name in ("l1_h", "l2_h", "linf_h", "l1_wind", "l2_wind", "linf_wind"):
                assert ds[name].dims == ("time",)
                assert ds[name].values[0] < 1e-13, name  # the initial state is the exact solution
            # measured at ne=2 np=4 ssprk3 dt=2400 s, day 1: l2_h 1.40e-3, linf_h 5.1e-3, l2_wind 1.33e-2
            assert 0 < ds.l2_h.values[-1] < 3e-3
            assert ds.linf_h.values[-1] < 1e-2
            assert ds.l2_wind.values[-1] < 3e-2
        else:
            assert scene["stepper"] == "rk4"  # the efficiency study's choice (docs/efficiency.md)
            assert "topography" in scene["terms"] and "hyperviscosity" in scene["terms"]
            assert scene["nu"] == pytest.approx(
                efold_nu(3.0, 2, 4, 6.37122e6), rel=1e-12
            )  # the scene's 3 h rule on this grid
            assert ds.hs.values.max() > 1000  # the mountain (2000 m at its centre)
            assert "l2_h" not in ds  # no exact solution for TC5


def test_time_is_cf_time_in_model_days(tc2_run):
    """time is CF time (days since an epoch, explicit calendar, no _FillValue), so CDO and
    the CF checker read dates; undecoded it is model days (``.sel(time=1)``, what
    ``swe_sphere.run`` returns), decoded it is datetimes — never the timedelta64 that
    xarray ≤ 2025.1 made of units "days" (its ``decode_timedelta=True`` asked for here)."""
    _, out = tc2_run
    with netCDF4.Dataset(out) as nc:
        t = nc["time"]
        assert t.units == "days since 2000-01-01 00:00:00" and t.calendar == "proleptic_gregorian"
        assert t.standard_name == "time" and t.axis == "T"
        assert "_FillValue" not in t.ncattrs()
        assert nc.Conventions == "CF-1.8 UGRID-1.0"
        assert "standard_name" not in nc["h"].ncattrs() and nc["h"].long_name == "fluid depth"  # CF has no name for it
        assert nc["vorticity"].standard_name == "atmosphere_upward_relative_vorticity"
    with xr.open_dataset(out, decode_timedelta=True) as ds:
        assert ds.time.dtype.kind == "M"
        assert list(ds.time.values) == [np.datetime64("2000-01-01"), np.datetime64("2000-01-02")]
        assert ds.h.sel(time="2000-01-02").shape == (ds.sizes["ncol"],)
    with xr.open_dataset(out, decode_times=False) as ds:
        assert ds.time.dtype == np.float64
        np.testing.assert_array_equal(ds.time.values, [0.0, 1.0])
        assert ds.h.sel(time=1).shape == (ds.sizes["ncol"],)
        assert ds.mass_change.sel(time=1) == ds.mass_change.values[-1]
        assert "swe-sphere run tc2_steady" in ds.attrs["history"]


def test_output_file_never_exists_while_writing(monkeypatch, capsys, tmp_path):
    """The target appears only when complete: while the run writes, only a .part file exists."""
    out = tmp_path / "run.nc"
    seen = []
    original = RunWriter.append

    def checking_append(self, *args, **kwargs):
        seen.append((out.exists(), any(p.suffix == ".part" for p in tmp_path.iterdir())))
        return original(self, *args, **kwargs)

    monkeypatch.setattr(RunWriter, "append", checking_append)
    code, _, _ = run_cli(capsys, "tc2_steady", *TINY, "--days", "2", "--output", out)
    assert code == 0
    assert seen == [(False, True)] * 3
    assert out.is_file() and nc_files(tmp_path) == [out]


def test_an_internal_failure_is_one_line_and_leaves_no_file(monkeypatch, capsys, tmp_path):
    """An unexpected exception mid-run: exit 1, one line naming it, no file; --debug re-raises it."""
    out = tmp_path / "run.nc"
    calls = []
    original = RunWriter.append

    class Broken(Exception):
        pass

    def failing_append(self, *args, **kwargs):
        calls.append(1)
        if len(calls) % 2 == 0:
            raise Broken("disk on fire")
        return original(self, *args, **kwargs)

    monkeypatch.setattr(RunWriter, "append", failing_append)
    code = main(["run", "tc2_steady", *TINY, "--days", "2", "--output", str(out)])
    err = capsys.readouterr().err
    assert code == 1 and stderr_lines(err) == [
        "swe-sphere: error: internal error: Broken: disk on fire (run with --debug for the traceback)"
    ]
    assert nc_files(tmp_path) == []
    with pytest.raises(Broken):
        main(["run", "tc2_steady", *TINY, "--days", "2", "--output", str(out), "--debug"])
    with pytest.raises(Broken):
        main(["--debug", "run", "tc2_steady", *TINY, "--days", "2", "--output", str(out)])
    assert nc_files(tmp_path) == []


@pytest.mark.parametrize("stepper", STEPPER_NAMES)
def test_every_stepper_runs_tc2(stepper, capsys, tmp_path):
    out = tmp_path / f"{stepper}.nc"
    code, stdout, err = run_cli(capsys, "tc2_steady", *TINY, "--days", "1", "--stepper", stepper, "--output", out)
    assert code == 0, err
    assert stepper in stdout
    with xr.open_dataset(out, decode_times=False) as ds:
        assert ds.attrs["stepper"] == stepper
        assert json.loads(ds.attrs["scene"])["stepper"] == stepper
        assert ds.l2_h.values[-1] < 3e-3  # measured 1.36e-3 .. 1.51e-3 for the four steppers
        roundoff.mass_kept(
            roundoff.run_file_history(ds), cached_grid(2, 4).nnodes, lambda d: 2 * roundoff.operations(d)
        )  # and leapfrog's time filter


@pytest.mark.parametrize("ne,np_", [(1, 3), (3, 2), (1, 8)])
def test_ncol_and_area_on_other_grids(ne, np_, capsys, tmp_path):
    out = tmp_path / "g.nc"
    code, _, err = run_cli(
        capsys,
        "tc2_steady",
        "--ne",
        ne,
        "--np",
        np_,
        "--days",
        "1",
        "--device",
        "cpu",
        "--no-progress",
        "--output",
        out,
    )
    assert code == 0, err
    with xr.open_dataset(out, decode_times=False) as ds:
        assert ds.sizes["ncol"] == 6 * ne**2 * (np_ - 1) ** 2 + 2
        assert abs(ds.area.values.sum() / (4 * math.pi * EARTH_RADIUS**2) - 1) < 1e-12
        scene = json.loads(ds.attrs["scene"])
        assert (scene["ne"], scene["np"]) == (ne, np_)


def test_overrides_reach_the_scene_and_output_is_daily(capsys, tmp_path):
    out = tmp_path / "o.nc"
    code, _, err = run_cli(
        capsys, "tc2_steady", *TINY, "--dt", "3600", "--days", "3", "--stepper", "rk4", "--output", out
    )
    assert code == 0, err
    with xr.open_dataset(out, decode_times=False) as ds:
        np.testing.assert_allclose(ds.time.values, [0, 1, 2, 3])
        np.testing.assert_array_equal(ds.steps.values, [0, 24, 48, 72])
        np.testing.assert_array_equal(ds.rhs_evals.values, [0, 96, 192, 288])
        scene = json.loads(ds.attrs["scene"])
        assert (scene["dt"], scene["days"], scene["stepper"]) == (3600.0, 3.0, "rk4")


def test_fractional_days_end_with_the_final_state(capsys, tmp_path):
    out = tmp_path / "f.nc"
    code, _, err = run_cli(capsys, "tc2_steady", *TINY, "--days", "1.5", "--output", out)
    assert code == 0, err
    with xr.open_dataset(out, decode_times=False) as ds:
        np.testing.assert_allclose(ds.time.values, [0, 1, 1.5])


def test_default_output_name_in_the_working_folder(capsys, tmp_path):
    code, stdout, err = run_cli(capsys, "tc2_steady", *TINY, "--days", "1")
    assert code == 0, err
    assert nc_files(tmp_path) == [tmp_path / "tc2_steady_ne2np4_ssprk3_1d.nc"]  # not the scene's 5 days


def test_scene_given_as_a_path_outside_testcases(capsys, tmp_path):
    scene = tmp_path / "my_scene.toml"
    shutil.copy(TESTCASES / "tc2_steady.toml", scene)
    out = tmp_path / "s.nc"
    code, _, err = run_cli(capsys, scene, *TINY, "--days", "1", "--output", out)
    assert code == 0, err
    with xr.open_dataset(out, decode_times=False) as ds:
        assert json.loads(ds.attrs["scene"])["name"] == "my_scene"


def test_summary_goes_to_stdout_and_no_bar_off_a_terminal(capsys, tmp_path):
    """The summary is stdout's; stderr, captured (not a terminal), gets no progress bar
    (the bar on a terminal: test_sweep.test_the_progress_bar_is_drawn_on_a_terminal_only)."""
    out = tmp_path / "p.nc"
    code = main(["run", "tc2_steady", "--ne", "2", "--np", "4", "--device", "cpu", "--days", "1", "--output", str(out)])
    captured = capsys.readouterr()
    assert code == 0
    assert out.is_file()
    assert "summary" in captured.out
    assert "\r" not in captured.err and "step" not in captured.err


# ---------------------------------------------------------------------------
# swe-sphere list
# ---------------------------------------------------------------------------


def test_list_names_every_scene_stepper_and_term(capsys):
    assert main(["list"]) == 0
    out, err = capsys.readouterr()
    assert err == ""
    words = set(re.findall(r"[\w.+-]+", out))
    scenes = sorted(p.stem for p in TESTCASES.rglob("*.toml"))  # tableaus/ too
    assert len(scenes) >= 10
    for name in scenes:
        assert name in words, f"scene {name} not listed"
    for name in STEPPER_NAMES:
        assert name in words, f"stepper {name} not listed"
    for name in TERM_NAMES:
        assert name in words, f"term {name} not listed"
    steppers = out.split("steppers:\n")[1].split("terms:\n")[0].splitlines()
    assert "``" not in out  # docstrings' reST literals printed plain
    assert all(len(line) < 400 and line.endswith(".") for line in steppers), steppers  # a whole first sentence each


# ---------------------------------------------------------------------------
# Bad input: exit 2, one line naming the field or value, no file
# ---------------------------------------------------------------------------


def assert_bad_input(code, out, err, tmp_path, *needles):
    line = one_line(code, err, 2)
    for needle in needles:
        assert needle.lower() in line.lower(), (needle, line)
    assert nc_files(tmp_path) == [], nc_files(tmp_path)


BAD_ARGS = [
    (("--dt", "0"), ("dt", "0")),
    (("--dt", "-300"), ("dt", "-300")),
    (("--dt", "nan"), ("dt", "nan")),
    (("--dt", "inf"), ("dt", "inf")),
    (("--dt", "7000"), ("dt", "7000")),  # does not divide the run length of 1 day
    (("--dt", "6750", "--days", "5"), ("dt", "6750", "output interval")),  # divides 5 days, not 1 day
    (("--days", "0"), ("days", "0")),
    (("--days", "-1"), ("days", "-1")),
    (("--days", "nan"), ("days", "nan")),
    (("--ne", "0"), ("ne", "0")),
    (("--ne", "-3"), ("ne", "-3")),
    (("--ne", "abc"), ("ne", "abc")),
    (("--np", "1"), ("np", "1")),
    (("--np", "9"), ("np", "9")),
    (("--stepper", "euler"), ("stepper", "euler")),
    (("--device", "tpu"), ("device", "tpu")),
]


@pytest.mark.parametrize("args,needles", BAD_ARGS, ids=[" ".join(a) for a, _ in BAD_ARGS])
def test_bad_command_line_values(args, needles, capsys, tmp_path):
    out = tmp_path / "out.nc"
    base = ["--ne", "2", "--np", "4", "--days", "1", "--device", "cpu", "--no-progress"]
    code, stdout, err = run_cli(capsys, "tc2_steady", *base, *args, "--output", out)
    assert_bad_input(code, stdout, err, tmp_path, *needles)


def test_unknown_scene_file(capsys, tmp_path):
    code, out, err = run_cli(capsys, tmp_path / "nope.toml", *TINY, "--output", tmp_path / "o.nc")
    assert_bad_input(code, out, err, tmp_path, "nope.toml")


@pytest.mark.parametrize(
    "edit,needles",
    [
        pytest.param(lambda t: t.replace("[grid]", "[grid"), ("TOML",), id="malformed-toml"),
        pytest.param(lambda t: t + "\nfoo = [1, \n", ("TOML",), id="unterminated-array"),
        pytest.param(
            lambda t: t.replace('name = "tc2_steady"', 'name = "tc99_nothing"'),
            ("case", "tc99_nothing"),
            id="unknown-case",
        ),
        pytest.param(
            lambda t: t.replace('"coriolis"', '"coriolis", "friction"'), ("term", "friction"), id="unknown-term"
        ),
        pytest.param(
            lambda t: t.replace('stepper = "ssprk3"', 'stepper = "euler"'), ("stepper", "euler"), id="unknown-stepper"
        ),
        pytest.param(lambda t: "colour = 3\n" + t, ("colour",), id="unknown-top-level-key"),
        pytest.param(lambda t: t.replace("[grid]\n", "[grid]\nnx = 3\n"), ("grid.nx",), id="unknown-grid-key"),
        pytest.param(lambda t: t.replace("[time]\n", "[time]\nsteps = 3\n"), ("time.steps",), id="unknown-time-key"),
        pytest.param(lambda t: t + "\n[physics]\ng = 9.8\n", ("physics",), id="unknown-table"),
        pytest.param(
            lambda t: t.replace("alpha = 0.0", "alpha = 0.0\nbeta = 1.0"), ("case.beta",), id="unknown-case-parameter"
        ),
        pytest.param(lambda t: t.replace("dt = 300.0", "dt = 0.0"), ("dt",), id="scene-dt-zero"),
        pytest.param(lambda t: t.replace("dt = 300.0", "dt = -300.0"), ("dt",), id="scene-dt-negative"),
        pytest.param(lambda t: t.replace("days = 5.0", "days = 0.0"), ("days",), id="scene-days-zero"),
        pytest.param(lambda t: t.replace("ne = 16", "ne = 0"), ("ne",), id="scene-ne-zero"),
        pytest.param(lambda t: t.replace("np = 4", "np = 9"), ("np",), id="scene-np-9"),
        pytest.param(lambda t: t.replace("ne = 16", 'ne = "two"'), ("grid.ne", "two"), id="scene-ne-string"),
        pytest.param(
            lambda t: t.replace("every_days = 1.0", "every_days = 0.0"), ("every_days",), id="scene-output-every-zero"
        ),
    ],
)
def test_bad_scene_files(edit, needles, capsys, tmp_path):
    scene = edited_scene(tmp_path, edit)
    # no overrides: they would mask the edited values (every case fails while loading the scene)
    args = ["--device", "cpu", "--no-progress", "--output", tmp_path / "out.nc"]
    code, out, err = run_cli(capsys, scene, *args)
    assert_bad_input(code, out, err, tmp_path, *needles)


def test_output_into_a_missing_folder(capsys, tmp_path):
    target = tmp_path / "no_such_folder" / "out.nc"
    code, out, err = run_cli(capsys, "tc2_steady", *TINY, "--days", "1", "--output", target)
    assert_bad_input(code, out, err, tmp_path, "no_such_folder")
    assert not target.parent.exists()


def test_output_under_a_regular_file(capsys, tmp_path):
    (tmp_path / "plain_file").write_text("not a folder")
    code, out, err = run_cli(capsys, "tc2_steady", *TINY, "--days", "1", "--output", tmp_path / "plain_file" / "o.nc")
    assert_bad_input(code, out, err, tmp_path, "plain_file")


def test_output_is_a_folder(capsys, tmp_path):
    (tmp_path / "folder.nc").mkdir()
    code, out, err = run_cli(capsys, "tc2_steady", *TINY, "--days", "1", "--output", tmp_path / "folder.nc")
    assert code == 2 and len(stderr_lines(err)) == 1 and "folder.nc" in err, err
    assert list((tmp_path / "folder.nc").iterdir()) == []


def test_output_into_a_read_only_folder(capsys, tmp_path):
    folder = tmp_path / "read_only"
    folder.mkdir()
    folder.chmod(0o555)
    try:
        code, out, err = run_cli(capsys, "tc2_steady", *TINY, "--days", "1", "--output", folder / "o.nc")
        if os.access(folder, os.W_OK):  # root may write into it, and does (the refusal: the test below)
            assert code == 0 and (folder / "o.nc").is_file(), err
        else:
            assert_bad_input(code, out, err, tmp_path, "read_only")
    finally:
        folder.chmod(0o755)


def test_output_into_a_folder_reported_read_only(monkeypatch, capsys, tmp_path):
    """The read-only check where permissions cannot bite (root): os.access says no."""
    folder = tmp_path / "locked"
    folder.mkdir()
    real_access = os.access

    def access(path, mode, *args, **kwargs):
        if Path(path).resolve() == folder.resolve() and mode & os.W_OK:
            return False
        return real_access(path, mode, *args, **kwargs)

    monkeypatch.setattr(os, "access", access)
    code, out, err = run_cli(capsys, "tc2_steady", *TINY, "--days", "1", "--output", folder / "o.nc")
    assert_bad_input(code, out, err, tmp_path, "locked")


@pytest.mark.skipif(cuda_available(), reason="CUDA is available here")
def test_device_cuda_without_cuda(capsys, tmp_path):
    out = tmp_path / "out.nc"
    code, stdout, err = run_cli(
        capsys,
        "tc2_steady",
        "--ne",
        "2",
        "--np",
        "4",
        "--days",
        "1",
        "--device",
        "cuda",
        "--no-progress",
        "--output",
        out,
    )
    assert_bad_input(code, stdout, err, tmp_path, "cuda")


@pytest.mark.gpu
@pytest.mark.skipif(not cuda_available(), reason="needs a CUDA device")
def test_tiny_run_on_cuda_matches_cpu(capsys, tmp_path):
    results = {}
    for device in ("cuda", "cpu"):
        out = tmp_path / f"{device}.nc"
        code, _, err = run_cli(
            capsys,
            "tc2_steady",
            "--ne",
            "2",
            "--np",
            "4",
            "--days",
            "1",
            "--device",
            device,
            "--no-progress",
            "--output",
            out,
        )
        assert code == 0, err
        with xr.open_dataset(out, decode_times=False) as ds:
            assert ds.attrs["device"] == device
            results[device] = ds.load()
    cuda, cpu = results["cuda"], results["cpu"]
    assert cuda.l2_h.values[-1] < 3e-3
    np.testing.assert_allclose(cuda.h.values, cpu.h.values, rtol=1e-10)
    np.testing.assert_allclose(cuda.u.values, cpu.u.values, rtol=1e-8, atol=1e-8)


# ---------------------------------------------------------------------------
# Blow-up: exit 3, message with step, model time and place, file keeps the good times
# ---------------------------------------------------------------------------


def test_blowup_exits_3_and_keeps_the_good_output(capsys, tmp_path):
    out = tmp_path / "blow.nc"
    code, stdout, err = run_cli(capsys, *BLOWUP, "--output", out)
    assert code == 3, err
    lines = stderr_lines(err)
    # the stability warning at start (Courant 1.54 > ssprk3's 1.11) foretold it
    assert len(lines) == 2 and "above ssprk3's stability limit" in lines[0], err
    lines = lines[1:]
    m = BLOWUP_RE.search(lines[0])
    assert m, lines[0]
    assert str(out) in lines[0] or out.name in lines[0]
    step, days = int(m["step"]), float(m["days"])
    lat, lon = float(m["lat"]), float(m["lon"])
    dt = 7200.0
    assert step >= 2
    assert days == pytest.approx(step * dt / 86400, abs=1e-4)
    assert days > 1  # so that at least one daily output precedes it
    assert -90 <= lat <= 90 and 0 <= lon < 360

    assert nc_files(tmp_path) == [out]
    with xr.open_dataset(out, decode_times=False) as ds:
        t = ds.time.values
        good_days = [d for d in range(0, 6) if d < days]
        last_good = (step - 1) * dt / 86400
        expected = good_days + ([last_good] if last_good not in good_days else [])
        np.testing.assert_allclose(t, expected, atol=1e-9)
        np.testing.assert_array_equal(ds.steps.values[-1], step - 1)
        assert np.all(np.diff(t) > 0)  # no repeated time
        for name in ("h", "u", "v", "mass", "total_energy", "l2_h", "rhs_evals", "wall_time"):
            assert np.isfinite(ds[name].values).all(), name
        assert (ds.h.values > 0).all()
        assert "blowup" in ds.attrs
        assert f"step {step}" in ds.attrs["blowup"]
        # the reported place is a node of the grid
        dist = np.hypot(ds.lat.values - lat, (ds.lon.values - lon + 180) % 360 - 180)
        assert dist.min() < 0.01
        assert json.loads(ds.attrs["scene"])["dt"] == dt


# ---------------------------------------------------------------------------
# The installed console script (the one real subprocess call)
# ---------------------------------------------------------------------------


def test_console_script_exit_status(tmp_path):
    """The entry point runs a whole (blowing-up) run and exits with status 3."""
    out = tmp_path / "blow.nc"
    proc = subprocess.run(
        [console_script(), "run", *BLOWUP, "--output", str(out)],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 3, proc.stderr
    assert BLOWUP_RE.search(proc.stderr), proc.stderr
    assert "summary" not in proc.stdout and "scene" in proc.stdout
    assert nc_files(tmp_path) == [out]
    with xr.open_dataset(out, decode_times=False) as ds:
        assert "blowup" in ds.attrs and ds.sizes["time"] >= 2


def _not_a_reference(folder: Path) -> Path:
    """A netCDF file of a reference's coefficients without its vorticity."""
    from swe_sphere.cases.reference import find_reference

    path = folder / "no_vorticity.nc"
    with xr.open_dataset(find_reference("galewsky", perturbed=False), decode_times=False) as ds:
        ds.drop_vars(["vort_spec_re", "vort_spec_im"]).to_netcdf(path)
    return path


@pytest.mark.parametrize(
    "command, scene, value, why",
    [
        ("sweep", "tc5_mountain", "missing.nc", "reference file not found: missing.nc"),
        ("run", "tc5_mountain", "junk.nc", "junk.nc: not a readable netCDF file"),
        (
            "run",
            "tc5_mountain",
            "NOT_A_REFERENCE",
            "not a reference file: missing variable(s) 'vort_spec_re', 'vort_spec_im'",
        ),
        (
            "run",
            "tc2_steady",
            "tc5_mountain_T213.nc",
            "case tc2_steady is scored against its exact solution, not a reference file",
        ),
        (
            "sweep",
            "tc5_mountain",
            "tc6_rossby_haurwitz_T213.nc",
            "the file is a tc6_rossby_haurwitz reference (its title), not one of tc5_mountain",
        ),
        (
            "run",
            "galewsky",
            "galewsky_balanced_T213.nc",
            "the file is a galewsky_balanced reference (its title), not one of galewsky",
        ),
    ],
    ids=["missing-sweep", "not-netcdf", "not-a-reference", "exact-solution", "other-case", "other-galewsky"],
)
def test_console_script_refuses_a_bad_case_reference(tmp_path, command, scene, value, why):
    """-s case.reference=...: exit 2, one line naming the key, the value and why; nothing written."""
    (tmp_path / "junk.nc").write_text("not netCDF")
    if value == "NOT_A_REFERENCE":
        value = str(_not_a_reference(tmp_path))
    proc = subprocess.run(
        [
            console_script(),
            command,
            scene,
            "--ne",
            "2",
            "--device",
            "cpu",
            "-s",
            f"case.reference={value}",
            "--output",
            str(tmp_path / "out"),
        ],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=120,
    )
    lines = stderr_lines(proc.stderr)
    assert proc.returncode == 2 and len(lines) == 1, proc.stderr
    assert lines[0].startswith(f"swe-sphere: error: case.reference = {value!r}: ") and why in lines[0], lines[0]
    assert not (tmp_path / "out").exists()


def _no_cuda_driver() -> bool:
    import ctypes.util

    return not cuda_available() and ctypes.util.find_library("cuda") is None


@pytest.mark.skipif(not _no_cuda_driver(), reason="needs a machine without a CUDA driver")
def test_console_script_device_cuda_without_driver_is_one_line(tmp_path):
    proc = subprocess.run(
        [
            console_script(),
            "run",
            "tc2_steady",
            "--ne",
            "2",
            "--days",
            "1",
            "--device",
            "cuda",
            "--output",
            str(tmp_path / "o.nc"),
        ],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 2
    assert nc_files(tmp_path) == []
    assert len(stderr_lines(proc.stderr)) == 1, proc.stderr
