"""Run by ``test_mpi.py`` under ``mpiexec`` (and imported by it for the one-rank runs): TC5
at ne 2 with each stepper that solves (semi-implicit, JFNK, IMEX, exponential), one simulation over all ranks each,
and a semi-implicit run continued from a restart file. Rank 0 saves the final
whole-grid states: ``python mpi_steppers.py OUT.npz CHECKPOINT``.
"""

from __future__ import annotations

import sys

import numpy as np

from swe_sphere import mpi
from swe_sphere.config import load_scene
from swe_sphere.simulation import Simulation

STEPPERS = ("semi_implicit", "implicit", "imex", "epi2", "epi3")
DAYS = 0.1


def scene(stepper: str, days: float = DAYS):
    return load_scene("tc5_mountain", ne=2, days=days, stepper=stepper)


def final_states(comm=None) -> dict[str, np.ndarray]:
    """Stepper name → final (u, v, h) (3, npts) of a run over ``comm``'s ranks (None: this process)."""
    out = {}
    for name in STEPPERS:
        sim = Simulation(scene(name), "cpu", progress=False, comm=comm)
        sim.run(None)
        out[name] = np.stack(sim.fields())
    return out


def continued_state(checkpoint, comm=None) -> np.ndarray:
    """Final (u, v, h) of the semi-implicit run continued from ``checkpoint`` to 2·DAYS."""
    sim = Simulation.from_checkpoint(checkpoint, "cpu", days=2 * DAYS, progress=False, comm=comm)
    sim.run(None)
    return np.stack(sim.fields())


if __name__ == "__main__":
    comm = mpi.world()
    states = final_states(comm)
    states["continued"] = continued_state(sys.argv[2], comm)
    if comm is None or comm.rank == 0:
        np.savez(sys.argv[1], ranks=comm.size if comm else 1, **states)
