"""The bad-state check read back every ``check_every`` steps (``Simulation.check_every``,
a GPU's default): forced on the CPU, a run gives the same bits, the same blow-up
report and the same run file as with a check every step, and a step inside a
block reads nothing back from the device."""

from __future__ import annotations

import os
import signal

import numpy as np
import pytest
import warp as wp
import xarray as xr

from swe_sphere.config.scene import load_scene
from swe_sphere.core.errors import BlowUp, Interrupted, StepFailure

from helpers import RUN_TIMES, assert_same_runs, make_sim, watched_run, write_tc2_scene


def test_blow_up_inside_a_block_is_reported_as_with_a_check_every_step(tmp_path):
    """Leapfrog at dt = 3600 s on TC2 ne = 2 blows up at step 17, inside the block
    16-20 of a check every 5 steps: the block is re-run from step 15 (state and
    leapfrog's x(n-1)) one checked step at a time, and the message (step, time,
    place), counters, the run file (every good output time, the last good state
    at step 16, the blowup attribute) and the state left are those of a check
    every step."""
    scene = load_scene(
        write_tc2_scene(
            tmp_path / "s.toml", stepper="leapfrog", dt=3600.0, days=2.0, tables="[output]\nlog_every_steps = 6"
        )
    )
    one = watched_run(scene, tmp_path / "one.nc", check_every=1)
    five = watched_run(scene, tmp_path / "five.nc", check_every=5)
    assert one[1].startswith("blow-up at step 17 (model time 0.7083 days): depth h = ")
    assert 17 % 5 and 17 % 6 and 17 % 10  # inside a block, not at a check
    assert list(one[2].steps.values) == [0, 16]
    assert_same_runs(one, five)


@pytest.mark.parametrize("stepper", ["leapfrog", "ssprk3"])
def test_blocks_give_the_same_bits_as_a_check_every_step(tmp_path, stepper):
    """A good run checked every 7 steps: the same final state, run file, restart
    file, callbacks' states and log lines as checked every step."""
    scene = load_scene(
        write_tc2_scene(
            tmp_path / "s.toml",
            stepper=stepper,
            dt=1800.0,
            days=2.0,
            tables="[output]\nevery_days = 0.75\nlog_every_steps = 9",
        )
    )
    runs = [watched_run(scene, tmp_path / f"{every}.nc", check_every=every, restart_every=0.5) for every in (1, 7)]
    assert runs[0][0].steps == 96 and runs[0][1] is None
    assert_same_runs(*runs)
    with xr.open_dataset(tmp_path / "1.restart.nc") as a, xr.open_dataset(tmp_path / "7.restart.nc") as b:
        xr.testing.assert_identical(a.drop_attrs(), b.drop_attrs())  # the state and x(n-1); attributes hold timings
        assert a.attrs["step"] == b.attrs["step"] == 96
    assert np.isfinite(runs[1][0].first_step_time)


def test_a_step_inside_a_block_reads_nothing_back(tmp_path, monkeypatch):
    """Host reads (``wp.array.numpy``) and device synchronisations counted between
    the ssprk3 steps of a run checked every 8 steps (output at 0, 24, 48): none
    after a step inside a block nor in any step, at least one after each block's
    last step (1, 4, the multiples of 8; the check, the outputs)."""
    scene = load_scene(write_tc2_scene(tmp_path / "s.toml", stepper="ssprk3", dt=3600.0, days=2.0))
    sim = make_sim(scene)
    sim.check_every = 8
    reads, steps = [0], []  # reads since the last event; per step: (reads before it, reads inside it)
    real_numpy, real_sync, real_step = wp.array.numpy, wp.synchronize_device, sim.stepper.step

    def numpy(self, *a, **k):
        reads[0] += 1
        return real_numpy(self, *a, **k)

    def sync(*a, **k):
        reads[0] += 1
        return real_sync(*a, **k)

    def step(x):
        before, reads[0] = reads[0], 0
        stats = real_step(x)
        steps.append((before, reads[0]))
        reads[0] = 0
        return stats

    monkeypatch.setattr(wp.array, "numpy", numpy)
    monkeypatch.setattr(wp, "synchronize_device", sync)
    monkeypatch.setattr(sim.stepper, "step", step)
    sim.run(tmp_path / "r.nc")
    assert len(steps) == 48
    after = [before for before, _ in steps[1:]] + [None]  # the reads after step n, for n = 1..47
    block_ends = {1, 4, 8, 16, 24, 32, 40}  # 1 alone, 2-4 the wall-time estimate's (ESTIMATE_STEPS)
    for n, count in enumerate(after[:-1], start=1):
        assert (count > 0) == (n in block_ends), (n, count)
    assert all(inside == 0 for _, inside in steps)


def _failing_in(sim, step):
    """Make ``step`` (counted from t = 0) of ``sim``'s run raise ``StepFailure``, each time it is taken."""
    real = sim.stepper.step

    def failing(x):
        if sim.step + 1 == step:
            raise StepFailure("Newton did not converge (forced)")
        return real(x)

    sim.stepper.step = failing


def test_a_failure_inside_a_block_is_reported_as_with_a_check_every_step(tmp_path):
    """A ``StepFailure`` in step 11, inside the block 9-12 of a check every 4 steps:
    the block is re-run from step 8, checked step by step, to the failure: the same
    message, counters and run file (ending at the last good step 10) as with a
    check every step."""
    scene = load_scene(write_tc2_scene(tmp_path / "s.toml", stepper="leapfrog", dt=1800.0, days=1.0))
    runs = []
    for every in (1, 4):
        sim = make_sim(scene)
        sim.check_every = every
        _failing_in(sim, 11)
        with pytest.raises(
            BlowUp, match=r"^step 11 failed \(model time 0\.2292 days\): Newton did not converge"
        ) as err:
            sim.run(tmp_path / f"{every}.nc")
        with xr.open_dataset(tmp_path / f"{every}.nc") as ds:
            runs.append(
                (
                    err.value.result.rhs_evals,
                    sim.step,
                    sim.x.numpy(),
                    ds.drop_vars(list(RUN_TIMES), errors="ignore").drop_attrs().load(),
                )
            )
    assert runs[0][:2] == runs[1][:2] == (11, 10)  # leapfrog: 2 RHS evaluations in its first step, then 1
    np.testing.assert_array_equal(runs[0][2], runs[1][2])
    xr.testing.assert_identical(runs[0][3], runs[1][3])
    assert list(runs[1][3].steps.values) == [0, 10]


def test_a_step_abandoned_inside_a_block_leaves_the_blocks_first_state(tmp_path):
    """SIGINT in step 11 (inside the block 9-12 of a check every 4 steps), which then
    never ends: abandoned after ``ABANDON_AFTER`` s, steps 9 and 10 unchecked go
    with it; the run stops at step 8 with the state and leapfrog's x(n-1) of a run
    of 8 steps (its next steps give the same bits)."""
    scene = load_scene(write_tc2_scene(tmp_path / "s.toml", stepper="leapfrog", dt=1800.0, days=1.0))
    sim = make_sim(scene)
    sim.check_every = 4
    real = sim.stepper.step

    def endless(x):
        if sim.step + 1 != 11:
            return real(x)
        os.kill(os.getpid(), signal.SIGINT)
        while True:  # real steps, as a step that never converges
            real(x)

    sim.stepper.step = endless
    with pytest.raises(
        Interrupted, match=r"at step 8 .*; step 11 abandoned after 1 s with steps 9-10 before it \(not yet checked\)"
    ):
        sim.run()
    sim.stepper.step = real
    sim.run(until_step=12)
    ref = make_sim(scene)
    ref.run(until_step=12)
    np.testing.assert_array_equal(sim.x.numpy(), ref.x.numpy())
