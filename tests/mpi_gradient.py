"""Run by ``test_mpi.py`` under ``mpiexec`` (and imported by it for the one-process run): the
gradient of TC5 at ne 2 over a few rk4 steps, of a cost of h at points observed at three of
them, with respect to the initial state, ν, ν_s and hs, from two snapshots (a recomputing
reverse sweep); the same along a history of steps of several Δt (a controlled run's) and by
mri. Rank 0 saves them: ``python mpi_gradient.py OUT.npz``."""

from __future__ import annotations

import sys
from dataclasses import replace

import numpy as np

from swe_sphere.adjoint import HeightObservations, PointHeights, gradient
from swe_sphere.config.scene import load_scene
from swe_sphere.core import mpi
from swe_sphere.grid.cubed_sphere import CubedSphere

STEPS = 6
# (time reached, Δt, error norm) a step, as a controlled run's ``history``: Δt of 1800, 900 and 1200 s
HISTORY = [(t, dt, float("nan")) for t, dt in ((1800.0, 1800.0), (2700.0, 900.0), (3900.0, 1200.0))]
HISTORY += [(3900.0 + 1800.0 * k, 1800.0, float("nan")) for k in (1, 2, 3)]


def whole_gradient(comm=None) -> dict[str, np.ndarray]:
    """The ``Gradient``'s arrays and numbers over ``comm``'s ranks (None: this process)."""
    scene = load_scene("tc5_mountain", ne=2, np_=4, dt=1800.0, stepper="rk4")
    grid = CubedSphere(2, 4, scene.make_case().planet.a)  # the whole grid, on every rank: the cost's (rank 0's)
    rng = np.random.default_rng(7)
    lat, lon = np.arcsin(rng.uniform(-1, 1, 40)), rng.uniform(0, 2 * np.pi, 40)
    values = {k: 5400.0 + 100.0 * rng.standard_normal(40) for k in (0, 3, STEPS)}
    cost = HeightObservations(PointHeights(grid, lat, lon), values, sigma=10.0)
    out = {}
    # rk4 along a history of several Δt (a controlled run's), and mri (its inner solves' transposes):
    # the other steppers' adjoints are built of the same transposes, DSS's and ordered sums
    runs = (("rk4", scene, None), ("history", scene, HISTORY), ("mri", replace(scene, stepper="mri"), None))
    for name, sc, history in runs:
        g = gradient(sc, STEPS, cost, snapshots=2, parameters=True, comm=comm, history=history)
        numbers = [g.cost, g.forward_steps, *g.costs.values(), g.d_nu, g.d_nu_s, g.d_g, g.d_omega]
        out |= {f"{key}_{name}": value for key, value in (("grad", g.grad), ("final", g.final), ("d_hs", g.d_hs))}
        out[f"numbers_{name}"] = np.array(numbers)
    return out


if __name__ == "__main__":
    comm = mpi.world()
    out = whole_gradient(comm)
    if comm is None or comm.rank == 0:
        np.savez(sys.argv[1], ranks=comm.size if comm else 1, **out)
