"""Gradients of split-explicit runs (``adjoint.multirate``): the slow tendency held over the
gravity waves' forward–backward substeps, each substep reversed."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import warp as wp

from swe_sphere.adjoint import HeightMisfit, gradient
from swe_sphere.adjoint.gradient import scene_model, step_adjoint
from swe_sphere.model.shallow_water import ShallowWater
from swe_sphere.simulation.simulation import Simulation
from swe_sphere.steppers import make_stepper

import taylor


@pytest.mark.parametrize("damping", [0.1, 0.0])
def test_a_split_explicit_run_s_gradient_falls_as_eps_squared(damping):
    """TC5, 4 steps of 2, 2 and 4 substeps a stage (``substeps = 4``): the gradient's
    forward run is the ``Simulation``'s to the bit, from two snapshots alike, and the Taylor
    remainder of x(0) falls as ε², with the divergence damping β and without."""
    scene = dataclasses.replace(
        taylor.tc5("split_explicit"), stepper_options={"substeps": 4, "divergence_damping": damping}
    )
    model, stepper, x0 = scene_model(scene)
    cost = taylor.misfit(model, x0, np.random.default_rng(17))
    every, few = gradient(scene, 4, cost), gradient(scene, 4, cost, snapshots=2)
    sim = Simulation(dataclasses.replace(scene, days=4 * scene.dt / 86400.0), "cpu", progress=False)
    sim.run(None)
    np.testing.assert_array_equal(every.final, np.stack(sim.fields()))
    assert sim.stepper.n_fast == (2, 2, 4)
    np.testing.assert_array_equal(few.grad, every.grad)
    taylor.assert_initial_state_taylor(scene, "split_explicit")


def test_split_explicit_s_per_node_transposes_give_the_element_kernels_adjoint():
    # one step reversed on the CPU's element kernels and on CUDA's per-node point and gather, here on the CPU
    scene = taylor.tc5("split_explicit")
    model, _, x0 = scene_model(scene)
    node = ShallowWater.from_scene(scene, model.grid, per_element=False)
    lam = taylor.continuous(model, np.random.default_rng(18).standard_normal((3, model.N)))
    out = []
    for m in (model, node):
        st = make_stepper(scene.stepper, m, scene.dt, **scene.stepper_options)
        first = wp.array(x0, dtype=taylor.f64)
        st.prepare(first)
        st.step(first)  # its first step fixes H and the substeps
        adjoint, mu = step_adjoint(m, st), wp.array(lam, dtype=taylor.f64)
        adjoint.reverse(wp.array(x0, dtype=taylor.f64), mu)
        out.append(mu.numpy())
    assert np.abs(out[0] - lam).max() > 1e-3 * np.abs(lam).max()  # the step acts
    assert np.abs(out[0] - out[1]).max() <= 64 * taylor.EPS * np.abs(out[0]).max()


def test_split_explicit_s_gradient_refuses_parameters_and_a_forcing():
    scene = taylor.tc5("split_explicit")
    cost = HeightMisfit(scene_model(scene)[2][2])
    with pytest.raises(ValueError, match="initial state alone and takes no forcing"):
        gradient(scene, 1, cost, parameters=True)
    with pytest.raises(ValueError, match="initial state alone and takes no forcing"):
        gradient(dataclasses.replace(taylor.tc4(), stepper="split_explicit"), 1, cost)
