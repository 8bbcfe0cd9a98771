"""Sweep bookkeeping on a tiny grid: two steppers × two Δt, resumable, outputs that open."""

import json
import math
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import netCDF4
import numpy as np
import pandas as pd
import pytest
import xarray as xr

from swe_sphere.cases.reference import find_reference, floor
from swe_sphere.cli import main
from swe_sphere.core import workers as workers_mod
from swe_sphere.simulation.simulation import Simulation
from swe_sphere.studies import sweep as sweep_mod

import roundoff
from helpers import TINY_SWEEP, cached_grid, cli_one_line


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


def test_an_unchanged_sweep_reuses_every_run_and_says_so(swept, monkeypatch, capsys):
    """The same command again: the small-Δt run and every (stepper, Δt) run are read
    back (their files hold the key this sweep would make), nothing runs, not even a
    warm-up, the files stay as they are and each run's line says it was reused."""
    out, args = swept
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
    assert stored["key"]["code"] == sweep_mod.code_version()


def test_the_code_version_covers_the_steppers_subpackage(monkeypatch):
    """A stepper's source is in ``code_version``'s hash, so a sweep does not reuse runs made
    before an edit of it (swe_sphere/steppers/*.py, a subpackage)."""
    before = sweep_mod.code_version.__wrapped__()["source_sha256"]
    real = Path.read_bytes
    monkeypatch.setattr(Path, "read_bytes", lambda p: real(p) + (b"#" if p.name == "multirate.py" else b""))
    assert sweep_mod.code_version.__wrapped__()["source_sha256"] != before


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
    best = sweep_mod.cheapest_sufficient(rows, spatial_error=1e-4)
    assert best["a"]["cost_time"] == 2.0 and "b" not in best


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
    wall = sweep_mod.table(rows, limits, "wall")
    assert [r["cost_time"] for r in wall] == list(df["wall_time"])
    np.testing.assert_allclose([r["rhs_equivalents"] for r in wall], df["wall_time"] / df["rhs_time"], rtol=1e-12)
    with pytest.raises(ValueError, match="unknown cost clock"):
        sweep_mod.table(rows, limits, "tsc")


def test_sweep_bad_input_exits_2(tmp_path, capsys):
    assert main(["sweep", "tc2_steady", "--steppers", "euler", "--output", str(tmp_path / "o")]) == 2
    assert main(["sweep", "tc2_steady", "--dt", "-5", "--output", str(tmp_path / "o")]) == 2
    assert main(["sweep", "tc2_steady", "--ne", "2", "--dt", "7000", "--output", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 3 and "euler" in err[0] and "-5" in err[1] and "7000" in err[2]


def test_sweep_with_two_workers_gives_the_serial_rows(swept, tmp_path):
    """--workers 2 (a spawned process pool) writes the same rows as the serial sweep;
    only the timings and the thread count (each worker gets cpus // 2) differ."""
    out, args = swept
    parallel = tmp_path / "parallel"
    assert main([*args[:-1], str(parallel), "--workers", "2"]) == 0
    pd.testing.assert_frame_equal(_rows(parallel), _rows(out), check_exact=True)
    assert (pd.read_csv(parallel / "sweep.csv")["wall_time"] > 0).all()
    assert sorted(p.name for p in (parallel / "runs").glob("*.json")) == sorted(
        p.name for p in (out / "runs").glob("*.json")
    )


def _blas_threads():
    import scipy.sparse.linalg  # noqa: F401  (what the Helmholtz CG loads)
    from threadpoolctl import threadpool_info

    return sorted({i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"}), len(threadpool_info())


def test_a_sweep_worker_runs_blas_on_its_share_of_the_cores(monkeypatch):
    """Each of N workers runs numpy's and scipy's BLAS (the Helmholtz CG's inner
    products) on cpus // N threads, although a spawned worker loads neither
    library before its first run (a limit set earlier reaches no library)."""
    monkeypatch.delenv("SWE_SPHERE_THREADS", raising=False)
    monkeypatch.setattr(workers_mod, "cpus", lambda: 2)
    with workers_mod.executor(2) as pool:
        threads, libraries = pool.submit(_blas_threads).result()
    assert threads == [1] and libraries >= 2  # numpy's OpenBLAS and scipy's


def test_sweep_refuses_zero_workers(tmp_path, capsys):
    assert (
        main(["sweep", "tc2_steady", "--ne", "2", "--dt", "3600", "--workers", "0", "--output", str(tmp_path / "o")])
        == 2
    )
    assert "--workers must be >= 1 (got 0)" in capsys.readouterr().err


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
    v = {(r["criterion"], r["threshold"], r["stepper"]): r for r in sweep_mod.verdicts(rows, info)}
    assert len(v) == 3 * 2 * 2  # no filtered criterion: the sweep did not filter
    assert v[("total h+hs", 0.1, "a")]["dt"] == 100.0 and v[("total h+hs", 0.5, "a")]["dt"] == 400.0
    assert v[("balanced flow (vorticity)", 0.5, "a")]["dt"] == 400.0
    assert v[("gravity waves (divergence)", 0.5, "a")]["dt"] == 100.0
    assert v[("gravity waves (divergence)", 0.5, "a")]["cost_time"] == 4.0
    assert v[("gravity waves (divergence)", 0.5, "a")]["rhs_equivalents"] == 40.0
    assert math.isnan(v[("total h+hs", 0.5, "b")]["dt"])
    text = sweep_mod.format_verdicts(sweep_mod.verdicts(rows, info), info)
    assert "b                      no run qualifies" in text
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
    text = sweep_mod.format_summary(sweep_mod.table(rows, limits), info)
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
        **dict(zip(sweep_mod.FLOOR_OF.values(), floor("tc5_mountain_T213.nc", 15.0))),
    }
    v = sweep_mod.verdicts([row], info)
    assert {r["criterion"]: r["reference_floor"] for r in v} == {
        "total h+hs": 1.0e-5,
        "balanced flow (vorticity)": 7.8e-3,
        "gravity waves (divergence)": 3.1e-3,
    }
    lines = sweep_mod.format_verdicts(v, info).splitlines()
    flag = "within 2x of the floor: the reference cannot tell the run's spatial error from its own, so these verdicts are provisional"
    assert lines[0] == f"  total h+hs: spatial error 1.900e-05, reference floor 1.0e-05 (T213 vs T341, day 15); {flag}"
    vorticity = next(line for line in lines if line.startswith("  balanced flow (vorticity):"))
    assert (
        vorticity
        == "  balanced flow (vorticity): spatial error 7.800e-02, reference floor 7.8e-03 (T213 vs T341, day 15)"
    )
    divergence = next(line for line in lines if line.startswith("  gravity waves (divergence):"))
    assert divergence.endswith(f"reference floor 3.1e-03 (T213 vs T341, day 15); {flag}")  # 6.2e-3 = 2.0 x 3.1e-3
    unknown = {**info, **dict.fromkeys(sweep_mod.FLOOR_OF.values(), math.nan)}
    assert (
        sweep_mod.format_verdicts(v, unknown).splitlines()[0] == "  total h+hs: spatial error 1.900e-05, floor unknown"
    )


def test_a_sweep_against_another_reference_makes_its_own_runs(tmp_path, capsys, monkeypatch):
    """A TC5 sweep against the bundled T213, then into the same folder against
    another file (``case.reference``; here the same data under another name): the
    second reads back none of the first's runs (its files carry ``_ref<stem>``),
    and each records and prints what it was scored against and its floor."""
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


def test_sweep_of_the_forced_low_scores_against_its_exact_solution(tmp_path):
    """TC4 (unsteady, forced, exact): the total error is against the exact
    solution (a direct run's l2(h)), the temporal error against the RK4
    reference falls at each stepper's order (measured: rk4 3.96, 4.01;
    ssprk3 2.76, 2.95 at 900, 450, 225 s on ne4)."""
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
    assert dt_ref <= sweep_mod.REFERENCE_MAX_GRAVITY_COURANT * dt_g < df["dt"].iloc[0] / 4
    assert bool(df["stable"].iloc[0]) and np.isfinite(df["temporal_error"].iloc[0]) and df["temporal_error"].iloc[0] > 0


def test_a_sweep_whose_reference_run_blows_up_exits_3_with_its_place(tmp_path, capsys):
    """The reference run (RK4 at a quarter of the gravity-wave limit) is made to blow
    up by a ∇⁴ coefficient far past its explicit limit: exit 3, one line naming the
    reference run, the step, model time and place (not an "internal error")."""
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
        "hyperviscosity.nu=1e22",
        "--output",
        str(tmp_path / "sweep"),
    ]
    assert main(args) == 3
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and err.startswith("swe-sphere: the reference run (rk4, dt = ")
    assert "blow-up at step" in err and "model time" in err and "lat " in err


def test_sweep_of_chosen_runs_makes_only_those(tmp_path, capsys):
    """--runs STEPPER@COURANT,...: only the named (stepper, Δt) runs, the reference at a
    quarter of the smallest; sweep.nc holds those runs alone; --runs with --steppers,
    an unknown stepper or a bad multiple exit 2 with one line; a pair named twice runs once."""
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
    code = sweep_mod.code_version()
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
    assert list(df.columns[-len(sweep_mod.RECORD) :]) == list(sweep_mod.RECORD)
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
        assert set(nc.variables) == {"run", *sweep_mod.COLUMNS}
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
    real = sweep_mod.sweep_plot
    monkeypatch.setattr(sweep_mod, "sweep_plot", lambda *a, **k: titles.append(k["title"]) or real(*a, **k))
    rows = sweep_mod.table(
        pd.read_csv(out / "sweep.csv").to_dict("records"), {"dt_gravity": 1.0, "dt_advective": 1.0, "dt_leapfrog": 1.0}
    )
    with xr.open_dataset(out / "sweep.nc") as ds:
        info = dict(ds.attrs)
    sweep_mod.write_outputs(rows, info, {}, tmp_path)
    assert titles == ["tc2_steady ne2 np4, 1 days"] * 5


def _signal_at_the_start_of(dt, monkeypatch):
    """Simulation.run of the run with this Δt gets SIGINT at its first output time
    (its handler notes it; the run stops after its first step)."""
    import signal

    real_run = Simulation.run

    def run(self, output=None, **kw):
        if self.scene.dt == dt:
            inner = kw["on_output"]
            kw["on_output"] = lambda step, x: inner(step, x) or signal.raise_signal(signal.SIGINT)
        return real_run(self, output, **kw)

    monkeypatch.setattr(Simulation, "run", run)


def test_an_interrupted_sweep_says_what_it_kept_and_a_rerun_reuses_it(tmp_path, capsys, monkeypatch):
    """SIGINT in the second of two runs: exit 130, one line saying the small-Δt run and
    1 of 2 runs are kept (not "no output was written"); the rerun reuses them. SIGINT
    in the small-Δt run: the line says it is not kept and will be made again."""
    out = tmp_path / "sweep"
    args = [
        *TINY_SWEEP,
        "--output",
        str(out),
    ]
    with monkeypatch.context() as m:
        _signal_at_the_start_of(3600.0, m)
        assert main(args) == 130
    err = capsys.readouterr().err
    assert err == (
        f"swe-sphere: interrupted by SIGINT: the reference run and 1 of 2 runs are kept in {out / 'runs'}; a rerun of "
        "the same command reuses them and makes the other 1\n"
    )
    assert sorted(p.name for p in (out / "runs").iterdir()) == ["reference_rk4_450.npz", "ssprk3_1800.json"]
    assert main(args) == 0
    text = capsys.readouterr().out
    assert "reference run: rk4, dt = 450 s: reused" in text and "[1/2] ssprk3 dt = 1800 s: reused" in text
    assert "runs: 1 reused, 1 made" in text

    other = tmp_path / "other"
    with monkeypatch.context() as m:
        _signal_at_the_start_of(450.0, m)
        assert main([*args[:-1], str(other)]) == 130
    err = capsys.readouterr().err
    assert err == (
        "swe-sphere: interrupted by SIGINT in the sweep's reference run (rk4, dt = 450 s) at model day 0, which is not "
        f"kept (a rerun of the same command makes it again); the runs already in {other / 'runs'} are kept\n"
    )
    assert list((other / "runs").iterdir()) == []


def test_runs_names_the_value_that_is_not_a_number(tmp_path, capsys):
    assert main(["sweep", "tc2_steady", "--runs", "rk4@1,rk4@abc", "--output", str(tmp_path / "o")]) == 2
    assert capsys.readouterr().err == (
        "swe-sphere: error: --runs rk4@abc: 'abc' is not a number > 0 (a multiple of the "
        "gravity-wave limit, e.g. rk4@0.5)\n"
    )
    assert not (tmp_path / "o").exists()


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


def _wait_for(started, path, most=60.0):
    """Say it has started (touch ``started``), then wait until ``path`` exists (it
    never will: a task that runs until it is ended)."""
    started.touch()
    t0 = time.perf_counter()
    while not path.exists() and time.perf_counter() - t0 < most:
        time.sleep(0.05)
    return "waited"


def test_a_signal_in_a_pool_ends_its_tasks_under_way_and_queued(tmp_path):
    """KeyboardInterrupt (a Ctrl-C in the main process) leaving ``executor(2)``'s block
    once both workers run a task (each waits for an event that never comes) ends
    both tasks and the one queued behind them (it would write a file), and leaves
    no worker behind."""
    import multiprocessing

    before = set(multiprocessing.active_children())
    started = [tmp_path / f"started{i}" for i in range(2)]
    with pytest.raises(KeyboardInterrupt):
        with workers_mod.executor(2) as pool:
            waiting = [pool.submit(_wait_for, s, tmp_path / "never") for s in started]
            queued = pool.submit(Path.touch, tmp_path / "queued")
            while not all(s.exists() for s in started):
                time.sleep(0.05)
            t0 = time.perf_counter()
            raise KeyboardInterrupt
    assert time.perf_counter() - t0 < 50  # not the 60 s the tasks would wait
    for future in (*waiting, queued):
        assert isinstance(future.exception(), KeyboardInterrupt)
    assert not (tmp_path / "queued").exists()
    assert set(multiprocessing.active_children()) == before


def test_a_stored_key_says_what_changed():
    key = {"scene": {"days": 1.0, "ne": 2, "stepper_options": {}}, "device": "cpu"}
    assert sweep_mod.stale(key, json.loads(json.dumps(key))) is None
    assert sweep_mod.stale({**key, "scene": {**key["scene"], "days": 2.0, "ne": 4}}, key) == (
        "other settings: scene.days 2.0 (now 1.0), scene.ne 4 (now 2)"
    )
    assert sweep_mod.stale({**key, "device": "cuda", "code": {"version": "0.0.1"}}, key) == (
        'other settings: code {"version": "0.0.1"} (now null), device "cuda" (now "cpu")'
    )
    assert sweep_mod.stale(None, key) == "made by an earlier swe_sphere that did not record its settings"


def test_the_plan_is_what_the_cli_runs(tmp_path, capsys):
    """``plan`` with the options of ``swe-sphere sweep --runs rk4@0.77`` resolves to the
    Δt the command ran (the largest at or below 0.77 × the gravity-wave limit that divides
    the 6 h run) and to the notes it printed before its runs, the first saying the multiple
    that ran (sweep.csv's), not the 0.77 asked for; ``Plan.run`` on a copy of
    the command's runs reuses them and writes the same sweep.csv, logging the same lines."""
    cli = tmp_path / "cli"
    args = ["sweep", "tc2_steady", "--ne", "2", "--days", "0.25", "--runs", "rk4@0.77"]
    assert main([*args, "--device", "cpu", "--output", str(cli)]) == 0
    printed = capsys.readouterr().out.splitlines()
    p = sweep_mod.plan("tc2_steady", ne=2, days=0.25, runs=[("rk4", 0.77)])
    assert list(p.scenes) == ["rk4"] and p.multiples == (0.77,) and p.dts is None
    resolved = p.resolve(tmp_path / "py", "cpu")
    g = resolved.limits["dt_gravity"]
    steps = math.ceil(0.25 * 86400 / (0.77 * g) - 1e-9)
    assert resolved.dts == [0.25 * 86400 / steps] and resolved.dts[0] < 0.77 * g * (1 - 1e-3)
    assert resolved.pairs == (("rk4", resolved.dts[0]),)
    assert list(pd.read_csv(cli / "sweep.csv")["dt"]) == resolved.dts
    assert printed[: len(resolved.notes)] == resolved.notes and len(resolved.notes) == 2
    assert resolved.notes[0].startswith(f"note        --runs rk4@0.77 runs at {resolved.dts[0] / g:.3g} x the")

    py = tmp_path / "py"
    shutil.copytree(cli / "runs", py / "runs", dirs_exist_ok=True)
    logged = []
    rows, info, paths = p.run(py, "cpu", log=logged.append)
    assert [path.name for path in paths] == list(sweep_mod.OUTPUTS) and len(rows) == 1
    pd.testing.assert_frame_equal(pd.read_csv(py / "sweep.csv"), pd.read_csv(cli / "sweep.csv"), check_exact=True)
    said = "\n".join(logged).splitlines()
    assert said[:2] == printed[:2] and f"runs: 1 reused, 0 made (in {py / 'runs'})" in said
    table = [printed.index(line) for line in printed if line.startswith("stepper ")] + [
        said.index(line) for line in said if line.startswith("stepper ")
    ]
    n = len(printed) - table[0] - len(sweep_mod.OUTPUTS)  # the table, summary and verdicts
    assert n > 5
    assert said[table[1] : table[1] + n] == printed[table[0] : table[0] + n]


@pytest.mark.parametrize(
    "options, words",
    [
        (dict(runs=[("rk4", 1.0)], steppers=["rk4"]), "not both"),
        (dict(dts=[3600.0], courant=[1.0]), "one of --dt, --courant and --runs"),
        (dict(dts=[-5.0]), "--dt values must be > 0 (got -5)"),
        (dict(courant=[]), "--courant values must be > 0 (got none)"),
        (dict(runs=[("rk4", 0.0)]), "--runs values must be > 0 (got 0)"),
        (dict(dts=[7000.0]), "dt = 7000 s does not divide the run length of 1 days"),
        (dict(dts=[1000.0], filter_days=0.5), "dt = 1000 s does not divide the filter's snapshot interval of 3 h"),
    ],
)
def test_the_plan_refuses_what_the_cli_refuses(options, words):
    """Bad options raise ValueError naming them as the command line spells them, before any run."""
    given = options if "runs" in options else {"steppers": ["rk4"], **options}
    with pytest.raises(ValueError) as err:
        sweep_mod.plan("tc2_steady", ne=2, days=1, **given)
    assert words in str(err.value)


@pytest.mark.parametrize("flag", ["--runs", "--courant", "--dt"])
def test_sweep_refuses_an_empty_list(capsys, flag, tmp_path, monkeypatch):
    """An empty --runs / --courant / --dt was read as "not given" and ran the whole default sweep."""
    monkeypatch.chdir(tmp_path)
    cli_one_line(capsys, ["sweep", "tc2_steady", "--ne", "2", flag, "", "--output", "o"], 2, flag)


def test_sweeps_of_other_cases_grids_and_lengths_default_to_folders_of_their_own():
    """A page's two sweeps with no --output both wrote into ./sweep: the second met
    "output file exists: sweep/sweep.csv"."""
    names = [
        sweep_mod.plan("tc5_mountain", ne=8, days=4, runs=[("rk4", 1.0)]).default_output,
        sweep_mod.plan("tc5_mountain", ne=16, days=1, runs=[("rk4", 1.0)]).default_output,
        sweep_mod.plan("galewsky", ne=16, days=1, runs=[("rk4", 1.0)]).default_output,
        sweep_mod.plan("tc5_mountain", ne=16, np_=3, days=1, runs=[("rk4", 1.0)]).default_output,
    ]
    assert [str(p) for p in names] == [
        "sweep_tc5_mountain_ne8np4_4d",
        "sweep_tc5_mountain_ne16np4_1d",
        "sweep_galewsky_ne16np4_1d",
        "sweep_tc5_mountain_ne16np3_1d",
    ]


def _source_changed(m):
    """A run's process whose swe_sphere source is not the one the sweep started with (a
    worker started after an edit)."""
    m.setattr(sweep_mod, "code_version", lambda: {"version": "0", "source_sha256": "0123456789abcdef"})


def _reference_removed(m):
    """The reference run's file removed by another process once it was made."""
    warm_up = sweep_mod.Sweep.warm_up

    def removing(self, stepper):
        self.reference_path().unlink()
        return warm_up(self, stepper)

    m.setattr(sweep_mod.Sweep, "warm_up", removing)


@pytest.mark.parametrize(
    "change, words",
    [
        (
            _source_changed,
            ("the swe_sphere source changed while the sweep ran", "0123456789abcdef", "run the sweep again"),
        ),
        (
            _reference_removed,
            ("reference_rk4_450.npz: the sweep's reference run was removed while", "run the sweep again"),
        ),
    ],
    ids=["source", "reference"],
)
def test_a_sweep_whose_folder_changes_under_it_says_so_in_one_line(tmp_path, capsys, monkeypatch, change, words):
    """Runs that could not be told apart from another version's ended in "internal error:
    RuntimeError"; the default folder is the scene's, grid's and length's."""
    monkeypatch.chdir(tmp_path)
    with monkeypatch.context() as m:
        change(m)
        cli_one_line(capsys, TINY_SWEEP, 2, *words)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["sweep_tc2_steady_ne2np4_1d"]
