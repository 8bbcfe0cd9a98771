"""The frontier on a tiny ladder: TC2 at ne 2–3 × np 3–4, kgu35 and RK4 near their limits, 0.1 day;
its front, its files, and a rerun that reuses every run."""

import json
import math

import numpy as np
import pandas as pd
import pytest
import xarray as xr

from swe_sphere.core.errors import OutputError
from swe_sphere.simulation.simulation import Simulation
from swe_sphere.studies import frontier

from helpers import without_sweep_figures

LADDER = dict(ne=[3, 2], np_=[4, 3], steppers=["kgu35", "rk4@0.8"], days=0.1)


def test_the_front_of_a_known_set_of_points():
    costs = [1.0, 2.0, 2.0, 3.0, 4.0, 0.5, 5.0, math.nan, 3.0]
    errors = [1.0, 0.5, 0.8, 0.5, 0.1, 2.0, 0.1, 0.01, 0.5]
    # (2, 0.8) by (2, 0.5); (3, 0.5) by (2, 0.5), twice; (5, 0.1) by (4, 0.1); NaN: an unstable run, on no front
    np.testing.assert_array_equal(
        frontier.pareto_front(costs, errors), [True, True, False, False, True, True, False, False, False]
    )
    assert frontier.pareto_front([1.0, 1.0], [0.3, 0.3]).tolist() == [True, True]  # equal points: both
    with pytest.raises(ValueError, match="one length"):
        frontier.pareto_front([1.0], [1.0, 2.0])
    rows = [
        {"label": lab, "stable": 1, "cost_per_day": c, "error": e}
        for lab, c, e in (("a", 1.0, 1.0), ("b", 2.0, 0.5), ("c", 4.0, 0.1), ("d", 3.0, 0.5))
    ]
    assert frontier.cheapest_for(rows, 0.6)["label"] == "b"
    assert frontier.cheapest_for(rows, 0.1)["label"] == "c"
    assert frontier.cheapest_for(rows, 0.05) is None


def test_steppers_near_their_limit_are_checked():
    assert frontier.parse_runs(["kgu35", "rk4@0.5", ("fbrk32", 0.7), "kgu35"]) == (
        ("kgu35", frontier.DEFAULT_FRACTION),
        ("rk4", 0.5),
        ("fbrk32", 0.7),
    )
    for items, message in (
        (["imex"], "imex has no measured stability limit"),
        (["nope"], "unknown stepper 'nope'"),
        (["rk4@-1"], "must be a number > 0"),
        (["rk4@x"], "must be a number > 0"),
        ([], "names no stepper"),
    ):
        with pytest.raises(ValueError, match=message):
            frontier.parse_runs(items)
    with pytest.raises(ValueError, match="--np names no grid"):
        frontier.plan("tc2_steady", ne=[2], np_=[])
    with pytest.raises(ValueError, match="--error must be one of"):
        frontier.plan("tc2_steady", ne=[2], np_=[3], error="wind")


def test_the_plan_orders_the_ladder_and_picks_the_error():
    f = frontier.plan("tc2_steady", **LADDER)
    assert f.grids == ((2, 3), (2, 4), (3, 3), (3, 4)) and f.error == "h"
    assert str(f.default_output) == "frontier_tc2_steady_0.1d"
    g = frontier.plan("galewsky", ne=[2], np_=[4], reference="T341")
    assert g.error == "vorticity" and g.overrides == {"case.reference": "T341"}
    assert g.runs == (("kgu35", 0.8), ("fbrk32", 0.8))


@pytest.fixture(scope="module")
def ladder(tmp_path_factory):
    """The ladder run once: its rows, files and frontier.png; each grid's sweep without its own
    figures (four sweeps' twenty PNGs no test here reads: test_sweep.py draws a sweep's)."""
    out = tmp_path_factory.mktemp("frontier")
    f = frontier.plan("tc2_steady", **LADDER)
    with pytest.MonkeyPatch.context() as mp:
        without_sweep_figures(mp)
        rows, paths = f.run(out, "cpu", log=lambda line: None)
    return f, out, rows, paths


def test_the_ladders_rows_errors_and_front(ladder):
    _, out, rows, paths = ladder
    assert [p.name for p in paths] == list(frontier.OUTPUTS)
    assert [r["label"] for r in rows] == [
        f"ne{n}/np{p}/{s}" for n, p in ((2, 3), (2, 4), (3, 3), (3, 4)) for s in ("kgu35", "rk4")
    ]
    assert all(r["stable"] == 1 for r in rows)
    by = {r["label"]: r for r in rows}
    # TC2's h + hs against the exact solution at day 0.1, measured: each grid's error is its spatial error
    # (the RK4 run at a quarter step) within 2 %, and falls with ne and np
    measured = {"ne2/np3": 3.63e-3, "ne2/np4": 1.12e-3, "ne3/np3": 1.955e-3, "ne3/np4": 2.92e-4}
    for grid, error in measured.items():
        for s in ("kgu35", "rk4"):
            r = by[f"{grid}/{s}"]
            assert r["spatial_error"] == pytest.approx(error, rel=1e-2)
            assert r["error"] == pytest.approx(r["spatial_error"], rel=2e-2)
    assert by["ne3/np4/rk4"]["nodes"] == 6 * 9 * 9 + 2
    # every Δt divides 0.1 day (8640 s) and is at most 0.8 of the stepper's limit
    for r in rows:
        assert 8640 % r["dt"] == 0 and 0 < r["fraction_of_limit"] <= 0.8 + 1e-12
        assert r["cost_per_day"] == pytest.approx(r["cpu_time"] / 0.1) and r["cost_time"] == r["cpu_time"]
    front = frontier.pareto_front([r["cost_per_day"] for r in rows], [r["error"] for r in rows])
    assert [r["on_front"] for r in rows] == front.astype(int).tolist()
    best = frontier.cheapest_for(rows, 5e-4)  # only ne3 np4 reaches it; which stepper is the clock's
    assert best["label"].startswith("ne3/np4/") and best["on_front"] == 1


def test_the_files_hold_the_table(ladder):
    _, out, rows, _ = ladder
    df = pd.read_csv(out / "frontier.csv")
    assert list(df["label"]) == [r["label"] for r in rows]
    np.testing.assert_array_equal(df["error"], [r["error"] for r in rows])
    assert set(df["error_column"]) == {"total_error"} and set(df["reference"]) == {"exact solution"}
    with xr.open_dataset(out / "frontier.nc") as ds:
        assert ds.sizes["config"] == len(rows) and list(ds["label"].values) == list(df["label"])
        np.testing.assert_array_equal(ds["on_front"].values, df["on_front"])
        assert ds["cost_per_day"].attrs["units"] == "s" and ds.attrs["error_column"] == "total_error"
    assert (out / "frontier.png").stat().st_size > 10_000
    for n, p in ((2, 3), (3, 4)):  # each grid's sweep, with its own files
        assert len(pd.read_csv(out / f"ne{n}np{p}" / "sweep.csv")) == 2


PEERS_CSV = (
    "model,label,error,cost_per_day\nDinosaur,T42,0.767,0.155\nDinosaur,T85,0.247,2.71\npySEs,ne16 np4,0.76,18.9\n"
)


def test_peers_are_read_from_csv_or_json_and_checked(tmp_path):
    csv = tmp_path / "peers.csv"
    csv.write_text(PEERS_CSV)
    peers = frontier.read_peers(csv)
    assert peers[1] == {"model": "Dinosaur", "label": "T85", "error": 0.247, "cost_per_day": 2.71}
    assert [p["model"] for p in peers] == ["Dinosaur", "Dinosaur", "pySEs"]
    js = tmp_path / "peers.json"
    js.write_text(json.dumps([{**p, "error": str(p["error"])} for p in peers]))  # numbers as text too
    assert frontier.read_peers(js) == peers
    (tmp_path / "no_cost.csv").write_text("model,label,error\nDinosaur,T42,0.767\n")
    with pytest.raises(ValueError, match=r"no_cost.csv: peer 1 lacks cost_per_day"):
        frontier.read_peers(tmp_path / "no_cost.csv")
    (tmp_path / "bad.csv").write_text("model,label,error,cost_per_day\nDinosaur,T42,-1,0.155\n")
    with pytest.raises(ValueError, match=r"bad.csv: peer 1 \(T42\): error and cost_per_day must be numbers > 0"):
        frontier.read_peers(tmp_path / "bad.csv")
    rows = [
        {
            "label": "ne8/np3/kgu35",
            "np": 3,
            "stepper": "kgu35",
            "stable": 1,
            "on_front": 1,
            "cost_per_day": 0.03,
            "error": 0.9,
        }
    ]
    assert frontier.frontier_plot(tmp_path / "f.png", rows, peers=peers).stat().st_size > 10_000


def test_a_rerun_reuses_every_run(ladder, monkeypatch):
    f, out, rows, _ = ladder
    with pytest.raises(OutputError, match="frontier.csv"):  # the results of a finished frontier: refused
        f.run(out, "cpu", log=lambda line: None)
    runs, lines = [], []
    real_run = Simulation.run
    monkeypatch.setattr(
        Simulation, "run", lambda self, output=None, **kw: runs.append(self.scene.dt) or real_run(self, output, **kw)
    )
    without_sweep_figures(monkeypatch)
    again, _ = f.run(out, "cpu", targets=(5e-4, 1e-5), overwrite=True, log=lines.append)
    assert runs == []  # no run, no reference run, no warm-up
    assert sum(line.startswith("runs: 2 reused, 0 made") for line in lines) == 4
    table = next(line for line in lines if line.startswith("frontier: tc2_steady"))
    assert (
        "cheapest for error <= 0.0005: ne3/np4/" in table and "cheapest for error <= 1e-05: no run reaches it" in table
    )
    assert [(r["label"], r["error"], r["cpu_time"]) for r in again] == [
        (r["label"], r["error"], r["cpu_time"]) for r in rows
    ]
