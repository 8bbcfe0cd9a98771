"""SIGINT and SIGTERM to a real ``swe-sphere run``: during start-up, inside a step that never
ends, after the last step and once the output is complete. Each ends in one line with exit 130
(SIGINT) or 143 (SIGTERM), and leaves the output whole or no file at all."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from helpers import TINY, console_script, one_line


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
        [console_script(), "run", "tc2_steady", *TINY, "--days", "1", "--output", "o.nc"],
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
