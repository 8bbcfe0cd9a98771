"""The model's costs on the CPU clock of one thread, through the public API: the RHS of TC5 at ne30
and ne120 in float64 and float32 (``numerics.precision``: the tendency's type), a Galewsky step (the
scene's stepper, its run loop), a step of 8 Galewsky members in one Simulation, and the gradient of
a height misfit over TC5 steps (``swe_sphere.gradient``)."""

import time

import numpy as np
import warp as wp

from swe_sphere import CubedSphere, HeightMisfit, Perturbation, ShallowWater, Simulation, gradient, load_scene

from . import QUICK

CPU = time.process_time  # asv's timer: the CPU clock of this (one-thread) process


class Rhs:
    """One RHS evaluation of TC5 (``ShallowWater.rhs``), the state at its initial value."""

    params = [[4] if QUICK else [30, 120], ["float64", "float32"]]
    param_names = ["ne", "precision"]
    timer = CPU
    timeout = 600
    number = 5

    def setup(self, ne, precision):
        scene = load_scene("tc5_mountain", ne=ne, precision=precision)
        grid = CubedSphere(ne, scene.np)
        case = scene.make_case()
        self.model = ShallowWater.from_scene(scene, grid, case, device="cpu", threads=1)
        self.x = self.model.new_state(*np.stack(case.initial(grid.lat, grid.lon)))
        self.out = wp.zeros_like(self.x)
        self.model.rhs(self.x, self.out)  # compiled and recorded: the calls timed replay

    def time_rhs(self, ne, precision):
        self.model.rhs(self.x, self.out)


def galewsky(members: int | None = None) -> Simulation:
    """Galewsky on its own grid (ne4 in the quick form), one step taken (compiled and recorded)."""
    scene = load_scene("galewsky", **({"ne": 4} if QUICK else {}))
    many = {"members": members, "initial": Perturbation(1.0, seed=1)} if members else {}
    sim = Simulation(scene, "cpu", progress=False, **many)
    sim.run(None, until_step=1)
    return sim


class Step:
    """A step of Galewsky through ``Simulation.run``: one member, and 8 in the same launches."""

    params = [[1, 2 if QUICK else 8]]
    param_names = ["members"]
    timer = CPU
    timeout = 600

    def setup(self, members):
        self.sim = galewsky(members if members > 1 else None)

    def time_step(self, members):
        self.sim.run(None, until_step=self.sim.step + 1)


class Gradient:
    """The gradient of ½ ∫ (h − 5000 m)² dA after 12 steps of TC5 at ne8 (ne4 in the quick form)
    with respect to the initial state: a forward run and its reverse sweep."""

    timer = CPU
    timeout = 600

    def setup(self):
        self.scene = load_scene("tc5_mountain", ne=4 if QUICK else 8)
        self.cost = HeightMisfit(5000.0)
        gradient(self.scene, 2, self.cost)  # compiled

    def time_gradient(self):
        gradient(self.scene, 12, self.cost)
