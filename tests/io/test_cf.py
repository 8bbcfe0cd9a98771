"""Every file the project writes in the CF tools: the run file, an ensemble's, its restart file, the lat-lon
remap, sweep.nc and stability.nc through the NCAS CF checker, the IOOS compliance-checker,
CDO and cf_xarray (each test skips only where its tool is absent)."""

from __future__ import annotations

import math

import netCDF4
import numpy as np
import pytest
import xarray as xr

from swe_sphere.cli import main
from swe_sphere.core.constants import DAY
from swe_sphere.studies import stability

from cf_checks import cdo, ioos_cf_errors, ncas_cf_errors, ugrid_roles
from helpers import TINY, without_sweep_figures

SPATIAL = ("run", "restart", "latlon")  # the files with fields on the sphere
TABLES = ("sweep", "stability")
ENSEMBLE = ("ensemble",)  # a run file with a member dimension (``run --members``)


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """TC5 at ne = 2 np = 4 for half a day with its restart file, its 10° lat-lon file, a
    two-member Galewsky ensemble's run file, a one-run sweep's sweep.nc and a stability table
    of two rows (one without a stable Δt)."""
    out = tmp_path_factory.mktemp("cf")
    run = out / "tc5.nc"
    assert main(["run", "tc5_mountain", *TINY, "--days", "0.5", "--restart-every", "0.5", "--output", str(run)]) == 0
    ensemble = [*("run", "galewsky", "--ne", "2", "--dt", "900", "--days", "0.5", "--members", "2")]
    assert main([*ensemble, "--perturbation", "1", "--output", str(out / "ensemble.nc")]) == 0
    latlon = out / "tc5_latlon.nc"
    assert main(["remap", str(run), "--resolution", "10", "--output", str(latlon)]) == 0
    sweep = [*("sweep", "tc2_steady", "--ne", "2", "--days", "0.25", "--steppers", "ssprk3", "--dt", "3600")]
    with pytest.MonkeyPatch.context() as mp:  # sweep.nc is checked here, not its figures
        without_sweep_figures(mp)
        assert main([*sweep, "--device", "cpu", "--output", str(out / "sweep")]) == 0
    found = stability.StabilityResult("tc5_mountain", "ssprk3", 2, 4, 0.5, DAY / 96, DAY / 100, 0.61, 0.05, [()] * 7)
    none = stability.StabilityResult("galewsky", "leapfrog", 2, 4, 0.5, math.nan, math.nan, math.nan, math.nan, [])
    stability.write_table([found, none], out)
    return {
        "run": run,
        "ensemble": out / "ensemble.nc",
        "restart": out / "tc5.restart.nc",
        "latlon": latlon,
        "sweep": out / "sweep" / "sweep.nc",
        "stability": out / "stability.nc",
    }


@pytest.mark.parametrize("which", SPATIAL + TABLES + ENSEMBLE)
def test_ncas_cf_checker_finds_no_errors(files, which, tmp_path):
    assert ncas_cf_errors(files[which], tmp_path) == []
    assert len(ugrid_roles(files[which])) == (
        4 if which in ("run", "ensemble") else 0
    )  # two meshes, each with its connectivity


@pytest.mark.filterwarnings("ignore::DeprecationWarning")  # loading every suite loads its deprecated ioos_sos
@pytest.mark.parametrize("which", SPATIAL + TABLES + ENSEMBLE)
def test_ioos_compliance_checker_cf18_finds_no_errors(files, which, tmp_path):
    assert ioos_cf_errors(files[which], tmp_path) == []


def test_stability_nc_is_classic_cf(files):
    """No variable-length strings (character arrays), no 64-bit integers, units and
    long_name on every numeric variable, and CF's global attributes."""
    with netCDF4.Dataset(files["stability"]) as nc:
        assert nc.Conventions == "CF-1.8" and nc.title.startswith("swe_sphere stability") and "stability" in nc.history
        assert nc["case"].dtype == "S1" and nc["case"].dimensions == ("row", "string12")
        assert nc["stepper"].dtype == "S1"
        for name, var in nc.variables.items():
            assert var.dtype != str and var.dtype.itemsize <= 8 and var.dtype not in (np.int64, np.uint64), name
            assert "long_name" in var.ncattrs(), name
            assert var.dtype == "S1" or "units" in var.ncattrs(), name
        assert nc["ne"].dtype == np.int32 and nc["trials"][:].tolist() == [7, 0]
    with xr.open_dataset(files["stability"]) as ds:
        table = ds.set_index(row=["case", "stepper"])  # the (case, stepper) labels back
        assert float(table.dt_stable.sel(row=("tc5_mountain", "ssprk3"))) == DAY / 96
        assert math.isnan(float(table.dt_stable.sel(row=("galewsky", "leapfrog"))))


@pytest.mark.parametrize(
    "which,names",
    [
        ("run", ("h", "u", "v", "vorticity", "divergence", "hs", "mass")),
        ("restart", ("u", "v", "h")),
        ("latlon", ("h", "h_surface", "hs")),
        ("sweep", ("dt", "stable", "total_error")),
        ("stability", ("ne", "np", "days", "dt_stable", "dt_unstable", "courant_gravity", "trials")),
    ],
)
def test_cdo_reads_every_file(files, which, names):
    """``cdo sinfon`` opens each file and lists its numeric variables (text columns it skips)."""
    done = cdo("sinfon", files[which])
    assert done.returncode == 0, done.stderr
    listed = {line.split(":")[-1].strip() for line in done.stdout.splitlines() if line.strip()[:1].isdigit()}
    assert set(names) <= listed
    if which == "stability":  # its rows are CDO's time steps (it notes that their unit is no time unit)
        values = cdo("outputf,%.17g", "-selname,dt_stable", files[which]).stdout.split()[-2:]
        assert float(values[0]) == DAY / 96 and math.isnan(float(values[1]))


@pytest.mark.parametrize("which", SPATIAL)
@pytest.mark.parametrize("decode_coords", [True, "all"])
def test_cf_xarray_finds_the_one_latitude_and_longitude(files, which, decode_coords):
    """The control volumes' corners (dual_lat/dual_lon) are no second latitude and longitude,
    with xarray's default decoding or with every CF-related variable as a coordinate."""
    pytest.importorskip("cf_xarray")
    with xr.open_dataset(files[which], decode_times=False, decode_coords=decode_coords) as ds:
        lat, lon = ds.cf["latitude"], ds.cf["longitude"]
        assert (lat.name, lon.name) == ("lat", "lon")
        assert (float(lat.min()), float(lat.max())) == (-90.0, 90.0)
        assert 0 <= float(lon.min()) and float(lon.max()) < 360
        assert ds.cf.coordinates["latitude"] == ["lat"] and ds.cf.coordinates["longitude"] == ["lon"]


def weighted_mean_h(path, dims):
    """cf_xarray's area-weighted mean of h over ``dims`` at each time (or the one time of a restart)."""
    with xr.open_dataset(path, decode_times=False, decode_coords="all") as ds:
        return np.atleast_1d(ds.h.cf.weighted("area").mean(dims).values), float(ds.area.sum())


def test_cf_xarray_weighted_area_is_the_model_quadrature(files):
    """With ``decode_coords="all"`` the cell measure ``area`` is a coordinate of h, and
    ``ds.h.cf.weighted("area")`` is the GLL quadrature: the run file's assembled spheremp
    and the restart file's element-local spheremp give the same mean (h is continuous),
    and every file's areas sum to the run's sphere, 4πa²."""
    pytest.importorskip("cf_xarray")
    run, run_area = weighted_mean_h(files["run"], "ncol")
    restart, restart_area = weighted_mean_h(files["restart"], "node")
    latlon, latlon_area = weighted_mean_h(files["latlon"], ("lat", "lon"))
    sphere = 4 * math.pi * 6.37122e6**2
    for area in (run_area, restart_area, latlon_area):
        assert area == pytest.approx(sphere, rel=1e-13)
    with xr.open_dataset(files["run"], decode_times=False) as ds:
        mine = (ds.h * ds.area).sum("ncol").values / float(ds.area.sum())
    assert np.allclose(run, mine, rtol=1e-14, atol=0)
    assert restart[0] == pytest.approx(run[-1], rel=1e-13)  # the restart holds the last output time
    # the lat-lon cells' midpoint sum at 10°: within 1e-3 of the GLL quadrature (5e-4 at ne = 2)
    assert np.allclose(latlon, run, rtol=1e-3, atol=0)
