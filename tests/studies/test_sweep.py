"""Sweep bookkeeping on a tiny grid: two steppers × two Δt, resumable, outputs that open."""

import json
import math
import os
import shutil
import subprocess
import sys

import netCDF4
import numpy as np
import pandas as pd
import pytest
import xarray as xr

from swe_sphere.cases.reference import find_reference
from swe_sphere.cli import main
from swe_sphere.simulation.simulation import Simulation
from swe_sphere.studies.sweep import report, store, verdicts
from swe_sphere.studies.sweep.plan import REFERENCE_MAX_GRAVITY_COURANT

import roundoff
from helpers import cached_grid, without_sweep_figures


@pytest.fixture(scope="module")
def swept(tmp_path_factory):
    out = tmp_path_factory.mktemp("sweep")
    args = [
        "sweep",
        "tc2_steady",
        "--ne",
        "2",
        "--days",
        "1",
        "--steppers",
        "ssprk3,implicit",
        "--dt",
        "3600,14400",
        "--device",
        "cpu",
        "--output",
        str(out),
    ]
    assert main(args) == 0
    return out, args


def test_sweep_rows_and_files(swept):
    out, _ = swept
    df = pd.read_csv(out / "sweep.csv")
    assert list(df["stepper"]) == ["ssprk3", "ssprk3", "implicit", "implicit"]
    assert list(df["dt"]) == [3600.0, 14400.0, 3600.0, 14400.0]
    # ssprk3 blows up at 14400 s (gravity-wave Courant ~ 2.6 at ne=2); the implicit stepper does not
    assert list(df["stable"]) == [1, 0, 1, 1]
    assert df.loc[1, "reason"].startswith("blow-up")
    steps = df["steps"].to_numpy()
    assert steps[0] == 24 and steps[2] == 24 and steps[3] == 6
    assert df.loc[0, "rhs_evals"] == 3 * 24  # ssprk3: 3 per step
    assert df.loc[2, "newton_iterations"] >= 24 and df.loc[2, "gmres_iterations"] > df.loc[2, "newton_iterations"]
    # errors: total error at the spatial level, temporal error far below it at the small step
    stable = df[df["stable"] == 1]
    assert (stable["total_error"] > 0).all() and (stable["total_error"] < 1e-2).all()
    assert df.loc[0, "temporal_error"] < 0.1 * df.loc[0, "total_error"]
    assert df.loc[3, "temporal_error"] > df.loc[2, "temporal_error"]  # longer step, larger time error
    # the decomposition: TC2's exact wind has zero divergence, so each split error is at the truncation level
    for part in ("vorticity", "divergence"):
        assert (stable[f"total_error_{part}"] > 0).all() and (stable[f"total_error_{part}"] < 0.15).all()
        # measured at ssprk3 3600 s: vorticity 1.9e-3 of 7.1e-2, divergence 4.2e-3 of 1.9e-2
        assert df.loc[0, f"temporal_error_{part}"] < 0.5 * df.loc[0, f"total_error_{part}"]
        assert df.loc[3, f"temporal_error_{part}"] > df.loc[2, f"temporal_error_{part}"]
    roundoff.mass_kept(roundoff.run_file_history(stable), cached_grid(2, 4).nnodes)
    np.testing.assert_allclose(df["dt_over_gravity_limit"] / df["dt"], df["dt_over_gravity_limit"][0] / 3600.0)
    with xr.open_dataset(out / "sweep.nc") as ds:  # one run dimension: sweep.csv's rows
        assert ds.sizes["run"] == len(df) == 4 and list(ds["stepper"].values) == list(df["stepper"])
        np.testing.assert_array_equal(ds["dt"].values, df["dt"])
        at = ds.where((ds.stepper == "implicit") & (ds.dt == 14400.0), drop=True)
        assert at.sizes["run"] == 1 and float(at["wall_time"][0]) == df["wall_time"][3] > 0
    for png in ("error_vs_wall_time.png", "error_vs_dt.png", "temporal_error_vs_dt.png"):
        assert (out / png).stat().st_size > 10_000


def test_an_unchanged_sweep_reuses_every_run_and_says_so(swept, monkeypatch, capsys, tmp_path):
    """The same command again: the small-Δt run and every (stepper, Δt) run are read
    back (their files hold the key this sweep would make), nothing runs, not even a
    warm-up, the files stay as they are and each run's line says it was reused. (Into a
    copy of the folder, its figures left empty: ``swept``'s stay as drawn, for the tests
    that read them.)"""
    first, args = swept
    out = tmp_path / "again"
    shutil.copytree(first, out)
    args = [*args[:-1], str(out)]
    without_sweep_figures(monkeypatch)
    before = {p.name: p.read_bytes() for p in (out / "runs").iterdir()}
    assert (
        len([n for n in before if n.endswith(".json")]) == 4
        and len([n for n in before if n.startswith("reference_")]) == 1
    )
    runs = []
    real_run = Simulation.run
    monkeypatch.setattr(
        Simulation, "run", lambda self, output=None, **kw: runs.append(self.scene.dt) or real_run(self, output, **kw)
    )
    assert main([*args, "--overwrite"]) == 0  # its results replace the first's: the same numbers
    assert runs == []
    assert {p.name: p.read_bytes() for p in (out / "runs").iterdir()} == before
    text = capsys.readouterr().out
    ref = next(n for n in before if n.startswith("reference_"))
    assert f"reference run: rk4, dt = 900 s: reused {ref} (made earlier with the same settings)" in text
    assert "[4/4] implicit dt = 14400 s: reused (made earlier with the same settings)" in text
    assert f"runs: 4 reused, 0 made (in {out / 'runs'})" in text
    stored = json.loads((out / "runs" / "ssprk3_3600.json").read_text())
    assert stored["row"]["stable"] is True and stored["row"]["steps"] == 24
    assert (
        stored["key"]["scene"]["days"] == 1.0
        and stored["key"]["scene"]["dt"] == 3600.0
        and stored["key"]["scene"]["ne"] == 2
    )
    assert stored["key"]["reference_dt"] == 900.0 and stored["key"]["device"] == "cpu"
    assert stored["key"]["code"] == store.code_version()


def test_rhs_equivalents_are_the_cpu_time_in_rhs_evaluations(swept):
    """Each run records its process CPU time beside its wall time, and the load
    average; by default (--cost cpu) it ranks by CPU time, and its cost in
    RHS-evaluation equivalents is that CPU time over one RHS evaluation timed on
    the same clock in its own process: at least its RHS count (ssprk3: 72, with
    ∇⁴ and the stage sums on top; the JFNK run: each Jacobian–vector product is one,
    plus the Helmholtz preconditioner). --cost wall ranks by wall time."""
    out, _ = swept
    df = pd.read_csv(out / "sweep.csv")
    assert (df["cpu_time"] > 0).all() and (df["rhs_cpu_time"] > 0).all() and (df["rhs_time"] > 0).all()
    assert (df["load_average"] >= 0).all() and (df["threads"] >= 1).all()
    np.testing.assert_array_equal(df["cost_time"], df["cpu_time"])
    np.testing.assert_allclose(df["rhs_equivalents"], df["cpu_time"] / df["rhs_cpu_time"], rtol=1e-12)
    stable = df[df["stable"] == 1]
    assert (stable["rhs_equivalents"] > 0.8 * stable["rhs_evals"]).all()
    rows = df.to_dict("records")
    limits = {"dt_gravity": 1.0, "dt_advective": 1.0, "dt_leapfrog": 1.0}
    wall = verdicts.table(rows, limits, "wall")
    assert [r["cost_time"] for r in wall] == list(df["wall_time"])
    np.testing.assert_allclose([r["rhs_equivalents"] for r in wall], df["wall_time"] / df["rhs_time"], rtol=1e-12)
    with pytest.raises(ValueError, match="unknown cost clock"):
        verdicts.table(rows, limits, "tsc")


def test_sweep_with_two_workers_gives_the_serial_rows(swept, tmp_path, monkeypatch):
    """--workers 2 (a spawned process pool) writes the same rows as the serial sweep;
    only the timings and the thread count (each worker gets cpus // 2) differ."""
    out, args = swept
    without_sweep_figures(monkeypatch)
    parallel = tmp_path / "parallel"
    assert main([*args[:-1], str(parallel), "--workers", "2"]) == 0
    pd.testing.assert_frame_equal(_rows(parallel), _rows(out), check_exact=True)
    assert (pd.read_csv(parallel / "sweep.csv")["wall_time"] > 0).all()
    assert sorted(p.name for p in (parallel / "runs").glob("*.json")) == sorted(
        p.name for p in (out / "runs").glob("*.json")
    )


def test_a_sweep_against_another_reference_makes_its_own_runs(tmp_path, capsys, monkeypatch):
    """A TC5 sweep against the bundled T213, then into the same folder against
    another file (``case.reference``; here the same data under another name): the
    second reads back none of the first's runs (its files carry ``_ref<stem>``),
    and each records and prints what it was scored against and its floor."""
    without_sweep_figures(monkeypatch)
    out = tmp_path / "sweep"
    args = [
        "sweep",
        "tc5_mountain",
        "--ne",
        "2",
        "--days",
        "1",
        "--steppers",
        "ssprk3",
        "--dt",
        "1800",
        "--device",
        "cpu",
        "--output",
        str(out),
    ]
    assert main(args) == 0
    text = capsys.readouterr().out
    assert "against tc5_mountain_T213.nc): " in text and ", reference floor 3.4e-06 (T213 vs T341, day 1); " in text
    first = pd.read_csv(out / "sweep.csv")
    other = tmp_path / "tc5_copy.nc"
    other.symlink_to(find_reference("tc5_mountain"))
    runs = []
    real_run = Simulation.run
    monkeypatch.setattr(
        Simulation,
        "run",
        lambda self, output=None, **kw: runs.append(self.scene.reference) or real_run(self, output, **kw),
    )
    assert main([*args, "-s", f"case.reference={other}", "--overwrite"]) == 0
    text = capsys.readouterr().out
    assert runs == [str(other)] * 3  # the small-Δt run, the warm-up and the run: none read back
    assert sorted(p.name for p in (out / "runs").iterdir()) == [
        "reference_rk4_450.npz",
        "reference_rk4_450_reftc5_copy.npz",
        "ssprk3_1800.json",
        "ssprk3_1800_reftc5_copy.json",
    ]
    assert "against tc5_copy.nc): " in text and "floor unknown" in text
    second = pd.read_csv(out / "sweep.csv")
    assert list(first["reference"]) == ["tc5_mountain_T213.nc"] and list(second["reference"]) == ["tc5_copy.nc"]
    assert second["total_error"][0] == first["total_error"][0]  # the same data scores the same
    with xr.open_dataset(out / "sweep.nc") as ds:
        assert ds.attrs["reference"] == "tc5_copy.nc" and math.isnan(ds.attrs["reference_floor"])
        assert "reference_floor_source" not in ds.attrs


def test_tiny_sweep_verdicts(swept, capsys):
    out, _ = swept
    rows = pd.read_csv(out / "sweep.csv")
    v = pd.read_csv(out / "verdicts.csv")
    assert set(v["criterion"]) == {"total h+hs", "balanced flow (vorticity)", "gravity waves (divergence)"}
    # ssprk3 is stable only at 3600 s, whose temporal errors are below 50 % of the spatial ones (test above)
    for _, r in v[(v["stepper"] == "ssprk3") & (v["threshold"] == 0.5)].iterrows():
        assert r["dt"] == 3600.0 and r["wall_time"] == rows.loc[0, "wall_time"] and r["rhs_evals"] == 72
        assert r["rhs_equivalents"] == rows.loc[0, "rhs_equivalents"]
        assert r["dt_over_leapfrog_limit"] == pytest.approx(rows.loc[0, "dt_over_leapfrog_limit"])
    # leapfrog's limit is 0.58 (|v| + c) dt/dx = 1: a shorter dt than the gravity-wave limit
    assert (rows["dt_over_leapfrog_limit"] > rows["dt_over_gravity_limit"]).all()
    for part in ("vorticity", "divergence"):
        assert (out / f"error_vs_wall_time_{part}.png").stat().st_size > 10_000


def test_sweep_of_the_forced_low_scores_against_its_exact_solution(tmp_path, monkeypatch):
    """TC4 (unsteady, forced, exact): the total error is against the exact
    solution (a direct run's l2(h)), the temporal error against the RK4
    reference falls at each stepper's order (measured: rk4 3.96, 4.01;
    ssprk3 2.76, 2.95 at 900, 450, 225 s on ne4)."""
    without_sweep_figures(monkeypatch)
    out = tmp_path / "tc4"
    assert (
        main(
            [
                "sweep",
                "tc4_forced_low",
                "--ne",
                "4",
                "--days",
                "0.25",
                "--steppers",
                "rk4,ssprk3",
                "--dt",
                "900,450,225",
                "--device",
                "cpu",
                "--output",
                str(out),
            ]
        )
        == 0
    )
    df = pd.read_csv(out / "sweep.csv")
    assert df["stable"].all()
    from swe_sphere.config.scene import load_scene

    direct = Simulation(
        load_scene("tc4_forced_low", ne=4, days=0.25, dt=450.0, stepper="rk4"), "cpu", progress=False
    ).run()
    row = df[(df["stepper"] == "rk4") & (df["dt"] == 450.0)].iloc[0]
    assert row["total_error"] == pytest.approx(direct.history[-1]["l2_h"], rel=1e-9)
    for stepper, order in (("rk4", 4), ("ssprk3", 3)):
        e = df[df["stepper"] == stepper].sort_values("dt", ascending=False)["temporal_error"].to_numpy()
        assert math.log2(e[-2] / e[-1]) >= order - 0.3, (stepper, e)


@pytest.mark.filterwarnings("error::RuntimeWarning")  # its figures have one Δt: no zero-width log axis
def test_sweep_of_large_steps_has_a_stable_reference(tmp_path):
    """Every Δt far beyond the explicit limit: the reference RK4 run is capped at a
    quarter of the gravity-wave limit (a quarter of the smallest Δt would blow up),
    and an explicit stepper's blow-up in its warm-up is recorded, not fatal."""
    out = tmp_path / "large"
    assert (
        main(
            [
                "sweep",
                "tc2_steady",
                "--ne",
                "2",
                "--days",
                "1",
                "--steppers",
                "implicit,rk4",
                "--courant",
                "12",
                "--device",
                "cpu",
                "--output",
                str(out),
            ]
        )
        == 0
    )
    df = pd.read_csv(out / "sweep.csv")
    assert list(df["stepper"]) == ["implicit", "rk4"] and not bool(df["stable"].iloc[1])
    dt_g = df["dt"].iloc[0] / df["dt_over_gravity_limit"].iloc[0]
    (ref,) = (out / "runs").glob("reference_rk4_*.npz")
    dt_ref = float(ref.name.removeprefix("reference_rk4_").removesuffix(".npz"))
    assert dt_ref <= REFERENCE_MAX_GRAVITY_COURANT * dt_g < df["dt"].iloc[0] / 4
    assert bool(df["stable"].iloc[0]) and np.isfinite(df["temporal_error"].iloc[0]) and df["temporal_error"].iloc[0] > 0


def test_a_sweep_whose_reference_run_blows_up_exits_3_with_its_place(tmp_path, capsys):
    """The reference run (RK4 at a quarter of the gravity-wave limit) is made to blow
    up by a ∇⁴ coefficient far past its explicit limit: exit 3, one line naming the
    reference run, the step, model time and place (not an "internal error"). ν = 1e19
    blows up at step 3 in 1.3 s of CPU; 1e22 blew up at step 2 but took 8.1 s (2026-11-28,
    warm kernel cache): the same failure, reported the same way."""
    args = [
        "sweep",
        "tc5_mountain",
        "--ne",
        "2",
        "--days",
        "1",
        "--steppers",
        "rk4",
        "--courant",
        "1",
        "--device",
        "cpu",
        "-s",
        "hyperviscosity.nu=1e19",
        "--output",
        str(tmp_path / "sweep"),
    ]
    assert main(args) == 3
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and err.startswith("swe-sphere: the reference run (rk4, dt = ")
    assert "blow-up at step" in err and "model time" in err and "lat " in err


def test_sweep_of_chosen_runs_makes_only_those(tmp_path, capsys, monkeypatch):
    """--runs STEPPER@COURANT,...: only the named (stepper, Δt) runs, the reference at a
    quarter of the smallest; sweep.nc holds those runs alone; --runs with --steppers,
    an unknown stepper or a bad multiple exit 2 with one line; a pair named twice runs once."""
    without_sweep_figures(monkeypatch)
    out = tmp_path / "sweep"
    args = [
        "sweep",
        "tc2_steady",
        "--ne",
        "2",
        "--days",
        "1",
        "--runs",
        "implicit@4,ssprk3@0.5,implicit@4",
        "--device",
        "cpu",
        "--output",
        str(out),
    ]
    assert main(args) == 0
    df = pd.read_csv(out / "sweep.csv")
    assert list(df["stepper"]) == ["implicit", "ssprk3"]  # in --runs order of first appearance, then by Δt
    ratio = df["dt_over_gravity_limit"] / [4, 0.5]  # the largest Δt ≤ the multiple that divides a day
    assert ((ratio > 0.9) & (ratio <= 1 + 1e-12)).all(), ratio
    assert list(df["stable"]) == [1, 1] and (df["temporal_error"] > 0).all()
    assert len(list((out / "runs").glob("*.json"))) == 2
    ref = next((out / "runs").glob("reference_*.npz")).name
    assert float(ref.split("_")[-1][:-4]) == pytest.approx(df["dt"].min() / 4, rel=1e-5)  # the name has 6 digits
    with xr.open_dataset(out / "sweep.nc") as ds:  # no stepper × dt grid of NaN
        assert ds.sizes["run"] == 2 and list(ds["stepper"].values) == ["implicit", "ssprk3"]
        assert np.isfinite(ds["wall_time"].values).all()
    capsys.readouterr()
    for bad, word in (
        (["--runs", "rk4@1", "--steppers", "rk4"], "not both"),
        (["--runs", "euler@1"], "euler"),
        (["--runs", "rk4@-1"], "-1"),
        (["--runs", "rk4"], "STEPPER@COURANT"),
    ):
        assert main(["sweep", "tc2_steady", "--ne", "2", *bad, "--output", str(tmp_path / "bad")]) == 2
        err = capsys.readouterr().err.strip()
        assert word in err and "\n" not in err, err
    assert not (tmp_path / "bad").exists()


def _rows(out):
    """sweep.csv without the columns a machine's load changes."""
    timings = [
        "wall_time",
        "cpu_time",
        "cost_time",
        "load_average",
        "startup_time",
        "setup_time",
        "rhs_time",
        "rhs_cpu_time",
        "rhs_equivalents",
        "threads",
    ]
    return pd.read_csv(out / "sweep.csv").drop(columns=timings)


TC5 = ["sweep", "tc5_mountain", "--ne", "2", "--steppers", "rk4", "--device", "cpu"]


@pytest.mark.slow  # 12 s: the default run's time is kept under ten minutes
def test_a_sweep_of_other_days_or_overrides_into_the_same_folder_makes_its_runs_again(tmp_path, capsys):
    """A user's sequence on a tiny grid: a 2-day sweep, then a 1-day one of part of
    it into the same folder. The second makes the small-Δt run and its runs again
    (it printed the 2-day errors, labelled day 1) and its rows equal a fresh 1-day
    sweep's; it says what changed. An override then makes them again too; an
    unchanged repeat reuses them."""
    out, fresh = tmp_path / "swr", tmp_path / "fresh"
    assert main([*TC5, "--days", "2", "--courant", "0.5,1", "--output", str(out)]) == 0
    two_days = _rows(out)
    capsys.readouterr()
    one_day = [*TC5, "--days", "1", "--courant", "0.5"]
    assert main([*one_day, "--output", str(out), "--overwrite"]) == 0
    text = capsys.readouterr().out
    assert "runs: 0 reused, 1 made" in text
    assert "made again: reference_rk4_" in text and "had other settings: scene.days 2.0 (now 1.0)" in text
    line = next(line for line in text.splitlines() if line.startswith("[1/1] rk4 dt = "))
    assert line.endswith("; replaces a run with other settings: scene.days 2.0 (now 1.0)"), line
    assert main([*one_day, "--output", str(fresh)]) == 0
    capsys.readouterr()
    pd.testing.assert_frame_equal(_rows(out), _rows(fresh), check_exact=True)
    assert _rows(out)["total_error"][0] != two_days["total_error"][0]
    assert _rows(out)["rhs_evals"][0] * 2 == two_days["rhs_evals"][0]

    assert main([*one_day, "-s", "hyperviscosity.efold_hours=24", "--output", str(out), "--overwrite"]) == 0
    text = capsys.readouterr().out
    assert "runs: 0 reused, 1 made" in text and "other settings: scene.nu " in text
    damped = _rows(out)
    assert damped["total_error"][0] != _rows(fresh)["total_error"][0]
    with xr.open_dataset(out / "sweep.nc") as ds:
        assert ds.attrs["overrides"] == "hyperviscosity.efold_hours=24"
    assert main([*one_day, "-s", "hyperviscosity.efold_hours=24", "--output", str(out), "--overwrite"]) == 0
    assert "runs: 1 reused, 0 made" in capsys.readouterr().out
    pd.testing.assert_frame_equal(_rows(out), damped, check_exact=True)


def test_sweep_files_record_what_the_sweep_was_made_with(swept):
    """sweep.nc's attributes and sweep.csv's last columns: scene, case, grid, days,
    overrides, stepper options, reference, device and code version (integers as integers)."""
    out, _ = swept
    code = store.code_version()
    expected = {
        "scene": "tc2_steady",
        "case": "tc2_steady",
        "ne": 2,
        "np": 4,
        "days": 1.0,
        "overrides": "",
        "reference": "exact solution",
        "time_filter": "",
        "device": "cpu",
        "swe_sphere_version": code["version"],
        "source_sha256": code["source_sha256"],
    }
    with xr.open_dataset(out / "sweep.nc") as ds:
        assert {k: ds.attrs[k] for k in expected} == expected
        assert isinstance(ds.attrs["ne"], (int, np.integer)) and json.loads(ds.attrs["stepper_options"]).keys() == {
            "ssprk3",
            "implicit",
        }
    # the hash as text: one like "01579e19..." reads as a float otherwise
    df = pd.read_csv(out / "sweep.csv", keep_default_na=False, dtype={"source_sha256": str})
    assert list(df.columns[-len(report.RECORD) :]) == list(report.RECORD)
    for k, v in expected.items():
        assert (df[k] == v).all(), k


def test_sweep_nc_describes_itself(swept):
    """sweep.nc: CF Conventions, title, history; long_name on every variable and units on
    every number; the strings (stepper, reason) CF character arrays, no string
    coordinate, no _FillValue on the run coordinate."""
    out, _ = swept
    with netCDF4.Dataset(out / "sweep.nc") as nc:
        assert nc.Conventions == "CF-1.8" and nc.title == "swe_sphere sweep: tc2_steady ne2 np4, 1 days"
        assert "swe_sphere sweep" in nc.history
        assert set(nc.variables) == {"run", *verdicts.COLUMNS}
        for name, var in nc.variables.items():
            assert var.long_name, name
            if name in ("stepper", "reason"):
                assert var.dtype == np.dtype("S1") and var.dimensions[0] == "run" and len(var.dimensions) == 2, name
            else:
                assert var.units, name
        assert "_FillValue" not in nc["run"].ncattrs()
        assert nc["dt"].units == "s" and nc["total_error"].units == "1"
    with xr.open_dataset(out / "sweep.nc") as ds:
        assert list(ds.stepper.values) == ["ssprk3", "ssprk3", "implicit", "implicit"]
        reasons = list(pd.read_csv(out / "sweep.csv")["reason"].fillna(""))
        assert list(ds.reason.values) == reasons and reasons[1].startswith("blow-up")


def test_sweep_figures_are_titled_with_case_grid_and_days(swept, monkeypatch, tmp_path):
    out, _ = swept
    titles = []
    without_sweep_figures(monkeypatch)  # the titles they are given; ``swept``'s are drawn with theirs
    real = report.sweep_plot
    monkeypatch.setattr(report, "sweep_plot", lambda *a, **k: titles.append(k["title"]) or real(*a, **k))
    rows = verdicts.table(
        pd.read_csv(out / "sweep.csv").to_dict("records"), {"dt_gravity": 1.0, "dt_advective": 1.0, "dt_leapfrog": 1.0}
    )
    with xr.open_dataset(out / "sweep.nc") as ds:
        info = dict(ds.attrs)
    report.write_outputs(rows, info, {}, tmp_path)
    assert titles == ["tc2_steady ne2 np4, 1 days"] * 5


def _cli(args, cwd, popen=False, **kw):
    """The console script's process (``python -m swe_sphere.cli``), one CPU thread:
    finished (``subprocess.run``), or started (``popen``)."""
    return (subprocess.Popen if popen else subprocess.run)(
        [sys.executable, "-m", "swe_sphere.cli", *args], cwd=cwd, env={**os.environ, "SWE_SPHERE_THREADS": "1"}, **kw
    )


def test_the_progress_bar_is_drawn_on_a_terminal_only(tmp_path):
    """Into a log file a run writes its summary and no progress bar (tqdm redrew it
    with carriage returns about 12 times a second); on a terminal (a pty) the bar is there."""
    import fcntl
    import pty
    import struct
    import termios

    args = ["run", "tc2_steady", "--ne", "2", "--days", "1", "--dt", "600", "--device", "cpu"]
    with open(tmp_path / "log", "w") as log:
        done = _cli([*args, "--output", "a.nc"], tmp_path, stdout=log, stderr=log)
    text = (tmp_path / "log").read_text()
    assert done.returncode == 0 and "a.nc" in text, text
    assert "\r" not in text and "step/s" not in text and "144/144" not in text
    main_fd, terminal = pty.openpty()
    fcntl.ioctl(
        terminal, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 100, 0, 0)
    )  # 100 columns (a new pty has 0: no bar)
    seen = b""
    try:
        child = _cli([*args, "--output", "b.nc"], tmp_path, stdout=subprocess.DEVNULL, stderr=terminal, popen=True)
        os.close(terminal)
        while True:  # until the child's end closes the terminal (EIO)
            try:
                chunk = os.read(main_fd, 65536)
            except OSError:
                break
            if not chunk:
                break
            seen += chunk
    finally:
        os.close(main_fd)
    assert child.wait() == 0 and b"\r" in seen and b"144/144" in seen, seen


@pytest.mark.slow  # 12 s: the default run's time is kept under ten minutes
def test_a_sweep_with_two_workers_says_one_line_a_run(tmp_path):
    """``sweep --workers 2`` of 9 runs into a log: before its table, the sweep's line,
    the small-Δt run's, one line per finished run and the count, nothing from the
    workers (Warp's banner, "CUDA driver not found", module loads: 108 lines before)."""
    args = [
        "sweep",
        "tc2_steady",
        "--ne",
        "2",
        "--days",
        "1",
        "--steppers",
        "rk4,ssprk3,imex",
        "--courant",
        "0.5,1,2",
        "--device",
        "cpu",
        "--workers",
        "2",
        "--output",
        "sw",
    ]
    with open(tmp_path / "log", "w") as log:
        done = _cli(args, tmp_path, stdout=log, stderr=log)
    lines = (tmp_path / "log").read_text().splitlines()
    assert done.returncode == 0, lines
    head = lines[: lines.index(next(line for line in lines if line.startswith("stepper ")))]
    assert len(head) == 13 and head[0].startswith("note        --courant 0.5 runs at ")  # the multiples that ran
    assert head[1].startswith("sweep tc2_steady ne=2 np=4, 1 days;") and head[2].startswith("reference run: rk4")
    assert sorted(int(line.split("/")[0][1:]) for line in head[3:12]) == list(range(1, 10))
    assert all(line.startswith(f"[{k}/9] ") for k, line in enumerate(head[3:12], 1))
    assert head[12] == "runs: 0 reused, 9 made (in sw/runs)"
    assert not [line for line in lines if "Warp" in line or "Module" in line or "CUDA" in line]
    summary = ("stepper ", "rk4 ", "ssprk3 ", "imex ", "spatial error", "  ", "verdicts: ", "wrote sw/")
    assert [line for line in lines[13:] if not line.startswith(summary)] == []  # the table, verdicts and files
