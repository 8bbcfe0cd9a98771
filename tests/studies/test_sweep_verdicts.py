"""The sweep's verdicts and summary on made-up rows: the cheapest sufficient run per criterion, threshold and stepper, the regions, the reference's floor."""

import math

from swe_sphere.cases.reference import floor
from swe_sphere.studies.sweep import report, verdicts


def test_cheapest_sufficient_picks_fastest_accurate_run():
    rows = [
        {"stepper": "a", "stable": True, "temporal_error": 1e-6, "cost_time": 5.0},
        {"stepper": "a", "stable": True, "temporal_error": 5e-6, "cost_time": 2.0},
        {
            "stepper": "a",
            "stable": True,
            "temporal_error": 2e-6,
            "cost_time": float("nan"),
        },  # no time on the clock: last
        {"stepper": "a", "stable": True, "temporal_error": 5e-5, "cost_time": 1.0},  # not accurate enough
        {"stepper": "b", "stable": False, "temporal_error": float("nan"), "cost_time": 0.1},
    ]
    best = verdicts.cheapest_sufficient(rows, spatial_error=1e-4)
    assert best["a"]["cost_time"] == 2.0 and "b" not in best


def test_verdicts_per_criterion_and_threshold():
    """Each criterion picks its own cheapest qualifying run: the long step passes the
    total and balanced-flow criteria at 50 % but not the gravity-wave one."""
    base = {
        "stable": True,
        "dt_over_gravity_limit": 1.0,
        "dt_over_advective_limit": 0.1,
        "dt_over_leapfrog_limit": 2.0,
        "rhs_evals": 10,
    }
    rows = [
        {
            **base,
            "stepper": "a",
            "dt": 100.0,
            "cost_time": 4.0,
            "rhs_equivalents": 40.0,
            "temporal_error": 1e-6,
            "temporal_error_vorticity": 1e-5,
            "temporal_error_divergence": 1e-5,
        },
        {
            **base,
            "stepper": "a",
            "dt": 400.0,
            "cost_time": 1.0,
            "rhs_equivalents": 10.0,
            "temporal_error": 3e-5,
            "temporal_error_vorticity": 3e-4,
            "temporal_error_divergence": 9e-4,
        },
        {**base, "stepper": "b", "dt": 100.0, "cost_time": 0.5, "rhs_equivalents": 5.0, "stable": False},
    ]
    info = {"spatial_error": 1e-4, "spatial_error_vorticity": 1e-3, "spatial_error_divergence": 1e-3}
    v = {(r["criterion"], r["threshold"], r["stepper"]): r for r in verdicts.verdicts(rows, info)}
    assert len(v) == 3 * 2 * 2  # no filtered criterion: the sweep did not filter
    assert v[("total h+hs", 0.1, "a")]["dt"] == 100.0 and v[("total h+hs", 0.5, "a")]["dt"] == 400.0
    assert v[("balanced flow (vorticity)", 0.5, "a")]["dt"] == 400.0
    assert v[("gravity waves (divergence)", 0.5, "a")]["dt"] == 100.0
    assert v[("gravity waves (divergence)", 0.5, "a")]["cost_time"] == 4.0
    assert v[("gravity waves (divergence)", 0.5, "a")]["rhs_equivalents"] == 40.0
    assert math.isnan(v[("total h+hs", 0.5, "b")]["dt"])
    text = report.format_verdicts(verdicts.verdicts(rows, info), info)
    assert "b                      no run qualifies" in text
    # where both thresholds pick the same run, or none, one line says so (a line a threshold was 12)
    assert "    total h+hs                     <= 10%, 50% b                      no run qualifies" in text
    assert len(text.splitlines()) == 3 + 3 + 3 + 2, text  # 3 + 12 lines, one a threshold, before
    assert "  total h+hs: spatial error 1.000e-04\n" in text  # an exact solution: no floor


def test_the_summary_gives_each_stable_runs_temporal_error_by_region_over_that_regions_spatial_error():
    """On a mesh of several resolutions the summary prints, under the spatial errors of h + hs and
    of the divergence by region, each stable run's temporal errors by region and their shares of
    that region's spatial error; an unstable run has none."""
    errors = {"temporal_error_refined": 3e-6, "temporal_error_transition": 1e-6, "temporal_error_coarse": 2.5e-6}
    errors.update({k.replace("error_", "error_divergence_"): 100 * e for k, e in errors.items()})
    rows = [
        {"stepper": "rk4", "dt": 300.0, "stable": True, "temporal_error": 2e-6, **errors},
        {"stepper": "rk4", "dt": 600.0, "stable": False},
    ]
    spatial = {"refined": 3e-5, "transition": 2e-5, "coarse": 1e-4}
    info = {
        "spatial_error": 1e-4,
        **{f"spatial_error_{k}": e for k, e in spatial.items()},
        "spatial_error_vorticity": 1e-3,
        "spatial_error_divergence": 1e-3,
        **{f"spatial_error_divergence_{k}": 10 * e for k, e in spatial.items()},
        "reference_dt": 75.0,
        "reference": "exact solution",
    }
    limits = {"dt_gravity": 300.0, "dt_advective": 3000.0, "dt_leapfrog": 150.0}
    text = report.format_summary(verdicts.table(rows, limits), info)
    assert (
        "  h + hs by region (quality.element_regions): refined 3.000e-05, transition 2.000e-05, coarse 1.000e-04\n"
        "    temporal error of h + hs by region (/ that region's spatial error):\n"
        "      rk4                    dt = 300 s: refined 3.000e-06 (0.100), transition 1.000e-06 (0.050), "
        "coarse 2.500e-06 (0.025)\n"
        "  divergence by region (quality.element_regions): refined 3.000e-04, transition 2.000e-04, coarse 1.000e-03\n"
        "    temporal error of divergence by region (/ that region's spatial error):\n"
        "      rk4                    dt = 300 s: refined 3.000e-04 (1.000), transition 1.000e-04 (0.500), "
        "coarse 2.500e-04 (0.250)\n"
    ) in text
    assert "dt = 600 s:" not in text


def test_verdicts_quote_the_reference_floor_and_flag_a_spatial_error_within_2x_of_it():
    """Beside each spatial error its reference's own error (``Sweep.run``'s info, from
    ``reference.floor``); within 2x of it the line says the verdicts are provisional."""
    row = {
        "stepper": "a",
        "dt": 100.0,
        "stable": True,
        "dt_over_gravity_limit": 1.0,
        "dt_over_advective_limit": 0.1,
        "dt_over_leapfrog_limit": 2.0,
        "rhs_evals": 10,
        "cost_time": 1.0,
        "rhs_equivalents": 10.0,
        "cpu_time": 1.0,
        "wall_time": 1.0,
        "temporal_error": 1e-7,
        "temporal_error_vorticity": 1e-5,
        "temporal_error_divergence": 1e-5,
    }
    info = {
        "spatial_error": 1.9e-5,
        "spatial_error_vorticity": 7.8e-2,
        "spatial_error_divergence": 6.2e-3,
        "reference": "tc5_mountain_T213.nc",
        "reference_floor_source": "T213 vs T341, day 15",
        **dict(zip(verdicts.FLOOR_OF.values(), floor("tc5_mountain_T213.nc", 15.0))),
    }
    v = verdicts.verdicts([row], info)
    assert {r["criterion"]: r["reference_floor"] for r in v} == {
        "total h+hs": 1.0e-5,
        "balanced flow (vorticity)": 7.8e-3,
        "gravity waves (divergence)": 3.1e-3,
    }
    lines = report.format_verdicts(v, info).splitlines()
    flag = "within 2x of the floor: the reference cannot tell the run's spatial error from its own, so these verdicts are provisional"
    assert lines[0] == f"  total h+hs: spatial error 1.900e-05, reference floor 1.0e-05 (T213 vs T341, day 15); {flag}"
    vorticity = next(line for line in lines if line.startswith("  balanced flow (vorticity):"))
    assert (
        vorticity
        == "  balanced flow (vorticity): spatial error 7.800e-02, reference floor 7.8e-03 (T213 vs T341, day 15)"
    )
    divergence = next(line for line in lines if line.startswith("  gravity waves (divergence):"))
    assert divergence.endswith(f"reference floor 3.1e-03 (T213 vs T341, day 15); {flag}")  # 6.2e-3 = 2.0 x 3.1e-3
    unknown = {**info, **dict.fromkeys(verdicts.FLOOR_OF.values(), math.nan)}
    assert report.format_verdicts(v, unknown).splitlines()[0] == "  total h+hs: spatial error 1.900e-05, floor unknown"
