"""Scores (swe_sphere.scoring): the norms against an independent numpy implementation
of Williamson et al. (1992) eqs. 82–87 on TC2 and TC5 run fields, the days the
truth cannot score (a sweep there has no total error, and says why), and the
stability criterion that the sweep and the stability suite share."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pandas as pd
import pytest
import xarray as xr

from swe_sphere.cases import Mountain, make_case
from swe_sphere.cli import main
from swe_sphere.config import load_scene
from swe_sphere.constants import DAY
from swe_sphere.scoring import instability, unscored
from swe_sphere.simulation import RunResult

from conftest import make_sim


def integral(grid, f):
    """∫ f dA over the unique nodes with their assembled areas: another sum than
    the scoring module's Σ spheremp·f over element-local nodes."""
    return math.fsum(grid.area * grid.to_unique(f))


def numpy_norms(grid, error, true):
    """Williamson et al. (1992) eqs. 82–84 (a scalar) or 85–87 (``error`` and
    ``true`` the pointwise lengths of the wind's error and of the true wind)."""
    e, t = np.abs(error), np.abs(true)
    return {"l1": integral(grid, e) / integral(grid, t), "l2": math.sqrt(integral(grid, e * e) / integral(grid, t * t)),
            "linf": e.max() / t.max()}


def numpy_split(sim, u, v, ut, vt):
    """l2 of the vorticity and divergence of the wind error (u − ut, v − vt), by
    the model's operators, over sqrt(I(ζT² + δT²)) of the true wind."""
    def rot_div(a, b):
        x = sim.model.new_state(a, b, np.zeros_like(a))
        return sim.model.vorticity(x), sim.model.wind_divergence(x)

    (ze, de), (zt, dt) = rot_div(u - ut, v - vt), rot_div(ut, vt)
    n = math.sqrt(integral(sim.grid, zt**2 + dt**2))
    return {"l2_vorticity": math.sqrt(integral(sim.grid, ze**2)) / n, "l2_divergence": math.sqrt(integral(sim.grid, de**2)) / n}


def run_to(name, ne, days):
    scene = dataclasses.replace(load_scene(name, ne=ne, np=4, days=days), output_every_days=days)
    sim = make_sim(scene)
    return sim, sim.run(None).history[-1]


def test_tc2_errors_are_williamsons_norms():
    """TC2 (α = π/4) at ne4 after one day: the run's h and wind errors against the
    exact solution and their vorticity/divergence split, as a numpy sum over the
    unique nodes gives them (to round-off)."""
    sim, d = run_to("tc2_steady_alpha_pi4", 4, 1.0)
    u, v, h = sim.fields()
    ue, ve, he = sim.case.exact(sim.grid.lat, sim.grid.lon, DAY)
    expected = {f"{k}_h": val for k, val in numpy_norms(sim.grid, h - he, he).items()}
    expected.update({f"{k}_wind": val for k, val in numpy_norms(sim.grid, np.hypot(u - ue, v - ve), np.hypot(ue, ve)).items()})
    expected.update(numpy_split(sim, u, v, ue, ve))
    assert expected["l2_h"] > 1e-5  # a real error, not round-off
    for k, val in expected.items():
        assert d[k] == pytest.approx(val, rel=1e-12, abs=0), k
    assert sim.scorer.total_errors(DAY, sim.x.numpy()) == {
        "total_error": d["l2_h"], "total_error_vorticity": d["l2_vorticity"], "total_error_divergence": d["l2_divergence"]}


def test_tc5_errors_against_t213_are_williamsons_norms():
    """TC5 at ne4 after one day (a day the T213 file stores): h + hs and the wind
    against the interpolated reference, and the split, as the numpy sums give them;
    a sweep's total errors are the l2 ones."""
    sim, d = run_to("tc5_mountain", 4, 1.0)
    u, v, h = sim.fields()
    r = sim.scorer.reference.at(1.0, sim.grid.lat, sim.grid.lon)
    expected = {f"ref_{k}_h_surface": val for k, val in numpy_norms(sim.grid, h + sim.hs - r["h_surface"], r["h_surface"]).items()}
    expected.update({f"ref_{k}_wind": val for k, val in
                     numpy_norms(sim.grid, np.hypot(u - r["u"], v - r["v"]), np.hypot(r["u"], r["v"])).items()})
    expected.update({f"ref_{k}": val for k, val in numpy_split(sim, u, v, r["u"], r["v"]).items()})
    assert expected["ref_l2_h_surface"] > 1e-5
    for k, val in expected.items():
        assert d[k] == pytest.approx(val, rel=1e-12, abs=0), k
    assert sim.scorer.total_errors(DAY, sim.x.numpy()) == {
        "total_error": d["ref_l2_h_surface"], "total_error_vorticity": d["ref_l2_vorticity"],
        "total_error_divergence": d["ref_l2_divergence"]}


def test_temporal_and_filtered_errors_are_williamsons_norms():
    """Against another state of the same grid (TC5's start against its day 1):
    h + hs and the wind as the numpy sums give them; a filtered pair is scored
    alike, and without both filtered states the filtered errors are NaN."""
    sim, _ = run_to("tc5_mountain", 4, 1.0)
    x = sim.x.numpy()
    x0 = np.stack(sim.case.initial(sim.grid.lat, sim.grid.lon))
    hs = sim.hs
    got = sim.scorer.temporal_errors(x, x0)
    split = numpy_split(sim, x[0], x[1], x0[0], x0[1])
    expected = {"temporal_error": numpy_norms(sim.grid, x[2] - x0[2], x0[2] + hs)["l2"],
                "temporal_error_wind": numpy_norms(sim.grid, np.hypot(x[0] - x0[0], x[1] - x0[1]), np.hypot(x0[0], x0[1]))["l2"],
                "temporal_error_vorticity": split["l2_vorticity"], "temporal_error_divergence": split["l2_divergence"]}
    assert list(got) == list(expected)
    for k, val in expected.items():
        assert got[k] == pytest.approx(val, rel=1e-12, abs=0), k
    assert sim.scorer.filtered_errors(x, x0) == {"temporal_error_filtered": got["temporal_error"],
                                                 "temporal_error_filtered_vorticity": got["temporal_error_vorticity"]}
    assert all(math.isnan(e) for e in sim.scorer.filtered_errors(x, None).values())


class _NoTruth(Mountain):
    reference_file = None


def test_unscored_says_why_the_truth_cannot_score_a_day():
    tc5 = make_case("tc5_mountain")
    assert unscored(tc5, 1.0) is None and unscored(tc5, 15.0) is None
    assert unscored(tc5, 4.0) == "tc5_mountain_T213.nc stores days 0, 1, 2, 5, 10, 15, not day 4"
    assert unscored(make_case("tc2_steady"), 4.0) is None  # an exact solution scores any day
    assert unscored(_NoTruth(), 1.0) == "_NoTruth has no exact solution and no reference file"


def test_a_sweep_to_a_day_the_reference_lacks_has_no_total_error_and_says_why(tmp_path, capsys):
    """TC5 to day 0.5 (T213 stores whole days 0, 1, 2, 5, 10, 15): the total and
    spatial errors are absent (NaN), the temporal ones are there; the reason is
    printed before the runs, in the summary instead of verdicts, and in sweep.nc."""
    why = "tc5_mountain_T213.nc stores days 0, 1, 2, 5, 10, 15, not day 0.5"
    args = ["sweep", "tc5_mountain", "--ne", "2", "--days", "0.5", "--steppers", "ssprk3", "--dt", "1800",
            "--device", "cpu", "--output", str(tmp_path)]
    assert main(args) == 0
    text = capsys.readouterr().out
    assert f"note: no total or spatial error at the end, so no verdicts: {why}" in text
    assert f"spatial error: none, so no run is judged sufficient and there are no verdicts ({why})" in text
    assert "verdicts: the cheapest" not in text
    df = pd.read_csv(tmp_path / "sweep.csv")
    assert df["total_error"].isna().all() and df["total_error_vorticity"].isna().all()
    assert (df["temporal_error"] > 0).all() and (df["temporal_error_vorticity"] > 0).all()
    with xr.open_dataset(tmp_path / "sweep.nc") as ds:
        assert ds.attrs["unscored"] == why and math.isnan(ds.attrs["spatial_error"])


def _result(blowup=None, growths=(0.0,)):
    history = [{"total_energy_change": g} for g in growths]
    return RunResult(steps=1, rhs_evals=1, wall_time=0.0, setup_time=0.0, diagnostics=history[-1], courant={}, output=None,
                     blowup=blowup, history=history)


def test_instability_is_a_blow_up_or_energy_growth_past_one_percent():
    assert instability(_result()) == ""
    assert instability(_result(growths=(0.0, 0.0099, -0.5))) == ""
    assert instability(_result(growths=(0.0, 0.0123, 0.0))) == "total energy grew by 1.23%"
    assert instability(_result("blow-up at step 3", growths=(0.0, 5.0))) == "blow-up at step 3"
