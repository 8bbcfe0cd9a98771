"""The tendency's vector lanes (``model.lanes``, ``kernels.tendency_lanes.tendency_across``): W
elements a vector at np 4 (and the float32 state's at np 8), the rows' arithmetic in float64 to
the bit (its sums in the rows' order), float32's to its round-off over steps, where it is
dispatched and where not."""

import numpy as np
import pytest
import warp as wp

from swe_sphere import load_scene, make_stepper
from swe_sphere.core.errors import ArgumentError
from swe_sphere.model import lanes
from swe_sphere.model.parts import ElementPart
from swe_sphere.model.shallow_water import ShallowWater
from tests.helpers import cached_grid

EPS32 = float(np.finfo(np.float32).eps)


def _model(scene, grid, width, **options):
    """``scene``'s model on ``grid`` with W = ``width`` lanes (0: the rows)."""
    return ShallowWater.from_scene(scene, grid, device="cpu", lanes=width, **options)


def _rhs(model, x0):
    """F(x0) (3, N) and the kernels ``model.rhs`` launched."""
    x = model.new_state(*x0)
    out = wp.zeros_like(x)
    model.rhs(x, out)
    return out.numpy(), model.rhs_kernels(x, out)


@pytest.mark.parametrize("width", [8, 16])
@pytest.mark.parametrize("name", ["tc5_mountain", "tc1_cosine_bell", "tc4_forced_low"])
def test_float64_lanes_have_the_rows_bits(name, width):
    """In float64 the lanes compute the rows' sums in their order: F to the bit, for TC5's five terms
    (mass-weighted), TC1's continuity alone and TC4's forcing (unweighted), on ne 3's 54 elements (a
    last block of 6 of W, its other lanes padded and not written), on two threads."""
    scene = load_scene(name, ne=3)
    grid = cached_grid(3, 4)
    x0 = np.stack(scene.make_case().initial(grid.lat, grid.lon))
    rows, k_rows = _rhs(_model(scene, grid, 0, threads=2), x0)
    lanes_, k_lanes = _rhs(_model(scene, grid, width, threads=2), x0)
    assert not any("across" in k for k in k_rows)
    assert any(k.startswith(f"tendency_across__np4_w{width}__") for k in k_lanes)
    assert np.array_equal(rows, lanes_)


@pytest.mark.parametrize("precision, ne, np_", [("float32", 3, 4), ("float32_state", 3, 4), ("float32_state", 2, 8)])
def test_float32_lanes_stay_within_steps_of_float32_round_off(precision, ne, np_):
    """In float32 clang contracts other products into FMAs than on rows: TC5 (its mountain, every
    term) stepped 12 rk4 steps with lanes and with rows stays within 12 steps × 8 ε₃₂ of each row's
    largest value (measured: u, v 1.3, 5.2 ε₃₂ in float32, 4.2, 16 in float32_state; h 0.2, 0.3;
    np 8's float32 state, its rows moved by four transposes of 16 an element, ne 2's 24 elements
    a block and a padded one: u, v 3.9, 25 ε₃₂, h 0.4), and the two are not the same bits (the lanes ran)."""
    scene = load_scene("tc5_mountain", ne=ne, np_=np_)
    grid = cached_grid(ne, np_)
    x0 = np.stack(scene.make_case().initial(grid.lat, grid.lon))
    steps, states = 12, []
    for width in (0, 16):
        model = _model(scene, grid, width, threads=1, precision=precision)
        assert model.lanes.lanes == width
        stepper = make_stepper("rk4", model, scene.dt)
        x = model.new_state(*x0)
        for _ in range(steps):
            stepper.step(x)
        states.append(x.numpy())
    rows, across = states
    scale = np.abs(rows).max(axis=1)
    apart = np.abs(rows - across).max(axis=1) / scale
    assert np.all(apart < steps * 8 * EPS32), apart
    assert apart.max() > 0


def test_lanes_run_where_they_pay():
    """The lanes at the shipped ``LANES``: float32 (the mixed and the state) on the CPU's elements at
    np 4, the float32 state's at np 8 (not the mixed float32's: its bits kept), a part's elements
    too (the blocks that hold them) and 6 elements (one block, its other lanes padded: a rank's few
    elements run the arithmetic of one rank's many, the bits of every rank count); not float64,
    np 6, the per-node layout or tracers (their rows ride the element kernel, the dynamics' too)."""
    scene = load_scene("tc5_mountain", ne=3)
    grid = cached_grid(3, 4)

    def kernels(scene, grid, **options):
        model = ShallowWater.from_scene(scene, grid, device="cpu", threads=1, **options)
        return model, _rhs(model, np.stack(scene.make_case().initial(grid.lat, grid.lon)))[1]

    for precision in ("float32", "float32_state"):
        model, names = kernels(scene, grid, precision=precision)
        assert model.lanes.lanes == lanes.LANES[wp.float32] == 16
        assert names[0].startswith("tendency_across__np4_w16__") and names[0].endswith("_float32")
    model = kernels(scene, grid, precision="float32")[0]
    assert model.tendency_arrays.metdet is None  # the lanes hold the geometry: no float32 rows of it
    part = ElementPart.of(model, np.arange(3, 30))  # a part's elements: in lanes, blocks 0 and 1
    x = model.new_state(*np.stack(scene.make_case().initial(grid.lat, grid.lon)))
    out = wp.zeros_like(x)
    model.rhs_part(x, out, part)
    key = ("rhs_part", id(part), *model.rhs_key(x, out)[1:])
    launch = model.launches.recorded(key)[0]
    assert launch.kernel.key.startswith("tendency_across__") and model.lanes.blocks(part.runs) == [0, 1]
    whole = wp.zeros_like(x)
    model.rhs(x, whole)  # the part's own nodes alone: the same as the whole F where no other element touches
    inner = [e * 16 + n for e in range(3, 30) for n in (5, 6, 9, 10)]
    assert np.array_equal(out.numpy()[:, inner], whole.numpy()[:, inner])
    assert kernels(scene, grid)[0].lanes.lanes == 0  # float64: its rows
    assert kernels(load_scene("tc5_mountain", ne=3, np_=6), cached_grid(3, 6), precision="float32")[0].lanes.lanes == 0
    np8 = load_scene("tc5_mountain", ne=2, np_=8), cached_grid(2, 8)  # the float32 state's lanes, not the mixed
    model, names = kernels(*np8, precision="float32_state")
    assert model.lanes.lanes == 16 and names[0].startswith("tendency_across__np8_w16__")
    assert kernels(*np8, precision="float32")[0].lanes.lanes == 0
    assert kernels(scene, grid, precision="float32", per_element=False)[0].lanes.lanes == 0
    assert kernels(load_scene("tc5_mountain", ne=1), cached_grid(1, 4), precision="float32")[0].lanes.lanes == 16
    tracers = load_scene("tc5_mountain_marker", ne=3)  # float64 (float32 refuses tracers), the lanes asked for
    model, names = kernels(tracers, grid, lanes=16)
    assert model.tracers and model.lanes.lanes == 16 and not any("across" in k for k in names)


def test_a_bad_lanes_is_refused_naming_it():
    """``lanes`` must be an integer ≥ 0: one line naming it."""
    grid = cached_grid(2, 4)
    z = np.zeros(grid.nnodes)
    with pytest.raises(ArgumentError, match="lanes"):
        ShallowWater(grid, ["continuity"], z, z, lanes=-16)
