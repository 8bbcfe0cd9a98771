"""Nothing a user does loses data (issue 24), through the installed console script
as a real subprocess: an output never replaces an input (same name, a link or a
hard link), whatever the command; each refusal is one line, exit 2, and the
input's bytes are unchanged."""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from conftest import TINY, one_line

SCRIPT = Path(sys.executable).with_name("swe-sphere")
SCRIPT = str(SCRIPT) if SCRIPT.is_file() else shutil.which("swe-sphere")


def cli(cwd, *args, timeout=120):
    assert SCRIPT is not None, "the swe-sphere console script is not installed (pip install -e .[test])"
    env = {**os.environ, "SWE_SPHERE_THREADS": "1"}
    return subprocess.run([SCRIPT, *map(str, args)], cwd=cwd, capture_output=True, text=True, timeout=timeout, env=env)


def digest(path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def refused(proc, *words):
    one_line(proc.returncode, proc.stderr, 2, *words)


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    """A one-day ne2 run with its restart file."""
    d = tmp_path_factory.mktemp("run")
    proc = cli(d, "run", "tc5_mountain", *TINY, "--days", "1", "--restart-every", "1", "--output", "a.nc")
    assert proc.returncode == 0, proc.stderr
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
def test_an_output_never_replaces_an_input(run_dir, argv):
    for name, make in (("link.nc", os.symlink), ("hard.nc", os.link)):
        if not (run_dir / name).exists():
            make(run_dir / "a.nc", run_dir / name)
    before = {p: digest(run_dir / p) for p in ("a.nc", "a.restart.nc")}
    refused(cli(run_dir, *argv), "is the input")
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
        "sweep",
        "tc2_steady",
        "--ne",
        "2",
        "--days",
        "1",
        "--steppers",
        "ssprk3",
        "--dt",
        "1800,3600",
        "--device",
        "cpu",
        "--output",
        "deep/sw",
    )
    first = paused("step:1", tmp_path, *argv)
    lock = tmp_path / "deep" / "sw" / "sweep.lock"
    assert lock.exists()
    refused(cli(tmp_path, *argv, timeout=120), "another run is writing", "sweep.lock")
    first.go()
    err = first.communicate(timeout=300)[1]
    assert first.returncode == 0, err
    assert (tmp_path / "deep" / "sw" / "sweep.nc").is_file() and not lock.exists()


def test_stability_creates_its_output_folder(tmp_path):
    proc = cli(
        tmp_path,
        "stability",
        "tc5_mountain",
        "--steppers",
        "ssprk3",
        "--ne",
        "2",
        "--device",
        "cpu",
        "--output",
        "new/dir",
    )
    assert proc.returncode == 0, proc.stderr
    assert sorted(p.name for p in (tmp_path / "new" / "dir").iterdir()) == ["stability.csv", "stability.nc"]


def test_api_errors_are_importable_and_name_the_api():
    import swe_sphere
    from swe_sphere.config import scene as config
    from swe_sphere.io import run_file as output

    assert swe_sphere.SceneError is config.SceneError and swe_sphere.OutputError is output.OutputError
    for name in ("CheckpointError", "BlowUp", "Interrupted", "StepFailure", "ResourceError"):
        assert issubclass(getattr(swe_sphere, name), Exception)
    with pytest.raises(swe_sphere.SceneError, match=r"ne must be an integer >= 1 \(got '8', a str\)"):
        swe_sphere.run("tc2_steady", ne="8", days=1, device="cpu")
    with pytest.raises(swe_sphere.SceneError, match=r"dt must be > 0 \(got '60', a str\)"):
        swe_sphere.run("tc2_steady", ne=2, dt="60", days=1, device="cpu")


def test_sigterm_inside_a_step_that_never_ends_abandons_it(tmp_path, paused):
    """A first step that never ends (the stepper's real steps repeated; the signal
    sent once it is inside) is abandoned 1 s after SIGTERM: exit 143, one line, and
    a valid output with the t = 0 state and the interruption in its attributes."""
    import signal

    import xarray as xr

    proc = paused("inside-step", tmp_path, "run", "tc5_mountain", *TINY, "--days", "1", "--output", "long.nc")
    proc.send_signal(signal.SIGTERM)
    err = proc.communicate(timeout=120)[1]
    one_line(proc.returncode, err, 143, "interrupted by SIGTERM at step 0", "step 1 abandoned after 1 s")
    with xr.open_dataset(tmp_path / "long.nc") as ds:
        assert ds.attrs["interrupted"] == "SIGTERM" and ds.attrs["interrupted_at_step"] == 0
        assert ds.sizes["time"] == 1 and float(ds.h.min()) > 0
    assert not list(tmp_path.glob("*.part")) and not list(tmp_path.glob("*.lock"))


@pytest.mark.parametrize("sig, code", [("SIGINT", 130), ("SIGTERM", 143)])
def test_a_signal_during_start_up_is_one_line(tmp_path, paused, sig, code):
    """Ctrl-C while Warp was being imported gave two or three tracebacks ("partially
    initialized module 'warp'"), exit 1: now one line, 130 (SIGTERM 143), no file."""
    import signal

    proc = paused("start-up", tmp_path, "run", "tc2_steady", *TINY, "--days", "1", "--output", "o.nc")
    proc.send_signal(getattr(signal, sig))
    err = proc.communicate(timeout=120)[1]
    one_line(proc.returncode, err, code, f"interrupted by {sig}", "no output was written")
    assert list(tmp_path.iterdir()) == []


def test_a_runaway_hyperviscosity_is_refused_before_the_run(tmp_path):
    refused(
        cli(tmp_path, "run", "tc5_mountain", *TINY, "-s", "hyperviscosity.nu=1e30", "--output", "nu.nc"),
        "explicit bound",
        "lower hyperviscosity.nu",
    )
    assert list(tmp_path.iterdir()) == []


def test_a_scrambled_restart_file_is_refused(run_dir, tmp_path):
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
def test_a_restart_file_with_a_bad_state_is_refused(run_dir, tmp_path, row, value, words):
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


def test_more_threads_than_cpus_are_clamped_with_a_note(tmp_path, monkeypatch):
    import warp as wp

    from swe_sphere.core.backend import Backend
    from swe_sphere.core.workers import cpus

    monkeypatch.setenv("SWE_SPHERE_THREADS", "1000")
    wp.init()
    cpu = Backend.of("cpu")
    assert cpu.threads() == cpus()
    assert (
        cpu.threads_note()
        == f"SWE_SPHERE_THREADS=1000 is more than the {cpus()} CPUs this process may run on: {cpus()} threads"
    )
    monkeypatch.setenv("SWE_SPHERE_THREADS", "1")
    assert cpu.threads() == 1 and cpu.threads_note() is None


def test_plot_refuses_existing_pngs_unless_overwrite(run_dir, tmp_path):
    """A second plot into one folder replaced its PNGs silently: now one line, exit 2,
    the PNGs' bytes unchanged; --overwrite replaces them (divergence maps included)."""
    argv = ("plot", run_dir / "a.nc", "--field", "h", "divergence", "--output", tmp_path)
    assert cli(tmp_path, *argv).returncode == 0
    pngs = {p.name: digest(p) for p in tmp_path.glob("*.png")}
    assert sorted(pngs) == ["a_divergence_day1.png", "a_h_day1.png", "a_series.png"]
    refused(cli(tmp_path, *argv), "output file exists", "a_h_day1.png", "--overwrite")
    assert {p.name: digest(p) for p in tmp_path.glob("*.png")} == pngs
    assert cli(tmp_path, *argv, "--overwrite").returncode == 0


def test_an_existing_restart_file_blocks_only_a_run_that_writes_one(run_dir, tmp_path):
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


def test_a_cold_kernel_cache_is_announced_once_on_a_terminal(tmp_path):
    """A cold Warp cache cost seconds of a tiny run without a word: on a terminal,
    one line says kernels are being compiled and where they are cached; a warm
    cache says nothing (and a piped stderr never gets the note)."""
    import pty

    def stderr_on_a_tty(output):
        master, slave = pty.openpty()
        env = {**os.environ, "SWE_SPHERE_THREADS": "1", "WARP_CACHE_PATH": str(tmp_path / "cache")}
        proc = subprocess.run(
            [SCRIPT, "run", "tc1_cosine_bell", *TINY, "--days", "1", "--output", output],
            cwd=tmp_path,
            stdout=subprocess.DEVNULL,
            stderr=slave,
            env=env,
            timeout=300,
        )
        os.close(slave)
        chunks = []
        while True:
            try:
                chunk = os.read(master, 4096)
            except OSError:  # EIO: the terminal's other end is closed and drained
                break
            if not chunk:
                break
            chunks.append(chunk)
        os.close(master)
        assert proc.returncode == 0, chunks
        return b"".join(chunks).decode().splitlines()

    lines = stderr_on_a_tty("cold.nc")
    assert len(lines) == 1 and lines[0].startswith("swe-sphere: compiling Warp kernels (first use; cached in "), lines
    assert str(tmp_path / "cache") in lines[0]
    assert stderr_on_a_tty("warm.nc") == []


def test_a_run_longer_than_a_day_says_so_at_its_start(tmp_path):
    """864 million steps of ne16 (~4 ms each on one thread; a day's wall time at
    0.1 ms, 40 times faster): one note on stderr, from the steps after the first,
    that the run will take days; then SIGTERM ends it."""
    import signal
    import threading

    env = {**os.environ, "SWE_SPHERE_THREADS": "1"}
    proc = subprocess.Popen(
        [
            SCRIPT,
            "run",
            "tc2_steady",
            "--ne",
            "16",
            "--device",
            "cpu",
            "--no-progress",
            "--days",
            "1000",
            "--dt",
            "0.1",
            "--output",
            "long.nc",
        ],
        cwd=tmp_path,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
    )
    guard = threading.Timer(120, proc.kill)  # no note: the test fails instead of waiting for the run
    guard.start()
    try:
        note = proc.stderr.readline()
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=60)
    finally:
        guard.cancel()
        if proc.poll() is None:
            proc.kill()
    assert note.startswith("swe-sphere: note: this run will take about ") and "days of wall time to day 1000" in note, (
        note
    )
    assert "s a step over steps 2-4; 863999996 steps left" in note, note
    assert proc.returncode == 143 and err.count("\n") == 1 and "interrupted by SIGTERM" in err, err


def test_a_signal_after_the_output_is_complete_exits_130_in_one_line(tmp_path):
    """SIGINT once the run's output was closed (here while the process waits to
    write its summary into a full pipe) ended it with status -2 and no word, or
    with a traceback: now one line, exit 130, the output whole."""
    import signal
    import time

    import xarray as xr

    read, write = os.pipe()
    os.set_blocking(write, False)
    try:
        while True:  # fill the pipe: the run's stdout (block-buffered) waits at its first flush, at the end
            os.write(write, b"." * 4096)
    except BlockingIOError:
        pass
    os.set_blocking(write, True)
    env = {k: v for k, v in os.environ.items() if k != "PYTHONUNBUFFERED"} | {"SWE_SPHERE_THREADS": "1"}
    proc = subprocess.Popen(
        [SCRIPT, "run", "tc2_steady", *TINY, "--days", "1", "--output", "o.nc"],
        cwd=tmp_path,
        stdout=write,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
    )
    os.close(write)
    try:
        wchan = Path(f"/proc/{proc.pid}/wchan")  # the kernel function the main thread sleeps in (Linux)
        deadline = time.monotonic() + 300
        while not (
            (tmp_path / "o.nc").exists() and "pipe" in wchan.read_text()
        ):  # its output closed, its summary waiting
            assert proc.poll() is None, proc.communicate()
            assert time.monotonic() < deadline, f"never seen waiting on the full pipe ({wchan}: {wchan.read_text()!r})"
            time.sleep(0.1)
        proc.send_signal(signal.SIGINT)
        with os.fdopen(read, "rb") as pipe:
            out = pipe.read()
        err = proc.communicate(timeout=60)[1]
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130, err
    assert err.splitlines() == [
        "swe-sphere: interrupted by SIGINT after the command had finished; its output is complete"
    ], err
    assert b"  output      o.nc" in out
    with xr.open_dataset(tmp_path / "o.nc") as ds:
        assert ds.sizes["time"] == 2 and "interrupted" not in ds.attrs
    assert sorted(p.name for p in tmp_path.iterdir()) == ["o.nc"]


LAST_OUTPUT_SIGNAL = """
import os, signal, sys
from swe_sphere.simulation import simulation
from swe_sphere.cli import main

run = simulation.Simulation.run

def run_signalled_at_the_last_output(self, *args, **kwargs):  # SIGINT while the last output time is written
    def on_output(step, x):
        if step == self.scene.nsteps:
            os.kill(os.getpid(), signal.SIGINT)
    return run(self, *args, on_output=on_output, **kwargs)

simulation.Simulation.run = run_signalled_at_the_last_output
sys.argv = ["swe-sphere", "run", "tc2_steady", "--ne", "2", "--device", "cpu", "--no-progress", "--days", "1", "--output", "o.nc"]
main()
"""


def test_a_signal_after_the_last_step_keeps_the_output_whole(tmp_path):
    """SIGINT after the loop's last check (writing the last output time, closing the
    file): the file is closed whole under the run's handlers, then exit 130 in one line."""
    import xarray as xr

    proc = subprocess.run(
        [sys.executable, "-c", LAST_OUTPUT_SIGNAL],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=120,
        env={**os.environ, "SWE_SPHERE_THREADS": "1"},
    )
    assert proc.returncode == 130, proc.stderr
    assert proc.stderr.splitlines() == [
        "swe-sphere: interrupted by SIGINT after the last step (model time 1.0000 days); the output o.nc is complete"
    ], proc.stderr
    with xr.open_dataset(tmp_path / "o.nc") as ds:
        assert ds.sizes["time"] == 2 and "interrupted" not in ds.attrs
    assert sorted(p.name for p in tmp_path.iterdir()) == ["o.nc"]
