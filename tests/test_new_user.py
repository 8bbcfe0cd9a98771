"""What a new user hits first (issue 45, item 1), as the user sees it: exit 2, one
line naming the field or file, nothing written, no earlier result replaced."""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr
from test_initial_state import LL, latlon_file, scene_file

from swe_sphere.studies import stability, sweep

from conftest import TINY, cli_main, cli_one_line


@pytest.fixture(autouse=True)
def _in_tmp(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)


@pytest.mark.parametrize("flag", ["--runs", "--courant", "--dt"])
def test_sweep_refuses_an_empty_list(capsys, flag):
    """An empty --runs / --courant / --dt was read as "not given" and ran the whole default sweep."""
    cli_one_line(capsys, ["sweep", "tc2_steady", "--ne", "2", flag, "", "--output", "o"], 2, flag)


@pytest.mark.parametrize("name", sweep.OUTPUTS)
def test_sweep_keeps_an_earlier_studys_results(tmp_path, capsys, name):
    """Each of an earlier sweep's results in --output refuses the sweep before any run
    (no runs/ folder), and is kept as it was; --overwrite is named as the way on."""
    earlier = tmp_path / "o" / name
    earlier.parent.mkdir()
    earlier.write_text("earlier study")
    cli_one_line(
        capsys,
        ["sweep", "tc2_steady", "--ne", "2", "--days", "0.25", "--runs", "rk4@1", "--device", "cpu", "--output", "o"],
        2,
        "output file exists",
        name,
        "--overwrite",
    )
    assert earlier.read_text() == "earlier study"
    assert sorted(p.name for p in earlier.parent.iterdir()) == [name]


@pytest.mark.parametrize("name", stability.OUTPUTS)
def test_stability_keeps_an_earlier_suites_results(tmp_path, capsys, name):
    earlier = tmp_path / "stability_tc5_mountain_ne2" / name  # the suite's default folder
    earlier.parent.mkdir()
    earlier.write_text("earlier suite")
    cli_one_line(
        capsys,
        ["stability", "tc5_mountain", "--steppers", "rk4", "--ne", "2", "--device", "cpu"],
        2,
        "output file exists",
        name,
        "--overwrite",
    )
    assert earlier.read_text() == "earlier suite"
    assert sorted(p.name for p in earlier.parent.iterdir()) == [name]


def test_the_initial_state_file_is_never_replaced(tmp_path, capsys):
    """``--output`` naming the file ``case.path`` reads: refused even with --overwrite."""
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
def test_an_initial_state_not_covering_the_globe_is_refused(tmp_path, capsys, lat, lon, words):
    """A regional lat-lon file was extrapolated to the poles; one in radians was read as
    a tiny regional one. Both: one line, exit 2, no output."""
    scene = scene_file(tmp_path, latlon_file(tmp_path / "part.nc", lat, lon))
    cli_one_line(
        capsys, ["run", scene, "--device", "cpu", "--no-progress", "--output", "out.nc"], 2, "case.path", *words
    )
    assert not (tmp_path / "out.nc").exists()


def test_continue_at_the_end_day_without_days_is_refused(tmp_path, capsys):
    """``--continue R.restart.nc`` of a finished run, no --days: it ran 0 steps, exit 0, and
    wrote R_continued.nc, which then blocked the real continuation. Now exit 2, nothing written."""
    run = ["run", "tc2_steady", *TINY, "--dt", "1800", "--days", "0.25", "-s", "output.every_days=0.25"]
    assert cli_main(capsys, *run, "--restart-every", "0.25", "--output", "r.nc")[0] == 0
    before = sorted(p.name for p in tmp_path.iterdir())
    cli_one_line(
        capsys,
        ["run", "--continue", "r.restart.nc", "--device", "cpu", "--no-progress"],
        2,
        "r.restart.nc is already at its run's end day 0.25",
        "--days",
    )
    assert sorted(p.name for p in tmp_path.iterdir()) == before
    assert (
        cli_main(capsys, "run", "--continue", "r.restart.nc", "--days", "0.5", "--device", "cpu", "--no-progress")[0]
        == 0
    )
    assert (tmp_path / "r_continued.nc").is_file()


def test_a_switched_case_is_named_in_header_title_and_file_name(tmp_path, capsys):
    """``-s case.name=file`` on tc2_steady: the header, the run file's title and its
    default name say the case that ran, not the scene file's own."""
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


def test_a_branch_at_another_dt_drops_the_dt_scaled_note(tmp_path, capsys):
    """The scene's dt was scaled to ne2 (a note says so); a branch with --dt runs at the
    dt given, so its header no longer says dt was scaled; a plain continuation still does."""
    run = ["run", "tc2_steady", *TINY, "--days", "0.25", "-s", "output.every_days=0.25"]
    code, out, _ = cli_main(capsys, *run, "--restart-every", "0.25", "--output", "r.nc")
    assert code == 0 and "note        dt scaled with the smallest node spacing" in out
    code, out, err = cli_main(
        capsys, "run", "--continue", "r.restart.nc", "--dt", "1800", "--days", "0.5", "--device", "cpu", "--no-progress"
    )
    assert code == 0, err
    assert "dt = 1800 s" in out and "dt scaled" not in out
    code, out, _ = cli_main(
        capsys, "run", "--continue", "r.restart.nc", "--days", "0.5", "--device", "cpu", "--no-progress"
    )
    assert code == 0 and "dt scaled" in out


def test_sweep_says_the_multiple_that_ran(tmp_path, capsys):
    """``--runs rk4@0.77`` runs at the largest dt that divides the run: the note gives that
    multiple of the gravity-wave limit (sweep.csv's), not the 0.77 asked for."""
    import pandas as pd

    code, out, err = cli_main(
        capsys,
        "sweep",
        "tc2_steady",
        "--ne",
        "2",
        "--days",
        "0.25",
        "--runs",
        "rk4@0.77",
        "--device",
        "cpu",
        "--output",
        "o",
    )
    assert code == 0, err
    ran = pd.read_csv(tmp_path / "o" / "sweep.csv")["dt_over_gravity_limit"][0]
    assert abs(ran - 0.77) > 1e-3
    note = next(line for line in out.splitlines() if line.startswith("note        --runs"))
    assert note.startswith(
        f"note        --runs rk4@0.77 runs at {ran:.3g} x the gravity-wave limit (each dt the largest"
    ), note


def test_an_option_of_another_stepper_warns(tmp_path, capsys):
    """``-s implicit.method=bdf2`` with ssprk3 running was ignored silently: now one warning line."""
    code, _, err = cli_main(
        capsys,
        "run",
        "tc2_steady",
        *TINY,
        "--dt",
        "1800",
        "--days",
        "0.125",
        "-s",
        "output.every_days=0.125",
        "-s",
        "implicit.method=bdf2",
    )
    assert code == 0
    assert err.strip() == (
        "swe-sphere: warning: -s implicit.method: not an option of ssprk3, the stepper that runs; not used"
    )


def test_tc2_plots_say_they_are_against_the_exact_solution(tmp_path, capsys):
    """TC2's series panel said "against T213"; ``plot --diff T213`` said "reference file not found"."""
    from swe_sphere.studies.plotting import open_run, plot_series

    assert (
        cli_main(
            capsys,
            "run",
            "tc2_steady",
            *TINY,
            "--dt",
            "1800",
            "--days",
            "0.125",
            "-s",
            "output.every_days=0.125",
            "--output",
            "tc2.nc",
        )[0]
        == 0
    )
    ds = open_run(tmp_path / "tc2.nc")
    try:
        assert plot_series(ds).axes[1].get_title() == "error norms against the exact solution"
    finally:
        ds.close()
    cli_one_line(
        capsys,
        ["plot", "tc2.nc", "--diff", "T213"],
        2,
        "no T213 reference for this case: it is scored against its exact solution",
    )
    assert not list(tmp_path.glob("*.png"))


def test_sweep_error_axes_name_the_norm_and_field():
    from swe_sphere.studies.plotting import error_label

    assert error_label("total_error") == "total error: normalized l2 of h + hs"
    assert error_label("temporal_error_vorticity") == "temporal error: normalized l2 of vorticity"
    assert error_label("wall_time") == "wall time"


def test_the_zonal_mean_of_the_wind_at_the_poles_is_its_limit(tmp_path, capsys):
    """TC2 with its jet over the poles (α = π/4), whose zonal mean of u is u0 cos(lat) cos(α)
    (Williamson 1992 eq. 90 averaged over longitude): the pole rows were ±27.6 m/s off it at
    ne2 (east turns with longitude there), 4.6x the worst other row; now they are the limit, 0
    (v's too), exact."""
    from swe_sphere.studies.analysis import zonal_mean

    assert (
        cli_main(
            capsys,
            "run",
            "tc2_steady_alpha_pi4",
            *TINY,
            "--dt",
            "1800",
            "--days",
            "0.125",
            "-s",
            "output.every_days=0.125",
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


def test_a_continued_run_keeps_writing_restart_files(tmp_path, capsys):
    """A run with --restart-every 0.125, continued without it: the continuation writes
    its restart file at its interval (the header says so), which continues again."""
    from swe_sphere.simulation import checkpoint

    run = ["run", "tc2_steady", *TINY, "--dt", "1800", "--days", "0.125", "-s", "output.every_days=0.125"]
    assert cli_main(capsys, *run, "--restart-every", "0.125", "--output", "r.nc")[0] == 0
    assert checkpoint.read(tmp_path / "r.restart.nc").restart_every == 0.125
    code, out, err = cli_main(
        capsys, "run", "--continue", "r.restart.nc", "--days", "0.25", "--device", "cpu", "--no-progress"
    )
    assert code == 0, err
    assert "every 0.125 days and at the end" in out
    again = checkpoint.read(tmp_path / "r_continued.restart.nc")
    assert (again.step, again.restart_every) == (12, 0.125)
