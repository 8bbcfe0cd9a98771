"""An ensemble under step control (issue 100): one Δt for every member, the controller's, its
error norm over every member's nodes; a single member's run is the single run's, bit for bit."""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr

from swe_sphere.cli import main
from swe_sphere.core.errors import ArgumentError, SceneError
from swe_sphere.ensemble import Perturbation
from swe_sphere.simulation.simulation import Simulation

from helpers import members_from_checkpoint, members_run, take_steps

CONTROLLED = {"ne": 2, "np": 4, "days": 0.25, "stepper": "bs32", "output.every_days": 0.125, "time.control": "error"}


def test_one_member_under_error_control_is_the_single_run(tmp_path, one_thread):
    """members=1: the same accepted and rejected steps, Δt and final state bits as
    ``Simulation.run`` under the same control, landing on the same output days."""
    sim = Simulation("galewsky", "cpu", progress=False, **CONTROLLED)
    sim.run(tmp_path / "run.nc")
    ens = members_run("galewsky", 1, device="cpu", **CONTROLLED)
    ens.run(tmp_path / "ens.nc")
    assert (ens.control.accepted, ens.control.rejected) == (sim.control.accepted, sim.control.rejected)
    assert ens.control.history == sim.control.history and ens.step == sim.step
    np.testing.assert_array_equal(ens.states()[0], sim.x.numpy())
    with xr.open_dataset(tmp_path / "ens.nc", decode_times=False) as ds:
        np.testing.assert_array_equal(ds.time.values, [0.0, 0.125, 0.25])


def test_members_take_one_controlled_dt_and_advance_lands_on_the_day(one_thread):
    """Two perturbed members: each accepted Δt is every member's (one history), ``advance``
    lands on the day asked; the error norm's
    tolerance tighter, more steps."""
    ens = members_run("galewsky", 2, Perturbation(1.0, seed=1), device="cpu", **CONTROLLED)
    ens.advance(0.1)
    assert ens.time == 0.1 and ens.control.accepted == ens.step > 2
    assert np.isfinite(ens.states()).all() and not np.array_equal(*ens.states())
    tight = members_run("galewsky", 2, Perturbation(1.0, seed=1), device="cpu", **CONTROLLED, **{"time.rtol": 1e-5})
    tight.advance(0.1)
    assert tight.control.accepted > ens.control.accepted


def test_the_command_line_runs_a_controlled_ensemble(tmp_path, one_thread, capsys):
    """``swe-sphere run galewsky --members 2 --perturbation 1 -s time.control=error`` (was refused:
    "ensembles take a fixed dt"): exit 0, the run file's output times landed on."""
    out = tmp_path / "e.nc"
    args = "run galewsky --ne 2 --np 4 --days 0.25 --stepper bs32 --members 2 --perturbation 1".split()
    args += ["-s", "time.control=error", "--device", "cpu", "--no-progress", "--output", str(out)]
    assert main(args) == 0, capsys.readouterr().err
    with xr.open_dataset(out, decode_times=False) as ds:
        assert ds.sizes["member"] == 2 and ds.time.values[-1] == 0.25


def test_a_controlled_ensemble_continues_from_its_restart_file_bitwise(tmp_path, one_thread):
    """The restart file keeps the control's state (its next Δt, controller history, counts): the
    continuation takes the same steps as the run never stopped, to the bit."""
    members = ("galewsky", 2, Perturbation(1.0, seed=1))
    whole = members_run(*members, device="cpu", **CONTROLLED)
    whole.advance(0.125)
    whole.write_checkpoint(tmp_path / "r.nc")
    whole.advance(0.125)
    again = members_from_checkpoint(tmp_path / "r.nc", device="cpu")
    assert again.time == 0.125 and again.control.accepted == again.step > 0
    again.advance(0.125)
    np.testing.assert_array_equal(again.states(), whole.states())
    assert again.control.state() == whole.control.state() and again.step == whole.step


def test_an_ensemble_calls_back_at_its_steps_and_a_callback_leaves_the_bits(one_thread):
    """``add_callback``: called after every 5th step (blocks end there; a fixed Δt) and every
    3rd accepted step under control, reading the ensemble; the states the bits of an ensemble
    without one. Bad intervals are one line each."""
    fixed = {"ne": 2, "np": 4, "dt": 900.0}
    seen, ens = [], members_run("galewsky", 2, Perturbation(1.0, seed=1), device="cpu", **fixed)
    ens.add_callback(lambda e: seen.append((e.step, e.time)), every_steps=5)
    take_steps(ens, 12)
    ens.advance(0.0625)  # 6 steps more, to 18
    assert seen == [(5, 5 * 900 / 86400), (10, 10 * 900 / 86400), (15, 15 * 900 / 86400)]
    plain = members_run("galewsky", 2, Perturbation(1.0, seed=1), device="cpu", **fixed)
    take_steps(plain, 18)
    np.testing.assert_array_equal(ens.states(), plain.states())
    with pytest.raises(ArgumentError, match=r"^an interval needs exactly one of every_steps, every_days$"):
        ens.add_callback(print)
    with pytest.raises(SceneError, match=r"every_days"):  # Simulation's (the old Ensemble's an ArgumentError)
        ens.add_callback(print, every_days=0.001)
    steered, counted = members_run("galewsky", 2, Perturbation(1.0, seed=1), device="cpu", **CONTROLLED), []
    steered.add_callback(lambda e: counted.append(e.step), every_steps=3)
    steered.advance(0.05)
    assert counted == list(range(3, steered.step + 1, 3)) and counted
    with pytest.raises(ArgumentError, match=r"^every_days: under step control the steps are the controller's"):
        steered.add_callback(print, every_days=0.25)
