"""A benchmark script's bad input ends as the command line's does (benchmarks/results.py's
``one_line`` for the package's own errors, argparse's for the scripts' own checks): one line
naming the value, exit 2, no traceback, and no results file (written at a normal exit only)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"


@pytest.mark.parametrize(
    "script, args, says",
    [
        ("step_cost.py", ["--ne", "-3"], "step_cost.py: error: ne must be an integer >= 1 (got -3)"),
        ("gradient_cost.py", ["--ne", "2", "--steps", "-2"], "gradient_cost.py: error: --steps must be >= 1"),
        ("ensemble_cost.py", ["--steps", "0"], "ensemble_cost.py: error: argument --steps: must be > 0 (got 0)"),
        ("kernel_roofline.py", ["--rounds", "0"], "kernel_roofline.py: error: argument --rounds: must be > 0 (got 0)"),
        ("across_elements.py", ["--case", "9,2,4"], "across_elements.py: error: argument --case: --case 9,2,4: np 2-8"),
        (
            "hyperviscosity_every.py",
            ["--scene", "tc2_steady", "--ne", "2"],
            "hyperviscosity_every.py: error: --scene tc2_steady: its terms have no hyperviscosity",
        ),
    ],
)
def test_a_bad_input_is_one_line_and_exit_2(tmp_path, script, args, says):
    results = {p: p.stat().st_mtime_ns for p in (BENCHMARKS / "results").iterdir()}
    env = {**os.environ, "OMP_NUM_THREADS": "1", "SWE_SPHERE_THREADS": "1"}
    done = subprocess.run(
        [sys.executable, str(BENCHMARKS / script), *args], cwd=tmp_path, env=env, capture_output=True, text=True
    )
    assert done.returncode == 2, done.stderr
    assert done.stderr.strip().splitlines()[-1].startswith(says), done.stderr
    assert "Traceback" not in done.stderr
    assert {p: p.stat().st_mtime_ns for p in (BENCHMARKS / "results").iterdir()} == results
