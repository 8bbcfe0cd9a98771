"""Warp's automatic differentiation of the CPU tendency kernel gives the hand-written transpose
(``kernels.tendency_adjoint.element``) to round-off (issue 82, item 1's prototype; the pieces in
warp_vjp.py, the figures in benchmarks/micro/tendency_vjp.py)."""

from __future__ import annotations

import math

import numpy as np
import warp_vjp as V

ALL = V.tendencies.TENDENCY_TERMS


def test_warp_autodiff_of_the_tendency_is_the_hand_written_transpose():
    # every term: each code path, and momentum advection with the pressure gradient, whose row
    # written twice Warp differentiates right only with vector component overwrites on
    m = V.model(2, 4, ALL)
    rng = np.random.default_rng(11)
    x, k = V.random_state(m, rng), rng.standard_normal((3, m.N))
    hand, warp, f_hand, f_warp = V.TendencyVJP(m, x, k).both()
    assert np.abs(hand).max() > 0.0
    # each side's error ≤ depth·ε·(the size of its entry's sum); measured ≤ 2 ε S (ne 2..4, np 4 and 8)
    size = V.sum_sizes(m, x, k)
    assert np.all(np.abs(hand - warp) <= 2 * V.sum_depth(4) * V.EPS * size)
    np.testing.assert_array_equal(f_hand, f_warp)  # the forcing's adjoint: W k̄'s wind rows, as is


def test_warp_autodiff_passes_the_dot_product_test():
    # T is quadratic in x: J v = (T(x + v) − T(x − v))/2 with no truncation error
    m = V.model(2, 4, ALL)
    rng = np.random.default_rng(12)
    x, v = V.random_state(m, rng), V.random_state(m, rng) - [[0.0], [0.0], [5000.0]]
    w = rng.standard_normal((3, m.N))
    jv = 0.5 * (V.tendency(m, x + v) - V.tendency(m, x - v))
    kbar = w / m.grid.spheremp  # the kernels weigh k̄ by W: the cotangent is w
    jtw = V.TendencyVJP(m, x, kbar).both()[1]
    left, right = math.fsum((jv * w).ravel()), math.fsum((v * jtw).ravel())
    forcing = np.zeros((3, m.N))
    forcing[:2] = np.abs(m.topo_forcing.numpy())
    size = sum(0.5 * np.sum(V.sum_sizes(m, y, kbar) * np.abs(y) + np.abs(w) * forcing) for y in (x + v, x - v))
    size += np.sum(np.abs(v) * V.sum_sizes(m, x, kbar))
    assert abs(left) > 1e3 * V.EPS * size  # the test is not of two round-offs
    # measured 0.01 ε·size
    assert abs(left - right) <= 2 * V.sum_depth(4) * V.EPS * size
