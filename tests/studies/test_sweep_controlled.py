"""A sweep's controlled runs (``--runs bs32@rtol=1e-5``): steps chosen by the error control,
named, scored and costed as the fixed-Δt runs are."""

import numpy as np
import pytest

from swe_sphere.simulation.simulation import Simulation
from swe_sphere.studies.sweep import verdicts
from swe_sphere.studies.sweep.plan import REFERENCE_MAX_GRAVITY_COURANT, plan

from helpers import without_sweep_figures


@pytest.fixture(autouse=True)
def no_figures(monkeypatch):
    """The sweeps' rows are this module's, not their figures (test_sweep.py's)."""
    without_sweep_figures(monkeypatch)


def test_a_sweep_s_controlled_runs_are_named_by_their_tolerance_and_scored_as_the_others(tmp_path):
    """--runs bs32@rtol=...: a run whose steps the error control chooses, from the scene's Δt;
    its row is the run made alone (the same steps and bits: its total error to the last digit),
    known as "bs32@rtol" with its tolerance, its accepted and rejected steps and its mean Δt;
    a hundredfold tighter rtol cuts the temporal error by more than ten; the verdict of
    "bs32@rtol" is its cheapest qualifying tolerance. A sweep of controlled runs alone has its
    reference at REFERENCE_MAX_GRAVITY_COURANT x the gravity-wave limit."""
    p = plan("tc2_steady", ne=2, days=0.25, runs=[("bs32", "rtol=1e-3"), ("bs32", "rtol=1e-5")])
    assert p.controlled == ("bs32@rtol=0.001", "bs32@rtol=1e-05") and p.multiples == ()
    assert p.scenes["bs32@rtol=1e-05"].control.rtol == 1e-5
    rows, info, _ = p.run(tmp_path / "s", "cpu", log=lambda line: None)
    loose, tight = rows
    assert [r["stepper"] for r in rows] == ["bs32@rtol"] * 2 and [r["tolerance"] for r in rows] == [1e-3, 1e-5]
    sim = Simulation(p.scenes["bs32@rtol=0.001"], "cpu", progress=False)
    alone = sim.run(None).history[-1]
    assert (loose["steps"], loose["rejected_steps"], loose["rhs_evals"]) == (
        alone["steps"],
        alone["rejected_steps"],
        alone["rhs_evals"],
    )
    assert loose["total_error"] == sim.scorer.total_errors(0.25 * 86400, np.stack(sim.fields()))["total_error"]
    assert loose["dt"] == 0.25 * 86400 / loose["steps"] and tight["steps"] > loose["steps"]
    assert 0 < tight["temporal_error"] < loose["temporal_error"] / 10
    limits = p.resolve(tmp_path / "s", "cpu").limits
    assert info["reference_dt"] <= REFERENCE_MAX_GRAVITY_COURANT * limits["dt_gravity"] * (1 + 1e-12)
    table = verdicts.table(rows, limits)
    v = next(
        v
        for v in verdicts.verdicts(table, info)
        if v["criterion"] == "total h+hs" and v["threshold"] == 0.1 and v["stepper"] == "bs32@rtol"
    )
    qualifying = {r["tolerance"]: r for r in table if r["temporal_error"] <= 0.1 * info["spatial_error"]}
    assert v["tolerance"] in qualifying and v["temporal_error"] == qualifying[v["tolerance"]]["temporal_error"]


def test_a_filtered_sweep_scores_a_controlled_run_s_filtered_flow(tmp_path):
    """With ``--filter-days`` a controlled run's outputs are known by their time, not their
    step (its steps land on the filter's 3-hourly snapshots): its filtered temporal error is
    scored, and its counters are those at the target day, not at the end of the half window."""
    p = plan("tc5_mountain", ne=2, days=2, runs=[("bs32", "rtol=1e-4")], filter_days=1.0)
    rows, _, _ = p.run(tmp_path / "s", "cpu", log=lambda line: None)
    (row,) = rows
    assert np.isfinite(row["temporal_error_filtered"]) and 0 < row["temporal_error_filtered"] < row["temporal_error"]
    assert row["dt"] == 2 * 86400 / row["steps"]  # the target's steps: the half window's not counted


def test_a_run_controlled_per_unit_step_is_named_apart_beside_a_fixed_one(tmp_path):
    """--runs rk4@0.5,dp54@rtol_per_day=1e-3,dp54@rtol=1e-3: the second is error control per unit
    step (``time.per_unit_step``), which -s cannot give one run of a sweep with fixed-Δt runs; its
    row is known as "dp54@rtol_per_day" with its rtol, and it takes more steps than the same rtol
    per step (its norm is a day's worth of such steps)."""
    runs = [("rk4", 0.5), ("dp54", "rtol_per_day=1e-3"), ("dp54", "rtol=1e-3")]
    p = plan("tc5_mountain", ne=2, days=0.25, runs=runs)
    assert p.controlled == ("dp54@rtol_per_day=0.001", "dp54@rtol=0.001")
    per_day, per_step = (p.scenes[n].control for n in p.controlled)
    assert (per_day.rtol, per_day.per_unit_step, per_step.per_unit_step) == (1e-3, True, False)
    rows, _, _ = p.run(tmp_path / "s", "cpu", log=lambda line: None)
    by = {r["stepper"]: r for r in rows}
    assert set(by) == {"rk4", "dp54@rtol_per_day", "dp54@rtol"} and by["dp54@rtol_per_day"]["tolerance"] == 1e-3
    assert by["dp54@rtol_per_day"]["steps"] > 2 * by["dp54@rtol"]["steps"]
