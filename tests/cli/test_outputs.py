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
