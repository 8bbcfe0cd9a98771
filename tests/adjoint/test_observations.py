"""Costs of a run (``gradient`` with a cost that observes several steps) and the observation
operator at points (``PointHeights``, ``HeightObservations``): the operator against the grid's
own nodes and its transpose, a Taylor test of a multi-time point-observation cost, the same
bits in every checkpointing mode, the final-state cost unchanged."""

from __future__ import annotations

import functools

import numpy as np
import pytest
import warp as wp

from swe_sphere.adjoint import HeightMisfit, HeightObservations, PointHeights, gradient
from swe_sphere.adjoint.gradient import scene_model
from swe_sphere.adjoint.revolve import griewank_steps, two_level_steps
from swe_sphere.config.scene import load_scene
from swe_sphere.core.errors import ArgumentError

EPS = float(np.finfo(np.float64).eps)
STEPS = 24  # 6 h of 900 s
OBSERVED = (0, 5, 11, 17, 24)


@functools.cache
def tc5():
    """TC5 ne4 np4 rk4 at Δt 900 s, its model and x(0)."""
    scene = load_scene("testcases/tc5_mountain.toml", ne=4, np_=4, dt=900.0, stepper="rk4")
    return scene, *scene_model(scene)


def points(m, seed):
    """m points uniform on the sphere (radians)."""
    rng = np.random.default_rng(seed)
    return np.arcsin(rng.uniform(-1.0, 1.0, m)), rng.uniform(-np.pi, np.pi, m)


def forward_states(x0, steps):
    """x(0) … x(steps) of TC5's run from x0 (numpy)."""
    _, model, stepper, _ = tc5()
    x = wp.array(x0, dtype=wp.float64)
    stepper.prepare(x)
    out = [x.numpy().copy()]
    for k in range(steps):
        stepper.set_phase(k)  # the ∇⁴ every k steps goes by the step's index
        stepper.step(x)
        out.append(x.numpy().copy())
    return out


@functools.cache
def observations():
    """50 points observed at ``OBSERVED`` steps of a run from x(0) + a 30 m h bump (the truth)."""
    _, model, _, x0 = tc5()
    grid = model.grid
    truth = x0.copy()
    truth[2] += 30.0 * np.exp(-((grid.lat - 0.5) ** 2 + (grid.lon - 1.0) ** 2) / 0.1)
    H = PointHeights(grid, *points(50, 1))
    states = forward_states(truth, STEPS)
    return HeightObservations(H, {k: H(states[k][2]) for k in OBSERVED}, sigma=2.0)


def test_point_heights_reproduce_the_nodes_and_polynomials_and_transpose():
    _, model, _, x0 = tc5()
    grid = model.grid
    at_nodes = PointHeights(grid, grid.lat[grid.first], grid.lon[grid.first])
    h = x0[2]  # continuous: each node's copies agree
    np.testing.assert_allclose(at_nodes(h), h[grid.first], rtol=1e-13)  # measured 1.0e-15
    H = PointHeights(grid, *points(40, 2))
    z = np.sin(H.lat)  # a degree-1 polynomial in Cartesian z: near, not exactly, GLL-reproduced
    assert np.abs(H(np.sin(grid.lat)) - z).max() < 1e-4  # measured 3.2e-5 (ne4 np4)
    np.testing.assert_allclose(H.matrix.sum(axis=1), 1.0, rtol=1e-13)  # weights of a constant
    rng = np.random.default_rng(3)
    a, r = rng.standard_normal(grid.lat.size), rng.standard_normal(40)
    assert abs(H(a) @ r - a @ H.transpose(r)) <= 1e-13 * np.abs(a) @ np.abs(H.transpose(np.abs(r)))


def test_taylor_remainder_of_a_multi_time_point_cost_falls_as_eps_squared():
    scene, model, _, x0 = tc5()
    cost = observations()
    g = gradient(scene, STEPS, cost)
    states = forward_states(x0, STEPS)
    assert g.cost == sum(cost(k, states[k])[0] for k in OBSERVED)  # the forward run's J_k, the same bits
    assert list(g.costs) == list(OBSERVED) and min(g.costs.values()) > 0
    rng = np.random.default_rng(4)
    bump = np.exp(-((model.grid.lat - 0.3) ** 2 + (model.grid.lon - 1.5) ** 2) / 0.2)  # continuous
    dx = np.stack([2.0 * bump, -1.0 * bump, 20.0 * bump * rng.uniform(0.5, 1.0)])
    dJ = np.sum(model.grid.spheremp * g.grad * dx)
    eps = 10.0 ** -np.arange(0.0, 4.5, 1.0)
    rest = []
    for e in eps:
        s = forward_states(x0 + e * dx, STEPS)
        rest.append(abs(sum(cost(k, s[k])[0] for k in OBSERVED) - g.cost - e * dJ))
    slopes = np.diff(np.log(rest)) / np.diff(np.log(eps))
    # measured 2.001, 2.0001, 2.00001, 2.000001 (remainders 1.1e3 … 1.1e-5, J 234.6)
    assert np.all(np.abs(slopes - 2.0) < 0.1), (slopes, rest)
    assert rest[-1] > 1e4 * EPS * g.cost, (rest, g.cost)  # measured 2e8 ε J


@pytest.mark.parametrize(
    ("snapshots", "disk", "interval"),
    [(None, False, None), (3, False, None), (4, True, 7), (3, True, 1), (2, True, 10)],
)
def test_a_run_cost_gradient_is_the_same_bits_in_every_checkpointing_mode(tmp_path, snapshots, disk, interval):
    scene, *_ = tc5()
    cost = observations()
    every = gradient(scene, STEPS, cost, snapshots=STEPS)
    g = gradient(scene, STEPS, cost, snapshots=snapshots, disk=tmp_path if disk else None, disk_interval=interval)
    np.testing.assert_array_equal(g.grad, every.grad)
    np.testing.assert_array_equal(g.final, every.final)
    assert (g.cost, g.costs) == (every.cost, every.costs)  # each J_k once: recomputed steps add none
    if disk:
        assert g.forward_steps == two_level_steps(STEPS, snapshots, interval)
    elif snapshots:
        assert g.forward_steps == 1 + griewank_steps(STEPS, snapshots)


def test_a_final_state_cost_as_a_run_cost_is_the_same_bits():
    scene, _, _, x0 = tc5()
    misfit = HeightMisfit(x0[2] + 10.0)

    class AtTheEnd:
        at_steps = (STEPS,)

        def __call__(self, k, x, spheremp):
            assert k == STEPS
            return misfit(x, spheremp)

    plain, run = gradient(scene, STEPS, misfit, snapshots=3), gradient(scene, STEPS, AtTheEnd(), snapshots=3)
    np.testing.assert_array_equal(plain.grad, run.grad)
    assert plain.cost == run.cost and plain.costs == {STEPS: plain.cost}


def test_bad_observations_are_refused():
    scene, model, _, _ = tc5()
    H = PointHeights(model.grid, *points(5, 5))
    with pytest.raises(ValueError, match=r"at_steps must be integers in 0 … 24"):
        gradient(scene, STEPS, HeightObservations(H, {25: np.zeros(5)}))
    with pytest.raises(ArgumentError, match=r"values\[3\] must have shape \(5,\)"):
        HeightObservations(H, {3: np.zeros(4)})
    with pytest.raises(ArgumentError, match=r"sigma must be a finite number > 0 \(m\) \(got 0.0\)"):
        HeightObservations(H, {3: np.zeros(5)}, sigma=0.0)
