"""The per-node (CUDA) layout's tendency and ∇⁴ kernels compiled for the grid's np
(``ElementOperators.static_np``: their loops along an element's rows unrolled, issue 83 item 5)
do the arithmetic of np read at run time, step after step, for every variant of the ∇⁴
they cover (constant ν, ν_div ≠ ν, the tensor ∇⁴) at np 3, 4 and 8: the same bits on the CPU;
on CUDA, whose compiler may contract other products into FMAs once a loop is unrolled, to the
round-off of the passes run."""

from __future__ import annotations

import numpy as np
import pytest
import warp as wp

from swe_sphere.cases.library import make_case
from swe_sphere.model.shallow_water import ShallowWater
from swe_sphere.steppers import make_stepper

from helpers import ON_CUDA
from roundoff import bound, operator_roundings, within

TC5_TERMS = ["continuity", "momentum_advection", "coriolis", "pressure_gradient", "topography", "hyperviscosity"]
VARIANTS = {
    "constant": {"nu": 1e15},
    "nu_div": {"nu": 1e15, "nu_div": 2.5e15},
    "tensor": {"nu": 1e15, "hypervis_scaling": 3.2},
}


STEPS = 3
PASSES = STEPS * (4 * 2 + 5)  # a step: 4 tendencies and their DSS, the ∇⁴'s flux, Laplacian, DSS, flux, Laplacian


def _steps(grid, device: str, static: bool, options: dict, monkeypatch) -> tuple[np.ndarray, set]:
    """(the state after ``STEPS`` RK4 steps of 300 s of TC5 from its start plus a ripple, on the
    per-node layout on ``device``, its kernels compiled for the grid's np (the model's own) or,
    not ``static``, reading np at run time; the names of the kernels the steps launched)."""
    case = make_case("tc5_mountain")
    model = ShallowWater.from_case(grid, case, TC5_TERMS, device=device, per_element=False, threads=1, **options)
    assert model.operators.static_np == grid.np
    if not static:
        model.operators.static_np = 0  # read as the step's launches are recorded
    launched, real_launch = set(), wp.launch

    def launch(kernel, *args, **kwargs):
        launched.add(kernel.key)
        return real_launch(kernel, *args, **kwargs)

    monkeypatch.setattr(wp, "launch", launch)
    u, v, h = case.initial(grid.lat, grid.lon)
    ripple = np.sin(3 * grid.lon) * np.cos(2 * grid.lat)  # modes the ∇⁴ damps within a few steps
    x = model.new_state(u + 2 * ripple, v - ripple, h + 50 * ripple)
    stepper = make_stepper("rk4", model, 300.0)
    for _ in range(STEPS):
        stepper.step(x)
    return x.numpy(), {key for key in launched if key.startswith(("tendency", "laplacian"))}


@pytest.mark.parametrize("device", ["cpu", ON_CUDA])
@pytest.mark.parametrize("variant", list(VARIANTS))
@pytest.mark.parametrize("np_", [3, 4, 8])
def test_kernels_compiled_for_the_grids_np_step_as_np_read_at_run_time(grid_factory, monkeypatch, np_, variant, device):
    grid = grid_factory(2, np_)
    at_run_time, read = _steps(grid, device, False, VARIANTS[variant], monkeypatch)
    compiled, fixed = _steps(grid, device, True, VARIANTS[variant], monkeypatch)
    assert read and all(not key.endswith(f"__np{np_}") for key in read), read
    assert {f"{key}__np{np_}" for key in read} == fixed and np.isfinite(compiled).all()
    if device == "cpu":
        assert np.array_equal(compiled, at_run_time)
    for row, name in enumerate(("u", "v", "h")):  # each row to its own scale
        scale = float(np.max(np.abs(at_run_time[row])))
        measured = float(np.max(np.abs(compiled[row] - at_run_time[row])))
        within(measured, bound(operator_roundings(np_, PASSES), scale), f"{name}: compiled for np against read")
