"""The sweep's plan: what `swe-sphere sweep` checks and runs, from Python and the command line."""

import math
import shutil

import pandas as pd
import pytest

from swe_sphere.cli import main
from swe_sphere.studies.sweep.plan import plan
from swe_sphere.studies.sweep.report import OUTPUTS

from helpers import cli_one_line, without_sweep_figures


def test_sweep_bad_input_exits_2(tmp_path, capsys):
    assert main(["sweep", "tc2_steady", "--steppers", "euler", "--output", str(tmp_path / "o")]) == 2
    assert main(["sweep", "tc2_steady", "--dt", "-5", "--output", str(tmp_path / "o")]) == 2
    assert main(["sweep", "tc2_steady", "--ne", "2", "--dt", "7000", "--output", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 3 and "euler" in err[0] and "-5" in err[1] and "7000" in err[2]


def test_sweep_refuses_zero_workers(tmp_path, capsys):
    assert (
        main(["sweep", "tc2_steady", "--ne", "2", "--dt", "3600", "--workers", "0", "--output", str(tmp_path / "o")])
        == 2
    )
    assert "--workers must be >= 1 (got 0)" in capsys.readouterr().err


def test_runs_names_the_value_that_is_not_a_number(tmp_path, capsys):
    assert main(["sweep", "tc2_steady", "--runs", "rk4@1,rk4@abc", "--output", str(tmp_path / "o")]) == 2
    assert capsys.readouterr().err == (
        "swe-sphere: error: --runs rk4@abc: 'abc' is not a number > 0 (a multiple of the "
        "gravity-wave limit, e.g. rk4@0.5)\n"
    )
    assert not (tmp_path / "o").exists()


def test_the_plan_is_what_the_cli_runs(tmp_path, capsys, monkeypatch):
    """``plan`` with the options of ``swe-sphere sweep --runs rk4@0.77`` resolves to the
    Δt the command ran (the largest at or below 0.77 × the gravity-wave limit that divides
    the 6 h run) and to the notes it printed before its runs, the first saying the multiple
    that ran (sweep.csv's), not the 0.77 asked for; ``Plan.run`` on a copy of
    the command's runs reuses them and writes the same sweep.csv, logging the same lines."""
    without_sweep_figures(monkeypatch)
    cli = tmp_path / "cli"
    args = ["sweep", "tc2_steady", "--ne", "2", "--days", "0.25", "--runs", "rk4@0.77"]
    assert main([*args, "--device", "cpu", "--output", str(cli)]) == 0
    printed = capsys.readouterr().out.splitlines()
    p = plan("tc2_steady", ne=2, days=0.25, runs=[("rk4", 0.77)])
    assert list(p.scenes) == ["rk4"] and p.multiples == (0.77,) and p.dts is None
    resolved = p.resolve(tmp_path / "py", "cpu")
    g = resolved.limits["dt_gravity"]
    steps = math.ceil(0.25 * 86400 / (0.77 * g) - 1e-9)
    assert resolved.dts == [0.25 * 86400 / steps] and resolved.dts[0] < 0.77 * g * (1 - 1e-3)
    assert resolved.pairs == (("rk4", resolved.dts[0]),)
    assert list(pd.read_csv(cli / "sweep.csv")["dt"]) == resolved.dts
    assert printed[: len(resolved.notes)] == resolved.notes and len(resolved.notes) == 2
    assert resolved.notes[0].startswith(f"note        --runs rk4@0.77 runs at {resolved.dts[0] / g:.3g} x the")

    py = tmp_path / "py"
    shutil.copytree(cli / "runs", py / "runs", dirs_exist_ok=True)
    logged = []
    rows, info, paths = p.run(py, "cpu", log=logged.append)
    assert [path.name for path in paths] == list(OUTPUTS) and len(rows) == 1
    pd.testing.assert_frame_equal(pd.read_csv(py / "sweep.csv"), pd.read_csv(cli / "sweep.csv"), check_exact=True)
    said = "\n".join(logged).splitlines()
    assert said[:2] == printed[:2] and f"runs: 1 reused, 0 made (in {py / 'runs'})" in said
    table = [printed.index(line) for line in printed if line.startswith("stepper ")] + [
        said.index(line) for line in said if line.startswith("stepper ")
    ]
    n = len(printed) - table[0] - len(OUTPUTS)  # the table, summary and verdicts
    assert n > 5
    assert said[table[1] : table[1] + n] == printed[table[0] : table[0] + n]


@pytest.mark.parametrize(
    "options, words",
    [
        (dict(runs=[("rk4", 1.0)], steppers=["rk4"]), "not both"),
        (dict(dts=[3600.0], courant=[1.0]), "one of --dt, --courant and --runs"),
        (dict(dts=[-5.0]), "--dt values must be > 0 (got -5)"),
        (dict(courant=[]), "--courant values must be > 0 (got none)"),
        (dict(runs=[("rk4", 0.0)]), "--runs values must be > 0 (got 0)"),
        (dict(runs=[("bs32", "rtol=0")]), "--runs bs32@rtol=0: '0' is not a number > 0"),
        (dict(runs=[("bs32", "tol=1e-5")]), "chosen by rtol=VALUE, rtol_per_day=VALUE, balance=VALUE, cfl=VALUE"),
        (dict(runs=[]), "--runs names no run"),
        (dict(dts=[7000.0]), "the run length of 1 days is not a whole number of steps of dt = 7000 s (--dt)"),
        (
            dict(dts=[1000.0], filter_days=0.5),
            "the filter's 3 h snapshot interval of 0.125 days is not a whole number of steps of dt = 1000 s (--dt)",
        ),
    ],
)
def test_the_plan_refuses_what_the_cli_refuses(options, words):
    """Bad options raise ValueError naming them as the command line spells them, before any run."""
    given = options if "runs" in options else {"steppers": ["rk4"], **options}
    with pytest.raises(ValueError) as err:
        plan("tc2_steady", ne=2, days=1, **given)
    assert words in str(err.value)


@pytest.mark.parametrize("flag", ["--runs", "--courant", "--dt"])
def test_sweep_refuses_an_empty_list(capsys, flag, tmp_path, monkeypatch):
    """An empty --runs / --courant / --dt was read as "not given" and ran the whole default sweep."""
    monkeypatch.chdir(tmp_path)
    cli_one_line(capsys, ["sweep", "tc2_steady", "--ne", "2", flag, "", "--output", "o"], 2, flag)


def test_sweeps_of_other_cases_grids_and_lengths_default_to_folders_of_their_own():
    """A page's two sweeps with no --output both wrote into ./sweep: the second met
    "output file exists: sweep/sweep.csv"."""
    names = [
        plan("tc5_mountain", ne=8, days=4, runs=[("rk4", 1.0)]).default_output,
        plan("tc5_mountain", ne=16, days=1, runs=[("rk4", 1.0)]).default_output,
        plan("galewsky", ne=16, days=1, runs=[("rk4", 1.0)]).default_output,
        plan("tc5_mountain", ne=16, np_=3, days=1, runs=[("rk4", 1.0)]).default_output,
    ]
    assert [str(p) for p in names] == [
        "sweep_tc5_mountain_ne8np4_4d",
        "sweep_tc5_mountain_ne16np4_1d",
        "sweep_galewsky_ne16np8_1d",  # the scene's np
        "sweep_tc5_mountain_ne16np3_1d",
    ]
