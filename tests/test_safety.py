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

SCRIPT = Path(sys.executable).with_name("swe-sphere")
SCRIPT = str(SCRIPT) if SCRIPT.is_file() else shutil.which("swe-sphere")
pytestmark = pytest.mark.skipif(SCRIPT is None, reason="the swe-sphere console script is not installed")
TINY = ("--ne", "2", "--np", "4", "--device", "cpu", "--no-progress")


def cli(cwd, *args, timeout=120):
    env = {**os.environ, "SWE_SPHERE_THREADS": "1"}
    return subprocess.run([SCRIPT, *map(str, args)], cwd=cwd, capture_output=True, text=True, timeout=timeout, env=env)


def digest(path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def refused(proc, *words):
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    assert proc.returncode == 2, proc.stderr
    assert len(lines) == 1 and "Traceback" not in proc.stderr, proc.stderr
    for word in words:
        assert word in lines[0], lines[0]


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    """A one-day ne2 run with its restart file."""
    d = tmp_path_factory.mktemp("run")
    proc = cli(d, "run", "tc5_mountain", *TINY, "--days", "1", "--restart-every", "1", "--output", "a.nc")
    assert proc.returncode == 0, proc.stderr
    return d


@pytest.mark.parametrize("argv", [
    ("run", "--continue", "a.restart.nc", "--days", "2", "--output", "a.restart.nc", "--overwrite"),
    ("run", "--continue", "a.restart.nc", "--days", "2", "--output", "a.nc", "--overwrite"),  # its restart sibling
    ("remap", "a.nc", "--output", "a.nc", "--overwrite"),
    ("remap", "link.nc", "--output", "a.nc", "--overwrite"),
    ("remap", "a.nc", "--output", "hard.nc", "--overwrite"),
])
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
    from swe_sphere.output import OutputError

    scene = tmp_path / "s.toml"
    shutil.copy(Path(swe_sphere.__file__).parent.parent / "testcases" / "tc2_steady.toml", scene)
    before = digest(scene)
    with pytest.raises(OutputError, match="is the input"):
        swe_sphere.run(scene, ne=2, days=1, device="cpu", output_file=scene, overwrite=True)
    assert digest(scene) == before


def test_a_second_sweep_into_one_folder_is_refused_at_its_start(tmp_path):
    """The first sweep holds the folder's lock from its start; the second exits 2
    within seconds, before computing anything, and the first finishes."""
    argv = ("sweep", "tc2_steady", "--ne", "2", "--days", "1", "--steppers", "ssprk3", "--dt", "1800,3600",
            "--device", "cpu", "--output", "deep/sw")
    env = {**os.environ, "SWE_SPHERE_THREADS": "1"}
    first = subprocess.Popen([SCRIPT, *argv], cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    try:
        lock = tmp_path / "deep" / "sw" / "sweep.lock"
        for _ in range(600):
            if lock.exists() or first.poll() is not None:
                break
            subprocess.run(["sleep", "0.1"])
        assert lock.exists(), first.communicate()
        second = cli(tmp_path, *argv, timeout=60)
        refused(second, "another run is writing", "sweep.lock")
        out, err = first.communicate(timeout=300)
        assert first.returncode == 0, err
    finally:
        if first.poll() is None:
            first.kill()
    assert (tmp_path / "deep" / "sw" / "sweep.nc").is_file() and not lock.exists()


def test_stability_creates_its_output_folder(tmp_path):
    proc = cli(tmp_path, "stability", "tc5_mountain", "--steppers", "ssprk3", "--ne", "2", "--device", "cpu", "--output", "new/dir")
    assert proc.returncode == 0, proc.stderr
    assert sorted(p.name for p in (tmp_path / "new" / "dir").iterdir()) == ["stability.csv", "stability.nc"]
