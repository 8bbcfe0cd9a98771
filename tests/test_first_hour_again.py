"""A new user's first hour, again (issue 84): inputs that hung, were slow to refuse or passed
silently, and docs that contradicted the commands. Each refusal is one line, exit 2 (3 for
memory), made before any work."""

from __future__ import annotations

from pathlib import Path

import pytest

import swe_sphere.io.remap as remap
from swe_sphere.core.clock import Clock
from swe_sphere.core.errors import SceneError

from helpers import cli_main, cli_one_line, one_line


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


def _never_listed(*args, **kwargs):
    raise AssertionError("the schedule was listed: the refusal came too late")


@pytest.mark.parametrize(
    "options, words",
    [
        # the dt scaled to ne 2 was cut 1.4e7x to divide the interval: 1e8 steps, 1e8 outputs listed in set-up
        (["-s", "output.every_days=1e-9"], ["output.every_days", "1e-09 days", "1e+08 times", "more than 1e+05"]),
        (
            ["--stepper", "bs32", "-s", "time.control=error", "-s", "output.every_days=1e-9"],
            ["output.every_days", "1e-09 days", "1e+08 times"],
        ),
        (  # under step control the restart interval was checked only by the writer, after the header
            ["--stepper", "bs32", "-s", "time.control=error", "--restart-every", "1e-9"],
            ["restart interval", "1e-09 days", "1e+08 times"],
        ),
    ],
)
def test_an_interval_of_too_many_times_is_refused_before_set_up(capsys, monkeypatch, options, words):
    """`run tc2_steady --ne 4 --days 0.1 -s output.every_days=1e-9` was still in set-up after
    300 s; the count is checked in O(1) before any schedule is listed or anything printed."""
    import swe_sphere.simulation.writers as writers

    for name in ("output_steps", "output_days", "interval_days", "restart_steps"):
        monkeypatch.setattr(writers, name, _never_listed)
    args = ["run", "tc2_steady", "--ne", "2", "--days", "0.1", *options, "--device", "cpu", "--output", "g66.nc"]
    code, out, err = cli_main(capsys, *args)
    one_line(code, err, 2, *words)
    assert out == "" and list(Path().iterdir()) == []


def test_the_count_of_times_is_checked_in_the_clock():
    clock = Clock(86400 * 1e-9, 0.0, 0.1)  # 1e8 steps, under MAX_STEPS
    with pytest.raises(SceneError, match=r"the output interval of 1e-09 days gives 1e\+08 times"):
        clock.check({"the output interval": 1e-9})
    Clock(86.4, 0.0, 100.0).check({"the output interval": 0.001})  # 1e5 outputs: the most
