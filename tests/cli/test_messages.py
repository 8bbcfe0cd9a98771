"""Messages a new user met: each one line, exit 2, naming the value."""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

import netCDF4
import pytest

from swe_sphere import cli
from swe_sphere.cli import main
from swe_sphere.config.scene import load_scene

TINY = ("--ne", "2", "--np", "4", "--device", "cpu", "--no-progress")
ROOT = Path(__file__).resolve().parents[2]


def one_line(capsys, argv, *words):
    """Run the CLI in-process; assert exit 2 and one stderr line holding ``words``; return it."""
    try:
        code = main([str(a) for a in argv])
    except SystemExit as exc:  # argparse
        code = exc.code
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.strip()]
    assert code == 2, (code, err)
    assert len(lines) == 1 and "Traceback" not in err, err
    for w in words:
        assert w in lines[0], (w, lines[0])
    return lines[0]


def digest(path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def test_an_output_interval_of_no_whole_steps_names_dt_its_source_and_what_works(capsys, tmp_path):
    """tc5_mountain's dt is 86400/408 s: 0.3 days is 122.4 steps. The message said
    "dt = 211.765 s does not divide the output interval", blaming a dt never set."""
    one_line(
        capsys,
        ["run", "tc5_mountain", "--days", "1", "-s", "output.every_days=0.3", "--output", tmp_path / "o.nc"],
        "output interval (output.every_days) of 0.3 days is not a whole number of steps",
        "dt = 211.765 s (time.dt of scene tc5_mountain)",
        "multiples of 0.125 days (nearest: 0.25 or 0.375)",
    )
    one_line(
        capsys,
        [
            "run",
            "tc2_steady",
            *TINY,
            "--dt",
            "1000",
            "--days",
            "5",
            "-s",
            "output.every_days=0.3",
            "--output",
            tmp_path / "o.nc",
        ],
        "dt = 1000 s (the dt given)",
        "multiples of 0.3125 days (nearest: 0.3125)",
    )
    one_line(
        capsys,
        ["run", "tc5_mountain", "--days", "1.3", "--output", tmp_path / "o.nc"],
        "run length of 1.3 days is not a whole number of steps",
        "(nearest: 1.25 or 1.375)",
    )
    assert list(tmp_path.iterdir()) == []


def test_a_scaled_dt_divides_both_the_output_interval_and_the_run_length():
    """With --ne, dt is chosen by the model: it divides 0.3 days and 1.07 days (their
    greatest common divisor, 0.01 days), so the run writes at whole steps."""
    scene = load_scene("tc5_mountain", ne=8, days=1.07, overrides={"output.every_days": 0.3})
    assert scene.dt == 432.0  # 794 s scaled from ne30, cut to 0.01 days / 2
    assert (0.3 * 86400 / scene.dt, scene.nsteps) == (60.0, 214)
    wide = load_scene("tc5_mountain", ne=8, days=1.001, overrides={"output.every_days": 0.3})  # gcd 0.001 days
    assert wide.dt == 86.4 and any(
        "to divide both the output interval of 0.3 and the run length of 1.001 days" in n for n in wide.notes
    )


@pytest.mark.parametrize("command", ["run tc2_steady", "plot x.nc", "remap x.nc", "sweep tc2_steady", "stability"])
def test_an_empty_output_path_is_named(capsys, command):
    one_line(capsys, [*command.split(), "--output", ""], "argument --output: empty path")


def test_a_mistyped_scene_name_gets_a_suggestion(capsys, tmp_path):
    one_line(
        capsys,
        ["run", "tc5_mountian", *TINY, "--output", tmp_path / "o.nc"],
        "scene file not found: tc5_mountian (did you mean tc5_mountain",
    )


def test_stability_help_lists_its_case_labels(capsys):
    from swe_sphere.studies.stability import HARD_CASES

    assert cli.STABILITY_CASES == tuple(label for label, *_ in HARD_CASES)
    with pytest.raises(SystemExit):
        main(["stability", "--help"])
    out = " ".join(capsys.readouterr().out.split())
    for label in cli.STABILITY_CASES:
        assert label in out, label


@pytest.fixture(scope="module")
def runs(tmp_path_factory, tc5_run_file):
    """a/run.nc and b/run.nc: TC5 ne2 runs of 1 day and 0.5 days (another picture, the same name);
    the day's run is the session's (tests/conftest.py ``tc5_run_file``: the same command), copied."""
    d = tmp_path_factory.mktemp("msg")
    for folder in ("a", "b"):
        (d / folder).mkdir()
    shutil.copy(tc5_run_file, d / "a" / "run.nc")
    assert main(["run", "tc5_mountain", *TINY, "--days", "0.5", "--output", str(d / "b" / "run.nc")]) == 0
    return d


def test_plot_diff_after_plot_keeps_the_same_series_figure(runs, tmp_path, capsys):
    """A plain plot, then plot --diff into the same folder: the series figure (the same
    picture) was refused as existing; now kept, byte for byte. (Another field into a folder
    holding the same series: tests/studies/test_plotting.py's
    test_a_series_written_over_another_is_drawn_once_as_a_fresh_plot_draws_it.)"""
    shutil.copy(runs / "a" / "run.nc", tmp_path / "other.nc")
    out = tmp_path / "figs"
    assert main(["plot", str(runs / "a" / "run.nc"), "--output", str(out)]) == 0
    series = digest(out / "run_series.png")
    assert main(["plot", str(runs / "a" / "run.nc"), "--diff", str(tmp_path / "other.nc"), "--output", str(out)]) == 0
    assert sorted(p.name for p in out.iterdir()) == [
        "run_h_surface_day1.png",
        "run_h_surface_day1_diff.png",
        "run_series.png",
    ]
    assert digest(out / "run_series.png") == series
    capsys.readouterr()
    # another run's series figure of the same name is still refused, and kept
    one_line(
        capsys, ["plot", runs / "b" / "run.nc", "--field", "v", "--output", out], "output file exists", "run_series.png"
    )
    assert digest(out / "run_series.png") == series and not (out / "run_v_day0.5.png").exists()


def test_grid_and_step_attributes_are_numbers(runs):
    """ne, np, mpi_ranks as 32-bit integers (NC_INT, which classic-model tools read
    as numbers; the 64-bit type read as text in CDO), dt as a double."""
    with netCDF4.Dataset(runs / "a" / "run.nc") as ds:
        for name in ("ne", "np", "mpi_ranks"):
            assert ds.getncattr(name).dtype == "int32", name
        assert (int(ds.ne), int(ds.getncattr("np")), ds.getncattr("dt").dtype) == (2, 4, "float64")


def test_mpi_without_mpi4py_names_the_extra(tmp_path):
    """Under mpiexec (PMI_SIZE) with mpi4py missing: one line naming the mpi extra, exit 2."""
    fake = tmp_path / "site" / "mpi4py"
    fake.mkdir(parents=True)
    (fake / "__init__.py").write_text("raise ImportError('No module named mpi4py')\n")
    env = {
        **os.environ,
        "PMI_SIZE": "2",
        "PYTHONPATH": os.pathsep.join([str(tmp_path / "site"), os.environ.get("PYTHONPATH", "")]),
    }
    p = subprocess.run(
        [
            sys.executable,
            "-m",
            "swe_sphere.cli",
            "run",
            "tc2_steady",
            *TINY,
            "--days",
            "1",
            "--output",
            str(tmp_path / "o.nc"),
        ],
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    lines = [line for line in p.stderr.splitlines() if line.strip()]
    assert p.returncode == 2 and len(lines) == 1, p.stderr
    assert "mpi4py cannot be imported" in lines[0] and "pip install 'swe-sphere[mpi]'" in lines[0]
    assert not (tmp_path / "o.nc").exists()


def test_the_mpi_extra_installs_mpi_and_the_test_extra_keeps_it():
    extras = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["optional-dependencies"]
    assert extras["mpi"] == ["mpich", "mpi4py>=4"]
    assert set(extras["mpi"]) <= set(extras["test"])
