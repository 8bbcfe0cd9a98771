"""No output replaces an input or an earlier result, through the command line (in this process:
its exit status and one line; tests/cli/test_console_script.py runs the installed console script)
and through the API: an output named as an input (the same name, a link or a hard link) is
refused whatever the command; an earlier sweep's, stability suite's, plot's or restart file is
kept unless --overwrite; a second sweep into a folder is refused at its start, the two sweeps
real processes (the folder's lock between them); a damaged restart file or a runaway ∇⁴ is
refused before anything is written. Each refusal is one line, exit 2, the input's bytes
unchanged."""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import pytest

from swe_sphere.cli import main
from swe_sphere.studies import stability, sweep

from helpers import TINY, TINY_SWEEP, cli_main, cli_one_line, console_script, digest, one_line


@pytest.mark.parametrize("name", sweep.OUTPUTS)
def test_sweep_keeps_an_earlier_studys_results(tmp_path, capsys, name, monkeypatch):
    """Each of an earlier sweep's results in --output refuses the sweep before any run
    (no runs/ folder), and is kept as it was; --overwrite is named as the way on."""
    monkeypatch.chdir(tmp_path)
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
def test_stability_keeps_an_earlier_suites_results(tmp_path, capsys, name, monkeypatch):
    monkeypatch.chdir(tmp_path)
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


def console(cwd, *args, timeout=120):
    """The installed console script in ``cwd``: a process of its own."""
    env = {**os.environ, "SWE_SPHERE_THREADS": "1"}
    return subprocess.run(
        [console_script(), *map(str, args)], cwd=cwd, capture_output=True, text=True, timeout=timeout, env=env
    )


@pytest.fixture
def cli(capsys, monkeypatch):
    """``cli(cwd, *args)``: the command line in this process, run in ``cwd``, as a finished
    process (its exit status, stdout and stderr): a process of its own imported the model
    again, a second of CPU each (the refusals are the command's, not the process's)."""

    def run(cwd, *args) -> subprocess.CompletedProcess:
        monkeypatch.chdir(cwd)
        code, out, err = cli_main(capsys, *args)
        return subprocess.CompletedProcess(args, code, out, err)

    return run


def refused(proc, *words):
    one_line(proc.returncode, proc.stderr, 2, *words)


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    """A one-day ne2 run with its restart file."""
    d = tmp_path_factory.mktemp("run")
    assert main(["run", "tc5_mountain", *TINY, "--days", "1", "--restart-every", "1", "--output", str(d / "a.nc")]) == 0
    return d


@pytest.mark.parametrize(
    "argv",
    [
        ("run", "--continue", "a.restart.nc", "--days", "2", "--output", "a.restart.nc", "--overwrite"),
        ("run", "--continue", "a.restart.nc", "--days", "2", "--output", "a.nc", "--overwrite"),  # its restart sibling
        ("remap", "a.nc", "--output", "a.nc", "--overwrite"),
        ("remap", "link.nc", "--output", "a.nc", "--overwrite"),
        ("remap", "a.nc", "--output", "hard.nc", "--overwrite"),
    ],
)
def test_an_output_never_replaces_an_input(run_dir, cli, argv):
    for name, make in (("link.nc", os.symlink), ("hard.nc", os.link)):
        if not (run_dir / name).exists():
            make(run_dir / "a.nc", run_dir / name)
    before = {p: digest(run_dir / p) for p in ("a.nc", "a.restart.nc")}
    sibling = argv[:2] == ("run", "--continue") and argv[-2] == "a.nc"  # named as --output's restart file
    refused(cli(run_dir, *argv), "the file --continue reads" if sibling else "is the input")
    assert {p: digest(run_dir / p) for p in before} == before
    assert not list(run_dir.glob("*.part")) and not list(run_dir.glob("*.lock"))


def test_the_api_refuses_its_scene_file_as_output(tmp_path):
    import swe_sphere
    from swe_sphere.core.errors import OutputError

    scene = tmp_path / "s.toml"
    shutil.copy(Path(swe_sphere.__file__).parent.parent / "testcases" / "tc2_steady.toml", scene)
    before = digest(scene)
    with pytest.raises(OutputError, match="is the input"):
        swe_sphere.run(scene, ne=2, days=1, device="cpu", output_file=scene, overwrite=True)
    assert digest(scene) == before


def test_a_second_sweep_into_one_folder_is_refused_at_its_start(tmp_path, paused):
    """The first sweep holds the folder's lock from its start (here held after its
    first run's first step); the second exits 2 before computing anything, and the
    first, let go, finishes."""
    argv = (
        *TINY_SWEEP,
        "--output",
        "deep/sw",
    )
    first = paused("step:1", tmp_path, *argv)
    lock = tmp_path / "deep" / "sw" / "sweep.lock"
    assert lock.exists()
    refused(console(tmp_path, *argv, timeout=120), "another run is writing", "sweep.lock")
    first.go()
    err = first.communicate(timeout=300)[1]
    assert first.returncode == 0, err
    assert (tmp_path / "deep" / "sw" / "sweep.nc").is_file() and not lock.exists()


def test_stability_creates_its_output_folder(tmp_path, cli):
    # one day, not the scene's 15: the folder and its two files are the same (3.0 -> 2.2 s of CPU)
    proc = cli(
        tmp_path,
        "stability",
        "tc5_mountain",
        "--steppers",
        "ssprk3",
        "--ne",
        "2",
        "--days",
        "1",
        "--device",
        "cpu",
        "--output",
        "new/dir",
    )
    assert proc.returncode == 0, proc.stderr
    assert sorted(p.name for p in (tmp_path / "new" / "dir").iterdir()) == ["stability.csv", "stability.nc"]


def test_a_runaway_hyperviscosity_is_refused_before_the_run(tmp_path, cli):
    refused(
        cli(tmp_path, "run", "tc5_mountain", *TINY, "-s", "hyperviscosity.nu=1e30", "--output", "nu.nc"),
        "explicit bound",
        "lower hyperviscosity.nu",
    )
    assert list(tmp_path.iterdir()) == []


def test_a_scrambled_restart_file_is_refused(run_dir, tmp_path, cli):
    """400 bytes of the state's data scrambled: the Fletcher-32 checksum names the variable."""
    import netCDF4
    import numpy as np

    with netCDF4.Dataset(run_dir / "a.restart.nc") as ds:
        raw = np.asarray(ds["u"][:], dtype=np.float64).tobytes()
    data = bytearray((run_dir / "a.restart.nc").read_bytes())
    at = data.find(raw[:64])
    assert at > 0
    data[at + 1000 : at + 1400] = np.random.default_rng(1).integers(0, 256, 400, dtype=np.uint8).tobytes()
    bad = tmp_path / "s.restart.nc"
    bad.write_bytes(bytes(data))
    before = digest(bad)
    refused(
        cli(tmp_path, "run", "--continue", bad, "--days", "2", "--output", "o.nc", "--no-progress"),
        "variable u",
        "checksum",
    )
    assert digest(bad) == before and not (tmp_path / "o.nc").exists()


@pytest.mark.parametrize(
    "row, value, words",
    [
        (2, -10.0, "variable h holds a depth h = -10"),
        (0, 5e4, "variables u, v hold a wind of 5e+04 m/s"),
        (1, float("nan"), "variable v holds 1 non-finite"),
    ],
)
def test_a_restart_file_with_a_bad_state_is_refused(run_dir, tmp_path, cli, row, value, words):
    """A checkpoint whose hash matches (as the API would write it) but whose state
    no run makes: a negative depth, a wind far beyond the gravity-wave speed, a NaN."""
    import netCDF4

    from swe_sphere.io.restart_file import content_hash
    from swe_sphere.simulation.checkpoint import read

    bad = tmp_path / "bad.restart.nc"
    shutil.copy(run_dir / "a.restart.nc", bad)
    ck = read(bad)
    ck.x[row, 5] = value
    with netCDF4.Dataset(bad, "a") as ds:
        ds["uvh"[row]][:] = ck.x[row]
        ds.content_sha256 = content_hash(ck.step, ck.x, ck.stepper_state)
    refused(cli(tmp_path, "run", "--continue", bad, "--days", "2", "--output", "o.nc", "--no-progress"), words)
    assert not (tmp_path / "o.nc").exists()


def test_plot_refuses_existing_pngs_unless_overwrite(run_dir, tmp_path, cli):
    """A second plot into one folder replaced its PNGs silently: now one line, exit 2,
    the PNGs' bytes unchanged; --overwrite replaces them (divergence maps included). The
    earlier plot's PNGs are stand-ins of the names it writes (one plot fewer, 4 s of
    CPU of this test's 12.5): the refusal reads the names; the plot with --overwrite then
    writes exactly those files, each replaced."""
    argv = ("plot", run_dir / "a.nc", "--field", "h", "divergence", "--output", tmp_path)
    names = ["a_divergence_day1.png", "a_h_day1.png", "a_series.png"]
    for name in names:
        (tmp_path / name).write_text(f"an earlier plot's {name}")
    pngs = {p.name: digest(p) for p in tmp_path.glob("*.png")}
    refused(cli(tmp_path, *argv), "output file exists", "a_h_day1.png", "--overwrite")
    assert {p.name: digest(p) for p in tmp_path.glob("*.png")} == pngs
    assert cli(tmp_path, *argv, "--overwrite").returncode == 0
    replaced = {p.name: digest(p) for p in tmp_path.glob("*.png")}
    assert sorted(replaced) == names and all(replaced[n] != pngs[n] for n in names)


def test_an_existing_restart_file_blocks_only_a_run_that_writes_one(run_dir, tmp_path, cli):
    """Without --restart-every a run writes its restart file only on a signal: an
    existing one beside the output neither blocks it nor is replaced; with
    --restart-every it is refused in one line. The API alike."""
    import swe_sphere

    for stem in ("o", "q"):
        shutil.copy(run_dir / "a.restart.nc", tmp_path / f"{stem}.restart.nc")
    before = digest(tmp_path / "o.restart.nc")
    assert cli(tmp_path, "run", "tc2_steady", *TINY, "--days", "1", "--output", "o.nc").returncode == 0
    (tmp_path / "o.nc").unlink()
    refused(
        cli(tmp_path, "run", "tc2_steady", *TINY, "--days", "1", "--restart-every", "1", "--output", "o.nc"),
        "output file exists",
        "o.restart.nc",
    )
    ds = swe_sphere.run("tc2_steady", ne=2, days=1, device="cpu", output_file=tmp_path / "q.nc")
    assert ds.sizes["time"] == 2 and (tmp_path / "q.nc").is_file()
    assert digest(tmp_path / "o.restart.nc") == before == digest(tmp_path / "q.restart.nc")
