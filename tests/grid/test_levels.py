"""Element levels for local time stepping (``grid.levels``) on a refined cube and the uniform one."""

from __future__ import annotations

import numpy as np
import pytest

from swe_sphere.grid.cubed_sphere import CubedSphere
from swe_sphere.grid.levels import element_levels, element_neighbours, element_rates
from swe_sphere.grid.quality import element_sizes

from meshes import refined_ne4_grid


def refined_grid():
    """The ne4 cube refined 2× about TC5's mountain (124 elements), np 4 (``meshes.refined_ne4_grid``)."""
    return refined_ne4_grid()


def test_levels_follow_the_element_sizes_and_keep_neighbours_one_apart():
    """On the refined ne4 cube, levels from the Dinv sizes alone (a uniform flow): two levels,
    the smallest element on the finest; every element's step Δt/2^k within its own limit
    (2^(K−k) ≤ λ_max/λ_e); neighbours at most one level apart; a finer level's elements smaller
    on average; the bound E·2^K / Σ 2^k counted by hand."""
    grid = refined_grid()
    rate = element_sizes(grid).norm_dinv
    lv = element_levels(grid, rate, 8)
    assert lv.count == 2 and lv.elements_per_level() == [60, 64]
    assert lv.level[np.argmax(rate)] == lv.count - 1
    assert np.all(2.0 ** (lv.count - 1 - lv.level) <= rate.max() / rate * (1 + 1e-12))
    a = element_neighbours(grid).tocoo()
    assert np.abs(lv.level[a.row] - lv.level[a.col]).max() == 1
    means = [rate[lv.level == k].mean() for k in range(lv.count)]
    assert means[0] < means[1]
    assert lv.bound() == pytest.approx(124 * 2 / (60 + 2 * 64))


def test_the_neighbour_rule_moves_the_coarser_element_finer():
    """Rates 4 levels apart on one element of the uniform ne2 cube: its neighbours go to
    level 2, theirs to 1, the rest stay at 0 (three rings); max_levels caps the count."""
    grid = CubedSphere(2, 4)
    rate = np.ones(grid.nelem)
    rate[0] = 8.0
    lv = element_levels(grid, rate, 8)
    near = element_neighbours(grid)[0].indices
    assert lv.count == 4 and lv.level[0] == 3
    assert set(lv.level[near[near != 0]]) == {2}
    assert np.all(2.0 ** (lv.count - 1 - lv.level) <= rate.max() / rate)
    assert element_levels(grid, rate, 2).count == 2
    assert element_levels(grid, rate, 1).count == 1


def test_a_uniform_cube_is_one_level_with_the_flow():
    """The uniform ne4 cube with TC2's flow (|v| ≤ 38.6 m/s, h ≤ 3 km): σ varies 1.31× over
    the cube, the wave speed by less, so one level and a bound of 1."""
    from swe_sphere.cases.library import make_case

    grid = CubedSphere(4, 4)
    case = make_case("tc2_steady")
    x = np.stack(case.initial(grid.lat, grid.lon))
    lv = element_levels(grid, element_rates(grid, x, case.planet.g), 4)
    assert lv.count == 1 and lv.bound() == 1.0 and not lv.level.any()


@pytest.mark.parametrize("bad", [0, -1, 1.5, True])
def test_a_level_count_below_one_is_refused(bad):
    with pytest.raises(ValueError, match="max_levels must be an integer >= 1"):
        element_levels(CubedSphere(1, 4), np.ones(6), bad)


def test_a_margin_moves_elements_near_a_levels_limit_finer():
    """The refined ne4 cube's Dinv sizes: with margin m an element is coarse only if m λ_e ≤
    λ_max/2; the worst element keeps the finest level; m = 1 is the default; m < 1 refused."""
    grid = refined_grid()
    rate = element_sizes(grid).norm_dinv
    assert np.array_equal(element_levels(grid, rate, 2, 1.0).level, element_levels(grid, rate, 2).level)
    for margin in (1.1, 1.3):
        lv = element_levels(grid, rate, 2, margin)
        assert lv.level[np.argmax(rate)] == 1
        coarse = lv.level == 0
        assert np.all(margin * rate[coarse] <= rate.max() / 2 * (1 + 1e-12))
        assert coarse.sum() < 60  # fewer than without the margin
    with pytest.raises(ValueError, match="margin must be >= 1"):
        element_levels(grid, rate, 2, 0.9)
