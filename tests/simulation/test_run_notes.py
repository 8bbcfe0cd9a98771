"""What a run says besides its progress: the header's notes (a dt scaled to the grid, not
after a branch at a dt given), a warning for an option of a stepper that does not run or for
more threads than CPUs, the note on a terminal that kernels are being compiled, and the note
that a run will take days."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

from helpers import EIGHTH_DAY, TINY, cli_main, console_script


def test_a_branch_at_another_dt_drops_the_dt_scaled_note(tmp_path, capsys, monkeypatch):
    """The scene's dt was scaled to ne2 (a note says so); a branch with --dt runs at the
    dt given, so its header no longer says dt was scaled; a plain continuation still does."""
    monkeypatch.chdir(tmp_path)
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


def test_an_option_of_another_stepper_warns(tmp_path, capsys, monkeypatch):
    """``-s implicit.method=bdf2`` with ssprk3 running was ignored silently: now one warning line."""
    monkeypatch.chdir(tmp_path)
    code, _, err = cli_main(
        capsys,
        "run",
        "tc2_steady",
        *TINY,
        *EIGHTH_DAY,
        "-s",
        "implicit.method=bdf2",
    )
    assert code == 0
    assert err.strip() == (
        "swe-sphere: warning: -s implicit.method: not an option of ssprk3, the stepper that runs; not used"
    )


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


# Two of the seven modules a tiny tc1 run compiles, and cheap ones: left out of the test's kernel
# cache, the rest are the session's own (a fully cold cache compiled all seven: 17 s of the test's
# 17.4 s, -n 0 at load 2.4; the note's hook is the same for one miss or seven)
LEFT_OUT = ("wp_vorticity_element_", "wp_divergence_element_")


def test_a_cold_kernel_cache_is_announced_once_on_a_terminal(tmp_path):
    """A cold Warp cache cost seconds of a tiny run without a word: on a terminal,
    one line says kernels are being compiled and where they are cached (once, for two modules
    compiled); a warm cache says nothing (and a piped stderr never gets the note)."""
    import pty

    import warp as wp

    session = Path(wp.config.kernel_cache_dir)  # the session's; the run's is tmp_path/cache/<Warp's version>
    cache = tmp_path / "cache" / session.name
    cache.mkdir(parents=True)
    for module in session.iterdir():
        if not module.name.startswith(LEFT_OUT):
            (cache / module.name).symlink_to(module)

    def stderr_on_a_tty(output):
        master, slave = pty.openpty()
        env = {**os.environ, "SWE_SPHERE_THREADS": "1", "WARP_CACHE_PATH": str(tmp_path / "cache")}
        proc = subprocess.run(
            [console_script(), "run", "tc1_cosine_bell", *TINY, "--days", "1", "--output", output],
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
    assert sorted(m.name.startswith(LEFT_OUT) for m in cache.iterdir() if not m.is_symlink()) == [True, True]
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
            console_script(),
            "run",
            "tc2_steady",
            "--ne",
            "16",
            "--device",
            "cpu",
            "--no-progress",
            "--no-cells",  # the cells' build note, if it took long, would come first
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
