"""``swe-sphere frontier`` through the in-process command line: a tiny ladder runs, writes the
frontier's files, and a bad ladder is refused in one line with nothing written."""

from __future__ import annotations

import numpy as np
import pandas as pd

from swe_sphere.studies.frontier import pareto_front

from helpers import cli_main, without_sweep_figures

PEERS = "model,label,error,cost_per_day\nDinosaur,T42,1e-3,0.1\n"


def test_a_tiny_frontier_runs_and_writes_its_table(capsys, tmp_path, monkeypatch):
    without_sweep_figures(monkeypatch)  # each grid's sweep's: the frontier's own figure is drawn and checked
    out, peers = tmp_path / "fr", tmp_path / "peers.csv"
    peers.write_text(PEERS)
    code, stdout, _ = cli_main(
        capsys, "frontier", "tc2_steady", "--ne", "2", "--np", "3,4", "--steppers", "rk4", "--days", "0.1",
        "--device", "cpu", "--output", str(out), "--peers", str(peers),
    )  # fmt: skip
    assert code == 0
    assert (out / "frontier.png").stat().st_size > 10_000  # the peer drawn on it, not in the table
    rows = pd.read_csv(out / "frontier.csv")
    assert sorted(rows["np"]) == [3, 4]
    # np 4 is more accurate than np 3 on TC2, so on the front whatever the clock measured; the
    # front is the table's own cost and error's (which run is dearer is the clock's, not asserted)
    assert (rows.sort_values("np")["error"].diff().dropna() < 0).all()
    assert rows.loc[rows["error"].idxmin(), "on_front"]
    assert np.array_equal(rows["on_front"], pareto_front(rows["cost_per_day"], rows["error"]))
    assert "front (cheapest first)" in stdout


def test_a_bad_ladder_is_one_line_and_writes_nothing(capsys, tmp_path):
    out = tmp_path / "fr"
    code, _, stderr = cli_main(
        capsys, "frontier", "tc2_steady", "--ne", "2,x", "--np", "4", "--output", str(out),
    )  # fmt: skip
    assert code == 2
    assert stderr.strip().count("\n") == 0 and "--ne" in stderr
    assert not out.exists()
    bad = tmp_path / "peers.csv"
    bad.write_text(PEERS.replace("1e-3", "0"))
    code, _, stderr = cli_main(
        capsys, "frontier", "tc2_steady", "--ne", "2", "--np", "4", "--output", str(out), "--peers", str(bad),
    )  # fmt: skip
    assert code == 2
    assert stderr.strip().count("\n") == 0 and "peers.csv: peer 1 (T42)" in stderr
    assert not out.exists()
