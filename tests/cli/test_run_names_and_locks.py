"""``swe-sphere run`` and the commands around it as a new user meets them on a fresh clone (the first
hour's first pass): run files and their locks, the device, default run names, read-only folders;
exit 2 and one line naming the field, value or file for bad input, nothing made before the refusal."""

from __future__ import annotations

import errno
from pathlib import Path

import pytest
import warp as wp

from swe_sphere.core.backend import DEVICE_ENV
from swe_sphere.io.output_files import acquire_lock, release_lock
from swe_sphere.simulation.simulation import Simulation

from helpers import EIGHTH_DAY, TINY, cli_main, cli_one_line, one_line


@pytest.fixture(autouse=True)
def _in_tmp(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)


def test_plot_into_a_folder_on_a_read_only_file_system_is_bad_input(tc5_run_file, capsys, monkeypatch):
    """A folder to be made where the file system is mounted read-only: EROFS is neither
    a PermissionError nor a blow-up, and was answered with exit 3."""

    def read_only(self, *args, **kwargs):
        raise OSError(errno.EROFS, "Read-only file system", str(self))

    monkeypatch.setattr(Path, "mkdir", read_only)
    cli_one_line(capsys, ["plot", tc5_run_file, "--output", "figs"], 2, "figs: Read-only file system")


def test_stability_refuses_a_bad_value_before_making_its_folder(capsys):
    cli_one_line(capsys, ["stability", "galewsky", "--days", "-1", "--output", "suite"], 2, "days", "-1")
    cli_one_line(capsys, ["stability", "galewsky", "--days", "-1"], 2, "days", "-1")
    assert list(Path().iterdir()) == []


def test_two_suites_each_write_into_a_folder_of_their_own(capsys):
    """A page's two `stability` commands wrote stability.csv into the same folder: the
    second met "output file exists"."""
    for cases in (["tc5_mountain"], ["tc5_mountain", "galewsky"]):
        code, out, err = cli_main(
            capsys, "stability", *cases, "--steppers", "ssprk3", "--ne", "2", "--days", "0.5", "--device", "cpu"
        )
        assert code == 0, err
    assert sorted(str(p) for p in Path().glob("*/stability.csv")) == [
        "stability_tc5_mountain_galewsky_ne2/stability.csv",
        "stability_tc5_mountain_ne2/stability.csv",
    ]


def test_a_run_to_a_file_another_run_writes_is_refused_before_its_header(capsys):
    """The second of two runs to one file printed its 9-line header, built its model,
    then refused at the first write."""
    lock = Path("o.nc.lock")
    fd = acquire_lock(lock, "o.nc")  # as the first run's writer holds it
    try:
        code, out, err = cli_main(capsys, "run", "tc2_steady", *TINY, "--days", "0.25", "--output", "o.nc")
    finally:
        release_lock(lock, fd)
    assert out == ""
    cli_line = [line for line in err.splitlines() if line.strip()]
    assert code == 2 and cli_line == ["swe-sphere: error: another run is writing o.nc (it holds o.nc.lock)"], err
    assert sorted(p.name for p in Path().iterdir()) == []


def test_the_second_of_two_runs_started_together_is_refused_before_its_header(capsys, monkeypatch):
    """Two runs to one file started together: the second came in while the first was still
    setting up (its writer not yet made, no lock held), printed its 9-line header, then
    refused. The first now holds the lock from before its header: the second, started at
    the first's header, prints nothing, exits 2 in one line and writes nothing; the first
    finishes."""
    from swe_sphere.cli import run as cli_run

    argv = ("run", "tc2_steady", *TINY, "--days", "0.25", "--output", "o.nc")
    second = []

    def header_then_second(*args, **kwargs):
        if not second:
            second.append(cli_main(capsys, *argv))
            second.append(sorted(p.name for p in Path().iterdir()))
        return header(*args, **kwargs)

    header = cli_run.header
    monkeypatch.setattr(cli_run, "header", header_then_second)
    code, out, err = cli_main(capsys, *argv)
    (code2, out2, err2), files = second
    assert (
        out2 == "" and one_line(code2, err2, 2) == "swe-sphere: error: another run is writing o.nc (it holds o.nc.lock)"
    )
    assert files == ["o.nc.lock"]  # the first run's lock, nothing of the second's
    assert code == 0 and "tc2_steady" in out, err
    assert sorted(p.name for p in Path().iterdir()) == ["o.nc"]


def test_a_left_lock_file_of_a_killed_run_does_not_refuse(capsys):
    """The lock file of a killed run stays, unlocked: the run goes ahead."""
    Path("o.nc.lock").touch()
    code, out, err = cli_main(capsys, "run", "tc2_steady", *TINY, "--days", "0.25", "--output", "o.nc")
    assert code == 0 and Path("o.nc").is_file(), err


@pytest.mark.parametrize("device", ["tpu", "cuda:x", "CPU"])
def test_an_unknown_device_is_named_in_python(device):
    """Warp's own "Invalid device identifier" came through from deep in the set-up."""
    with pytest.raises(ValueError, match=f"^device must be 'cpu', 'cuda' or 'cuda:N' \\(got '{device}'\\)$"):
        Simulation("tc2_steady", device, ne=2)


def test_swe_sphere_device_chooses_the_device_a_run_names_none_and_a_bad_one_is_one_line(capsys, monkeypatch):
    """``SWE_SPHERE_DEVICE`` is the device of a run that names none (the suite sets it to the
    CPU: a GPU machine's tests keep their CPU runs there); --device and ``device=`` win; a bad
    value, or a CUDA device the machine lacks, is one line naming it, exit 2, nothing written."""
    monkeypatch.setenv(DEVICE_ENV, "cpu")
    assert Simulation("tc2_steady", ne=2).device == "cpu"
    monkeypatch.setenv(DEVICE_ENV, "tpu")
    with pytest.raises(ValueError, match=f"^{DEVICE_ENV} must be 'cpu', 'cuda' or 'cuda:N' \\(got 'tpu'\\)$"):
        Simulation("tc2_steady", ne=2)
    assert Simulation("tc2_steady", "cpu", ne=2).device == "cpu"  # named: the variable is not read
    run = ["run", "tc2_steady", "--ne", "2", *EIGHTH_DAY, "--output", "o.nc"]  # no --device
    line = cli_one_line(capsys, run, 2)
    assert line == f"swe-sphere: error: {DEVICE_ENV} must be 'cpu', 'cuda' or 'cuda:N' (got 'tpu')"
    monkeypatch.setenv(DEVICE_ENV, f"cuda:{wp.get_cuda_device_count()}")  # one past the last
    line = cli_one_line(capsys, run, 2)
    assert line.endswith(f"is not available on this machine (set {DEVICE_ENV}=cpu or unset it)"), line
    assert not Path("o.nc").exists()


@pytest.mark.parametrize("command", ["plot", "remap"])
@pytest.mark.parametrize("content", [b"not netCDF\n", b"\x89HDF\r\n\x1a\n" + bytes(100)], ids=["text", "cut_hdf5"])
def test_an_unreadable_file_is_named_without_the_exception_type(capsys, command, content):
    """ "junk.nc: not a readable netCDF file (ValueError)": the type told a user nothing."""
    Path("junk.nc").write_bytes(content)
    line = cli_one_line(capsys, [command, "junk.nc"], 2)
    assert line == "swe-sphere: error: junk.nc: not a readable netCDF file"


def run_names(capsys, *commands) -> list[str]:
    """The default file name of each ``run`` command line (run in order, each must succeed)."""
    names = []
    for command in commands:
        before = set(Path().glob("*.nc"))
        code, _, err = cli_main(capsys, "run", *command.split(), *TINY)
        assert code == 0, err
        (new,) = set(Path().glob("*.nc")) - before
        names.append(new.name)
    return names


def test_default_run_names_say_the_days_dt_and_planet_that_differ_from_the_scenes(capsys):
    """A page's runs of one scene at other lengths and steps, in order: each its own file
    (the default name ignored --days and --dt, and the second run met "output file exists")."""
    assert run_names(
        capsys,
        "tc2_steady",  # the scene's 5 days at its own dt for ne2
        "tc2_steady --days 0.5",
        "tc2_steady -s time.days=0.25",
        "tc2_steady --days 0.5 --dt 1800",
        "tc2_steady --days 0.05 -s planet.radius=637122 -s planet.omega=7.292e-4",
    ) == [
        "tc2_steady_ne2np4_ssprk3.nc",
        "tc2_steady_ne2np4_ssprk3_0.5d.nc",
        "tc2_steady_ne2np4_ssprk3_0.25d.nc",
        "tc2_steady_ne2np4_ssprk3_0.5d_dt1800.nc",
        "tc2_steady_ne2np4_ssprk3_a637122_omega0.0007292_0.05d.nc",
    ]
    # the dt the scene takes itself at ne2 for 0.5 days: the same run, the same name
    cli_one_line(
        capsys, ["run", "tc2_steady", "--days", "0.5", "--dt", "2400", *TINY], 2, "output file exists", "_0.5d.nc"
    )


def test_a_blown_up_runs_file_is_named_as_one_when_it_blocks_a_rerun(capsys):
    """A run that blew up keeps its good outputs; the same command again is refused with
    a line that says the file is that run's, and how to replace it."""
    command = ["run", "tc2_steady", "--days", "1", "--dt", "14400", *TINY]  # Courant number 3 with ssprk3
    assert cli_main(capsys, *command)[0] == 3
    cli_one_line(
        capsys,
        command,
        2,
        "output file exists: tc2_steady_ne2np4_ssprk3_1d_dt14400.nc, a run that ended in a blow-up at step 4 "
        "(model time 0.6667 days) (--overwrite replaces it",
    )
    assert cli_main(capsys, *command, "--dt", "1800")[0] == 0  # a smaller step: a file of its own
    assert sorted(p.name for p in Path().glob("*.nc")) == [
        "tc2_steady_ne2np4_ssprk3_1d_dt14400.nc",
        "tc2_steady_ne2np4_ssprk3_1d_dt1800.nc",
    ]


def test_a_small_planet_run_names_its_planet_and_why_dt_changed(capsys):
    """Without --ne the grid is the scene's: Δt 300 s → 30 s is the radius's doing alone,
    and the header said "scaled with the smallest node spacing" and named no planet."""
    code, out, err = cli_main(
        capsys,
        "run",
        "tc2_steady",
        "-s",
        "planet.radius=637122",
        "-s",
        "planet.omega=7.292e-4",
        "--days",  # the scene's own grid (any other, --ne or -s grid.ne, scales dt with it too)
        "0.0125",
        "-s",
        "output.every_days=0.0125",
        "--device",
        "cpu",
        "--no-progress",
    )
    assert code == 0, err
    lines = out.splitlines()
    assert "planet      radius 637122 m, omega 0.0007292 1/s, gravity 9.80616 m/s^2 (the Earth's: " in out
    assert (
        "note        dt scaled with the planet's radius (637122 m against the scene's 6.37122e+06 m) to 30 s" in lines
    )
    assert "output      tc2_steady_ne16np4_ssprk3_a637122_omega0.0007292_0.0125d.nc (every 0.0125 days)" in lines


def test_an_interrupted_run_and_its_continuation_join_without_a_repeated_time(tmp_path):
    """Both files held the interrupt time: joined with ``xr.open_mfdataset`` (or ``cdo
    mergetime``) it appeared twice. The continuation leaves it to the first file; joined,
    they are the uninterrupted run's file, bit for bit."""
    import os
    import signal

    import numpy as np
    import xarray as xr

    from swe_sphere.config.scene import load_scene
    from swe_sphere.core.errors import Interrupted

    scene = load_scene("tc2_steady", ne=2, np_=4, days=1.0, overrides={"output.every_days": 0.25})
    first = Simulation(scene, "cpu", progress=False)
    first.add_callback(lambda sim: os.kill(os.getpid(), signal.SIGINT), every_steps=7)  # between output times
    with pytest.raises(Interrupted):
        first.run(tmp_path / "first.nc")
    Simulation.from_checkpoint(tmp_path / "first.restart.nc", "cpu", progress=False).run(tmp_path / "cont.nc")
    Simulation(scene, "cpu", progress=False).run(tmp_path / "whole.nc")
    step = scene.dt * 7 / 86400
    with (
        xr.open_mfdataset(
            [tmp_path / "first.nc", tmp_path / "cont.nc"],
            decode_times=False,
            data_vars="minimal",
            coords="minimal",
            compat="override",
        ) as joined,
        xr.open_dataset(tmp_path / "whole.nc", decode_times=False) as whole,
    ):
        assert joined.time.values.tolist() == [0.0, step, 0.25, 0.5, 0.75, 1.0]
        for day in whole.time.values:
            np.testing.assert_array_equal(joined.h.sel(time=day).values, whole.h.sel(time=day).values)


README_OUTPUTS = (  # what the README's commands write in a clone's top folder
    "tc5_mountain_ne30np4_rk4.nc",
    "tc5_r.restart.nc",
    "tc5.nc.part",
    "tc5.nc.lock",
    "sweep_tc5/sweep.csv",
    "sweep_tc5/verdicts.csv",
    "sweep_tc5_mountain_ne16np4_15d/runs/rk4_211_x.npz",
    "sweep_tc5_mountain_ne16np4_15d/sweep.lock",
    "stability_tc5_mountain_galewsky_ne8/stability.csv",
    "figs/tc5_vorticity_day5.png",
    "tc5_series.png",
    "tc5_spectrum_day0_5.csv",
    "galewsky.nc",
    "docs/galewsky_series.png",
    "galewsky_6h_vorticity_lat0to90.gif",
)


@pytest.mark.skipif(not (Path(__file__).parents[2] / ".git").exists(), reason="not a git checkout")
def test_what_the_readme_writes_in_a_clone_is_ignored_by_git():
    import subprocess

    root = Path(__file__).parents[2]
    proc = subprocess.run(
        ["git", "-C", str(root), "check-ignore", "--no-index", *README_OUTPUTS], capture_output=True, text=True
    )
    assert sorted(proc.stdout.split()) == sorted(README_OUTPUTS), proc.stderr
    kept = [
        "testcases/tc5_mountain.toml",
        "testcases/reference/tc5_mountain_T213.nc",
        "docs/explanation/efficiency/tc5_ne30_temporal_error.png",
        "docs/galewsky_vorticity_day6_lat0to90.png",  # the README's picture
    ]
    assert (
        subprocess.run(["git", "-C", str(root), "check-ignore", "--no-index", *kept], capture_output=True).returncode
        == 1
    )


def test_a_scene_that_loads_only_with_its_overrides_still_gets_a_name(capsys):
    """A scene file without time.dt runs with -s time.dt=...; its name could not be made
    by loading the file alone."""
    from helpers import write_tc2_scene

    path = write_tc2_scene(Path("nodt.toml"), dt=1800.0, days=0.25)
    path.write_text(path.read_text().replace("dt = 1800.0\n", ""))
    assert run_names(capsys, "nodt.toml -s time.dt=1800") == ["nodt_ne2np4_ssprk3_dt1800.nc"]


FOLDER_OR_NOT_THE_FORMAT = [
    (["run", "adir.nc"], "adir.nc: is a directory"),
    (["run", "tc2_steady", "-s", "case.name=file", "-s", "case.path=adir.nc", "-s", "case.time=0"], "is a directory"),
    (["run", "tc2_steady", "--continue", "adir.nc"], "checkpoint adir.nc is a directory"),
    (["run", "tc2_steady", "--mesh", "adir.nc"], "adir.nc is a directory"),
    (["plot", "adir.nc"], "adir.nc: is a directory"),
    (["run", "binary.toml"], "scene binary.toml is not a text (UTF-8) file"),
    (["run", "tc2_steady", "--mesh", "notamesh.g"], "notamesh.g is not a netCDF file"),
]


@pytest.mark.parametrize("args, words", FOLDER_OR_NOT_THE_FORMAT, ids=lambda a: " ".join(a)[:40])
def test_a_folder_or_a_file_of_another_format_is_named_as_such(capsys, args, words):
    """A folder was reported "not found"; a binary scene, a mesh that is not netCDF gave
    Python's, numpy's or netCDF's wording (issue 65, item 4)."""
    Path("adir.nc").mkdir()
    Path("binary.toml").write_bytes(b"\xff\xfe[time]\n")
    Path("notamesh.g").write_text("not netCDF")
    cli_one_line(capsys, [*args, *TINY[4:]] if args[0] == "run" else args, 2, words)
    assert sorted(p.name for p in Path().iterdir()) == ["adir.nc", "binary.toml", "notamesh.g"]


OPTIONS_BEFORE_FILES = [
    (["run", "tc2_steady", *TINY, "--graphs", "maybe", "--output", "x.nc"], "--graphs must be one of"),
    (["run", "tc2_steady", *TINY, "--restart-every", "0", "--output", "x.nc"], "--restart-every must be a number"),
    (
        ["run", "tc2_steady", *TINY, "--dt", "3600", "--restart-every", "0.3", "--output", "x.nc"],
        "restart interval of 0.3 days",
    ),
    (["mesh", "--ne", "2", "--target-lat", "30", "--output", "x.g"], "they need stretch_factor"),
    (["mesh", "--ne", "2", "--output", "x.nc"], "an Exodus II mesh, its name must end in .g or .exo"),
    (["run", "", *TINY, "--output", "y.nc"], "the scene name is empty"),
]
if wp.get_cuda_device_count() == 0:
    OPTIONS_BEFORE_FILES.append((["run", "tc2_steady", "--device", "cuda", "--output", "x.nc"], "device cuda is not"))


@pytest.mark.parametrize("args, words", OPTIONS_BEFORE_FILES, ids=[w for _, w in OPTIONS_BEFORE_FILES])
def test_a_command_names_what_is_wrong_with_its_options_before_its_files(capsys, args, words):
    """With the output file there, a bad --graphs, --restart-every or --device was answered
    "output file exists" (issue 86, item 4); ``mesh --output m.nc`` wrote an Exodus file under a
    run file's name, and ``run ""`` said "cannot read scene .: is a directory" (item 5)."""
    Path("x.nc").write_text("mine")
    Path("x.g").write_text("mine")
    line = cli_one_line(capsys, args, 2, words)
    assert "exists" not in line, line
    assert sorted(p.name for p in Path().iterdir()) == ["x.g", "x.nc"]
    assert Path("x.nc").read_text() == Path("x.g").read_text() == "mine"
