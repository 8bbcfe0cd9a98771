"""CUDA against the CPU where the cube's tests do not go: a refined mesh read from a ``.g`` file
(nodes shared by 3 to 5 elements, DSS over an unstructured topology), a stretched cube,
E3SM's tensor ∇⁴ (``hyperviscosity.scaling``) and local time stepping over two levels, each a
few steps of TC5; and a two-level ``lts`` step replayed as a CUDA graph, the bits of plain
launches. Skipped without a CUDA device (issue 67: these paths had never run on a GPU)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import warp as wp

from swe_sphere.config.scene import load_scene
from swe_sphere.core.constants import DAY
from swe_sphere.grid.refine import Box, refined_cube
from swe_sphere.mesh.mesh import write_exodus
from swe_sphere.simulation.simulation import Simulation

from helpers import requires_cuda, rows_apart

BOX = Box(15.0, 45.0, 255.0, 285.0)  # 2×2 elements of the ne4 cube about TC5's mountain
STEPS = 6
STRETCH = {"grid.stretch_factor": 2.0, "grid.target_lat": 30.0, "grid.target_lon": 270.0}
TENSOR = {"hyperviscosity.scaling": 3.2}  # E3SM's hypervis_scaling (Guba et al. 2014)


@pytest.fixture(scope="module")
def refined(tmp_path_factory):
    """The ne4 cube refined 2× over ``BOX`` (124 elements; lts: two levels at TC5's Δt), as a .g file."""
    return write_exodus(tmp_path_factory.mktemp("mesh") / "r4.g", refined_cube(4, BOX, 1))


def tc5(stepper, mesh=None, ne=None, overrides=None, steps=STEPS):
    scene = load_scene("tc5_mountain", mesh=mesh, ne=ne, np_=4, stepper=stepper, overrides=overrides)
    days = steps * scene.dt / DAY
    return dataclasses.replace(scene, days=days, output_every_days=days)


def final_state(scene, device, graphs=False):
    """(the state (3, N) after the scene's steps on ``device``, the stepper)."""
    sim = Simulation(scene, device, progress=False)
    sim.graphs = graphs
    sim.run(None)
    return sim.x.numpy(), sim.stepper


def assert_round_off_apart(scene):
    """The scene's final state on CUDA within 1e-12 of the CPU's, row by row (relative to the
    row's largest value: sums in another order, and NVRTC's FMA contraction)."""
    cpu, cuda = final_state(scene, "cpu")[0], final_state(scene, "cuda")[0]
    rel = rows_apart(cuda, cpu)
    assert max(rel) <= 1e-12, rel


@requires_cuda
@pytest.mark.parametrize("stepper", ["rk4", "ssprk3", "lts"])
@pytest.mark.parametrize("overrides", [None, TENSOR], ids=["constant", "tensor"])
def test_a_refined_mesh_on_cuda_is_the_cpu_s(refined, stepper, overrides):
    """TC5 on the refined ne4 cube from its .g file: the explicit steppers and lts over its two
    levels (66 and 58 elements), with a constant and with the tensor ∇⁴."""
    scene = tc5(stepper, mesh=refined, overrides=overrides)
    if stepper == "lts":
        assert final_state(scene, "cpu")[1].levels.elements_per_level() == [66, 58]
    assert_round_off_apart(scene)


@requires_cuda
@pytest.mark.parametrize("overrides", [STRETCH, {**STRETCH, **TENSOR}], ids=["constant", "tensor"])
def test_a_stretched_cube_on_cuda_is_the_cpu_s(overrides):
    """TC5 on the ne4 cube stretched 2× toward 30°N 270°E (Schmidt), kgu35."""
    assert_round_off_apart(tc5("kgu35", ne=4, overrides=overrides))


@requires_cuda
@pytest.mark.parametrize("overrides", [None, TENSOR], ids=["constant", "tensor"])
def test_a_two_level_lts_step_graphed_on_cuda_is_the_bits_of_plain_launches(monkeypatch, refined, overrides):
    """12 lts steps over the refined cube's two levels, graphed and plain on CUDA: the same
    bits, the steps after the first few replayed as graphs (on a CPU 10 of the 12, the checked
    capture's replay included) and none failed back to plain launches."""
    scene = tc5("lts", mesh=refined, overrides=overrides, steps=12)
    plain = final_state(scene, "cuda", graphs=False)[0]
    replays, real = [0], wp.capture_launch

    def counted(*args, **kwargs):
        replays[0] += 1
        return real(*args, **kwargs)

    monkeypatch.setattr(wp, "capture_launch", counted)
    sim = Simulation(scene, "cuda", progress=False)
    sim.graphs = True
    sim.run(None)
    np.testing.assert_array_equal(sim.x.numpy(), plain)
    assert sim.model.launches.guard.failure is None, sim.model.launches.guard.failure
    assert replays[0] >= 12 - 3, replays[0]
