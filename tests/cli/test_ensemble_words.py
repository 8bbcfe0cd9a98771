"""The command line's words on an ensemble and on a continuation (issue 127, items 10 and 11): a
member count given twice is one refusal, a one-member ensemble is said as one member, a
continuation says its dt notes as the continued run's, and an ensemble's continuation branches
neither on the command line nor in Python (one rule)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from helpers import TINY, cli_main, one_line

RUN = ("run", "tc5_mountain", *TINY)


@pytest.fixture(autouse=True)
def _in_tmp(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)


def test_members_given_twice_and_differing_is_refused(capsys):
    """`--members 2 -s ensemble.members=3` ran 2 members in silence; refused as `--precision` with
    `-s numerics.precision` is, nothing written; the same count twice runs."""
    args = (*RUN, "--days", "0.25", "--members", "2", "--perturbation", "1")
    code, out, err = cli_main(capsys, *args, "-s", "ensemble.members=3", "--output", "m.nc")
    one_line(code, err, 2, "--members 2 and -s ensemble.members=3: give one of them")
    assert out == "" and list(Path().iterdir()) == []
    code, out, err = cli_main(capsys, *args, "-s", "ensemble.members=2", "--output", "m.nc")
    assert code == 0 and "ensemble    2 members" in out, err


def test_one_member_is_said_as_one(capsys):
    code, out, err = cli_main(capsys, *RUN, "--days", "0.25", "--members", "1", "--perturbation", "1")
    assert code == 0, err
    assert "ensemble    1 member in the same launches" in out or "ensemble    1 member each" in out, out


def test_a_continuation_says_its_dt_notes_as_the_continued_run_s(capsys):
    """A run whose dt was cut to divide its restart interval of 0.3 days, continued writing every
    0.2 days, said "dt cut ... to divide the restart interval of 0.3 days" beside "every 0.2 days"
    as if this run's: the note now names the run continued, whose dt goes on."""
    code, out, err = cli_main(capsys, *RUN, "--days", "0.6", "--restart-every", "0.3", "--output", "c.nc")
    assert code == 0 and "to divide the restart interval of 0.3 days\n" in out, err
    code, out, err = cli_main(
        capsys, "run", "--continue", "c.restart.nc", "--days", "1.2", "--restart-every", "0.2", "--no-progress"
    )
    assert code == 0, err
    cut = [line for line in out.splitlines() if "restart interval" in line]
    assert cut == [
        "note        dt cut from 3049.41 s to 2880 s to divide the restart interval of 0.3 days "
        "(the run continued, c.restart.nc: its dt goes on)"
    ]
    assert "(every 0.2 days and at the end)" in out


def test_an_ensemble_s_continuation_branches_in_python_no_more_than_on_the_command_line(capsys):
    """`run --continue E --stepper S` is refused for an ensemble's file where S is not its own
    stepper (saying the file's), and continues it where S and --dt are its own (refused before,
    whatever they were); Python's ``from_checkpoint(E, members=True, stepper=..., dt=...)``
    branched it: refused alike now, and the same stepper and dt given (no branch) continue."""
    import swe_sphere
    from swe_sphere.core.errors import SceneError

    args = (*RUN, "--days", "0.25", "--members", "2", "--perturbation", "1", "--restart-every", "0.25")
    code, _, err = cli_main(capsys, *args, "--output", "e.nc")
    assert code == 0, err
    own = swe_sphere.Simulation.from_checkpoint("e.restart.nc", "cpu", members=True, progress=False)
    other = "ssprk3" if own.scene.stepper != "ssprk3" else "rk4"
    code, _, err = cli_main(capsys, "run", "--continue", "e.restart.nc", "--days", "0.5", "--stepper", other)
    one_line(code, err, 2, f"--stepper {other}: an ensemble continues with its own stepper, dt")
    assert f"the file's: {own.scene.stepper}, dt = {own.scene.dt:g} s" in err and not Path("e_continued.nc").exists()
    same = ("--stepper", own.scene.stepper, "--dt", f"{own.scene.dt!r}", "--no-progress")
    code, out, err = cli_main(capsys, "run", "--continue", "e.restart.nc", "--days", "0.5", *same)
    assert code == 0 and "ensemble    2 members" in out, err
    code, _, err = cli_main(capsys, "run", "--continue", "e.restart.nc", "--days", "0.5", "--output", "plain.nc")
    assert code == 0, err
    with (
        xr.open_dataset("e_continued.nc", decode_times=False) as a,
        xr.open_dataset("plain.nc", decode_times=False) as b,
    ):
        assert list(a.time.values) == [0.5] and np.array_equal(a.h.values, b.h.values)
    for branch in ({"stepper": other}, {"dt": own.scene.dt / 2}):
        with pytest.raises(SceneError, match="an ensemble continues with its own stepper and dt") as raised:
            swe_sphere.Simulation.from_checkpoint("e.restart.nc", "cpu", members=True, progress=False, **branch)
        assert str(raised.value).startswith(next(iter(branch)))
    same = {"stepper": own.scene.stepper, "dt": own.scene.dt}
    again = swe_sphere.Simulation.from_checkpoint("e.restart.nc", "cpu", members=True, progress=False, **same)
    assert (again.step, again.scene.stepper) == (own.step, own.scene.stepper) and again.step > 0
