"""A new user's first hour, again (issue 84): inputs that hung, were slow to refuse or passed
silently, and docs that contradicted the commands. Each refusal is one line, exit 2 (3 for
memory), made before any work."""

from __future__ import annotations

from pathlib import Path

import pytest

import swe_sphere.io.remap as remap

from helpers import cli_one_line


@pytest.fixture(autouse=True)
def _in_tmp(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)


def _not_built(*args, **kwargs):
    raise AssertionError("built before the memory check")


def test_a_remap_too_large_for_memory_is_refused_before_its_grid_is_built(tc5_run_file, capsys, monkeypatch):
    """`remap --resolution 1e-6` built its 1.8e8 x 3.6e8 lat-lon axes and the run's grid (57 s)
    before saying it would need 7.9e10 GiB."""
    monkeypatch.setattr(remap, "latlon_grid", _not_built)
    monkeypatch.setattr(remap, "run_grid", _not_built)
    line = cli_one_line(capsys, ["remap", tc5_run_file, "--resolution", "1e-6"], 3, "180000001 x 360000000 points")
    assert "7.92e+10 GiB" in line
    assert list(Path().iterdir()) == []
