"""A float32 model (``ShallowWater(precision="float32")``, ``model.precision``): its tendency's and
∇⁴'s round-off against float64's, the reference depth that keeps the pressure gradient's digits, a
run's error and mass against float64's, and a continuation that has the uninterrupted run's bits."""

import numpy as np
import pytest
import warp as wp
import xarray as xr

from swe_sphere import Simulation, load_scene
from swe_sphere.cli import main
from swe_sphere.model.launches import Update
from swe_sphere.model.shallow_water import ShallowWater
from tests.helpers import cached_grid

EPS32 = float(np.finfo(np.float32).eps)


def _rhs(scene, grid, x0, **options):
    """F(x0) (3, N) of ``scene``'s model on ``grid``, and x0 + 100 s·F written by ``rhs_update``."""
    model = ShallowWater.from_scene(scene, grid, **options)
    x = model.new_state(*x0)
    out, stage = wp.zeros_like(x), wp.zeros_like(x)
    model.rhs(x, out)
    model.rhs_update(x, [Update(stage, ((1.0, x), (100.0, None)), None)])
    return out.numpy(), stage.numpy()


@pytest.mark.parametrize("np_, per_element", [(4, True), (4, False), (6, True)])
def test_the_float32_tendency_is_float64_s_to_float32_round_off(np_, per_element):
    """Galewsky's jet (the geostrophic balance: du/dt a small difference of the Coriolis and
    pressure terms): each row of F in float32 within 64 ε₃₂ of its largest float64 value
    (measured 4–12 ε₃₂ at np 4, 50 at np 6's wind: the rows' derivative sums of np terms), and
    not float64's bits (it ran in float32); a stage update x + 100 s·F the same to that F's
    round-off times 100 s, its DSS summed in float64 (h to 1.2e-7 m of 10 km)."""
    scene = load_scene("galewsky", ne=3, np_=np_)
    grid = cached_grid(3, np_)
    x0 = np.stack(scene.make_case().initial(grid.lat, grid.lon))
    (f64, s64), (f32, s32) = (
        _rhs(scene, grid, x0, per_element=per_element, precision=p) for p in ("float64", "float32")
    )
    scale = np.abs(f64).max(axis=1)
    apart = np.abs(f32 - f64).max(axis=1) / scale
    assert np.all(apart < 64 * EPS32) and np.all(apart > 0), apart
    assert np.all(np.abs(s32 - s64).max(axis=1) <= 100.0 * 64 * EPS32 * scale)


def test_the_reference_depth_keeps_the_pressure_gradient_s_digits():
    """h = H₀ + a 50 m wave at rest, the pressure gradient alone: with h − H₀ formed in float64
    (``depth``, the model's choice from the case) the float32 du/dt keeps 16× the digits it keeps
    from h itself (10 km rounded to float32 loses log2(10 km / 50 m) ≈ 7.6 bits)."""
    grid = cached_grid(3, 4)
    z = np.zeros(grid.nnodes)
    h = 1.0e4 + 50.0 * np.cos(grid.lat) ** 2 * np.sin(2.0 * grid.lon)

    def du(**options):
        model = ShallowWater(grid, ["pressure_gradient"], z, z, **options)
        out = wp.zeros((3, grid.nnodes), dtype=wp.float64)
        model.rhs(model.new_state(h=h), out)
        return out.numpy()[:2]

    exact = du()
    shifted = np.abs(du(precision="float32", depth=1.0e4) - exact).max()
    plain = np.abs(du(precision="float32") - exact).max()
    assert shifted * 16 < plain and shifted < 64 * EPS32 * np.abs(exact).max()


def _hyperviscosity_increment(scene, grid, x0, **options):
    """The increment (3, N) of ``scene``'s ∇⁴ over its Δt on ``grid`` from the state x0, and the model."""
    model = ShallowWater.from_scene(scene, grid, **options)
    x = model.new_state(*x0)
    model.hyperviscosity(x, scene.dt)
    return x.numpy() - x0, model


@pytest.mark.parametrize("np_, per_element", [(4, True), (6, True), (4, False)])
def test_the_float32_hyperviscosity_is_float64_s_to_float32_round_off(np_, per_element):
    """Galewsky's ∇⁴ over its Δt (np 4: one forward-Euler substep, on rows or per node; np 6: a
    two-stage RKL1 step, its weak Laplacians 16 elements a vector, 54 elements: three blocks and
    6 on rows): each row of the float32 increment within 4 ε₃₂ max|X| an evaluation of
    float64's, X what the ∇⁴ reads (the wind, h + hs − H₀). A stable step has |coef ν λ| ≤ 1.5
    (λ the ∇⁴'s spectral radius), so the rounding of X (ε₃₂/2 |X|) moves an increment by
    ≤ 0.75 ε₃₂ |X|, the float32 sums adding theirs (measured 0.04–0.45 ε₃₂ |X| at np 4, 0.1–1.5
    over np 6's two stages: 2–9 ε₃₂ of np 4's increment, 26–97 of np 6's smaller one); and not
    float64's bits. Mass: float64's ∇⁴ keeps it to ε₆₄ (an element's weak Laplacian sums to 0 over
    its nodes, Σᵢ dvv[m, i] = 0), float32's to its round-off of those sums, within ε₃₂ ∫|Δh|
    (measured 0.0015 ε₃₂ ∫|Δh| on rows, 0.011 per node, 0.03 across at np 6: a relative mass
    change of 3e-14 to 2e-13 a step)."""
    scene = load_scene("galewsky", ne=3, np_=np_)
    grid = cached_grid(3, np_)
    x0 = np.stack(scene.make_case().initial(grid.lat, grid.lon))
    (d64, m64), (d32, m32) = (
        _hyperviscosity_increment(scene, grid, x0, per_element=per_element, precision=p) for p in ("float64", "float32")
    )
    evaluations = m32.hv.plan(scene.dt)[0]
    assert m64.hv.plan(scene.dt) == m32.hv.plan(scene.dt) == ((1, False) if np_ == 4 else (2, True))
    assert m32.hv.lanes == (16 if np_ == 6 else 0) and m32.hv.hv_L.dtype == wp.float32
    hs, depth = m32.operators.hs.numpy(), m32.tendency_arrays.depth
    speed = np.hypot(x0[0], x0[1]).max()
    X = np.array([speed, speed, np.abs(x0[2] + hs - depth).max()])
    apart = np.abs(d32 - d64).max(axis=1)
    assert np.all(apart <= 4 * evaluations * EPS32 * X) and np.all(apart > 0), apart / (EPS32 * X)
    assert abs(grid.integrate(d32[2])) <= EPS32 * grid.integrate(np.abs(d64[2]))


def test_a_float32_run_keeps_float64_s_error_and_mass():
    """TC2 (steady geostrophic flow, exact solution) ne4 np4 for a day with rk4: the float32 run's h
    error within 1 % of float64's, its h within 1 % of that error of float64's h; its mass to the
    float32 fluxes' mismatch on the element edges (each side rounds its own), 1e-3 ε₃₂ a step
    (measured 1e-5 ε₃₂ a step: 9e-12 over 8 steps; float64's stays at 1e-16 a step)."""
    runs = {}
    for precision in ("float64", "float32"):
        sim = Simulation("tc2_steady", ne=4, np=4, days=1.0, stepper="rk4", progress=False, precision=precision)
        runs[precision] = (sim.run(), sim.x.numpy()[2].copy(), sim.model.precision)
    (r64, h64, p64), (r32, h32, p32) = runs["float64"], runs["float32"]
    assert (p64, p32) == ("float64", "float32")
    d64, d32 = r64.diagnostics, r32.diagnostics
    assert abs(d32["l2_h"] - d64["l2_h"]) <= 0.01 * d64["l2_h"]
    assert 0 < np.abs(h32 - h64).max() <= 0.01 * d64["linf_h"] * np.abs(h64).max()
    assert abs(d32["mass_change"]) <= r32.steps * 1e-3 * EPS32
    assert abs(d64["mass_change"]) <= r64.steps * 10 * np.finfo(float).eps


@pytest.mark.parametrize("precision", ["float32", "float32_state"])
def test_a_float32_run_continues_bitwise(tmp_path, precision):
    """A float32 run (mixed, or its state in float32) stopped at day 0.1 and continued to 0.2
    ends with the uninterrupted run's bits: the restart keeps its precision (the run file says
    which), and the state between steps (float64, or the float32 state kept from step to step
    with its fixer's mass) is the whole of what a step starts from."""
    common = ["run", "tc5_mountain", "--ne", "2", "--stepper", "kgu35", "--precision", precision, "--no-progress"]
    assert main([*common, "--days", "0.2", "--output", str(tmp_path / "whole.nc")]) == 0
    half = ["--days", "0.1", "--restart-every", "0.1", "--output", str(tmp_path / "half.nc")]
    assert main([*common, *half]) == 0
    rest = ["run", "--continue", str(tmp_path / "half.restart.nc"), "--days", "0.2", "--no-progress"]
    assert main([*rest, "--output", str(tmp_path / "rest.nc")]) == 0
    with xr.open_dataset(tmp_path / "whole.nc") as a, xr.open_dataset(tmp_path / "rest.nc") as b:
        assert a.attrs["precision"] == b.attrs["precision"] == precision
        for name in ("h", "u", "v"):
            assert np.array_equal(a[name].isel(time=-1).values, b[name].isel(time=-1).values), name
