"""A planet of one's own (``[planet]`` radius, omega, gravity): the DCMIP small
planet reproduces the Earth's run X times faster, gravity enters the balance and
the invariants, the planet is recorded in the run and restart files and kept by
a continuation, and bad values are refused with one line, exit 2.

Runs are of tc2_steady on small grids (ne = 2 to 6) on the CPU."""

from __future__ import annotations

import math

import numpy as np
import pytest
import xarray as xr

import swe_sphere
from swe_sphere.config.scene import load_scene
from swe_sphere.core.constants import EARTH
from swe_sphere.core.errors import SceneError
from swe_sphere.simulation.simulation import Simulation

from helpers import TINY, cli_main, cli_one_line

ERRORS = ("l1_h", "l2_h", "linf_h", "l1_wind", "l2_wind", "linf_wind", "l2_vorticity", "l2_divergence")


def tc2(**overrides) -> xr.Dataset:
    """tc2_steady at ne = 6 (dt 800 s on the Earth) through the API."""
    return swe_sphere.run("tc2_steady", ne=6, device="cpu", **overrides)


def test_small_planet_tc2_reproduces_the_earth_run_x_times_faster():
    """DCMIP's small planet: radius a/10 and rotation 10 Ω, run to day 0.1 with
    the scene's dt scaled to dt/10 (80 s) by the radius, holds the Earth's run to
    day 1 at its output times: the same depths and winds and the same normalized
    errors to 1e-10 (measured: 6e-12; the metric's round-off differs); the grid
    area is 4π(a/10)²; the file records the planet."""
    X = 10.0
    earth = tc2(days=1.0, output={"every_days": 0.5})
    small = tc2(days=1.0 / X, output={"every_days": 0.5 / X}, planet={"radius": EARTH.a / X, "omega": EARTH.omega * X})
    assert earth.attrs["dt"] == 800.0 and small.attrs["dt"] == 80.0
    assert (small.attrs["planet_radius"], small.attrs["planet_omega"], small.attrs["planet_gravity"]) == (
        EARTH.a / X,
        EARTH.omega * X,
        EARTH.g,
    )
    assert earth.attrs["planet_radius"] == EARTH.a
    assert abs(small.area.values.sum() / (4 * math.pi * (EARTH.a / X) ** 2) - 1) < 1e-12
    np.testing.assert_array_equal(small.time.values * X, earth.time.values)
    for name in ("h", "u", "v"):
        scale = np.abs(earth[name].values).max()
        np.testing.assert_allclose(small[name].values, earth[name].values, rtol=0, atol=1e-10 * scale)
    for key in ERRORS:
        assert earth[key].values[-1] > 1e-6  # a real error, not a zero compared with a zero
        np.testing.assert_allclose(small[key].values, earth[key].values, rtol=1e-10, atol=0)
    # Coriolis and the vorticity scale with 1/time: X times the Earth's
    np.testing.assert_allclose(
        small.vorticity.values,
        X * earth.vorticity.values,
        rtol=0,
        atol=1e-10 * X * np.abs(earth.vorticity.values).max(),
    )


def test_gravity_enters_the_balance_and_the_invariants():
    """TC2 holds g h fixed (gh0 = 2.94e4 m² s⁻²), so with gravity 2g the run is the
    Earth's with h halved, bit for bit (a factor 2 is exact), its normalized
    errors the same; mass and total energy (½h|v|² + ½g h² with the planet's g)
    are halved, which they would not be with the Earth's g in the energy."""
    earth = tc2(days=1.0, output={"every_days": 0.5})
    heavy = tc2(days=1.0, output={"every_days": 0.5}, planet={"gravity": 2 * EARTH.g})
    assert heavy.attrs["planet_gravity"] == 2 * EARTH.g
    np.testing.assert_array_equal(2 * heavy.h.values, earth.h.values)
    np.testing.assert_array_equal(heavy.u.values, earth.u.values)
    for key in ERRORS:
        np.testing.assert_array_equal(heavy[key].values, earth[key].values)
    for key in ("mass", "total_energy"):
        np.testing.assert_allclose(heavy[key].values / earth[key].values, 0.5, rtol=1e-14)


def test_cli_small_planet_run_and_continuation_keep_the_planet(tmp_path, capsys):
    """``swe-sphere run tc2_steady -s planet.radius=637122 -s planet.omega=7.292e-4``
    runs on the small planet (the scene's dt, 2400 s at ne = 2, scaled to 240 s) and writes the
    planet in the run and restart files; ``--continue`` keeps it, ending on the
    bits of the uninterrupted run."""
    small = ["-s", "planet.radius=637122", "-s", "planet.omega=7.292e-4", "-s", "output.every_days=0.05"]
    args = ["run", "tc2_steady", *TINY, *small]
    code, out, err = cli_main(capsys, *args, "--days", "0.1", "--output", tmp_path / "whole.nc")
    assert code == 0, err
    assert (  # the note of the scaled dt
        "dt scaled with the smallest node spacing and the planet's radius (637122 m against the scene's "
        "6.37122e+06 m) to 240 s" in out
    )
    code, _, err = cli_main(capsys, *args, "--days", "0.05", "--output", tmp_path / "cut.nc", "--restart-every", "0.05")
    assert code == 0, err
    code, _, err = cli_main(
        capsys, "run", "--continue", tmp_path / "cut.restart.nc", "--days", "0.1", "--device", "cpu", "--no-progress"
    )
    assert code == 0, err
    with (
        xr.open_dataset(tmp_path / "whole.nc", decode_times=False) as a,
        xr.open_dataset(tmp_path / "cut_continued.nc", decode_times=False) as b,
    ):
        for ds in (a, b):
            assert (ds.attrs["planet_radius"], ds.attrs["planet_omega"], ds.attrs["dt"]) == (637122.0, 7.292e-4, 240.0)
            assert abs(ds.area.values.sum() / (4 * math.pi * 637122.0**2) - 1) < 1e-12
        np.testing.assert_array_equal(a.h.sel(time=0.1).values, b.h.sel(time=0.1).values)
        np.testing.assert_array_equal(a.u.sel(time=0.1).values, b.u.sel(time=0.1).values)
    sim = Simulation.from_checkpoint(tmp_path / "cut.restart.nc", "cpu", progress=False)
    assert sim.scene.planet == {"radius": 637122.0, "omega": 7.292e-4, "gravity": EARTH.g}
    assert sim.grid.radius == 637122.0 and sim.case.planet.omega == 7.292e-4


@pytest.mark.parametrize(
    "setting, words",
    [
        ("planet.radius=-6.4e6", ("planet.radius", "positive", "-6400000.0")),
        ("planet.gravity=0", ("planet.gravity", "positive")),
        ("planet.omega=inf", ("planet.omega", "finite")),
        ("planet.omega='fast'", ("planet.omega", "fast")),
        ("planet.mass=6e24", ("planet.mass", "radius, omega, gravity")),
        ("planet.radius=1e308", ("planet.radius", "between 1e-30 and 1e+30", "1e+308")),
        ("planet.gravity=1e-300", ("planet.gravity", "between")),
    ],
)
def test_bad_planet_is_one_line_exit_2(tmp_path, capsys, setting, words):
    """A planet value that is not a positive finite number, or an unknown key, is
    refused naming it, before anything is written."""
    cli_one_line(capsys, ["run", "tc2_steady", *TINY, "-s", setting, "--output", tmp_path / "x.nc"], 2, *words)
    assert not list(tmp_path.iterdir())


def test_a_planet_at_the_range_s_ends_runs_and_scores():
    """The largest gravity a scene takes (1e30; TC2's depth h0/g about 3e-26 m) runs and scores
    finite errors (at 1e300 the depth's squared norm was zero and its scoring an internal
    ZeroDivisionError; a radius of 1e308 overflowed the grid's area)."""
    ds = tc2(days=0.05, planet={"gravity": 1e30})
    assert 0 < float(ds["l2_h"].values[-1]) < 1e-3 and 0 < float(ds["l2_wind"].values[-1]) < 1e-3


def test_reference_scoring_is_for_the_earth_only():
    """tc5_mountain on another planet is not scored against its T213 reference (the
    Earth's), with a note saying so; a chosen reference is refused. Its
    hyperviscosity keeps its damping time at the grid scale: ν ∝ a⁴, and dt
    scales with the radius."""
    earth = load_scene("tc5_mountain")
    small = load_scene("tc5_mountain", overrides={"planet.radius": EARTH.a / 10, "planet.omega": EARTH.omega * 10})
    assert earth.reference_file.name == "tc5_mountain_T213.nc" and small.reference_file is None
    assert any("not scored against the tc5_mountain_T213.nc reference" in note for note in small.notes)
    assert math.isclose(small.nu, earth.nu / 1e4, rel_tol=1e-12) and math.isclose(
        small.dt, earth.dt / 10, rel_tol=1e-12
    )
    with pytest.raises(
        SceneError, match=r"^case.reference = 'T341': the spectral references are of Williamson's Earth"
    ):
        load_scene("tc5_mountain", overrides={"planet.gravity": 3.71, "case.reference": "T341"})


def test_a_dt_given_is_not_scaled():
    """With -s time.dt (or --dt) the dt is the one for the planet given."""
    scene = load_scene("tc2_steady", overrides={"planet.radius": EARTH.a / 10, "time.dt": 30.0})
    assert scene.dt == 30.0
    assert load_scene("tc2_steady", dt=20.0, overrides={"planet.radius": EARTH.a / 10}).dt == 20.0


@pytest.mark.parametrize(
    "name",
    [
        "tc1_cosine_bell",
        "tc2_steady",
        "tc3_compact_zonal",
        "tc4_forced_low",
        "lauter_unsteady",
        "tc5_mountain",
        "tc6_rossby_haurwitz",
        "galewsky",
    ],
)
def test_every_case_on_a_small_planet_is_the_earths_x_times_faster(name):
    """The DCMIP convention of ``cases``: on radius a/X with rotation Ω·X every
    case starts from the Earth's winds, depth and surface height at the same
    latitude and longitude, with X times the Coriolis parameter; an exact
    solution at time t/X is the Earth's at t."""
    from swe_sphere.cases.library import make_case
    from swe_sphere.core.constants import DAY, Planet

    X = 10.0
    rng = np.random.default_rng(1)
    lat, lon = np.arcsin(rng.uniform(-1, 1, 500)), rng.uniform(0, 2 * np.pi, 500)
    earth, small = make_case(name), make_case(name, planet=Planet(a=EARTH.a / X, omega=EARTH.omega * X))
    pairs = [
        (earth.initial(lat, lon), small.initial(lat, lon)),
        ([earth.hs(lat, lon)], [small.hs(lat, lon)]),
        ([X * earth.fcor(lat, lon)], [small.fcor(lat, lon)]),
    ]
    if earth.exact_solution:
        pairs.append((earth.exact(lat, lon, 1.3 * DAY), small.exact(lat, lon, 1.3 * DAY / X)))
    for want, got in pairs:
        for w, g in zip(want, got):
            np.testing.assert_allclose(g, w, rtol=0, atol=1e-12 * max(np.abs(w).max(), 1.0))


@pytest.mark.parametrize("name, efold_hours", [("tc5_mountain", 3.0), ("tc6_rossby_haurwitz", 6.0)])
def test_small_planet_with_hyperviscosity_and_topography(name, efold_hours):
    """With hyperviscosity (ν ∝ a⁴ from the e-folding rule) and TC5's mountain, the
    small planet reproduces the Earth's day 1 at day 1/X when the scene's times
    are all divided by X (run length, output interval, e-folding time): depths
    and winds to 1e-12 of their maxima (measured: 2.5e-14)."""
    X = 10.0
    earth = swe_sphere.run(name, ne=4, days=1.0, device="cpu")
    small = swe_sphere.run(
        name,
        ne=4,
        days=1.0 / X,
        output={"every_days": 1.0 / X},
        device="cpu",
        planet={"radius": EARTH.a / X, "omega": EARTH.omega * X},
        hyperviscosity={"efold_hours": efold_hours / X},
    )
    assert math.isclose(small.attrs["dt"], earth.attrs["dt"] / X, rel_tol=1e-12)
    assert small.attrs["reference"] == "none" and earth.attrs["reference"].endswith("_T213.nc")
    for v in ("h", "u", "v"):
        np.testing.assert_allclose(small[v].values, earth[v].values, rtol=0, atol=1e-12 * np.abs(earth[v].values).max())


def test_plot_diff_against_a_reference_refuses_another_planet(tmp_path, capsys):
    """``plot --diff T213`` of a tc5_mountain run on a small planet is refused with
    one line, exit 2 (the reference is the Earth's), and no figure is written."""
    run = tmp_path / "small.nc"
    code, _, err = cli_main(
        capsys,
        "run",
        "tc5_mountain",
        *TINY,
        "--days",
        "0.1",
        "-s",
        "output.every_days=0.1",
        "-s",
        "planet.radius=637122",
        "-s",
        "planet.omega=7.292e-4",
        "--output",
        run,
    )
    assert code == 0, err
    with xr.open_dataset(run, decode_times=False) as ds:
        assert ds.attrs["reference"] == "none"
    cli_one_line(
        capsys,
        ["plot", run, "--diff", "T213", "--output", tmp_path / "figs"],
        2,
        "tc5_mountain_T213.nc is a reference of Williamson's Earth",
        "radius 637122 m",
    )
    assert not (tmp_path / "figs").exists()
