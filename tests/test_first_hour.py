"""A new user's first hour on a fresh clone, as the user meets it: exit 2 and one line
naming the field, value or file for bad input, nothing made before the refusal."""

from __future__ import annotations

import errno
from pathlib import Path

import pytest

from swe_sphere.io.run_file import acquire_lock, release_lock
from swe_sphere.simulation.simulation import Simulation

from conftest import TINY, cli_main, cli_one_line


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
    assert not Path("suite").exists()


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


@pytest.mark.parametrize("command", ["plot", "remap"])
@pytest.mark.parametrize("content", [b"not netCDF\n", b"\x89HDF\r\n\x1a\n" + bytes(100)], ids=["text", "cut_hdf5"])
def test_an_unreadable_file_is_named_without_the_exception_type(capsys, command, content):
    """ "junk.nc: not a readable netCDF file (ValueError)": the type told a user nothing."""
    Path("junk.nc").write_bytes(content)
    line = cli_one_line(capsys, [command, "junk.nc"], 2)
    assert line == "swe-sphere: error: junk.nc: not a readable netCDF file"
