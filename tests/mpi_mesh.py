"""Run by ``test_mesh_mpi.py`` under ``mpiexec`` (and imported by it for the one-rank run): TC6
with ∇⁴, SSP-RK3, on a mesh of the project's own whose nodes are shared by 3 to 6 elements (the
icosahedral quadrilaterals), its elements over all ranks along the curve through their
centroids. Rank 0 saves the final whole-grid state: ``python mpi_mesh.py OUT.npz``.
"""

from __future__ import annotations

import sys

import numpy as np

from swe_sphere.core import mpi
from swe_sphere.grid.cubed_sphere import CubedSphere
from swe_sphere.grid.topology import Topology, rank_parts
from swe_sphere.steppers import make_stepper

from meshes import TC6_TERMS, case_model, icosahedral_mesh

STEPS = 4


def final_state(comm=None) -> np.ndarray | None:
    """The whole-grid (u, v, h) (3, nnodes) after ``STEPS`` steps over ``comm``'s ranks (None: this
    process), on rank 0; None on the others."""
    mesh = icosahedral_mesh(1)
    size, rank = (1, 0) if comm is None else (comm.size, comm.rank)
    parts = rank_parts(0, size, mesh)
    grid = CubedSphere(0, 4, elements=parts[rank], mesh=mesh)
    topology = Topology(grid, "cpu", 1, comm, parts=parts)
    case, model = case_model(
        grid, "tc6_rossby_haurwitz", TC6_TERMS, nu=1e15, nu_div=1e15, nu_s=1e15, threads=1, topology=topology
    )
    stepper = make_stepper("ssprk3", model, 300.0)
    x = model.new_state(*np.stack(case.initial(grid.lat, grid.lon)))
    for _ in range(STEPS):
        stepper.step(x)
    return topology.gather(x.numpy())


if __name__ == "__main__":
    comm = mpi.world()
    state = final_state(comm)
    if comm.rank == 0:
        np.savez(sys.argv[1], state=state, ranks=comm.size)
