"""The stability suite: bisection bookkeeping (fast) and the hard cases at small size (slow)."""

import dataclasses
import math

import pandas as pd
import pytest
import xarray as xr

from swe_sphere.config.scene import load_scene
from swe_sphere.core.constants import DAY
from swe_sphere.simulation.simulation import Simulation
from swe_sphere.steppers import STEPPERS
from swe_sphere.studies import stability
from swe_sphere.studies.sweep import explicit_limits


def test_bisection_brackets_a_known_limit(monkeypatch, tmp_path):
    """With a fake criterion 'stable iff dt <= 1000 s' the search ends with a stable
    dt <= 1000 s and an unstable one above it, within the 5 % tolerance."""
    monkeypatch.setattr(
        stability,
        "run_is_stable",
        lambda scene, device: (scene.dt <= 1000.0, "", 0.0, {"steps": round(86400 / scene.dt), "day": 1.0}),
    )
    scene = load_scene("tc2_steady", ne=2, days=1.0, stepper="ssprk3")
    r = stability.largest_stable_dt(scene, "cpu", log=lambda *_: None)
    assert r.dt_stable == DAY / 87 and r.dt_stable <= 1000.0 < r.dt_unstable <= 1.05 * r.dt_stable
    assert all((dt <= 1000.0) == ok for dt, ok, _, _ in r.trials)
    assert r.courant_gravity == pytest.approx(r.dt_stable / scene.dt * load_courant(scene), rel=1e-12)
    csv, nc = stability.write_table([r, dataclasses.replace(r, stepper="rk4")], tmp_path)
    df = pd.read_csv(csv)
    assert list(df["stepper"]) == ["ssprk3", "rk4"] and df["dt_stable"][0] == pytest.approx(DAY / 87)
    with xr.open_dataset(nc) as ds:  # one row a (case, stepper), as stability.csv
        assert list(ds.stepper.values) == ["ssprk3", "rk4"] and list(ds.case.values) == ["tc2_steady"] * 2
        table = ds.set_index(row=["case", "stepper"])
        assert float(table.dt_stable.sel(row=("tc2_steady", "rk4"))) == pytest.approx(DAY / 87)


@pytest.mark.parametrize("days, every, part", [(0.5, 1.0, 0.5), (1.0, 0.25, 0.25), (2.0, 1.0, 1.0)])
def test_every_trial_dt_divides_the_run_and_its_output_interval(monkeypatch, days, every, part):
    """A half-day run tried Δt = 86400 s / n, most of which do not divide it, and each run was
    rounded to a whole number of steps: the bisection is on steps per ``span``, the longest
    interval that divides the day, the run and its output interval (a day for whole days, as
    before)."""
    monkeypatch.setattr(
        stability, "run_is_stable", lambda s, device: (s.dt <= 1000.0, "", 0.0, {"steps": 1, "day": s.days})
    )
    scene = load_scene("tc2_steady", ne=2, days=days, stepper="ssprk3", overrides={"output.every_days": every})
    assert stability.span(scene) == part * DAY
    r = stability.largest_stable_dt(scene, "cpu", log=lambda *_: None)
    for dt, *_ in r.trials:
        for interval in (days, min(every, days)):
            steps = interval * DAY / dt
            assert abs(steps - round(steps)) < 1e-9, (dt, interval)
    assert r.dt_stable <= 1000.0 < r.dt_unstable <= 1.05 * r.dt_stable


def test_suite_days_and_overrides_reach_every_scene(monkeypatch):
    """``--days`` sets the run length of the cases that do not fix one (Galewsky: 6 → 12
    days; the 100-day TC2 keeps 100) and ``-s`` overrides every case (∇⁴ e-folding
    3 h → 6 h halves ν, the rule ν ∝ 1/τ)."""
    seen = {}
    monkeypatch.setattr(stability, "largest_stable_dt", lambda scene, device, log: seen.setdefault(scene.name, scene))
    cases = [c for c in stability.HARD_CASES if c[0] in ("galewsky", "tc2_steady_alpha_pi4_100d")]
    stability.run_suite(
        cases, ["rk4"], "cpu", ne=4, days=12.0, overrides={"hyperviscosity.efold_hours": 6.0}, log=lambda *_: None
    )
    assert seen["galewsky"].days == 12.0 and seen["tc2_steady_alpha_pi4_100d"].days == 100.0
    assert seen["galewsky"].nu == pytest.approx(load_scene("galewsky", ne=4).nu / 2, rel=1e-12)


def test_under_step_control_the_suite_bisects_the_first_step_and_says_so(tmp_path):
    """Under error control a run ends from any first step up to a day (the controller rejects
    what is too long): dt stable is that first step, beside the steps the run took (its own,
    as a run made alone), the rejected ones and the mean step; the table says which rows are
    controlled, and the files hold them."""
    scene = load_scene(
        "tc5_mountain", ne=2, days=1.0, stepper="bs32", overrides={"time.control": "error", "time.rtol": 1e-4}
    )
    said = []
    r = stability.largest_stable_dt(scene, "cpu", log=said.append)
    alone = Simulation(dataclasses.replace(scene, dt=DAY), "cpu", progress=False).run(None).history[-1]
    assert r.control == "error" and r.dt_stable == DAY and math.isnan(r.dt_unstable)
    assert (r.steps, r.rejected_steps) == (alone["steps"], alone["rejected_steps"]) and r.rejected_steps >= 1
    assert r.dt_mean == DAY / r.steps < DAY / 4
    assert all(" first dt = " in line for line in said) and f"{r.steps} steps ({r.rejected_steps} rejected)" in said[-1]
    table = stability.format_table([r])
    assert table.splitlines()[-1].startswith("under step control dt stable is the largest first step")
    assert f"{'error':>8s} {r.steps:7.0f} {r.rejected_steps:8.0f} {r.dt_mean:8.1f}" in table
    csv, _ = stability.write_table([r], tmp_path)
    row = pd.read_csv(csv).iloc[0]
    assert row["control"] == "error" and row["steps"] == r.steps and row["dt_mean"] == pytest.approx(r.dt_mean)


def load_courant(scene):
    return Simulation(scene, "cpu", progress=False).courant()["courant_gravity"]


def test_unstable_run_is_detected():
    scene = load_scene("tc2_steady", ne=2, days=2.0, stepper="ssprk3", dt=21600.0)
    ok, reason, _, _ = stability.run_is_stable(scene, "cpu")
    assert not ok and "blow-up" in reason


# the (case, stepper) pairs known to blow up in the test below (docs/explanation/methods.md, "The ∇⁴ rule"):
# strict, so that one which comes to run to the end fails the test until it is taken off
KNOWN_UNSTABLE = {
    ("tc6_inviscid_ne30", "epi2"): "no ∇⁴: blows up on day 12.6 at 675 s (ne4); the other steppers run 14 days",
    ("tc6_inviscid_ne30", "epi3"): "no ∇⁴: blows up on day 12.8 at 675 s (ne4); the other steppers run 14 days",
}


@pytest.mark.slow
@pytest.mark.parametrize(
    "label,name",
    [
        pytest.param(
            label,
            name,
            marks=[pytest.mark.xfail(strict=True, raises=AssertionError, reason=KNOWN_UNSTABLE[label, name])]
            if (label, name) in KNOWN_UNSTABLE
            else [],
        )
        for label, *_ in stability.HARD_CASES
        for name in STEPPERS
    ],
)
def test_every_stepper_stable_within_its_limit(label, name):
    """Every stepper finishes each hard case (small grid) at the scene's default Δt or,
    where that is above the stepper's measured Courant limit on the initial state
    (``largest_dt_within_limit``, the Δt the run's warning offers), at the largest
    whole-day fraction within it: the scene's Δt is its own stepper's, which
    leapfrog (limit 0.58) cannot take."""
    _, scene_name, days, _ = next(c for c in stability.HARD_CASES if c[0] == label)
    scene = load_scene(scene_name, ne=4, days=days, stepper=name)
    dt_max = Simulation(scene, "cpu", progress=False).largest_dt_within_limit()
    if dt_max is not None and dt_max < scene.dt:
        scene = dataclasses.replace(scene, dt=DAY / math.ceil(DAY / dt_max))
    ok, reason, _, _ = stability.run_is_stable(scene, "cpu")
    assert ok, f"{label} {name} dt={scene.dt}: {reason}"


@pytest.mark.slow
def test_fully_implicit_stable_at_30x_gravity_wave_limit_on_tc5():
    base = load_scene("tc5_mountain", ne=4, stepper="implicit")
    dt_gw = explicit_limits(base, "cpu")["dt_gravity"]
    n = math.floor(DAY / (30 * dt_gw))  # the shortest whole-day fraction that is >= 30x the limit
    scene = dataclasses.replace(base, dt=DAY / n)
    assert scene.dt >= 30 * dt_gw
    ok, reason, _, _ = stability.run_is_stable(scene, "cpu")
    assert ok, reason


def test_local_time_stepping_on_a_refined_mesh_outlasts_rk4(tmp_path, capsys):
    """``stability --mesh`` runs every case on the file's elements: on the ne4 cube refined 2×
    over TC5's mountain lts (MIS4a/RK4, two levels) holds a longer step than rk4 (4320 s
    against 2541 s over half a day: the coarse level's elements are twice the fine ones, and
    the fine ones take two steps); a case that fixes its own grid is
    refused with --mesh, one line, exit 2, nothing written."""
    from swe_sphere.cli import main
    from swe_sphere.grid.refine import Box, refined_cube
    from swe_sphere.mesh.mesh import write_exodus

    from helpers import one_line

    mesh = write_exodus(tmp_path / "r4.g", refined_cube(4, Box(15.0, 45.0, 255.0, 285.0), 1))
    args = ["stability", "--mesh", str(mesh), "--days", "0.5", "--steppers", "lts,rk4"]
    code = main([*args, "tc6_inviscid_ne30", "--output", str(tmp_path / "no")])
    one_line(code, capsys.readouterr().err, 2, "tc6_inviscid_ne30 fixes its grid", "--mesh")
    assert not (tmp_path / "no").exists()
    assert main([*args, "tc5_mountain", "--output", str(tmp_path / "s")]) == 0
    table = pd.read_csv(tmp_path / "s" / "stability.csv").set_index("stepper")
    assert table.loc["lts", "ne"] == 0
    assert table.loc["lts", "dt_stable"] > 1.3 * table.loc["rk4", "dt_stable"]
