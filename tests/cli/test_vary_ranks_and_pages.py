"""``--vary`` twice, a serial command under mpiexec, the time left past the first step's compiling,
the efficiency page (the first hour's sixth pass, issue 117 items 5 and 14): a refusal is one line,
exit 2, made before anything is written; a command under mpiexec writes its files once."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from helpers import TINY, cli_main, one_line

RUN = ("run", "tc2_steady", *TINY, "--days", "0.1")
SWEEP = ("sweep", "tc2_steady", "--ne", "2", "--days", "1", "--steppers", "kgu35", "--dt", "5400,10800")


@pytest.fixture(autouse=True)
def _in_tmp(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)


@pytest.mark.parametrize("command", [RUN, SWEEP])
def test_a_key_varied_twice_is_refused(capsys, command):
    """Item 5: `--vary case.alpha=0,1 --vary case.alpha=0,2` ran the second values, the first
    dropped without a word."""
    twice = ("--members", "2", "--vary", "case.alpha=0,1", "--vary", "case.alpha=0,2")
    code, out, err = cli_main(capsys, *command, *twice, "--output", "v.nc" if command is RUN else "s")
    one_line(code, err, 2, "--vary 'case.alpha=0,1' and 'case.alpha=0,2': case.alpha is varied twice")
    assert out == "" and list(Path().iterdir()) == []


@pytest.mark.xdist_group("mpi")
def test_a_serial_command_under_mpiexec_runs_on_rank_0_alone(capsys, tmp_path):
    """Item 14: `mpiexec -n 2 swe-sphere plot` drew and wrote the same files on each rank (each
    path printed twice); `mpiexec -n 2 swe-sphere mesh` met the other rank's file (exit 2, no
    line: rank 1's refusal is not printed)."""
    from test_mpi import check_mpi, mpirun

    check_mpi()
    assert cli_main(capsys, *RUN, "--output", "r.nc")[0] == 0
    plot = mpirun(2, ["plot", "r.nc", "--output", "figs"], tmp_path)
    assert plot.returncode == 0, plot.stderr
    assert plot.stdout.splitlines() == ["figs/r_h_surface_day0.1.png", "figs/r_series.png"]
    mesh = mpirun(2, ["mesh", "--ne", "2", "--output", "m.g"], tmp_path)
    assert mesh.returncode == 0 and mesh.stdout.count("m.g: ne2 cube: 24 elements") == 1, mesh.stderr


def test_the_time_left_is_not_paced_by_the_first_step_s_compiling(monkeypatch):
    """Item 14: a first progress line 5 s into a 30 s run said "about 4 min left": the first step's
    compiling counted as the pace of every step. A run from day 0 to 1 whose first step (day 0.01)
    took 4 s, every other 0.1 s: at 5 s the 89 steps left take 8.9 s (the whole 5 s over 0.11 days
    said 40 s)."""
    import swe_sphere.cli.progress as progress

    now, lines = [0.0], []
    monkeypatch.setattr(progress, "clock", lambda: now[0])
    ticker = progress.ProgressLines(lines.append, 5)
    ticker.start(0.0, 1.0)
    for t, step in ((4.0, 1), (5.0, 11), (9.0, 51)):
        now[0] = t
        ticker.tick(step, step / 100)
    assert lines == ["day 0.11 of 1 (11 %), step 11, 5 s of wall time, about 9 s left"]
    slow = progress.ProgressLines(lines.append, 3)  # a first step longer than the interval: no pace yet
    now[0] = 0.0
    slow.start(0.0, 1.0)
    now[0] = 13.0
    slow.tick(1, 0.01)
    assert lines[1:] == ["day 0.01 of 1 (1 %), step 1, 13 s of wall time"]


DOCS = Path(__file__).resolve().parents[2] / "docs"


def _reached(page: Path) -> set[Path]:
    """The files ``page``'s markdown links reach, following the pages among them under docs/."""
    seen, todo = set(), [page.resolve()]
    while todo:
        here = todo.pop()
        for target in re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", here.read_text()):
            path = (here.parent / target).resolve()
            if path not in seen and path.is_file():
                seen.add(path)
                if path.suffix == ".md" and DOCS in path.parents:
                    todo.append(path)
    return seen


def test_the_efficiency_page_is_its_verdict_and_tables():
    """Item 15: the efficiency page (docs/explanation/efficiency.md) had grown to 879 lines, most
    of them the step-cost history of one issue; the page is its verdict and tables (<= 600
    lines), every figure of the study still reachable from it."""
    page = DOCS / "explanation" / "efficiency.md"
    assert len(page.read_text().splitlines()) <= 600
    figures = {p.resolve() for p in (DOCS / "explanation" / "efficiency").glob("*.png")}
    assert len(figures) >= 20 and figures - _reached(page) == set()
    assert (DOCS / "explanation" / "efficiency" / "step_cost.md").resolve() in _reached(page)
