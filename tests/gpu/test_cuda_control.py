"""CUDA against the CPU under error control (``integrator.control.StepControl``): every
embedded pair and the JFNK stepper on TC5 ne2 np4 over a quarter day at rtol 1e-6, and an
IMEX pair's and the JFNK stepper's rejected tries put back from device copies
(``TrialSteps.checkpoint``/``rollback``), as on the CPU (``tests/steppers/test_variable_dt.py``).
Skipped without a CUDA device."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from swe_sphere.config.scene import load_scene
from swe_sphere.simulation.simulation import Simulation
from swe_sphere.steppers import STEPPERS

from helpers import assert_same_runs, requires_cuda, rows_apart, watched_run

# the steppers error control takes with their scene's options (a tableau's table has no b̂)
PAIRS = sorted(n for n, cls in STEPPERS.items() if n != "tableau" and cls.has_estimate({}) and cls.changes_dt({}))


def _controlled(name: str, device: str):
    """(final state, accepted Δt) of ``name`` under error control at rtol 1e-6 on ``device``."""
    overrides = {"time.control": "error", "time.rtol": 1e-6, "output.every_days": 0.25}
    scene = load_scene("tc5_mountain", ne=2, np_=4, days=0.25, stepper=name, overrides=overrides)
    sim = Simulation(scene, device, progress=False)
    sim.run(None)
    return sim.x.numpy(), [dt for _, dt, _ in sim.control.history]


@requires_cuda
@pytest.mark.parametrize("name", PAIRS)
def test_a_controlled_run_on_cuda_matches_the_cpu(name):
    """The error norms agree to round-off, which the controller's Δt grid (``on_grid``) mostly
    rounds away: as many steps to one, the states to the tolerance's order."""
    (cpu, cpu_dts), (cuda, cuda_dts) = _controlled(name, "cpu"), _controlled(name, "cuda")
    assert len(cpu_dts) > 10 and abs(len(cuda_dts) - len(cpu_dts)) <= 1
    rel = rows_apart(cuda, cpu)
    assert max(rel) <= 1e-5, f"{name}: rows differ by {rel}"


def _tries(name: str, device: str, tries: tuple) -> np.ndarray:
    """x after three steps at 1200 s, ``tries`` each put back (``checkpoint``/``rollback``), and
    three more at 1200 s; TC5 ne4, the stepper's error estimate on."""
    scene = load_scene("tc5_mountain", ne=4, days=1.0, stepper=name, dt=1200.0)
    sim = Simulation(scene, device, progress=False)
    st = sim.stepper
    st.estimate_errors()
    for dt in (1200.0,) * 3 + tries:
        if dt != 1200.0:
            saved, x = st.checkpoint(), sim.x.numpy().copy()
        st.set_dt(dt)
        st.step(sim.x)
        if dt != 1200.0:
            sim.x.assign(x)
            st.rollback(saved)
    for _ in range(3):
        st.set_dt(1200.0)
        st.step(sim.x)
    return sim.x.numpy()


@requires_cuda
@pytest.mark.parametrize("name", ["ark324", "implicit"])
def test_a_rejected_try_on_cuda_leaves_no_trace(name):
    plain, tried = _tries(name, "cuda", ()), _tries(name, "cuda", (700.0, 2400.0, 900.0))
    assert np.array_equal(tried, plain)


@requires_cuda
def test_tries_launched_ahead_on_cuda_are_bitwise_the_run_without(tmp_path):
    """``StepControl.lookahead`` (on by default on CUDA): TC5 ne4 ``rk43`` at rtol 1e-4 from 5×
    its Δt (steps rejected, Δt changing), outputs every 0.25 day, a callback every 10 steps and
    a log, as CUDA graphs: the run file, the states and the counts bitwise those of the same run
    with it off; most steps were tries launched ahead."""
    overrides = {"time.control": "error", "time.rtol": 1e-4, "output.every_days": 0.25}
    scene = load_scene("tc5_mountain", ne=4, days=1.0, stepper="rk43", overrides=overrides)
    scene = dataclasses.replace(scene, dt=5 * scene.dt)
    controls = {}

    def keep(on: bool):
        def setup(sim):
            assert sim.control.lookahead  # CUDA's default
            sim.control.lookahead = on
            controls[on] = sim.control

        return setup

    runs = [
        watched_run(scene, tmp_path / f"{on}.nc", device="cuda", graphs=True, setup=keep(on)) for on in (False, True)
    ]
    assert_same_runs(*runs)
    ahead = controls[True]
    assert ahead.rejected > 0 and ahead.ahead_taken > ahead.accepted / 2 and controls[False].ahead_taken == 0
