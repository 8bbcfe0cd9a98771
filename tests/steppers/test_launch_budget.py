"""Launches a step, counted for every registered stepper (issue 83 item 5).

TC5 np 4 at ne 2 (topography, ∇⁴), each stepper at the scene's defaults (its own options,
the scene's Δt rescaled to the grid), on the CPU: the third step's Warp launches, memsets and
copies (``core.tally.Tally.total_launches``) after two that record and compile, the
Helmholtz solve's own launches left out (it is a graph of its own on a card:
``tally.paused``, as ``benchmarks/micro/step/step_cost.py``'s "own launches"). The Newton-GMRES and
exponential steppers' Krylov iterations are part of their step and counted: their budgets
hold for the iterations named beside them.

LAUNCHES is today's count, exact: the budget a fusion of kernels must lower (and then lower
here); an added launch fails this test. At small grids a step on a GPU waits on its launches,
not on memory (about 3 µs each plain, 1 µs in a graph).
"""

from __future__ import annotations

import pytest

from swe_sphere.config.scene import load_scene
from swe_sphere.core.tally import Tally, instrumented
from swe_sphere.simulation.simulation import Simulation
from swe_sphere.steppers import STEPPERS

# stepper: (launches a step, its counted solvers' iterations that step; the Helmholtz solve's, left
# out, vary from step to step); the budget a fusion must lower
LAUNCHES = {
    "leapfrog": (10, {}),  # its ∇⁴ in 2 RKL1 stages where 3 Euler substeps were
    "leapfrog_trapezoidal": (10, {}),
    "ssprk3": (12, {}),
    "rk4": (14, {}),
    "kgu35": (16, {}),
    "bs32": (14, {}),
    "rk43": (16, {}),
    "kgu352": (19, {}),
    "dp54": (26, {}),
    "ssprk43": (14, {}),
    "rdpk3sp35": (22, {}),
    "fbrk32": (19, {}),
    "split_explicit": (37, {"fast": 4}),
    "mri": (68, {"fast": 12}),
    "lts": (14, {}),
    "semi_implicit": (15, {}),  # likewise
    "implicit": (60, {"newton": 3, "gmres": 5, "precond": 5}),
    "imex": (21, {}),
    "ark324": (23, {}),
    "ark436": (36, {}),
    "tableau": (14, {}),
    "epi2": (29, {"krylov": 10, "substeps": 1, "rejected": 0}),
    "epi3": (34, {"krylov": 10, "substeps": 1, "rejected": 0}),
}


def test_every_registered_stepper_has_a_launch_budget():
    assert sorted(LAUNCHES) == sorted(STEPPERS)


@pytest.mark.parametrize("name", list(LAUNCHES))
def test_a_step_launches_its_budget(name):
    launches, iterations = LAUNCHES[name]
    sim = Simulation(load_scene("tc5_mountain", ne=2, np_=4, stepper=name), "cpu", progress=False)
    tally = Tally()
    with instrumented(tally):
        helmholtz = getattr(sim.stepper, "helmholtz", None)
        if helmholtz is not None:
            helmholtz.solve = tally.paused(helmholtz.solve)
        sim.stepper.step(sim.x), sim.stepper.step(sim.x)  # recorded and compiled outside the count
        with tally.counting():
            stats = sim.stepper.step(sim.x)
    assert {k: n for k, n in stats.iterations.items() if k != "helmholtz"} == iterations
    assert tally.total_launches == launches, dict(tally.launches)
