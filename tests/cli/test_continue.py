"""``swe-sphere run --continue``: refusals made before anything is written."""

from __future__ import annotations

from swe_sphere.cli import main

from cli_helpers import (
    in_tmp,  # noqa: F401  (the fixture: every test in a folder of its own)
    nc_files,
)
from helpers import TINY, cli_one_line


def test_continue_to_the_day_the_checkpoint_is_at_is_refused(capsys, tmp_path):
    """A continuation of no step (the checkpoint at day 1, --days 1) is exit 2, one line
    saying the checkpoint's day, and no file: an empty run file would block the real one."""
    assert main(["run", "tc2_steady", *TINY, "--days", "1", "--restart-every", "1", "--output", "x.nc"]) == 0
    before = nc_files(tmp_path)
    assert [p.name for p in before] == ["x.nc", "x.restart.nc"]
    capsys.readouterr()
    for days in ((), ("--days", "1")):
        cli_one_line(
            capsys,
            ["run", "--continue", "x.restart.nc", *days, "--device", "cpu", "--no-progress"],
            2,
            "is already at",
            "day 1",
        )
    line = cli_one_line(capsys, ["run", "--continue", "x.restart.nc", "--days", "1", "--device", "cpu"], 2)
    assert "the checkpoint is already at day 1" in line, line
    assert nc_files(tmp_path) == before  # no x_continued.nc


def test_a_continued_controlled_run_names_the_checkpoint_s_day(capsys, tmp_path):
    """Under error control the steps are not the scene's Δt: the continuation's header names the
    checkpoint's model time (day 0.5), not its step count times the first Δt (issue 86)."""
    control = ["--stepper", "bs32", "-s", "time.control=error", "-s", "time.rtol=1e-4"]
    assert (
        main(["run", "tc2_steady", *TINY, "--days", "0.5", *control, "--restart-every", "0.5", "--output", "c.nc"]) == 0
    )
    capsys.readouterr()
    assert main(["run", "--continue", "c.restart.nc", "--days", "0.75", "--device", "cpu", "--no-progress"]) == 0
    out = capsys.readouterr().out
    line = next(line for line in out.splitlines() if line.startswith("continue "))
    assert line.endswith("(day 0.5)"), line
    assert "(max over nodes at t = 0.5 d)" in out
