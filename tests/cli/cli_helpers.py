"""What the command line's tests share: the scenes and steppers they expect, the tiny
blow-up, a folder of its own per test, and small readers of a run's output."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
import warp as wp

from helpers import TINY, cli_main

REPO = Path(__file__).resolve().parents[2]
TESTCASES = REPO / "testcases"
EARTH_RADIUS = 6.37122e6
STEPPER_NAMES = ("leapfrog", "leapfrog_trapezoidal", "ssprk3", "rk4", "kgu35", "fbrk32", "split_explicit", "mri")
TERM_NAMES = ("continuity", "momentum_advection", "coriolis", "pressure_gradient", "topography", "hyperviscosity")
# tc2_steady at ne=2 with dt = 2 h (gravity-wave Courant number ~1.25) goes
# negative in depth after ~1.4 days: well after the first daily output.
BLOWUP = ("tc2_steady", *TINY, "--dt", "7200", "--days", "5")
BLOWUP_RE = re.compile(
    r"step (?P<step>\d+) \(model time (?P<days>[-+0-9.eE]+) days\).*"
    r"lat (?P<lat>[-+0-9.]+), lon (?P<lon>[-+0-9.]+)"
)


def cuda_available() -> bool:
    return wp.is_cuda_available()


@pytest.fixture(autouse=True)
def in_tmp(tmp_path, monkeypatch):
    """Every test runs in its own folder, so a default output name lands there."""
    monkeypatch.chdir(tmp_path)


def run_cli(capsys, *args):
    """``main(["run", *args])`` → (exit status, stdout, stderr)."""
    return cli_main(capsys, "run", *args)


def stderr_lines(err: str) -> list[str]:
    return [line for line in err.splitlines() if line.strip()]


def nc_files(folder: Path) -> list[Path]:
    return sorted(p for p in folder.rglob("*") if p.name.endswith((".nc", ".nc.part")))


def edited_scene(tmp_path: Path, edit, source: str = "tc2_steady.toml", name: str = "edited.toml") -> Path:
    """A copy of a bundled scene, rewritten by ``edit(text) -> text``."""
    text = (TESTCASES / source).read_text()
    new = edit(text)
    assert new != text, "the edit did not change the scene"
    path = tmp_path / name
    path.write_text(new)
    return path
