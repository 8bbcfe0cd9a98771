"""A sweep over an ensemble's perturbed starts (`swe-sphere sweep --members N --perturbation M`):
each member's sweep under member<k>/, from the start an ensemble's member k has; members.csv the
mean and spread of each run's errors over them; the runs' keys name their start, so a rerun
reuses a member's runs and another seed makes them again; bad options are one line, exit 2."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from swe_sphere.cli import main
from swe_sphere.config.scene import load_scene
from swe_sphere.ensemble import Ensemble, Perturbation
from swe_sphere.studies.sweep import Members

from helpers import cli_main

pytestmark = pytest.mark.xdist_group("sweep_members")  # one module fixture, one worker

ARGS = ["sweep", "tc2_steady", "--ne", "2", "--days", "1", "--steppers", "kgu35", "--dt", "5400,10800"]
MEMBERS = ["--members", "2", "--perturbation", "1", "--device", "cpu"]


@pytest.fixture(scope="module")
def swept(tmp_path_factory):
    out = tmp_path_factory.mktemp("members")
    assert main([*ARGS, *MEMBERS, "--output", str(out)]) == 0
    return out


def test_members_csv_is_the_mean_and_spread_of_the_members_sweeps(swept):
    spread = pd.read_csv(swept / "members.csv")
    rows = [pd.read_csv(swept / f"member{k}" / "sweep.csv") for k in range(2)]
    assert list(spread["stepper"]) == ["kgu35", "kgu35"] and list(spread["dt"]) == [5400.0, 10800.0]
    assert list(spread["stable"]) == [2, 2]
    for column in ("total_error", "temporal_error", "cost_time"):
        values = np.stack([r[column].to_numpy() for r in rows])  # (member, run)
        np.testing.assert_array_equal(spread[f"{column}_mean"], values.mean(axis=0))
        np.testing.assert_array_equal(spread[f"{column}_spread"], values.std(axis=0, ddof=1))
    assert (spread["temporal_error_spread"] > 0).all()  # the starts differ, and so do the runs' errors


def test_member_k_starts_where_an_ensemble_s_member_k_does(swept):
    """The starts (``Members.starts``) are an ensemble's members' (``Perturbation``), bit for bit;
    the members' sweeps differ run by run."""
    scene = load_scene("tc2_steady", ne=2)
    ensemble = Ensemble("tc2_steady", 2, Perturbation(1.0, seed=0), device="cpu", ne=2).states()
    assert np.array_equal(Members(2, 1.0, 0).starts(scene), ensemble)
    first, second = (pd.read_csv(swept / f"member{k}" / "sweep.csv") for k in range(2))
    assert (first["total_error"] != second["total_error"]).all()


def test_a_rerun_reuses_a_member_s_runs_and_another_seed_makes_them_again(swept, capsys):
    code, out, _ = cli_main(capsys, *ARGS, *MEMBERS, "--output", str(swept), "--overwrite")
    assert code == 0 and out.count("runs: 2 reused, 0 made") == 2 and "other settings" not in out
    code, out, _ = cli_main(capsys, *ARGS, *MEMBERS, "--seed", "3", "--output", str(swept), "--overwrite")
    assert code == 0 and out.count("start.seed 0 (now 3)") == 6  # each member's reference run and its two runs


@pytest.mark.parametrize(
    ("more", "says"),
    [
        (["--members", "2"], "--members N and --perturbation M go together (--perturbation missing)"),
        (["--members", "1", "--perturbation", "1"], "--members must be an integer >= 2"),
        (["--seed", "1"], "--seed only with --members N --perturbation M"),
        (["--members", "2", "--perturbation", "0"], "--perturbation must be a finite number > 0"),
    ],
)
def test_bad_member_options_are_one_line_and_exit_2(capsys, tmp_path, more, says):
    code, _, err = cli_main(capsys, *ARGS, *more, "--output", str(tmp_path / "s"))
    assert code == 2 and says in err and len(err.strip().splitlines()) == 1, err
    assert not (tmp_path / "s").exists()
