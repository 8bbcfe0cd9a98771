"""GLL interpolation to arbitrary points (``swe_sphere.io.remap``) and ``swe-sphere remap``:
exact on polynomials of degree < np in each element's reference coordinates,
spectrally accurate on smooth fields, equal to the model at GLL nodes that a
lat-lon point hits, and a CF file that xarray opens."""

from __future__ import annotations

import math

import netCDF4
import numpy as np
import pytest
import xarray as xr
from scipy.spatial import cKDTree

from swe_sphere.cli import main
from swe_sphere.io.remap import Remapper, lagrange_basis, latlon_grid, locate, remap_dataset
from swe_sphere.mesh.face_map import FACES

import roundoff


def cartesian(lat, lon):
    return np.stack([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)], axis=-1)


def random_points(rng, m):
    return np.arcsin(rng.uniform(-1, 1, m)), rng.uniform(0, 2 * math.pi, m)


def node_angles(grid):
    """(face, α, β) of every element-local node, from the index layout of grid.py."""
    ne, n = grid.ne, grid.np
    e = np.arange(grid.nnodes) // (n * n)
    j = (np.arange(grid.nnodes) // n) % n
    i = np.arange(grid.nnodes) % n
    face, jb, ia = e // (ne * ne), (e // ne) % ne, e % ne
    d = math.pi / 2 / ne
    ref = grid.rule.points
    return face, -math.pi / 4 + (ia + (ref[i] + 1) / 2) * d, -math.pi / 4 + (jb + (ref[j] + 1) / 2) * d


def point_angles(lat, lon):
    """(face, α, β) of points, independently of remap.locate: α = atan2(P·ea, P·c)."""
    P = cartesian(lat, lon)
    face = np.argmax(P @ FACES[:, 0].T, axis=1)
    c, ea, eb = FACES[face, 0], FACES[face, 1], FACES[face, 2]
    pc = np.einsum("ij,ij->i", P, c)
    return face, np.arctan2(np.einsum("ij,ij->i", P, ea), pc), np.arctan2(np.einsum("ij,ij->i", P, eb), pc)


@pytest.mark.parametrize("np_", range(2, 9))
def test_lagrange_basis_is_cardinal_and_reproduces_polynomials(grid_factory, np_):
    x = grid_factory(1, np_).rule.points
    assert np.array_equal(lagrange_basis(x, x), np.eye(np_))  # exactly 1/0 at the nodes
    t = np.random.default_rng(np_).uniform(-1, 1, 301)
    by_k = np.ones((t.size, np_))  # the product k by k, factor by factor in order of m: the same bits
    for k in range(np_):
        for m in range(np_):
            if m != k:
                by_k[:, k] *= (t - x[m]) / (x[k] - x[m])
    assert np.array_equal(lagrange_basis(x, t), by_k)
    t = np.linspace(-1, 1, 37)
    L = lagrange_basis(x, t)
    for k in range(np_):  # monomials of degree < np
        assert np.max(np.abs(L @ x**k - t**k)) < 1e-13


@pytest.mark.parametrize("ne,np_", [(1, 4), (3, 4), (2, 7)])
def test_locate_inverts_the_grid(grid_factory, ne, np_):
    """Each GLL node is found in an element whose forward map at (ξ, η) gives the node back."""
    grid = grid_factory(ne, np_)
    elem, xi, eta = locate(ne, grid.lat, grid.lon)
    assert elem.min() >= 0 and elem.max() < grid.nelem
    assert np.abs(xi).max() <= 1 + 1e-12 and np.abs(eta).max() <= 1 + 1e-12
    face, ia, jb = elem // ne**2, elem % ne, (elem // ne) % ne
    d = math.pi / 2 / ne
    alpha = -math.pi / 4 + (ia + (xi + 1) / 2) * d
    beta = -math.pi / 4 + (jb + (eta + 1) / 2) * d
    P = FACES[face, 0] + np.tan(alpha)[:, None] * FACES[face, 1] + np.tan(beta)[:, None] * FACES[face, 2]
    P /= np.linalg.norm(P, axis=1)[:, None]
    assert np.abs(P - grid.xyz.T).max() < 1e-14
    # nodes inside an element are found in their own element at their own (ξ, η)
    n = np_
    i, j = np.arange(grid.nnodes) % n, (np.arange(grid.nnodes) // n) % n
    inner = (i > 0) & (i < n - 1) & (j > 0) & (j < n - 1)
    own = np.arange(grid.nnodes) // (n * n)
    assert np.array_equal(elem[inner], own[inner])
    assert np.abs(xi[inner] - grid.rule.points[i[inner]]).max() < 1e-13


@pytest.mark.parametrize("np_", range(2, 9))
def test_remap_reproduces_polynomials_of_degree_below_np_exactly(grid_factory, rng, np_):
    """Node data from a polynomial of degree np−1 in α and in β on each face (α, β are
    linear in ξ, η inside an element) comes back exactly at random points."""
    ne = 3
    grid = grid_factory(ne, np_)
    coef = rng.normal(size=(6, np_, np_))  # face k: Σ c[k, a, b] α^a β^b

    def poly(face, alpha, beta):
        A = np.stack([alpha**a for a in range(np_)], axis=-1)
        B = np.stack([beta**b for b in range(np_)], axis=-1)
        return np.einsum("ma,mab,mb->m", A, coef[face], B)

    f_local = poly(*node_angles(grid))
    lat, lon = random_points(rng, 4000)
    exact = poly(*point_angles(lat, lon))
    got = Remapper(grid, lat, lon).local(f_local)
    scale = np.abs(exact).max()
    assert np.abs(got - exact).max() < 1e-13 * max(scale, 1.0)
    # a degree-np polynomial is not reproduced: the test can fail
    if np_ <= 6:
        f_hi = f_local + node_angles(grid)[1] ** np_
        _, a_t, _ = point_angles(lat, lon)
        assert np.abs(Remapper(grid, lat, lon).local(f_hi) - exact - a_t**np_).max() > 1e-9


@pytest.mark.parametrize("np_", [3, 4, 5, 8])
def test_remap_matrix_is_scipys_canonical_matrix_bit_for_bit(grid_factory, rng, np_):
    """The matrix the remapper builds row by row is, array for array and bit for bit, the one scipy
    makes from the (target, node) pairs of ``weights`` and ``nodes`` (sorted, duplicates summed), on
    the cube and on a stretched mesh; so the remapped values are too. On the cube ``weights`` is the
    product ℓ_j(η) ℓ_i(ξ) at [j np + i] of ``lagrange_basis``'s factors; and a part of the targets
    alone gives their bits (on a mesh, their values to round-off)."""
    from scipy.sparse import csr_matrix

    from swe_sphere.grid.cubed_sphere import CubedSphere
    from swe_sphere.mesh.schmidt import schmidt_cube

    lat, lon = random_points(rng, 3000)
    lat[:3], lon[:3] = (math.pi / 2, -math.pi / 2, 0.0), (0.0, 0.0, math.pi / 4)  # the poles, a cube edge
    m, n2 = lat.size, np_**2
    cube = grid_factory(3, np_)
    elem, xi, eta = locate(3, lat, lon)
    rm = Remapper(cube, lat, lon)
    li, lj = lagrange_basis(cube.rule.points, xi), lagrange_basis(cube.rule.points, eta)
    assert np.array_equal(rm.weights, (lj[:, :, None] * li[:, None, :]).reshape(m, n2))
    assert np.array_equal(rm.nodes, elem[:, None] * n2 + np.arange(n2))
    for grid in (cube, CubedSphere(2, np_, mesh=schmidt_cube(2, 2.0, 40.0, 270.0))):
        rm = Remapper(grid, lat, lon)
        rows = np.repeat(np.arange(m), n2)
        want = csr_matrix((rm.weights.ravel(), (rows, grid.gid[rm.nodes].ravel())), shape=(m, grid.nunique))
        for name in ("data", "indices", "indptr"):
            a, b = getattr(rm.matrix, name), getattr(want, name)
            assert a.dtype == b.dtype and np.array_equal(a.view(np.uint8), b.view(np.uint8)), name
        assert rm.matrix.has_canonical_format
        f = rng.normal(size=(2, grid.nunique))
        assert np.array_equal(rm(f), np.asarray(want @ f.T).T)
        part = Remapper(grid, lat[100:200], lon[100:200])
        if grid.mesh is None:
            assert np.array_equal(part(f), rm(f)[:, 100:200])
        else:  # Newton's method on a mesh iterates until the batch's worst point converges
            assert np.abs(part(f) - rm(f)[:, 100:200]).max() < 1e-14 * np.abs(f).max()


def test_remap_is_spectrally_accurate_on_smooth_fields(grid_factory, rng):
    """Errors on a smooth field at random points fall by orders of magnitude with np
    (measured at ne=4: np=4 1.4e-3, np=6 9.3e-6, np=8 4.9e-8)."""
    lat, lon = random_points(rng, 5000)

    def f(lat, lon):
        x, y, z = np.moveaxis(cartesian(lat, lon), -1, 0)
        return np.exp(x) * np.sin(2 * y) + z**3

    errors = {}
    for np_ in (4, 6, 8):
        grid = grid_factory(4, np_)
        rm = Remapper(grid, lat, lon)
        errors[np_] = np.abs(rm(f(grid.lat, grid.lon)[grid.first]) - f(lat, lon)).max()
    assert errors[4] < 3e-3
    assert errors[6] < 2e-5
    assert errors[8] < 1e-7
    assert errors[8] < errors[6] / 50 and errors[6] < errors[4] / 50


def test_latlon_grid_and_bad_resolutions():
    lat, lon = latlon_grid(1.0)
    assert lat.size == 181 and lon.size == 360
    assert lat[0] == -90 and lat[-1] == 90 and lat[90] == 0
    assert lon[0] == 0 and lon[-1] == 359 and lon[45] == 45
    lat, lon = latlon_grid(0.25)
    assert (lat.size, lon.size) == (721, 1440)
    for bad in (0, -1, 0.7, 100, float("nan")):
        with pytest.raises(ValueError):
            latlon_grid(bad)


@pytest.fixture
def run_file(tc5_run_file):
    return tc5_run_file


@pytest.mark.roundoff
def test_remap_cli_matches_the_model_at_coinciding_points(run_file, tmp_path, capsys):
    out = tmp_path / "latlon.nc"
    assert main(["remap", str(run_file), "--resolution", "1.0", "--output", str(out)]) == 0
    assert str(out) in capsys.readouterr().out
    assert out.is_file() and not out.with_name(out.name + ".part").exists()
    with xr.open_dataset(out, decode_times=False) as r, xr.open_dataset(run_file, decode_times=False) as m:
        assert r.sizes["lat"] == 181 and r.sizes["lon"] == 360 and r.sizes["time"] == 2
        assert r.lat.dims == ("lat",) and r.lon.dims == ("lon",)
        assert r.lat.attrs["units"] == "degrees_north" and r.lon.attrs["units"] == "degrees_east"
        assert r.lat.attrs["standard_name"] == "latitude" and r.lat.attrs["axis"] == "Y"
        for name in ("h", "u", "v", "vorticity", "h_surface"):
            assert r[name].dims == ("time", "lat", "lon"), name
            assert np.isfinite(r[name].values).all(), name
        assert r.hs.dims == ("lat", "lon")
        assert r.h.attrs["units"] == "m" and r.vorticity.attrs["units"] == "s-1"
        np.testing.assert_allclose(r.h_surface.values, r.h.values + r.hs.values, rtol=0, atol=1e-9)
        np.testing.assert_array_equal(r.mass_change.values, m.mass_change.values)
        assert r.time.values[-1] == m.time.values[-1]

        # lat-lon points that are GLL nodes: both poles (360 points each) and the
        # element corners on the face-centre meridians and the equator
        LA, LO = np.meshgrid(r.lat.values, r.lon.values, indexing="ij")
        tree = cKDTree(cartesian(np.radians(m.lat.values), np.radians(m.lon.values)))
        dist, idx = tree.query(cartesian(np.radians(LA), np.radians(LO)).reshape(-1, 3))
        hit = dist < 1e-12
        assert hit.sum() >= 2 * 360 + 8
        for name in ("h", "u", "v", "vorticity"):
            a = r[name].values.reshape(2, -1)[:, hit]
            b = m[name].values[:, idx[hit]]
            scale = np.abs(b).max()
            # the np² Lagrange basis values (1 and 0 up to their round-off) times the element's values,
            # summed: a pass of roundoff.operator_roundings (the run file is ne = 2, np = 4)
            roundoff.within(
                np.abs(a - b).max(),
                roundoff.bound(roundoff.operator_roundings(4), scale),
                f"max |remapped − {name}| at nodes",
            )
        a = r.hs.values.reshape(-1)[hit]
        assert np.abs(a - m.hs.values[idx[hit]]).max() <= 1e-12 * m.hs.values.max()


def test_remap_default_output_name(run_file, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["remap", str(run_file), "--resolution", "30"]) == 0
    with xr.open_dataset(tmp_path / "tc5_latlon30.nc", decode_times=False) as r:
        assert (r.sizes["lat"], r.sizes["lon"]) == (7, 12)


def test_latlon_file_is_cf_and_selects_by_model_day(run_file, tmp_path):
    """The lat-lon file's coordinates hold no _FillValue and time stays CF time; the
    README's ``remap_dataset(run) → .sel(time=day)`` works on the undecoded run and on
    the written file, and a decoded read (xarray ≤ 2025.1 decoded timedeltas too) gives dates."""
    out = tmp_path / "ll.nc"
    assert main(["remap", str(run_file), "--resolution", "30", "--output", str(out)]) == 0
    with netCDF4.Dataset(out) as nc:
        for name in ("time", "lat", "lon"):
            assert "_FillValue" not in nc[name].ncattrs(), name
        assert nc["time"].units == "days since 2000-01-01 00:00:00" and nc["time"].calendar == "proleptic_gregorian"
        assert "_FillValue" in nc["h"].ncattrs()  # the fields keep theirs
    with xr.open_dataset(run_file, decode_times=False) as run:
        day = float(run.time.values[-1])
        assert day > 0
        ll = remap_dataset(run, 30.0)
        assert ll.h_surface.sel(time=day).dims == ("lat", "lon")
    with xr.open_dataset(out, decode_times=False) as ds:
        np.testing.assert_array_equal(ds.h_surface.sel(time=day).values, ll.h_surface.sel(time=day).values)
    with xr.open_dataset(out, decode_timedelta=True) as ds:
        assert ds.time.dtype.kind == "M"
        assert ds.time.values[-1] == np.datetime64("2000-01-01") + np.timedelta64(round(day * 86400), "s")


@pytest.mark.parametrize(
    "args,message",
    [
        (["missing.nc"], "not found"),
        (["RUN", "--resolution", "0.7"], "resolution"),
        (["RUN", "--resolution", "-1"], "resolution"),
        (["REF"], "REF: not a swe_sphere run"),  # the file named
        (["RUN", "--output", "nodir/out.nc"], "does not exist"),
    ],
)
def test_remap_bad_input_exits_2_and_writes_nothing(run_file, tmp_path, monkeypatch, capsys, args, message):
    from swe_sphere.cases.reference import find_reference

    monkeypatch.chdir(tmp_path)
    ref = str(find_reference("tc5_mountain"))
    args = [str(run_file) if a == "RUN" else ref if a == "REF" else a for a in args]
    message = message.replace("REF", ref)
    try:
        code = main(["remap", *args])
    except SystemExit as exc:
        code = exc.code
    out, err = capsys.readouterr()
    assert code == 2
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1 and message in lines[0], err
    assert list(tmp_path.iterdir()) == []
