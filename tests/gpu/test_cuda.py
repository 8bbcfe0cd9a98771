"""CUDA against the CPU for every registered stepper.

TC5 (every term: advection, Coriolis, pressure gradient, topography, ∇⁴) on
ne = 2 np = 4 for a few steps, once on each device: the final states agree to
round-off for the explicit steppers and to the solver tolerances for the
implicit-type ones, whose Krylov and Newton loops may stop at another iteration
when the last bits of an inner product differ. Skipped without a CUDA device.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from swe_sphere.config.scene import load_scene
from swe_sphere.core.constants import DAY
from swe_sphere.simulation.simulation import Simulation
from swe_sphere.steppers import STEPPERS
from swe_sphere.steppers.base import option_types

from helpers import requires_cuda, rows_apart

STEPS = 6
# relative max-norm difference of the final state, per stepper family
TOLERANCE = {"explicit": 1e-12, "solver": 1e-8}
SOLVER = {
    "semi_implicit",
    "implicit",
    "imex",
    "ark324",
    "ark436",
    "epi2",
    "epi3",
}  # epi: forward-difference J·v (1e-8 of it) reads the last bits


def tc5_state(name: str, device: str, options: dict | None = None) -> np.ndarray:
    """(3, nelem, np, np) state after STEPS steps of TC5 ne2 np4 on ``device``;
    implicit-type steppers at 4× the scene's Δt."""
    scene = load_scene("tc5_mountain", ne=2, np_=4, stepper=name)
    dt = scene.dt * (4.0 if name in SOLVER else 1.0)
    scene = dataclasses.replace(
        scene, dt=dt, days=STEPS * dt / DAY, output_every_days=STEPS * dt / DAY, stepper_options=dict(options or {})
    )
    sim = Simulation(scene, device, progress=False)
    sim.run(None)
    return sim.x.numpy()


@requires_cuda
@pytest.mark.parametrize("name", list(STEPPERS))
def test_every_stepper_on_cuda_matches_the_cpu(name):
    cpu, cuda = tc5_state(name, "cpu"), tc5_state(name, "cuda")
    rel = rows_apart(cuda, cpu)
    tol = TOLERANCE["solver" if name in SOLVER else "explicit"]
    assert max(rel) <= tol, f"{name}: rows differ by {rel} (tolerance {tol:g})"


# the steppers with a Helmholtz solve and its ``precision`` option (the exponential ones have neither)
MIXED = sorted(n for n in SOLVER if "precision" in option_types(STEPPERS[n].Options))


@requires_cuda
@pytest.mark.parametrize("name", MIXED)
def test_float32_helmholtz_solves_on_cuda_match_the_cpu(name):
    """``precision = "float32"`` (float32 CG, the element kernels on either device): the
    devices' float32 round-off differs, so the states agree to the solves' tolerance
    (1e-6 relative, refined; JFNK's Newton to its 1e-8), not to round-off."""
    cpu, cuda = (tc5_state(name, d, {"precision": "float32"}) for d in ("cpu", "cuda"))
    rel = rows_apart(cuda, cpu)
    assert max(rel) <= 1e-5, f"{name}: rows differ by {rel}"


@requires_cuda
def test_tracers_on_cuda_match_the_cpu():
    """TC5 ne2 np4 with two tracers (q = 1 and the latitude marker; issue 125), rk4, six steps on
    each device: every row, the tracers' masses too, within the explicit steppers' tolerance."""

    def state(device: str) -> np.ndarray:
        tracers = {"names": ["one", "marker"], "initial": ["constant", "latitude"]}
        scene = load_scene("tc5_mountain", ne=2, np_=4, stepper="rk4", tracers=tracers)
        days = STEPS * scene.dt / DAY
        sim = Simulation(dataclasses.replace(scene, days=days, output_every_days=days), device, progress=False)
        sim.run(None)
        return sim.x.numpy()

    cpu, cuda = state("cpu"), state("cuda")
    assert cpu.shape[0] == 5
    rel = rows_apart(cuda, cpu)
    assert max(rel) <= TOLERANCE["explicit"], rel
