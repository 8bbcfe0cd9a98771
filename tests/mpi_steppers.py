"""Run by ``test_mpi.py`` under ``mpiexec`` (and imported by it for the one-rank runs): TC5
at ne 2 with each stepper that solves (semi-implicit, JFNK, IMEX, an IMEX Butcher pair,
exponential; JFNK and IMEX also with their Helmholtz solves in float32, ``precision = "float32"``),
one simulation over all ranks each, and a semi-implicit run continued from a restart file.
Rank 0 saves the final whole-grid states: ``python mpi_steppers.py OUT.npz CHECKPOINT``.
"""

from __future__ import annotations

import dataclasses
import sys

import numpy as np

from swe_sphere.config.scene import load_scene
from swe_sphere.core import mpi
from swe_sphere.simulation.simulation import Simulation

import roundoff

# label → (stepper, its options; None: the bundled ARK3(2)4L[2]SA pair)
STEPPERS = {
    "semi_implicit": ("semi_implicit", {}),
    "implicit": ("implicit", {}),
    "imex": ("imex", {}),
    "tableau": ("tableau", None),
    "implicit_mixed": ("implicit", {"precision": "float32"}),
    "imex_mixed": ("imex", {"precision": "float32", "tol": 1e-10}),  # its ranks agree to tol (test_mpi): a tight one
    "epi2": ("epi2", {}),
    "epi3": ("epi3", {}),
}
DAYS = 0.1


def scene(stepper: str, days: float = DAYS, options: dict | None = None):
    """TC5 at ne 2 with the stepper's ``options`` (the tableau stepper's default: the bundled pair)."""
    s = load_scene("tc5_mountain", ne=2, days=days, stepper=stepper)
    if stepper == "tableau" and options is None:
        options = load_scene("ark324l2sa").stepper_options
    return dataclasses.replace(s, stepper_options=dict(options or {}))


def final_states(comm=None, nudge=None, runs=None) -> dict[str, np.ndarray]:
    """Label → final (u, v, h) (3, nnodes) of a run over ``comm``'s ranks (None: this process),
    from the start moved by ``nudge(x, grid)`` (None: not moved); ``runs``: a dict to fill
    with each run's RHS evaluations and solver iterations (``roundoff.operations``) and
    how far it moved from its start (the larger of ``roundoff.state_difference``)."""
    out = {}
    for name, (stepper, options) in STEPPERS.items():
        sim = Simulation(scene(stepper, options=options), "cpu", progress=False, comm=comm)
        if nudge is not None:
            sim.x.assign(nudge(sim.x.numpy(), sim.grid))
        start = np.stack(sim.fields())
        result = sim.run(None)
        out[name] = np.stack(sim.fields())
        if runs is not None:
            runs[name] = roundoff.operations(result), max(roundoff.state_difference(out[name], start))
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
