"""The arrays a float32 state's run holds (issue 128): its steps read float32 copies of the
geometry, so its float64 geometry stays on the host (``ElementOperators``' ``on_demand``), the
diagnostics' vorticity and divergence run on copies for one use, and they give the bits of the
operators that hold their arrays."""

import gc

import numpy as np
import pytest
import warp as wp

from swe_sphere import load_scene
from swe_sphere.model.element_operators import GEOMETRY, WORK
from swe_sphere.model.shallow_water import ShallowWater
from swe_sphere.steppers import make_stepper
from tests.helpers import cached_grid


def built(precision, per_element, **options):
    """(model, stepper, held state) of TC5 at ne4 np4 (topography, Coriolis, the ∇⁴)."""
    scene = load_scene("tc5_mountain", ne=4, np_=4)
    case, grid = scene.make_case(), cached_grid(4, 4)
    model = ShallowWater.from_scene(
        scene, grid, case, device="cpu", threads=1, per_element=per_element, precision=precision, **options
    )
    stepper = make_stepper(scene.stepper, model, scene.dt, **scene.stepper_options)
    return model, stepper, model.held.new(np.stack(case.initial(grid.lat, grid.lon)))


@pytest.mark.parametrize("per_element", [True, False])
def test_a_float32_state_holds_no_float64_geometry_and_diagnoses_with_the_same_bits(per_element):
    """A kept float32 state's model after 3 steps and a diagnosis holds, of the float64 geometry
    and work arrays, hs alone (its ∇⁴ reads it; ν_div = ν, so no δ); its vorticity and divergence (on copies for one
    use) are the float64 model's (held arrays) on the same float64 state to the bit, and so are its
    host geometry and −g∇hs; both layouts."""
    m32, stepper, x = built("float32_state", per_element, compensated=False)
    m64 = built("float64", per_element)[0]
    for _ in range(3):
        stepper.step(x)
    ops = m32.operators
    y = m32.held.float64(x, once=True)
    zeta, delta = ops.vorticity(y), ops.wind_divergence(y)
    both = ops.rotation_divergence(*m32.held.values(x)[:2])
    held = sorted(k for k in (*GEOMETRY, *WORK) if k in vars(ops))
    assert ops.on_demand and not m64.operators.on_demand
    assert held == ["hs"], held
    y64 = m64.held.new(m32.held.values(x))
    assert np.array_equal(zeta, m64.operators.vorticity(y64)) and np.array_equal(zeta, both[0])
    assert np.array_equal(delta, m64.operators.wind_divergence(y64)) and np.array_equal(delta, both[1])
    assert np.abs(zeta).max() > 1e-6 and np.abs(delta).max() > 1e-9  # a flow, not zeros
    for name in ("D", "Dinv", "metdet", "fcor", "forcing"):
        assert np.array_equal(ops.values(name), getattr(m64.operators, name).numpy()), name
    assert np.array_equal(ops.values("forcing"), m64.topo_forcing.numpy())


@pytest.mark.parametrize("precision", ["float64", "float32_state"])
def test_set_fcor_reaches_what_the_launches_read(precision):
    """``set_fcor`` after the build: the device array the float64 tendency reads, or (a float32
    state's, not uploaded) the host values its lanes are made from."""
    model = built(precision, True)[0]
    ops, fcor = model.operators, np.linspace(-1e-4, 1e-4, model.N)
    ops.set_fcor(fcor)
    assert np.array_equal(ops.values("fcor"), fcor)
    assert ("fcor" in vars(ops)) == (precision == "float64")
    if precision == "float64":
        assert np.array_equal(ops.fcor.numpy(), fcor)


def test_the_float32_state_lanes_make_no_metdet():
    """The kept float32 state's tendency lanes take metdet as det D (``tendency_lanes``' determinant)
    and read none, so after a step its model holds no metdet in the lanes' across layout (4 B a
    node): asking the lanes for the geometry a float64 state's launch reads (``geometry(False)``)
    makes it then, one float32 W-vector a node (ne4's 96 elements fill 6 blocks of 16)."""
    model, stepper, x = built("float32_state", True, compensated=False)
    stepper.step(x)
    assert model.lanes.lanes == 16

    def owned() -> int:  # bytes of the live Warp arrays that own their memory
        gc.collect()
        return sum(a.capacity for a in gc.get_objects() if type(a) is wp.array and a.ptr and a.deleter is not None)

    before = owned()
    metdet = model.lanes.geometry(False)[1]
    assert owned() - before == metdet.capacity == 4 * model.N
    across, host = np.sort(metdet.numpy().ravel()), np.sort(model.operators.values("metdet"))  # another order
    assert np.allclose(across, host, rtol=1e-7)
