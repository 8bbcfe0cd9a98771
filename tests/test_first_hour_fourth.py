"""A new user's first hour, a fourth pass (issue 102): ensembles that say what they are, values
replaced by an option still checked, ``load_scene`` taking what ``run`` takes, and the header
naming the case as run. Each refusal is one line, exit 2, made before anything is written."""

from __future__ import annotations

from pathlib import Path

import pytest

from swe_sphere.config.scene import load_scene
from swe_sphere.core.errors import SceneError

from helpers import cli_main, one_line

RUN = ("run", "tc2_steady", "--ne", "2", "--days", "0.1", "--device", "cpu", "--no-progress")


@pytest.fixture(autouse=True)
def _in_tmp(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)


@pytest.mark.parametrize(
    "options, words",
    [
        (["--ne", "4", "-s", "grid.ne=-4"], ["grid.ne = -4", "integer >= 1", "ne = 4 replaces it"]),
        (["-s", "time.days=-2"], ["time.days = -2", "must be > 0", "days = 0.1 replaces it"]),
        (["--np", "4", "-s", "grid.np=9"], ["grid.np = 9", "2..8"]),
        (["--dt", "600", "-s", "time.dt=-1"], ["time.dt = -1", "must be > 0"]),
        (["--stepper", "rk4", "-s", "time.stepper='rk5'"], ["time.stepper = 'rk5'", "unknown stepper"]),
    ],
)
def test_a_set_value_an_option_replaces_is_still_checked(capsys, options, words):
    """`run tc2_steady --ne 4 -s grid.ne=-4` and `-s time.days=-2` with --days ran, exit 0:
    -s is documented as checked like the file, and a value the option replaces was dropped unread."""
    code, out, err = cli_main(capsys, *RUN, *options, "--output", "x.nc")
    one_line(code, err, 2, *words)
    assert out == "" and list(Path().iterdir()) == []


def test_a_value_an_option_replaces_is_fine_when_good():
    scene = load_scene("tc2_steady", ne=2, days=0.5, overrides={"grid.ne": 8, "time.days": 3})
    assert (scene.ne, scene.days) == (2, 0.5)


def test_load_scene_takes_np_as_run_does():
    """`load_scene("tc2_steady", ne=2, np=4)` raised a bare TypeError (it wanted np_=)."""
    assert load_scene("tc2_steady", ne=2, np=3).np == 3
    assert load_scene("tc2_steady", ne=2, np_=3).np == 3
    with pytest.raises(SceneError, match="np = 3 and np_ = 4: give one of them"):
        load_scene("tc2_steady", ne=2, np=3, np_=4)


def test_a_table_given_as_a_dict_is_merged_into_the_files():
    """`load_scene(..., overrides={"time": {"control": "error"}})` replaced the whole [time]
    table and then said "time.dt is missing"; `run(time={...})` merges."""
    scene = load_scene("tc2_steady", ne=2, stepper="bs32", overrides={"time": {"control": "error", "rtol": 1e-5}})
    plain = load_scene("tc2_steady", ne=2, stepper="bs32")
    assert scene.control.mode == "error" and scene.control.rtol == 1e-5
    assert scene.days == plain.days and scene.output_every_days == plain.output_every_days


def test_the_header_names_the_case_as_run(capsys):
    """`-s case.alpha=0.5` printed the file's "(alpha = 0)" alone."""
    code, out, _ = cli_main(capsys, *RUN, "-s", "case.alpha=0.5", "--output", "a.nc")
    assert code == 0
    first = out.splitlines()[0]
    assert first.startswith("scene       tc2_steady: ") and first.endswith("; run with case.alpha = 0.5"), first


@pytest.mark.parametrize(
    "value, words",
    [("1e308", ["case.alpha", "within ±2π", "1e+308"]), ("45", ["case.alpha", "radians", "45"])],
)
def test_an_angle_out_of_range_is_refused(capsys, value, words):
    """`-s case.alpha=1e308` ran (cos and sin of 1e308 are no tilt one means)."""
    code, out, err = cli_main(capsys, *RUN, "-s", f"case.alpha={value}", "--output", "a.nc")
    one_line(code, err, 2, *words)
    assert out == "" and list(Path().iterdir()) == []
    with pytest.raises(SceneError, match="case.lat2 must be an angle in radians within ±π/2"):
        load_scene("galewsky", ne=2, overrides={"case.lat2": 2.0})
