"""The installed console script in a subprocess: the entry point and its exit status."""

from __future__ import annotations

import subprocess
from pathlib import Path

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


def _not_a_reference(folder: Path) -> Path:
    """A netCDF file of a reference's coefficients without its vorticity."""
    from swe_sphere.cases.reference import find_reference

    path = folder / "no_vorticity.nc"
    with xr.open_dataset(find_reference("galewsky", perturbed=False), decode_times=False) as ds:
        ds.drop_vars(["vort_spec_re", "vort_spec_im"]).to_netcdf(path)
    return path


@pytest.mark.parametrize(
    "command, scene, value, why",
    [
        ("sweep", "tc5_mountain", "missing.nc", "reference file not found: missing.nc"),
        ("run", "tc5_mountain", "junk.nc", "junk.nc: not a readable netCDF file"),
        (
            "run",
            "tc5_mountain",
            "NOT_A_REFERENCE",
            "not a reference file: missing variable(s) 'vort_spec_re', 'vort_spec_im'",
        ),
        (
            "run",
            "tc2_steady",
            "tc5_mountain_T213.nc",
            "case tc2_steady is scored against its exact solution, not a reference file",
        ),
        (
            "sweep",
            "tc5_mountain",
            "tc6_rossby_haurwitz_T213.nc",
            "the file is a tc6_rossby_haurwitz reference (its title), not one of tc5_mountain",
        ),
        (
            "run",
            "galewsky",
            "galewsky_balanced_T213.nc",
            "the file is a galewsky_balanced reference (its title), not one of galewsky",
        ),
    ],
    ids=["missing-sweep", "not-netcdf", "not-a-reference", "exact-solution", "other-case", "other-galewsky"],
)
def test_console_script_refuses_a_bad_case_reference(tmp_path, command, scene, value, why):
    """-s case.reference=...: exit 2, one line naming the key, the value and why; nothing written."""
    (tmp_path / "junk.nc").write_text("not netCDF")
    if value == "NOT_A_REFERENCE":
        value = str(_not_a_reference(tmp_path))
    proc = subprocess.run(
        [
            console_script(),
            command,
            scene,
            "--ne",
            "2",
            "--device",
            "cpu",
            "-s",
            f"case.reference={value}",
            "--output",
            str(tmp_path / "out"),
        ],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=120,
    )
    lines = stderr_lines(proc.stderr)
    assert proc.returncode == 2 and len(lines) == 1, proc.stderr
    assert lines[0].startswith(f"swe-sphere: error: case.reference = {value!r}: ") and why in lines[0], lines[0]
    assert not (tmp_path / "out").exists()


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
