"""T213 reference files and their interpolation to model nodes (swe_sphere.reference)."""

import math

import numpy as np
import pytest
import xarray as xr

from swe_sphere.cases import make_case
from swe_sphere.grid import CubedSphere
from swe_sphere.reference import Reference, find_reference, floor, locate


@pytest.fixture(scope="module")
def grid():
    return CubedSphere(16, 4)


@pytest.fixture(scope="module")
def tc5():
    return Reference(find_reference("tc5_mountain"))


def l2(grid, a, b):
    """Williamson's normalized l2 error of a against b, GLL-quadrature weighted."""
    w = grid.spheremp
    return math.sqrt(np.sum(w * (a - b) ** 2) / np.sum(w * b**2))


def test_tc5_day0_matches_analytic_at_cubed_sphere_nodes(grid, tc5):
    # Day 0 of the reference is the analytic TC5 state, so this measures the
    # interpolation error (measured: h_surface 2.3e-8, u 2.8e-8, at the float32 floor).
    case = make_case("tc5_mountain")
    u, v, h = case.initial(grid.lat, grid.lon)
    surface = h + case.hs(grid.lat, grid.lon)
    r = tc5.at(0.0, grid.lat, grid.lon)
    assert set(r) == {"h_surface", "h", "hs", "u", "v", "vorticity"}
    assert all(a.shape == grid.lat.shape and a.dtype == np.float64 for a in r.values())
    assert l2(grid, r["h_surface"], surface) <= 1e-6
    assert np.max(np.abs(r["h_surface"] - surface)) <= 5e-3  # m, out of ~5000 m
    assert l2(grid, r["u"], u) <= 1e-6
    assert np.max(np.abs(r["u"] - 20.0 * np.cos(grid.lat))) <= 1e-4  # m/s
    assert np.max(np.abs(r["v"])) <= 1e-4
    np.testing.assert_allclose(r["h"], r["h_surface"] - r["hs"], rtol=0, atol=1e-9)


@pytest.mark.parametrize("lat_deg", [89.9, -89.9, 90.0, -90.0])
def test_tc5_day0_near_and_at_poles(tc5, lat_deg):
    case = make_case("tc5_mountain")
    lon = np.linspace(-math.pi, 3 * math.pi, 49)
    lat = np.full_like(lon, math.radians(lat_deg))
    u, v, h = case.initial(lat, lon)
    r = tc5.at(0.0, lat, lon)
    assert np.max(np.abs(r["h_surface"] - (h + case.hs(lat, lon)))) <= 2e-3  # measured 1.6e-4 m
    assert np.max(np.abs(r["u"] - u)) <= 1e-5  # u0 cos(lat) = 0.035 m/s at 89.9°
    assert np.max(np.abs(r["v"])) <= 1e-5


def test_tc6_day0_longitude_dependent_fields(grid):
    # Wavenumber-4 fields exercise longitude wrapping and the sign change of
    # u, v across the poles (measured: h 2.6e-8, u 2.2e-8, |v| error 2.9e-6 m/s).
    ref = Reference(find_reference("tc6_rossby_haurwitz"))
    case = make_case("tc6_rossby_haurwitz")
    u, v, h = case.initial(grid.lat, grid.lon)
    r = ref.at(0.0, grid.lat, grid.lon - 2 * math.pi)  # any longitude range
    assert l2(grid, r["h_surface"], h) <= 1e-6
    assert l2(grid, r["u"], u) <= 1e-6
    assert l2(grid, r["v"], v) <= 1e-6
    lon = np.linspace(0.0, 2 * math.pi, 73)
    for lat_deg in (89.9, -89.9):
        lat = np.full_like(lon, math.radians(lat_deg))
        u, v, h = case.initial(lat, lon)
        r = ref.at(0.0, lat, lon)
        assert np.max(np.abs(r["h_surface"] - h)) <= 2e-3
        assert np.max(np.abs(r["u"] - u)) <= 1e-5
        assert np.max(np.abs(r["v"] - v)) <= 1e-5


def test_tc6_day0_vorticity(grid):
    """The stored vorticity at day 0 against the Rossby–Haurwitz wave's,
    ζ = 2ω sin φ − K sin φ cos^R φ (R² + 3R + 2) cos Rλ (Williamson eq. 145)."""
    ref = Reference(find_reference("tc6_rossby_haurwitz"))
    c = make_case("tc6_rossby_haurwitz")
    s, co = np.sin(grid.lat), np.cos(grid.lat)
    zeta = 2 * c.omega_w * s - c.K * s * co**c.R * (c.R**2 + 3 * c.R + 2) * np.cos(c.R * grid.lon)
    assert l2(grid, ref.at(0.0, grid.lat, grid.lon)["vorticity"], zeta) <= 1e-6


def test_interpolation_reproduces_stored_grid_values(tc5):
    # At the file's own grid points the spline returns the stored values (day 15).
    with xr.open_dataset(tc5.path, decode_times=False) as ds:
        j = np.array([0, 1, 100, 159, 160, 318, 319])
        i = np.array([0, 1, 320, 480, 639])
        stored = {k: ds[k].values[-1][np.ix_(j, i)].astype(np.float64) for k in ("h_surface", "u", "v")}
    lat, lon = np.meshgrid(tc5.lat[j], tc5.lon[i], indexing="ij")
    r = tc5.at(15.0, lat, lon)
    assert r["h_surface"].shape == (7, 5)
    np.testing.assert_allclose(r["h_surface"], stored["h_surface"], rtol=1e-12)
    np.testing.assert_allclose(r["u"], stored["u"], rtol=0, atol=1e-9)
    np.testing.assert_allclose(r["v"], stored["v"], rtol=0, atol=1e-9)


def test_longitude_is_periodic(tc5):
    rng = np.random.default_rng(0)
    lat = rng.uniform(-math.pi / 2, math.pi / 2, (4, 6))
    lon = rng.uniform(0.0, 2 * math.pi, (4, 6))
    a, b = tc5.at(5.0, lat, lon), tc5.at(5.0 + 5e-7, lat, lon - 4 * math.pi)
    for k in a:
        np.testing.assert_allclose(a[k], b[k], rtol=0, atol=1e-9)


def test_find_reference():
    names = {
        ("tc5_mountain", True): "tc5_mountain_T213.nc",
        ("tc6_rossby_haurwitz", True): "tc6_rossby_haurwitz_T213.nc",
        ("galewsky", True): "galewsky_T213.nc",
        ("galewsky", False): "galewsky_balanced_T213.nc",
    }
    for (case, perturbed), name in names.items():
        path = find_reference(case, perturbed=perturbed)
        assert path is not None and path.is_file() and path.name == name
    assert find_reference("tc2_steady") is None
    assert find_reference("tc1_cosine_bell", perturbed=False) is None


def test_stored_days():
    days = {
        "tc5_mountain": [0, 1, 2, 5, 10, 15],
        "tc6_rossby_haurwitz": [0, 1, 2, 7, 14],
        "galewsky": [0, 1, 2, 4, 5, 6],
    }
    for case, expected in days.items():
        np.testing.assert_array_equal(Reference(find_reference(case)).days, expected)
    np.testing.assert_array_equal(Reference(find_reference("galewsky", perturbed=False)).days, [0, 6])


def test_errors(tc5, tmp_path):
    with pytest.raises(ValueError, match="day 3 not stored"):
        tc5.at(3.0, 0.0, 0.0)
    with pytest.raises(ValueError, match="not stored"):
        tc5.at(5.0 + 1e-5, 0.0, 0.0)
    with pytest.raises(ValueError, match="latitude"):
        tc5.at(5.0, 2.0, 0.0)
    with pytest.raises(FileNotFoundError, match="nope.nc"):
        Reference(tmp_path / "nope.nc")
    junk = tmp_path / "junk.nc"
    junk.write_text("not netCDF")
    with pytest.raises(ValueError, match="junk.nc"):
        Reference(junk)
    partial = tmp_path / "partial.nc"
    xr.Dataset(
        {"h_surface": (("time", "lat", "lon"), np.zeros((1, 2, 4)))},
        coords={"time": [0.0], "lat": [-45.0, 45.0], "lon": [0.0, 90.0, 180.0, 270.0]},
    ).to_netcdf(partial)
    with pytest.raises(ValueError, match=r"not a reference file: missing variable\(s\) 'hs', 'u', 'v', 'vorticity', 'divergence'"):
        Reference(partial)


def test_locate_a_path_or_a_bundled_name(tmp_path, monkeypatch):
    bundled = find_reference("tc5_mountain")
    assert locate("tc5_mountain_T213.nc") == bundled
    link = tmp_path / "mine.nc"
    link.symlink_to(bundled)
    monkeypatch.chdir(tmp_path)
    assert locate("mine.nc") == link  # relative to the current folder, absolute, its own name kept
    with pytest.raises(FileNotFoundError, match="sub/tc5_mountain_T213.nc"):
        locate("sub/tc5_mountain_T213.nc")  # a bundled name only without a folder


def test_floor_is_the_readmes_t213_vs_t341_table():
    """TC5 T213's own error (/work/shared/reference/README.md) at its stored days
    after t = 0, by file name; unknown elsewhere."""
    assert floor("tc5_mountain_T213.nc", 15.0) == (1.0e-5, 7.8e-3, 3.1e-3)
    assert floor(find_reference("tc5_mountain"), 1.0 + 1e-7) == (3.4e-6, 1.7e-3, 6.3e-3)  # a path: its name counts
    assert floor("tc5_mountain_T213.nc", 5.0) == (5.9e-6, 5.7e-3, 4.2e-3)
    for name, day in (("tc5_mountain_T213.nc", 3.0), ("tc5_mountain_T213.nc", 0.0), ("tc5_mountain_T341.nc", 15.0),
                      ("tc6_rossby_haurwitz_T213.nc", 14.0), ("galewsky_T213.nc", 6.0)):
        assert floor(name, day) is None, (name, day)


def test_interpolation_error_far_below_model_error_at_ne16(grid, tc5):
    """Williamson's comparison is only meaningful if interpolating the reference costs
    far less than the model's own error: at ne=16 np=4 the interpolation error of
    h + hs (day 0, where the reference is analytic) must be <= 1e-3 of the model's
    error against the reference after one day of TC5."""
    from swe_sphere.config import load_scene
    from swe_sphere.simulation import Simulation

    case = make_case("tc5_mountain")
    u, v, h = case.initial(grid.lat, grid.lon)
    interpolation = l2(grid, tc5.at(0.0, grid.lat, grid.lon)["h_surface"], h + case.hs(grid.lat, grid.lon))
    result = Simulation(load_scene("tc5_mountain", ne=16, np=4, days=1.0), "cpu", progress=False).run(None)
    model = result.diagnostics["ref_l2_h_surface"]
    print(f"\ninterpolation l2 {interpolation:.2e}, model l2 after 1 day {model:.2e}, ratio {interpolation / model:.1e}")
    assert interpolation <= 1e-3 * model
