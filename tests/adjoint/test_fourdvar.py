"""The 4D-Var-style recovery of the gallery (docs/examples/assimilation/plot_fourdvar.py, its
functions in docs/examples/assimilation/_assimilation.py): L-BFGS on ``gradient`` recovers an
initial height field from the final one, on a grid small enough for the suite."""

from __future__ import annotations

import numpy as np
from gallery_helpers import assimilation

import swe_sphere
from swe_sphere.config.scene import load_scene


def test_lbfgs_on_the_gradient_recovers_the_initial_height():
    # TC5 ne 2 np 4, 4 rk4 steps of 1800 s; the first guess 80 m off the truth in a 1600 km bump
    scene = load_scene("testcases/tc5_mountain.toml", ne=2, np_=4, dt=1800.0, stepper="rk4")
    r = assimilation().recover_height(scene, 4, 80.0, 1.6e6, 10)
    assert r.result.nit == 10  # no early stop: every iteration made progress
    assert r.cost0 / r.cost > 100.0  # measured 237
    assert r.error0 / r.error > 2.0  # measured 2.84: closer to the truth's h(0), not only to the data
    assert r.costs[0] == r.cost0 and min(r.costs) == r.cost  # every evaluation's J kept, the first the guess's


def test_the_cost_handed_to_lbfgs_has_the_gradient_of_its_unknowns():
    # the unique-node unknowns against the element-local gradient: central differences agree
    a = assimilation()
    scene = load_scene("testcases/tc5_mountain.toml", ne=2, np_=4, dt=1800.0, stepper="rk4")
    states, grid, _ = a.observed_run(scene, 4)
    cost = a.mean_square_cost(scene, 4, grid, states[0], states[4][2])
    h0 = states[0][2][grid.first] + a.bump(grid, 80.0, 1.6e6)
    d = np.random.default_rng(5).standard_normal(grid.nunique)
    _, grad = cost(h0)
    e = 1e-2  # m: truncation ~ e² (4e-8 relative at e = 0.1), round-off ~ ε J / e (5e-9 at 1e-3)
    fd = (cost(h0 + e * d)[0] - cost(h0 - e * d)[0]) / (2 * e)
    assert abs(fd - grad @ d) <= 1e-8 * abs(grad @ d)  # measured 7.7e-10; a copy missed: O(1)


def test_the_observed_run_is_the_run_the_gradient_differentiates():
    """``observed_run``'s final state is the forward pass of ``gradient``: a cost of h at the
    end against observations 1 m below the observed run's is exactly ½ (σ = 1 m)."""
    a = assimilation()
    scene = load_scene("testcases/tc5_mountain.toml", ne=2, np_=4, dt=1800.0, stepper="rk4")
    states, grid, _ = a.observed_run(scene, 4, every=2)
    assert sorted(states) == [0, 2, 4]
    H = swe_sphere.PointHeights(grid, np.radians([40.0, -10.0]), np.radians([255.0, 30.0]))
    g = swe_sphere.gradient(scene, 4, swe_sphere.HeightObservations(H, {4: H(states[4][2]) - 1.0}, 1.0))
    assert abs(g.cost - 1.0) <= 64 * np.finfo(float).eps  # two points, each ½; a different run: O(1)
