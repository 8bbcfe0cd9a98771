"""A sweep over an ensemble's members (`swe-sphere sweep --members N` with `--perturbation M`,
`--initial FILE` or `--vary KEY=...`): each member's sweep under member<k>/, from the start an
ensemble's member k has (with --vary, of its own scenes); members.csv the mean and spread of each
run's errors over them; the runs' keys name their start, so a rerun reuses a member's runs and
another seed makes them again; bad options are one line, exit 2."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from swe_sphere.cli import main
from swe_sphere.config.scene import load_scene
from swe_sphere.ensemble import MemberFile, Perturbation
from swe_sphere.studies.sweep import Members
from swe_sphere.studies.sweep.members import FIGURES

from helpers import cli_main, members_run, png_size, without_sweep_figures

pytestmark = pytest.mark.xdist_group("sweep_members")  # one module fixture, one worker

ARGS = ["sweep", "tc2_steady", "--ne", "2", "--days", "1", "--steppers", "kgu35", "--dt", "5400,10800"]
MEMBERS = ["--members", "2", "--perturbation", "1", "--device", "cpu"]


@pytest.fixture(scope="module")
def swept(tmp_path_factory):
    """The members' sweep, made once: members.csv and its figures; each member's own sweep without
    its figures (none read here; test_sweep.py draws a sweep's)."""
    out = tmp_path_factory.mktemp("members")
    with pytest.MonkeyPatch.context() as mp:
        without_sweep_figures(mp)
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
    assert [png_size(swept / name) for name in FIGURES.values()] == [(800, 500)] * 2  # mean ± sd against dt


def test_member_k_starts_where_an_ensemble_s_member_k_does(swept):
    """The starts (``Members.starts``) are an ensemble's members' (``Perturbation``), bit for bit;
    the members' sweeps differ run by run."""
    scene = load_scene("tc2_steady", ne=2)
    ensemble = members_run("tc2_steady", 2, Perturbation(1.0, seed=0), device="cpu", ne=2).states()
    assert np.array_equal(Members(2, Perturbation(1.0, 0)).starts({"kgu35": scene}), ensemble)
    assert "degrees" not in Members(2, Perturbation(1.0, 0)).key(0, ensemble[0])  # white noise's keys as before
    band = Members(2, Perturbation(1.0, 0, (1, 4)))
    in_band = members_run("tc2_steady", 2, Perturbation(1.0, 0, (1, 4)), device="cpu", ne=2).states()
    assert np.array_equal(band.starts({"kgu35": scene}), in_band) and band.key(1, in_band[1])["degrees"] == [1, 4]
    first, second = (pd.read_csv(swept / f"member{k}" / "sweep.csv") for k in range(2))
    assert (first["total_error"] != second["total_error"]).all()


def test_a_rerun_reuses_a_member_s_runs_and_another_seed_makes_them_again(swept, capsys, monkeypatch):
    without_sweep_figures(monkeypatch)
    code, out, _ = cli_main(capsys, *ARGS, *MEMBERS, "--output", str(swept), "--overwrite")
    assert code == 0 and out.count("runs: 2 reused, 0 made") == 2 and "other settings" not in out
    code, out, _ = cli_main(capsys, *ARGS, *MEMBERS, "--seed", "3", "--output", str(swept), "--overwrite")
    assert code == 0 and out.count("start.seed 0 (now 3)") == 6  # each member's reference run and its two runs


@pytest.mark.parametrize(
    ("more", "says"),
    [
        (["--members", "2"], "go together (--perturbation, --initial or --vary missing)"),
        (["--perturbation", "1"], "go together (--members missing)"),
        (
            ["--members", "2", "--perturbation", "1", "--vary", "case.h0=1,2"],
            "--perturbation and --vary: the members start",
        ),
        (["--members", "2", "--vary", "case.h0=1,2", "--seed", "1"], "--seed only with --members N --perturbation M"),
        (["--members", "2", "--vary", "planet.radius=1,2"], "'planet.radius' cannot differ between members"),
        (["--members", "2", "--initial", "/nonexistent/ens.nc"], "not a readable netCDF file"),
        (["--members", "2", "--vary", "case.h0=1,2", "--perturbation-degrees", "1,3"], "--perturbation-degrees only"),
        (["--members", "3", "--vary", "case.h0=1,2"], "variants: case.h0 needs 3 values, one a member"),
        (["--members", "1", "--perturbation", "1"], "--members must be an integer >= 2"),
        (["--seed", "1"], "--seed only with --members N --perturbation M"),
        (["--members", "2", "--perturbation", "0"], "--perturbation must be a finite number > 0"),
        # a band past the ne2 grid's degrees (run had this check; the sweep made noise that aliased)
        (
            ["--members", "2", "--perturbation", "1", "--perturbation-degrees", "1,500"],
            "--perturbation-degrees 1,500: the ne=2 np=4 grid resolves degrees up to about 12",
        ),
    ],
)
def test_bad_member_options_are_one_line_and_exit_2(capsys, tmp_path, more, says):
    code, _, err = cli_main(capsys, *ARGS, *more, "--output", str(tmp_path / "s"))
    assert code == 2 and says in err and len(err.strip().splitlines()) == 1, err
    assert not (tmp_path / "s").exists()


def test_members_from_an_ensemble_s_file_start_where_its_members_are(tmp_path, capsys, monkeypatch):
    """--initial: member k's sweep starts from the file's member k (``MemberFile``, as an ensemble
    continued from it starts), its runs keyed by that start's SHA-256."""
    without_sweep_figures(monkeypatch)
    ens = tmp_path / "ens.nc"
    assert (
        main(
            [
                "run",
                "tc2_steady",
                "--ne",
                "2",
                "--days",
                "0.5",
                "--members",
                "2",
                "--perturbation",
                "2",
                "--output",
                str(ens),
            ]
        )
        == 0
    )
    scene = load_scene("tc2_steady", ne=2)
    starts = Members(2, MemberFile(ens)).starts({"kgu35": scene})
    states = members_run("tc2_steady", 2, MemberFile(ens), device="cpu", ne=2).states()
    assert np.array_equal(starts, states) and not np.array_equal(starts[0], starts[1])
    out = tmp_path / "s"
    code, text, _ = cli_main(
        capsys, *ARGS, "--members", "2", "--initial", str(ens), "--device", "cpu", "--output", str(out)
    )
    assert code == 0 and f"from {ens}" in text
    spread = pd.read_csv(out / "members.csv")
    assert list(spread["stable"]) == [2, 2] and (spread["temporal_error_spread"] > 0).all()


def test_a_varied_member_s_sweep_is_the_sweep_of_its_own_scene(tmp_path, monkeypatch):
    """--vary: member k's sweep is the single sweep of the scene with member k's value (its runs
    and reference run at its g), the same errors to the bit."""
    without_sweep_figures(monkeypatch)
    vary = tmp_path / "vary"
    assert (
        main(
            [*ARGS, "--members", "2", "--vary", "planet.gravity=9.80616,9.7", "--device", "cpu", "--output", str(vary)]
        )
        == 0
    )
    alone = tmp_path / "alone"
    assert main([*ARGS, "-s", "planet.gravity=9.7", "--device", "cpu", "--output", str(alone)]) == 0
    member, single = (pd.read_csv(p / "sweep.csv") for p in (vary / "member1", alone))
    for column in ("total_error", "temporal_error", "total_energy_change"):
        np.testing.assert_array_equal(member[column], single[column])
    first = pd.read_csv(vary / "member0" / "sweep.csv")
    assert (first["total_error"] != member["total_error"]).all()
