"""docs/explanation/efficiency/tables.py, the script that makes the efficiency study's tables and
figures from sweep folders: it runs on any sweep folder, and refuses in one line what
is not one (it ended in a traceback)."""

from __future__ import annotations

import importlib.util
import math
import runpy
import shutil
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

from swe_sphere.cli import main

from helpers import without_sweep_figures

SCRIPT = Path(__file__).resolve().parents[2] / "docs" / "explanation" / "efficiency" / "tables.py"


@pytest.fixture(scope="module")
def sweep(tmp_path_factory) -> Path:
    """A TC2 sweep (ne = 2, 1 day, ssprk3 at three steps), in a folder named as the study's; its
    own figures left empty (the script reads its tables, not its PNGs)."""
    out = tmp_path_factory.mktemp("study") / "tc2_ne2"
    args = ["sweep", "tc2_steady", "--ne", "2", "--days", "1", "--steppers", "ssprk3", "--dt", "900,1800,3600"]
    with pytest.MonkeyPatch.context() as mp:
        without_sweep_figures(mp)
        assert main([*args, "--device", "cpu", "--output", str(out)]) == 0
    return out


@dataclass
class Done:
    """What the script ended with: its exit status and what it wrote."""

    returncode: int
    stdout: str
    stderr: str


@pytest.fixture
def tables(monkeypatch, capsys):
    """``tables(cwd, *args)``: the script run as ``python tables.py ARGS`` runs it, in ``cwd``,
    in this process (a process of its own imported pandas, xarray and matplotlib again, a second
    or more each call): its exit status (argparse's exit, else 0; a traceback fails the test) and
    its output."""

    def run(cwd, *args) -> Done:
        monkeypatch.chdir(cwd)
        monkeypatch.setattr(sys, "argv", [str(SCRIPT), *map(str, args)])
        capsys.readouterr()
        try:
            runpy.run_path(str(SCRIPT), run_name="__main__")
            code = 0
        except SystemExit as stop:
            code = stop.code
        out, err = capsys.readouterr()
        return Done(code, out, err)

    return run


def test_the_tables_and_a_missing_figures_folder_made(sweep, tmp_path, tables):
    proc = tables(tmp_path, sweep, "--figures", "figs/new")
    assert proc.returncode == 0, proc.stderr
    assert "| tc2 | 2 | total h+hs |" in proc.stdout
    assert (tmp_path / "figs" / "new" / "tc2_ne2_temporal_error.png").is_file()


def test_a_sweep_folder_of_another_name_takes_case_and_grid_from_its_table(sweep, tmp_path, tables):
    shutil.copytree(sweep, tmp_path / "my sweep")
    proc = tables(tmp_path, "my sweep", "--temporal-regions")
    assert proc.returncode == 0, proc.stderr
    assert "| tc2_steady | 2 | total h+hs |" in proc.stdout
    assert "no temporal errors by region: the mesh has one resolution" in proc.stdout


def test_reach_interpolates_at_the_bracketing_runs_order_and_extrapolates_at_the_nearest():
    """The step at which a temporal error reaches 10 % of the spatial error: between the two runs
    that bracket it at their order, else at the order of the two runs nearest it."""
    spec = importlib.util.spec_from_file_location("efficiency_tables", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    at, inside = module.reach([1, 2, 4], [0.0125, 0.05, 0.2])  # (2, 4) brackets 0.1, order 2
    assert inside and at == pytest.approx(2 * math.sqrt(2), rel=1e-14)
    at, inside = module.reach([1, 2, 4], [0.001, 0.01, 0.02])  # beyond: the last pair's order 1
    assert not inside and at == pytest.approx(20, rel=1e-14)
    at, inside = module.reach([1, 2, 4], [0.4, 0.8, 3.2])  # below: the first pair's order 1
    assert not inside and at == pytest.approx(0.25, rel=1e-14)
    assert math.isnan(module.reach([1], [0.05])[0])


@pytest.mark.parametrize(
    "make, args, words",
    [
        (lambda d: (d / "empty").mkdir(), ["empty"], "empty: not a sweep folder (no sweep.csv or verdicts.csv"),
        (lambda d: (d / "figs").write_text(""), ["SWEEP", "--figures", "figs"], "--figures figs: not a folder"),
    ],
    ids=["not_a_sweep", "figures_is_a_file"],
)
def test_what_is_refused_is_one_line_before_any_table(sweep, tmp_path, tables, make, args, words):
    make(tmp_path)
    proc = tables(tmp_path, *[sweep if a == "SWEEP" else a for a in args])
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    assert proc.returncode == 2 and len(lines) == 1 and words in lines[0], proc.stderr
    assert proc.stdout == ""
