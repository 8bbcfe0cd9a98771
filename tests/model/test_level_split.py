"""The assembled tendency split by element level (``ElementPart.of``/``rhs_part``):
f = Σ_k f_k, f_k = M⁻¹ DSS(level k's elements' contributions), on a refined cube."""

from __future__ import annotations

import numpy as np
import pytest
import warp as wp

from swe_sphere.grid.cubed_sphere import CubedSphere
from swe_sphere.grid.levels import element_levels, element_rates
from swe_sphere.model.parts import ElementPart

import roundoff
from meshes import case_model, refined_ne4_grid

TC5_TERMS = ["continuity", "momentum_advection", "coriolis", "pressure_gradient", "topography"]


def refined_grid():
    """The ne4 cube refined 2× about TC5's mountain (124 elements), np 4 (``meshes.refined_ne4_grid``)."""
    return refined_ne4_grid()


@pytest.mark.parametrize("per_element, gap", [(True, 0), (False, 0), (True, 16)])
def test_the_levels_tendencies_add_up_to_the_assembled_one(per_element, gap):
    """TC5 (topography included) on the refined ne4 cube, its two levels from the flow: Σ_k f_k
    equals F to the DSS's round-off (each node's copies summed in two groups, then added:
    ≤ 2·copies roundings of the copies' Σ spheremp|tend| / area), f_k zero at the nodes its
    elements do not touch, with either kernel layout, and with a level's ranges merged over
    gaps of the other level's elements (computed, left out of its assembly)."""
    grid = refined_grid()
    case, model = case_model(grid, "tc5_mountain", TC5_TERMS, per_element=per_element, threads=1)
    x = model.new_state(*case.initial(grid.lat, grid.lon))
    levels = element_levels(grid, element_rates(grid, x.numpy(), model.g), 4)
    assert levels.count == 2
    F = wp.zeros_like(x)
    model.rhs(x, F)
    tend = model.tend.numpy()
    parts, total = [], np.zeros((3, model.N))
    for k in range(levels.count):
        mine = np.flatnonzero(levels.level == k)
        part = ElementPart.of(model, mine, gap)
        assert part.nelem == levels.elements_per_level()[k]
        ranges = 1 + np.count_nonzero(np.diff(mine) > 1)  # of consecutive elements
        assert len(part.runs) == ranges if gap == 0 else len(part.runs) < ranges
        ran = np.concatenate([np.arange(a, b) for a, b in part.runs])
        assert set(mine) <= set(ran) and (gap or len(ran) == len(mine))
        f_k = wp.zeros_like(x)
        model.rhs_part(x, f_k, part)
        model.rhs_part(x, f_k, part)  # replayed: the same
        total += f_k.numpy()
        parts.append((part, f_k.numpy()))
    copies = np.bincount(grid.gid).max()
    for r in range(3):
        weighted = np.bincount(grid.gid, grid.spheremp * np.abs(tend[r])) / np.bincount(grid.gid, grid.spheremp)
        limit = roundoff.bound(2 * copies, weighted.max() / np.abs(F.numpy()[r]).max())
        roundoff.within(np.abs(total[r] - F.numpy()[r]).max() / np.abs(F.numpy()[r]).max(), limit, f"row {r}")
    for part, f_k in parts:
        untouched = np.ones(model.N, dtype=bool)
        untouched[part.nodes.numpy()] = False
        assert untouched.any() and not f_k[:, untouched].any()


def test_part_elements_outside_the_grid_are_refused():
    grid = CubedSphere(1, 4)
    _, model = case_model(grid, "tc2_steady", TC5_TERMS[:4], threads=1)
    with pytest.raises(ValueError, match="part elements must be ascending distinct indices in 0..5"):
        ElementPart.of(model, [3, 7])
    with pytest.raises(ValueError, match="part elements must be ascending"):
        ElementPart.of(model, [2, 0])
    with pytest.raises(ValueError, match="gap must be an integer >= 0"):
        ElementPart.of(model, [0, 1], -1)


@pytest.mark.parametrize("per_element", [True, False])
def test_a_combination_at_listed_nodes_has_the_whole_ones_bits_there_alone(per_element, rng):
    """``lincomb_at`` over 1000 of the refined cube's nodes (not a whole number of elements'
    np² blocks): out = x + a·y + b·z + c·w with ``lincomb``'s bits at those nodes, out's other
    nodes untouched; three terms, one row or no nodes are refused."""
    grid = refined_grid()
    _, model = case_model(grid, "tc2_steady", TC5_TERMS[:4], per_element=per_element, threads=1)
    dev = model.device
    x, y, z, w = (wp.array(rng.standard_normal((3, model.N)), dtype=wp.float64, device=dev) for _ in range(4))
    terms = ((1.0, x), (0.3, y), (-0.7, z), (1.1, w))
    nodes = np.sort(rng.choice(model.N, 1000, replace=False)).astype(np.int32)
    whole, out = wp.zeros_like(x), wp.full_like(x, 7.0)
    model.lincomb(whole, terms).launch()
    model.launches.lincomb_at(out, terms, wp.array(nodes, dtype=wp.int32, device=dev)).launch()
    listed = np.zeros(model.N, dtype=bool)
    listed[nodes] = True
    np.testing.assert_array_equal(out.numpy()[:, listed], whole.numpy()[:, listed])
    assert np.all(out.numpy()[:, ~listed] == 7.0)
    with pytest.raises(ValueError, match="lincomb_at takes four terms, three rows and some nodes"):
        model.launches.lincomb_at(out, terms[:3], wp.array(nodes, dtype=wp.int32, device=dev))
    with pytest.raises(ValueError, match="lincomb_at takes four terms, three rows and some nodes"):
        model.launches.lincomb_at(out, terms, wp.zeros(0, dtype=wp.int32, device=dev))
    with pytest.raises(ValueError, match="lincomb_at takes four terms, three rows and some nodes"):
        model.launches.lincomb_at(
            out[2:3], tuple((c, a[2:3]) for c, a in terms), wp.array(nodes, dtype=wp.int32, device=dev)
        )
