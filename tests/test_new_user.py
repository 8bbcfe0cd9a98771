"""What a new user hits first (issue 45, item 1), as the user sees it: exit 2, one
line naming the field or file, nothing written, no earlier result replaced."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import cli_one_line
from test_initial_state import LL, latlon_file, scene_file
from swe_sphere import stability, sweep


@pytest.fixture(autouse=True)
def _in_tmp(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)


@pytest.mark.parametrize("flag", ["--runs", "--courant", "--dt"])
def test_sweep_refuses_an_empty_list(capsys, flag):
    """An empty --runs / --courant / --dt was read as "not given" and ran the whole default sweep."""
    cli_one_line(capsys, ["sweep", "tc2_steady", "--ne", "2", flag, "", "--output", "o"], 2, flag)


@pytest.mark.parametrize("name", sweep.OUTPUTS)
def test_sweep_keeps_an_earlier_studys_results(tmp_path, capsys, name):
    """Each of an earlier sweep's results in --output refuses the sweep before any run
    (no runs/ folder), and is kept as it was; --overwrite is named as the way on."""
    earlier = tmp_path / "o" / name
    earlier.parent.mkdir()
    earlier.write_text("earlier study")
    cli_one_line(capsys, ["sweep", "tc2_steady", "--ne", "2", "--days", "0.25", "--runs", "rk4@1", "--device", "cpu",
                          "--output", "o"], 2, "output file exists", name, "--overwrite")
    assert earlier.read_text() == "earlier study"
    assert sorted(p.name for p in earlier.parent.iterdir()) == [name]


@pytest.mark.parametrize("name", stability.OUTPUTS)
def test_stability_keeps_an_earlier_suites_results(tmp_path, capsys, name):
    (tmp_path / name).write_text("earlier suite")
    cli_one_line(capsys, ["stability", "tc5_mountain", "--steppers", "rk4", "--ne", "2", "--device", "cpu"], 2,
                 "output file exists", name, "--overwrite")
    assert (tmp_path / name).read_text() == "earlier suite"
    assert sorted(p.name for p in tmp_path.iterdir()) == [name]


def test_the_initial_state_file_is_never_replaced(tmp_path, capsys):
    """``--output`` naming the file ``case.path`` reads: refused even with --overwrite."""
    state = latlon_file(tmp_path / "state.nc", *LL)
    before = state.read_bytes()
    cli_one_line(capsys, ["run", scene_file(tmp_path, state), "--device", "cpu", "--no-progress", "--output", "state.nc",
                          "--overwrite"], 2, "would replace the input", "state.nc")
    assert state.read_bytes() == before


@pytest.mark.parametrize("lat, lon, words", [
    (np.arange(-30.0, 30.0), np.arange(360.0), ["lat covers -30 to 29 degrees, not the globe"]),
    (np.radians(np.linspace(-90.0, 90.0, 19)), np.radians(np.arange(36) * 10.0), ["not the globe", "radians?"]),
])
def test_an_initial_state_not_covering_the_globe_is_refused(tmp_path, capsys, lat, lon, words):
    """A regional lat-lon file was extrapolated to the poles; one in radians was read as
    a tiny regional one. Both: one line, exit 2, no output."""
    scene = scene_file(tmp_path, latlon_file(tmp_path / "part.nc", lat, lon))
    cli_one_line(capsys, ["run", scene, "--device", "cpu", "--no-progress", "--output", "out.nc"], 2, "case.path", *words)
    assert not (tmp_path / "out.nc").exists()
