"""Branching from a restart file: ``run --continue R --stepper S --dt DT`` and
``Simulation.from_checkpoint(R, stepper=..., dt=...)`` start a new run from the
checkpoint's state; without a change it is the bitwise continuation; ``sweep
--from R`` starts every run of a sweep there.

The spin-up: TC2 on ne = 2 np = 4, one day of RK4 at 1 h, a restart file at its
end. The independent path a branch is checked against: a plain run (from t = 0)
of the new stepper started from the restart file's state (``Simulation(start=)``):
TC2's RHS does not depend on time, so the same steps from the same state give
the same bits whatever the clock reads.
"""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
import xarray as xr

from swe_sphere.config.scene import load_scene
from swe_sphere.core.constants import DAY
from swe_sphere.model.shallow_water import ShallowWater
from swe_sphere.simulation import checkpoint as ckpt
from swe_sphere.simulation.simulation import Simulation

from helpers import cli_main, cli_ok, cli_one_line, digest, make_sim, without_sweep_figures, write_tc2_scene

EVERY = "[output]\nevery_days = 0.25\n"
RUN = ("--device", "cpu", "--no-progress")
DT_408 = DAY / 408  # 211.76... s: step x dt / 86400 is not the output day in floating point


@pytest.fixture
def spun_up(tmp_path, monkeypatch):
    """(scene file, restart file) of one day of ``stepper`` at ``dt`` (leapfrog is unstable at 1 h),
    written in tmp_path (the cwd)."""
    monkeypatch.chdir(tmp_path)

    def make(stepper="rk4", dt=3600.0, name="spin"):
        scene = write_tc2_scene(tmp_path / f"{name}.toml", stepper=stepper, dt=dt, days=1.0, tables=EVERY)
        assert cli_ok("run", scene, *RUN, "--restart-every", "1", "--output", f"{name}.nc")
        return scene, tmp_path / f"{name}.restart.nc"

    return make


def fresh_from(restart, stepper, dt, days):
    """A plain run (t = 0, no branch) of ``stepper`` at ``dt`` for ``days`` from the restart file's state."""
    ck = ckpt.read(restart)
    scene = dataclasses.replace(ck.scene, stepper=stepper, stepper_options={}, dt=dt, days=days, output_every_days=days)
    sim = Simulation(scene, "cpu", progress=False, start=ck.x)
    sim.run(None)
    return sim


def test_a_branch_with_an_unchanged_stepper_and_dt_is_the_continuation(spun_up, tmp_path, capsys):
    """--stepper and --dt naming the checkpoint's own: the continuation, bitwise (its
    history and counters kept, no branch record)."""
    _, restart = spun_up("leapfrog", 1800.0)
    assert cli_ok("run", "--continue", restart, "--days", "2", *RUN, "--output", "cont.nc")
    assert cli_ok(
        "run",
        "--continue",
        restart,
        "--days",
        "2",
        "--stepper",
        "leapfrog",
        "--dt",
        "1800",
        *RUN,
        "--output",
        "same.nc",
    )
    with xr.open_dataset("cont.nc", decode_times=False) as a, xr.open_dataset("same.nc", decode_times=False) as b:
        assert list(b.time.values) == [1.25, 1.5, 1.75, 2.0] and b.attrs["continued_from_day"] == 1.0
        assert "branched_from" not in b.attrs and json.loads(b.attrs["scene"])["branch"] is None
        for v in ("h", "u", "v", "total_energy_change", "rhs_evals", "steps"):
            np.testing.assert_array_equal(a[v].values, b[v].values, err_msg=v)
        assert b.steps.values[-1] == 96
    sim = Simulation.from_checkpoint(restart, "cpu", days=2.0, stepper="leapfrog", dt=1800.0, progress=False)
    assert sim.step == 48 and sim.scene.branch is None and sim.stepper.steps == 48


def test_a_branch_to_another_stepper_and_dt_is_a_fresh_run_from_the_state(spun_up, tmp_path, capsys, monkeypatch):
    """RK4 at 1 h to day 1, then SSPRK3 at dt = 86400/408 s to day 2 through the CLI and
    the API: the same bits as a plain SSPRK3 run of 408 steps from the restart
    file's state; output times 1, 1.25, ..., 2 exactly (``sel(time=2)``); the file
    records where it branched from; counters start at zero, the invariants' changes
    at the branch state; the stepper's clock starts at day 1."""
    _, restart = spun_up("rk4")
    code, out, err = cli_main(
        capsys, "run", "--continue", restart, "--stepper", "ssprk3", "--dt", repr(DT_408), "--days", "2", *RUN
    )
    assert code == 0, err
    assert f"branch      from {restart} at its step 24 (day 1; rk4, dt = 3600 s): ssprk3 starts there afresh" in out
    assert "ssprk3, dt = 211.765 s, 408 steps to day 2" in out
    fresh = fresh_from(restart, "ssprk3", DT_408, 1.0)
    branched = tmp_path / f"spin_branch_ssprk3_dt{DT_408:g}.nc"
    with xr.open_dataset(branched, decode_times=False) as b, xr.open_dataset("spin.nc", decode_times=False) as spin:
        assert list(b.time.values) == [1.0, 1.25, 1.5, 1.75, 2.0]
        assert b.attrs["branched_from"] == str(restart.resolve()) and b.attrs["branched_from_step"] == 24
        assert b.attrs["branched_from_day"] == 1.0 and b.attrs["branched_from_stepper"] == "rk4"
        assert b.attrs["branched_from_dt"] == 3600.0 and "continued_from_day" not in b.attrs
        assert b.attrs["branched_from_sha256"] == digest(restart)
        assert b.attrs["stepper"] == "ssprk3" and b.attrs["dt"] == DT_408
        np.testing.assert_array_equal(b.h.sel(time=1).values, spin.h.sel(time=1).values)  # the branch state
        grid = fresh.grid
        for row, name in enumerate("uvh"):
            np.testing.assert_array_equal(
                b[name].sel(time=2).values, grid.to_unique(fresh.x.numpy()[row]), err_msg=name
            )
        assert list(b.steps.values) == [0, 102, 204, 306, 408] and b.rhs_evals.values[0] == 0
        assert b.total_energy_change.values[0] == 0.0 and b.total_energy_change.values[-1] != 0.0
    times = []
    real = ShallowWater.set_time
    monkeypatch.setattr(ShallowWater, "set_time", lambda self, t: times.append(t) or real(self, t))
    sim = Simulation.from_checkpoint(restart, "cpu", stepper="ssprk3", dt=DT_408, days=2.0, progress=False)
    assert sim.step == 0 and sim.scene.start_day == 1.0 and sim.scene.nsteps == 408
    sim.run(None)
    np.testing.assert_array_equal(sim.x.numpy(), fresh.x.numpy())
    assert times[0] == DAY and times[-1] == pytest.approx(
        2 * DAY - DT_408 / 2, abs=1e-6
    )  # SSPRK3: the last stage at t + dt/2


@pytest.mark.parametrize(
    "spin, stepper, dt",
    [("leapfrog", "leapfrog", 900.0), ("rk4", "leapfrog_trapezoidal", 1800.0)],
    ids=["leapfrog-new-dt", "rk4-to-leapfrog_trapezoidal"],
)
def test_a_leapfrog_branch_starts_as_at_t0(spun_up, tmp_path, spin, stepper, dt):
    """A leapfrog-family branch drops the restart file's history (a leapfrog
    spin-up's previous state belongs to another dt) and takes its one-step start:
    the bits of a fresh run from the state; and it differs from what the history
    would give (the same leapfrog at the same dt continued)."""
    _, restart = spun_up(spin, 1800.0 if spin == "leapfrog" else 3600.0)
    assert cli_ok(
        "run", "--continue", restart, "--stepper", stepper, "--dt", dt, "--days", "1.5", *RUN, "--output", "b.nc"
    )
    fresh = fresh_from(restart, stepper, dt, 0.5)
    with xr.open_dataset("b.nc", decode_times=False) as b:
        np.testing.assert_array_equal(b.h.sel(time=1.5).values, fresh.grid.to_unique(fresh.x.numpy()[2]))
        np.testing.assert_array_equal(b.u.sel(time=1.5).values, fresh.grid.to_unique(fresh.x.numpy()[0]))
        assert b.steps.values[-1] == round(0.5 * DAY / dt)
    sim = Simulation.from_checkpoint(restart, "cpu", stepper=stepper, dt=dt, days=1.5, progress=False)
    assert sim.stepper.steps == 0  # the stepper's own start, not the restart file's history
    if spin == "leapfrog":
        cont = Simulation.from_checkpoint(restart, "cpu", days=1.5, progress=False)
        cont.run(None)
        assert not np.array_equal(cont.x.numpy(), fresh.x.numpy())


def test_a_branched_run_continues_bitwise_and_keeps_its_record(spun_up, tmp_path):
    """A branch cut at day 1.5 (its restart file) and continued to day 2 ends on the
    bits of the branch run straight to day 2; the continued file still says where
    the run branched from."""
    _, restart = spun_up("rk4")
    branch = ("run", "--continue", restart, "--stepper", "ssprk3", "--dt", "1800", *RUN)
    assert cli_ok(*branch, "--days", "2", "--output", "whole.nc")
    assert cli_ok(*branch, "--days", "1.5", "--output", "cut.nc", "--restart-every", "0.25")
    assert cli_ok("run", "--continue", "cut.restart.nc", "--days", "2", *RUN, "--output", "rest.nc")
    with xr.open_dataset("whole.nc", decode_times=False) as a, xr.open_dataset("rest.nc", decode_times=False) as b:
        assert list(b.time.values) == [1.75, 2.0] and b.attrs["continued_from_day"] == 1.5
        assert b.attrs["branched_from"] == str(restart.resolve()) and b.attrs["branched_from_day"] == 1.0
        for v in ("h", "u", "v", "total_energy_change", "steps", "rhs_evals"):
            np.testing.assert_array_equal(a[v].sel(time=2).values, b[v].sel(time=2).values, err_msg=v)
    assert ckpt.read(tmp_path / "cut.restart.nc").step == 24  # steps of 1800 s since the branch at day 1


def test_bad_branches_are_one_line_exit_2_and_write_nothing(spun_up, tmp_path, capsys):
    _, restart = spun_up("rk4")
    before = sorted(p.name for p in tmp_path.iterdir())
    cont = ("run", "--continue", restart, *RUN, "--output", "x.nc")
    cli_one_line(capsys, [*cont, "--stepper", "ssprk3"], 2, "days must be > 1 (got 1.0): the run branches at day 1")
    cli_one_line(
        capsys,
        [*cont, "--dt", "1728", "--days", "2"],
        2,
        "output interval (output.every_days) of 0.25 days is not a whole number of steps of dt = 1728 s (the dt given)",
    )
    cli_one_line(
        capsys,
        [*cont, "--dt", "7000", "--days", "2"],
        2,
        "run length of 1 days is not a whole number of steps of dt = 7000 s",
    )
    cli_one_line(capsys, [*cont, "--dt", "-5", "--days", "2"], 2, "--dt: must be a finite number > 0 (got -5)")
    cli_one_line(capsys, [*cont, "--stepper", "euler", "--days", "2"], 2, "unknown stepper 'euler'")
    cli_one_line(
        capsys,
        [*cont, "--stepper", "ssprk3", "--ne", "3", "--days", "2"],
        2,
        "is a run with ne = 2; it cannot continue with --ne 3",
    )
    cli_one_line(
        capsys,
        [*cont, "--stepper", "ssprk3", "-s", "hyperviscosity.nu=1e15", "--days", "2"],
        2,
        "-s hyperviscosity.nu=1e15: a checkpointed scene continues as it was written (-s cannot change it)",
    )
    cli_one_line(
        capsys,
        ["run", "--continue", "spin.nc", "--stepper", "ssprk3", "--days", "2", *RUN, "--output", "x.nc"],
        2,
        "spin.nc: not a swe_sphere checkpoint",
    )
    assert sorted(p.name for p in tmp_path.iterdir()) == before


# -- sweep --from -------------------------------------------------------------------


def test_sweep_from_a_restart_file_branches_every_run_there(spun_up, tmp_path, capsys, monkeypatch):
    """``sweep --from``: every run and the small-Δt reference start from the restart
    file's state (a run's total error is that of a plain run from it, not of one from
    the case's initial state); each run's key names the file and its SHA-256, so a
    rerun reuses them, and a restart file rewritten in place makes them again."""
    without_sweep_figures(monkeypatch)
    _, restart = spun_up("rk4")
    sweep = (
        "sweep",
        "--from",
        restart,
        "--days",
        "1.5",
        "--runs",
        "rk4@0.5,ssprk3@1",
        "--device",
        "cpu",
        "--output",
        "sw",
    )
    code, out, err = cli_main(capsys, *sweep)
    assert code == 0, err
    assert f"start       the state of {restart} at day 1 (step 24 of rk4, dt = 3600 s)" in out
    rows = {
        r["stepper"]: r for r in (json.loads(p.read_text())["row"] for p in (tmp_path / "sw" / "runs").glob("*.json"))
    }
    keys = [json.loads(p.read_text())["key"] for p in (tmp_path / "sw" / "runs").glob("*.json")]
    sha = digest(restart)
    for key in keys:
        assert key["scene"]["branch"]["restart"] == str(restart.resolve()) and key["scene"]["branch"]["sha256"] == sha
    for stepper, row in rows.items():
        fresh = fresh_from(restart, stepper, row["dt"], 0.5)
        errors = fresh.scorer.total_errors(1.5 * DAY, fresh.x.numpy())
        assert row["total_error"] == errors["total_error"], stepper
        from_t0 = make_sim(
            dataclasses.replace(
                load_scene(tmp_path / "spin.toml", stepper=stepper, dt=row["dt"]), days=0.5, output_every_days=0.5
            )
        )
        from_t0.run(None)
        assert row["total_error"] != fresh.scorer.total_errors(1.5 * DAY, from_t0.x.numpy())["total_error"]
    with np.load(next((tmp_path / "sw" / "runs").glob("reference_*.npz"))) as ref:
        assert json.loads(str(ref["key"]))["scene"]["branch"]["sha256"] == sha
    code, out, _ = cli_main(capsys, *sweep, "--overwrite")
    assert code == 0 and "runs: 2 reused, 0 made" in out
    # the restart file rewritten (a spin-up at another dt): the runs are made again
    assert cli_ok(
        "run", "spin.toml", *RUN, "--dt", "1800", "--restart-every", "1", "--output", "spin.nc", "--overwrite"
    )
    code, out, _ = cli_main(capsys, *sweep, "--overwrite")
    assert code == 0 and "runs: 0 reused, 2 made" in out and "scene.branch.sha256" in out


def test_sweep_from_refuses_what_it_cannot_change(spun_up, tmp_path, capsys):
    _, restart = spun_up("rk4")
    sweep = ("sweep", "--runs", "rk4@0.5", "--device", "cpu", "--output", "sw")
    cli_one_line(capsys, [*sweep, "--from", "spin.nc", "--days", "2"], 2, "spin.nc: not a swe_sphere checkpoint")
    cli_one_line(capsys, [*sweep, "--from", restart, "--days", "2", "--ne", "3"], 2, "--from", "--ne")
    cli_one_line(capsys, [*sweep, "--from", restart, "--days", "2", "-s", "hyperviscosity.nu=1e15"], 2, "--from", "-s")
    cli_one_line(capsys, [*sweep, "spin.toml", "--from", restart, "--days", "2"], 2, "--from", "SCENE")
    cli_one_line(capsys, [*sweep, "--from", restart], 2, "days must be > 1 (got 1.0): the run branches at day 1")
    cli_one_line(capsys, ["sweep", "--runs", "rk4@0.5", "--output", "sw"], 2, "SCENE")
    assert not (tmp_path / "sw").exists()
