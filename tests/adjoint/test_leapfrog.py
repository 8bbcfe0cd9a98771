"""Gradients of runs by the three-level schemes (``adjoint.tape``: their own steps on a tape):
leapfrog with the Robert–Asselin filter and leapfrog-trapezoidal, their states (x(n), x̃(n−1))
reversed together."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import warp as wp

from swe_sphere.adjoint import gradient
from swe_sphere.adjoint.gradient import scene_model, step_adjoint
from swe_sphere.model.shallow_water import ShallowWater

import taylor

THREE_LEVEL = ["leapfrog", "leapfrog_trapezoidal"]


@pytest.mark.parametrize("stepper", THREE_LEVEL)
def test_a_three_level_run_s_gradients_fall_as_eps_squared(stepper):
    """TC5, 6 steps (the midpoint start and five three-level steps): the gradient's forward run
    is the ``Simulation``'s to the bit, from every state and from two snapshots alike (the
    states x̃ carried through the checkpoints), and the Taylor remainders of x(0), ν, ν_s, hs,
    g and Ω fall as ε²."""
    scene, steps = taylor.tc5(stepper), 6
    model, _, x0 = taylor.setup(stepper)
    rng = np.random.default_rng(13)
    cost = taylor.misfit(model, x0, rng)
    every = taylor.assert_replays_the_run(scene, steps, cost, parameters=True)
    taylor.assert_initial_state_taylor(scene, stepper, steps)
    taylor.assert_parameter_gradients(scene, model, every, steps, cost, x0, rng)


@pytest.mark.parametrize("stepper", THREE_LEVEL)
def test_a_forced_or_nu_div_three_level_run_s_gradient_falls_as_eps_squared(stepper):
    """TC4's forcing at the steps' times (the forward the ``Simulation``'s to the bit) and
    ν_div = 2.5 ν (the ∇δ term's transpose over the leapfrog's 2Δt span): x(0)'s and ν's
    remainders fall as ε²."""
    forced = dataclasses.replace(taylor.tc4(), stepper=stepper)
    model, _, x0 = scene_model(forced)
    taylor.assert_replays_the_run(forced, 6, taylor.misfit(model, x0, np.random.default_rng(14)))
    taylor.assert_initial_state_taylor(forced, stepper, 6)
    divergent = dataclasses.replace(taylor.divergent_tc5(), stepper=stepper)
    taylor.assert_initial_state_taylor(divergent, stepper, 6)
    model, _, x0 = scene_model(divergent)
    cost = taylor.misfit(model, x0, np.random.default_rng(15))
    g = gradient(divergent, 6, cost, parameters=True)
    taylor.assert_falls_as_eps_squared(taylor.coefficients(divergent, ("nu", "nu_div"), g.d_nu, 6, cost), "nu")


@pytest.mark.parametrize("stepper", THREE_LEVEL)
def test_a_three_level_step_s_per_node_transposes_give_the_element_kernels_adjoint(stepper):
    # a three-level step (k = 1) reversed on the CPU's element kernels and on CUDA's per-node
    # point and gather, run here on the CPU
    model, stepper_, x0 = taylor.setup(stepper)
    node = ShallowWater.from_scene(taylor.tc5(stepper), model.grid, per_element=False)
    rng = np.random.default_rng(16)
    lam = np.concatenate([taylor.continuous(model, rng.standard_normal((3, model.N))) for _ in range(2)])
    state = np.concatenate([x0, x0 + taylor.continuous(model, rng.standard_normal((3, model.N)))])
    out = []
    for m in (model, node):
        adjoint, mu = step_adjoint(m, stepper_), wp.array(lam, dtype=taylor.f64)
        adjoint.reverse(wp.array(state, dtype=taylor.f64), mu, 1)
        out.append(mu.numpy())
    assert np.abs(out[0] - lam).max() > 1.0 * np.abs(lam).max()  # the step acts (measured 23 and 6.3×)
    # measured 1.8 and 1.3 eps of the largest entry (TC5 ne 2): sums in another order
    assert np.abs(out[0] - out[1]).max() <= 64 * taylor.EPS * np.abs(out[0]).max()


def test_a_three_level_adjoint_keeps_its_dt():
    model, stepper, _ = taylor.setup("leapfrog")
    adjoint = step_adjoint(model, stepper)
    assert adjoint.dt == stepper.dt == 1800.0
    with pytest.raises(ValueError, match="leapfrog cannot change its dt"):
        adjoint.set_dt(900.0)
