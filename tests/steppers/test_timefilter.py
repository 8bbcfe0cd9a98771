"""The Lanczos low-pass in time (Duchon 1979) and the sweep's --filter-days option."""

from __future__ import annotations

import math

import numpy as np
import pytest

from swe_sphere.cli import main
from swe_sphere.steppers.timefilter import TimeFilter, lanczos_weights, response

from helpers import TINY_SWEEP, cli_one_line


def test_weights_sum_to_one_symmetric_half_power_at_cutoff():
    w = lanczos_weights(0.0625, 24)
    assert w.size == 49 and w.sum() == pytest.approx(1.0, abs=1e-15)
    np.testing.assert_array_equal(w, w[::-1])
    assert w[0] == w[-1] == pytest.approx(0.0, abs=1e-18)  # the sigma factor's zeros at ±n
    assert response(w, 0.0625) == pytest.approx(0.5, abs=0.01)  # measured 0.5017


def test_slow_sine_survives_fast_sine_removed():
    """A 2-day filter over ±3 days of 3-hourly snapshots: a 20-day sine passes to
    2e-4 (measured response 1.00012), a 12-hour one and an 8-hour one are gone."""
    f = TimeFilter(period_days=2.0)
    days = f.days(15.0)
    assert days[0] == pytest.approx(12.0) and days[-1] == pytest.approx(18.0) and days.size == 49
    slow = np.sin(2 * math.pi * days / 20.0 + 0.3)
    fast = np.sin(2 * math.pi * days / 0.5 + 1.1) + 0.5 * np.cos(2 * math.pi * days * 3)
    # snapshots of a 2-node "field": the slow + fast signal and the fast one alone
    filtered = f.apply(np.stack([slow + fast, fast], axis=1))
    exact_slow = math.sin(2 * math.pi * 15.0 / 20.0 + 0.3)
    assert filtered[0] == pytest.approx(exact_slow, abs=1e-3)
    assert abs(filtered[1]) < 1e-4


@pytest.mark.parametrize(
    "options, message",
    [
        (["--filter-days", "-2"], "filter period days must be positive"),
        (["--filter-days", "2", "--filter-window", "-1"], "filter half window days must be positive"),
        (["--filter-days", "2", "--filter-window", "3"], "starts before the run"),  # the run is 1 day
        (["--filter-days", "0.2"], "needs snapshots more often"),
        (["--filter-days", "2", "--filter-window", "0.3"], "not a multiple of its 3 h snapshots"),
        (
            ["--filter-days", "1", "--filter-window", "0.5", "--dt", "7200"],
            "the filter's 3 h snapshot interval of 0.125 days is not a whole number of steps of dt = 7200 s",
        ),
    ],
)
def test_bad_filter_options_exit_2_with_one_line(tmp_path, capsys, options, message):
    out = tmp_path / "sweep"
    args = ["sweep", "tc2_steady", "--ne", "2", "--days", "1", "--steppers", "ssprk3", "--output", str(out), *options]
    cli_one_line(capsys, args, 2, message)
    assert not out.exists()  # nothing written


def test_filtered_sweep_scores_the_balanced_flow(tmp_path):
    """A tiny TC2 sweep with a 1-day filter over ±0.5 day: the runs go on to day 1.5,
    their counters are those to day 1, the filtered temporal error is reported and
    the filtered criterion has verdicts."""
    import pandas as pd

    out = tmp_path / "sweep"
    args = [
        *TINY_SWEEP,
        "--output",
        str(out),
        "--filter-days",
        "1",
        "--filter-window",
        "0.5",
    ]
    assert main(args) == 0
    df = pd.read_csv(out / "sweep.csv")
    assert list(df["steps"]) == [48, 24]
    assert (df["temporal_error_filtered"] > 0).all() and (df["temporal_error_filtered_vorticity"] > 0).all()
    # measured: filtered 3.3e-7, 2.6e-6 against unfiltered 1.4e-5, 9.6e-5: at ne2 most of TC2's
    # temporal error is fast (gravity-wave) noise that the filter removes
    assert (df["temporal_error_filtered"] < 0.1 * df["temporal_error"]).all()
    assert df.loc[1, "temporal_error_filtered"] > df.loc[0, "temporal_error_filtered"]
    v = pd.read_csv(out / "verdicts.csv")
    assert {"balanced flow (filtered h+hs)", "balanced flow (filtered vorticity)"} <= set(v["criterion"])
    for _, r in v[v["criterion"] == "balanced flow (filtered vorticity)"].iterrows():
        limit = r["threshold"] * r["spatial_error"]
        if np.isfinite(r["dt"]):  # the cheapest qualifying run, scored by its filtered vorticity
            assert (
                r["temporal_error"] == df.loc[df["dt"] == r["dt"], "temporal_error_filtered_vorticity"].iloc[0] <= limit
            )
        else:
            assert (df["temporal_error_filtered_vorticity"] > limit).all()
    assert sorted((out / "runs").glob("*.json"))[0].name.endswith("_lp1d0.5d3h.json")


def test_filtered_sweep_says_when_it_caps_the_courant_factor(tmp_path, capsys):
    """Δt must divide the 3 h snapshot interval, so a --courant factor past it runs
    at 3 h; the sweep says so in one line instead of silently."""
    import pandas as pd

    out = tmp_path / "sweep"
    args = [
        "sweep",
        "tc2_steady",
        "--ne",
        "2",
        "--days",
        "1",
        "--steppers",
        "imex",
        "--courant",
        "1,5",
        "--device",
        "cpu",
        "--output",
        str(out),
        "--filter-days",
        "1",
        "--filter-window",
        "0.5",
    ]
    assert main(args) == 0
    notes = [line for line in capsys.readouterr().out.splitlines() if "capped" in line]
    assert len(notes) == 1 and notes[0].startswith("note        --courant 5: dt capped at the filter's 3 h"), notes
    assert pd.read_csv(out / "sweep.csv")["dt"].max() == 10800.0
