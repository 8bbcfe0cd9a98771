"""Where a command's output may go: refusals in one line, exit 2, nothing written."""

from __future__ import annotations

import pytest

from cli_helpers import (
    in_tmp,  # noqa: F401  (the fixture: every test in a folder of its own)
)
from helpers import TINY, cli_one_line


@pytest.mark.parametrize("name", ["out.txt", "out", "out.nc.part"])
def test_a_run_file_not_named_nc_is_refused(capsys, tmp_path, name):
    """`--output out.txt` wrote netCDF under a .txt name, silently."""
    line = cli_one_line(capsys, ["run", "tc2_steady", *TINY, "--days", "0.25", "--output", name], 2)
    assert line == f"swe-sphere: error: --output {name}: the file is netCDF, its name must end in .nc", line
    assert list(tmp_path.iterdir()) == []


def test_a_remap_not_named_nc_is_refused(capsys, tmp_path, tc5_run_file):
    line = cli_one_line(capsys, ["remap", tc5_run_file, "--output", "ll.txt"], 2, "--output ll.txt", "end in .nc")
    assert list(tmp_path.iterdir()) == [], line


def test_a_plot_output_named_as_an_image_is_refused_not_made_a_folder(capsys, tmp_path, tc5_run_file):
    """`plot --output nodir/x.png` made a folder called x.png and put the PNGs in it."""
    line = cli_one_line(capsys, ["plot", tc5_run_file, "--output", "nodir/x.png"], 2, "--output nodir/x.png", "folder")
    assert list(tmp_path.iterdir()) == [], line


@pytest.mark.parametrize("folder", ["figs", "figs/day1"])
def test_plot_into_a_read_only_folder_is_worded_as_run_words_it(capsys, tmp_path, tc5_run_file, monkeypatch, folder):
    """`plot` said "figs: Read-only file system" where run, remap and mesh say "output
    directory is not writable"; the folder is made by nothing."""
    import os

    real = os.access
    monkeypatch.setattr(os, "access", lambda path, mode, **kw: False if mode == os.W_OK else real(path, mode, **kw))
    line = cli_one_line(capsys, ["plot", tc5_run_file, "--output", folder], 2)
    assert line == f"swe-sphere: error: output directory is not writable: {tmp_path}", line
    line = cli_one_line(capsys, ["run", "tc2_steady", *TINY, "--output", "x.nc"], 2)
    assert line == f"swe-sphere: error: output directory is not writable: {tmp_path}", line
    assert list(tmp_path.iterdir()) == []
