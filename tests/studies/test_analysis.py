"""``swe_sphere.studies.analysis`` and ``swe-sphere plot --spectrum / --zonal-mean``: the
kinetic-energy spectrum of known fields (single harmonics, TC2's solid-body
rotation at l = 1 alone) and Parseval's sum on a developed flow; TC2's zonal-mean
depth against Williamson et al.'s h(φ); the CLI files and its refusals; and the
periodic log lines of ``swe-sphere run`` (``[output] log_every_steps``)."""

from __future__ import annotations

import math
import re

import numpy as np
import pandas as pd
import pytest

from swe_sphere.core.constants import DAY, EARTH
from swe_sphere.core.errors import SceneError
from swe_sphere.grid.cubed_sphere import CubedSphere
from swe_sphere.io.run_file import RunWriter
from swe_sphere.model.diagnostics import harmonic_state
from swe_sphere.studies import analysis_plots
from swe_sphere.studies.analysis import kinetic_energy_spectrum, zonal_mean

from helpers import EIGHTH_DAY, TINY, cli_main, cli_one_line, png_size

A, OMEGA, G = EARTH.a, EARTH.omega, EARTH.g
U0 = 2 * math.pi * A / (12 * DAY)  # TC2's solid-body speed at the equator
GH0 = 2.94e4  # TC2's g h at the poles (m² s⁻²)


def write_run(path, grid, u, v, vorticity, divergence, scene=None):
    """A one-time (day 0) run file of element-local fields, as ``RunWriter`` writes them."""
    scene = {"name": "synthetic", "ne": grid.ne, "np": grid.np, **(scene or {})}
    w = RunWriter(path, grid, np.zeros(grid.nnodes), {"scene": scene}, [])
    w.append(0.0, u, v, np.full(grid.nnodes, 1e3), {}, vorticity=vorticity, divergence=divergence)
    w.close()
    return path


@pytest.fixture(scope="module")
def harmonics(tmp_path_factory):
    """A rotational wind of degree 3 plus half a divergent wind of degree 5 (unit
    harmonics mixing all orders, ``harmonic_state``) with their exact vorticity and
    divergence, on ne = 6 np = 8 (fine enough that the GLL interpolant is the
    field to 1e-10): (run file, grid, mean ½|v|² of each part)."""
    grid = CubedSphere(6, 8)
    ur, vr, _ = harmonic_state(grid, 3, "rotational")
    ud, vd, _ = harmonic_state(grid, 5, "divergent", seed=1)
    y3 = harmonic_state(grid, 3, "height")[2]
    y5 = harmonic_state(grid, 5, "height", seed=1)[2]
    # v = r̂ × ∇₁Y = k × ∇(aY): ζ = ∇²(aY) = −l(l+1) Y / a; likewise δ of ∇₁Y
    path = write_run(
        tmp_path_factory.mktemp("harm") / "harm.nc",
        grid,
        ur + 0.5 * ud,
        vr + 0.5 * vd,
        -12 * y3 / A,
        -0.5 * 30 * y5 / A,
    )
    area = grid.integrate(np.ones(grid.nnodes))
    return path, grid, grid.integrate(0.5 * (ur**2 + vr**2)) / area, grid.integrate(0.125 * (ud**2 + vd**2)) / area


def test_single_harmonics_are_analysed_back(harmonics):
    path, grid, e_rot, e_div = harmonics
    sp = kinetic_energy_spectrum(path)
    assert sp.E_rot.dims == ("time", "l") and sp.sizes["l"] == 2 * 6 * 7 and list(sp.l.values[:2]) == [1, 2]
    assert sp.E.attrs["units"] == "m2 s-2" and sp.attrs["radius"] == A
    rot, div = sp.E_rot.isel(time=0).values, sp.E_div.isel(time=0).values
    assert rot[2] == pytest.approx(e_rot, rel=1e-9)  # l = 3
    assert div[4] == pytest.approx(e_div, rel=1e-9)  # l = 5
    assert np.delete(rot, 2).max() < 1e-15 * e_rot and np.delete(div, 4).max() < 1e-15 * e_div
    assert float(sp.E.sum()) == pytest.approx(e_rot + e_div, rel=1e-9)  # Parseval
    assert kinetic_energy_spectrum(path, lmax=5).sizes["l"] == 5


def test_spectrum_scales_with_the_runs_planet_radius(harmonics):
    """ζ and δ fixed, E ∝ a² (ψ = −a² ζ_lm / l(l+1)): a run of a tenth-radius planet
    (its scene's planet.radius) has a hundredth of the energy."""
    import json

    import xarray as xr

    path, grid, e_rot, _ = harmonics
    small = xr.load_dataset(path)  # a Dataset in memory, as swe_sphere.run returns
    small.attrs["scene"] = json.dumps({**json.loads(small.attrs["scene"]), "planet": {"radius": A / 10}})
    sp = kinetic_energy_spectrum(small)
    assert sp.attrs["radius"] == A / 10
    assert float(sp.E_rot.isel(time=0, l=2)) == pytest.approx(e_rot / 100, rel=1e-9)


@pytest.fixture(scope="module")
def tc2_file(tmp_path_factory):
    """``swe-sphere run tc2_steady`` (α = 0) at ne = 4 np = 4 for 1 day, outputs at days 0 and 1."""
    from swe_sphere.cli import main

    out = tmp_path_factory.mktemp("tc2") / "tc2.nc"
    assert (
        main(
            [
                "run",
                "tc2_steady",
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


def test_tc2_energy_is_all_rotational_at_degree_1(tc2_file):
    """u = u0 cos φ: ζ = 2 u0 sin φ / a = (2 u0 / a) √(4π/3) Y₁₀, so E_rot(1) = u0² / 3
    (the mean of ½ u0² cos² φ) and nothing else; to the model's ζ's discretisation
    error (2e-6 at day 0, 2e-4 after a day of the run)."""
    sp = kinetic_energy_spectrum(tc2_file)
    assert list(sp.time.values) == [0.0, 1.0]
    for day, tol, rest in ((0, 1e-5, 1e-8), (1, 5e-4, 1e-6)):
        e = sp.sel(time=day)
        assert float(e.E_rot.sel(l=1)) == pytest.approx(U0**2 / 3, rel=tol)
        assert float(e.E_rot.sel(l=slice(2, None)).max()) < rest * U0**2 / 3
        assert float(e.E_div.max()) < rest * U0**2 / 3
    assert kinetic_energy_spectrum(tc2_file, days=[1]).sizes["time"] == 1


def test_parseval_on_a_developed_flow(tc5_run_file):
    """Σ_l E(l) is the area mean of ½|v|² on the nodes, for TC5 over its mountain
    after a day at ne = 2, to the discretisation error of its ζ and δ (4e-4)."""
    import xarray as xr

    sp = kinetic_energy_spectrum(tc5_run_file)
    with xr.open_dataset(tc5_run_file, decode_times=False) as ds:
        w = ds.area.values
        for it in range(ds.sizes["time"]):
            ke = np.sum(w * 0.5 * (ds.u[it].values ** 2 + ds.v[it].values ** 2)) / w.sum()
            assert float(sp.E.isel(time=it).sum()) == pytest.approx(ke, rel=1e-3)
    assert float(sp.E_div.isel(time=-1).sum()) > 1e-5 * float(sp.E.isel(time=-1).sum())  # the mountain's gravity waves


def test_tc2_zonal_mean_depth_is_williamsons(tc2_file):
    """g h = g h0 − (a Ω u0 + u0²/2) sin² φ (Williamson et al. 1992, eq. 95), to the
    GLL interpolant's error (8e-5 of h at day 0) and the run's (4e-4 at day 1)."""
    z = zonal_mean(tc2_file, "h")
    assert z.dims == ("time", "lat") and z.name == "h_zonal_mean" and z.attrs["units"] == "m"
    assert z.lat.values[0] == -90 and z.lat.values[-1] == 90 and z.sizes["lat"] == 4 * 4 * 3 + 1
    h = (GH0 - (A * OMEGA * U0 + 0.5 * U0**2) * np.sin(np.radians(z.lat.values)) ** 2) / G
    for day, tol in ((0, 2e-4), (1, 1e-3)):
        assert np.max(np.abs(z.sel(time=day).values - h)) < tol * h.max()
    assert zonal_mean(tc2_file, "h", days=[1], resolution=2.0).shape == (1, 91)


def test_a_mesh_run_has_its_zonal_mean_and_spectrum(tmp_path, capsys):
    """On a refined mesh (ne 0 in its file) the default resolution and degree divided by zero
    (``zonal_mean``: ZeroDivisionError) or came out 0 (the spectrum: "lmax must be >= 1"); they
    are now the cube's of as many elements (``node_degree``). TC2 there: Williamson's h(φ) and
    E_rot(1) = u0²/3, as on the cube."""
    mesh, out = tmp_path / "m.g", tmp_path / "m.nc"
    assert cli_main(capsys, "mesh", "--ne", "4", "--refine-box", "20", "40", "10", "30", "--output", mesh)[0] == 0
    run = ["run", "tc2_steady", "--mesh", mesh, "--np", "4", "--days", "0.25", "--device", "cpu", "--no-progress"]
    assert cli_main(capsys, *run, "--output", out)[0] == 0
    z = zonal_mean(out, "h", days=[0])
    h = (GH0 - (A * OMEGA * U0 + 0.5 * U0**2) * np.sin(np.radians(z.lat.values)) ** 2) / G
    assert z.sizes["lat"] > 1 and np.max(np.abs(z.values[0] - h)) < 2e-4 * h.max()
    e = kinetic_energy_spectrum(out, days=[0]).isel(time=0)
    assert e.sizes["l"] > 1 and float(e.E_rot.sel(l=1)) == pytest.approx(U0**2 / 3, rel=1e-4)


def test_plot_spectrum_and_zonal_mean_files(tc2_file, tmp_path, capsys):
    code, out, err = cli_main(
        capsys,
        "plot",
        tc2_file,
        "--spectrum",
        "--zonal-mean",
        "--field",
        "h",
        "u",
        "--day",
        "0",
        "1",
        "--output",
        tmp_path / "figs",
    )
    assert code == 0, err
    names = [
        "tc2_spectrum_day0_1.png",
        "tc2_spectrum_day0_1.csv",
        "tc2_h_zonal_mean_day0_1.png",
        "tc2_u_zonal_mean_day0_1.png",
    ]
    assert out.split() == [str(tmp_path / "figs" / n) for n in names]
    assert sorted(p.name for p in (tmp_path / "figs").iterdir()) == sorted(names)
    assert png_size(tmp_path / "figs" / names[0]) == (800, 500) and png_size(tmp_path / "figs" / names[2]) == (800, 500)
    table = pd.read_csv(tmp_path / "figs" / names[1])
    assert list(table.columns) == ["day", "l", "E_rot", "E_div", "E"]
    sp = kinetic_energy_spectrum(tc2_file)
    assert np.allclose(table.E_rot.values, sp.E_rot.values.ravel(), rtol=1e-9, atol=0)
    assert list(table.day.unique()) == [0.0, 1.0] and table.l.max() == 24
    # the default: the last day's spectrum alone
    assert cli_main(capsys, "plot", tc2_file, "--spectrum", "--output", tmp_path)[0] == 0
    assert sorted(p.name for p in tmp_path.glob("*spectrum*")) == ["tc2_spectrum_day1.csv", "tc2_spectrum_day1.png"]
    assert pd.read_csv(tmp_path / "tc2_spectrum_day1.csv").day.unique().tolist() == [1.0]


def test_plot_functions_return_figures(tc2_file):
    fig = analysis_plots.plot_spectrum(kinetic_energy_spectrum(tc2_file))
    assert len(fig.axes[0].get_lines()) == 6  # E, E_rot, E_div at two days
    fig = analysis_plots.plot_zonal_mean(zonal_mean(tc2_file, "vorticity"), lat_range=(0, 90))
    assert fig.axes[0].get_xlim() == (0, 90) and fig.axes[0].get_ylabel() == "vorticity (10$^{-5}$ s$^{-1}$)"


@pytest.mark.parametrize(
    "args, message",
    [
        (["RUN", "--spectrum", "--day", "3"], "day 3 not in"),
        (["RUN", "--zonal-mean", "--day", "0.5"], "day 0.5 not in"),
        (["RUN", "--spectrum", "--lat-range", "0", "90"], "--lat-range applies to maps and --zonal-mean"),
        (["RUN", "--spectrum", "--field", "h"], "--field applies to maps and --zonal-mean"),
        (["RUN", "--zonal-mean", "--diff", "RUN"], "--diff and --force compare maps"),
        (["RUN", "--zonal-mean", "--lat-range", "10", "0"], "latitude range"),
        (["OLD", "--spectrum"], "no vorticity"),
        (["OLD", "--zonal-mean", "--field", "divergence"], "no divergence"),
        (["missing.nc", "--spectrum"], "not found"),
    ],
)
def test_bad_input_exits_2_one_line_nothing_written(
    tc2_file,
    old_file,
    tmp_path,
    monkeypatch,
    capsys,
    args,
    message,
):
    monkeypatch.chdir(tmp_path)
    args = [{"RUN": str(tc2_file), "OLD": str(old_file)}.get(a, a) for a in args]
    cli_one_line(capsys, ["plot", *args, "--output", tmp_path / "figs"], 2, message)
    assert list(tmp_path.iterdir()) == []


def test_existing_outputs_are_refused_before_anything_is_written(tc2_file, tmp_path, capsys):
    (tmp_path / "tc2_h_surface_zonal_mean_day1.png").write_bytes(b"mine")
    cli_one_line(capsys, ["plot", tc2_file, "--spectrum", "--zonal-mean", "--output", tmp_path], 2, "exists")
    assert [p.name for p in tmp_path.iterdir()] == ["tc2_h_surface_zonal_mean_day1.png"]
    assert cli_main(capsys, "plot", tc2_file, "--spectrum", "--zonal-mean", "--output", tmp_path, "--overwrite")[0] == 0
    assert (tmp_path / "tc2_h_surface_zonal_mean_day1.png").read_bytes()[:4] == b"\x89PNG"


def test_api_refusals():
    with pytest.raises(ValueError, match="unknown field 'pv'"):
        zonal_mean(_tiny_dataset(), "pv")
    with pytest.raises(ValueError, match="lmax must be an integer >= 1"):
        kinetic_energy_spectrum(_tiny_dataset(), lmax=0)
    with pytest.raises(SceneError, match="no_such_run.nc"):
        zonal_mean("no_such_run.nc")


def _tiny_dataset():
    import xarray as xr

    grid = CubedSphere(2, 3)
    return xr.Dataset(
        {"h": (("time", "ncol"), grid.to_unique(np.ones(grid.nnodes))[None])},
        coords={
            "time": [0.0],
            "lat": ("ncol", np.degrees(grid.lat[grid.first])),
            "lon": ("ncol", np.degrees(grid.lon[grid.first])),
            "area": ("ncol", grid.to_unique(grid.spheremp)),
        },
        attrs={"ne": 2, "np": 3},
    )


# -- the run's periodic log lines -------------------------------------------------
LOG = re.compile(
    r"^log +step (\d+) day ([0-9.]+)  mass ([-+0-9.e]+)  energy ([-+0-9.e]+)  enstrophy ([-+0-9.e]+)  "
    r"Courant advective ([0-9.]+) gravity-wave ([0-9.]+)$"
)


def test_log_lines_every_n_steps(tmp_path, capsys):
    """TC2 at ne = 2: dt = 2400 s, 36 steps a day; a line every 9 steps, the one at
    step 18 (day 0.5, an output time) with the file's invariant changes there."""
    import xarray as xr

    out = tmp_path / "run.nc"
    code, stdout, err = cli_main(
        capsys,
        "run",
        "tc2_steady",
        *TINY,
        "--days",
        "1",
        "-s",
        "output.every_days=0.5",
        "-s",
        "output.log_every_steps=9",
        "--output",
        out,
    )
    assert code == 0, err
    lines = [m.groups() for m in map(LOG.match, stdout.splitlines()) if m]
    assert [int(g[0]) for g in lines] == [9, 18, 27, 36]
    assert [float(g[1]) for g in lines] == [0.25, 0.5, 0.75, 1.0]
    assert sum(line.startswith("log ") for line in stdout.splitlines()) == 4 + 1  # and the header's "log every 9 steps"
    with xr.open_dataset(out, decode_times=False) as ds:
        for g in (lines[1], lines[3]):
            at = ds.sel(time=float(g[1]))
            for value, name in zip(g[2:5], ("mass_change", "total_energy_change", "potential_enstrophy_change")):
                assert float(value) == pytest.approx(float(at[name]), rel=5e-4, abs=1e-18)
            assert float(g[5]) == pytest.approx(float(at.courant_advective), abs=5e-4)
            assert float(g[6]) == pytest.approx(float(at.courant_gravity), abs=5e-4)
    # the lines between outputs are the state's own: the energy changes from line to line
    assert len({g[3] for g in lines}) == 4
    code, stdout, _ = cli_main(capsys, "run", "tc2_steady", *TINY, "--days", "1", "--output", tmp_path / "quiet.nc")
    assert code == 0 and not any(line.startswith("log") for line in stdout.splitlines())  # off by default


def test_log_every_steps_must_not_be_negative(capsys, tmp_path):
    cli_one_line(
        capsys,
        ["run", "tc2_steady", *TINY, "-s", "output.log_every_steps=-1", "--output", tmp_path / "x.nc"],
        2,
        "output.log_every_steps must be >= 0",
    )
    cli_one_line(
        capsys,
        ["run", "tc2_steady", *TINY, "-s", "output.log_every_steps=1.5", "--output", tmp_path / "x.nc"],
        2,
        "output.log_every_steps must be int",
    )
    assert list(tmp_path.iterdir()) == []


def test_the_zonal_mean_of_the_wind_at_the_poles_is_its_limit(tmp_path, capsys, monkeypatch):
    """TC2 with its jet over the poles (α = π/4), whose zonal mean of u is u0 cos(lat) cos(α)
    (Williamson 1992 eq. 90 averaged over longitude): the pole rows were ±27.6 m/s off it at
    ne2 (east turns with longitude there), 4.6x the worst other row; now they are the limit, 0
    (v's too), exact."""
    monkeypatch.chdir(tmp_path)
    from swe_sphere.studies.analysis import zonal_mean

    assert (
        cli_main(
            capsys,
            "run",
            "tc2_steady_alpha_pi4",
            *TINY,
            *EIGHTH_DAY,
            "--output",
            "a.nc",
        )[0]
        == 0
    )
    for field in ("u", "v"):
        assert zonal_mean(tmp_path / "a.nc", field).isel(time=-1).values[[0, -1]].tolist() == [0.0, 0.0], field
    u = zonal_mean(tmp_path / "a.nc", "u").isel(time=-1)
    u0 = 2 * np.pi * 6.37122e6 / (12 * 86400)
    error = np.abs(u.values - u0 * np.cos(np.radians(u.lat.values)) * np.cos(np.pi / 4))
    assert error[[0, -1]].max() < 1e-9 < error[1:-1].max()
