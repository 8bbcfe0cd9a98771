"""The installed console script in a subprocess: the entry point and its exit status (its
refusals are the command line's, in process: test_refusals.py)."""

from __future__ import annotations

import subprocess

import pytest
import xarray as xr

from cli_helpers import (
    BLOWUP,
    BLOWUP_RE,
    cuda_available,
    in_tmp,  # noqa: F401  (the fixture: every test in a folder of its own)
    nc_files,
    stderr_lines,
)
from helpers import console_script

# ---------------------------------------------------------------------------
# The installed console script (the one real subprocess call)
# ---------------------------------------------------------------------------


def test_console_script_exit_status(tmp_path):
    """The entry point runs a whole (blowing-up) run and exits with status 3."""
    out = tmp_path / "blow.nc"
    proc = subprocess.run(
        [console_script(), "run", *BLOWUP, "--output", str(out)],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 3, proc.stderr
    assert BLOWUP_RE.search(proc.stderr), proc.stderr
    assert "summary" not in proc.stdout and "scene" in proc.stdout
    assert nc_files(tmp_path) == [out]
    with xr.open_dataset(out, decode_times=False) as ds:
        assert "blowup" in ds.attrs and ds.sizes["time"] >= 2


def _no_cuda_driver() -> bool:
    import ctypes.util

    return not cuda_available() and ctypes.util.find_library("cuda") is None


@pytest.mark.skipif(not _no_cuda_driver(), reason="needs a machine without a CUDA driver")
def test_console_script_device_cuda_without_driver_is_one_line(tmp_path):
    proc = subprocess.run(
        [
            console_script(),
            "run",
            "tc2_steady",
            "--ne",
            "2",
            "--days",
            "1",
            "--device",
            "cuda",
            "--output",
            str(tmp_path / "o.nc"),
        ],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 2
    assert nc_files(tmp_path) == []
    assert len(stderr_lines(proc.stderr)) == 1, proc.stderr
