"""``swe-sphere run``: a successful run on a tiny grid (ne = 2, np = 4: 218 unique nodes,
in this process, on the CPU) and the netCDF file it writes."""

from __future__ import annotations

import json
import math
import shutil

import netCDF4
import numpy as np
import pytest
import xarray as xr

from swe_sphere import __version__
from swe_sphere.cli import main
from swe_sphere.config.scene import efold_nu
from swe_sphere.io.run_file import RunWriter

import roundoff
from cli_helpers import (
    EARTH_RADIUS,
    STEPPER_NAMES,
    TESTCASES,
    in_tmp,  # noqa: F401  (the fixture: every test in a folder of its own)
    nc_files,
    run_cli,
    stderr_lines,
)
from helpers import TINY, cached_grid

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


CONTROLLED = ["--stepper", "bs32", "-s", "time.control=error", "-s", "time.rtol=1e-3"]


def test_the_control_line_names_the_first_step_dt_max_clamps(tmp_path, capsys):
    """Under a dt_max below the scene's dt the first step is dt_max's (``StepControl``): the header
    says so, where it said the dt above it was."""
    for cap, says in ((None, "; dt above is the first step, dt_min "), (600, "; dt_max 600 s is the first step, ")):
        limit = ["-s", f"time.dt_max={cap}"] if cap else []
        run = [
            "run",
            "tc2_steady",
            *TINY,
            "--days",
            "0.25",
            *CONTROLLED,
            *limit,
            "--output",
            str(tmp_path / f"{cap}.nc"),
        ]
        assert main(run) == 0
        control = [line for line in capsys.readouterr().out.splitlines() if line.startswith("control ")]
        assert len(control) == 1 and says in control[0], control


@pytest.mark.parametrize(
    "days, quoted, extra",
    [
        (1.25, "(day 1, its last output time T213 stores)", []),
        (1.25, "(day 1, its last output time T213 stores)", CONTROLLED),
        (0.25, None, []),
    ],
)
def test_summary_quotes_the_last_output_time_the_reference_stores(tmp_path, capsys, days, quoted, extra):
    """T213 stores days 0, 1, 2, 5, 10 and 15: a 1.25-day run quotes its day-1 errors (labelled,
    under error control too, whose steps are not 1800 s), a 0.25-day run says there is none (not
    "nan"); t = 0 is never quoted. Either says plainly that T213 is the scene's default and where
    the finer bundled T341 is."""
    out = tmp_path / "r.nc"
    assert main(["run", "tc5_mountain", *TINY, "--dt", "1800", "--days", str(days), *extra, "--output", str(out)]) == 0
    printed = capsys.readouterr().out.splitlines()
    finer = "  reference   T213, the scene's default; the bundled T341 stores days 1, 15: -s case.reference=T341"
    assert finer in printed
    lines = [line for line in printed if "vs T213" in line]
    assert not any("nan" in line for line in lines)
    if quoted is None:
        assert lines == ["  vs T213     none: no output time after t = 0 is one T213 stores (days 0, 1, 2, 5, 10, 15)"]
    else:
        assert len(lines) == 4 and lines[0].endswith(quoted)  # h+hs, wind, its curl and divergence, eq. 83
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
            assert scene["stepper"] == "rk4"  # the efficiency study's choice (docs/explanation/efficiency.md)
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
