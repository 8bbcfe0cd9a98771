"""Peak resident memory of each MPI rank of one run (each rank builds and stores its own elements).

Run under ``mpiexec``; rank 0 prints one line per rank: its peak RSS
(``resource.getrusage(RUSAGE_SELF).ru_maxrss``), the bytes of its grid's numpy
arrays, its element-local nodes and its setup time. A tiny TC5 run (np = 4,
the scene's leapfrog_trapezoidal unless ``--stepper``), 0.01 day by default.

    mpiexec -n 1 python benchmarks/rank_memory.py --ne 60
    mpiexec -n 2 python benchmarks/rank_memory.py --ne 60      # docs/scaling.md, item 1
"""

from __future__ import annotations

import argparse
import resource
import time

import numpy as np


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--ne", type=int, default=30)
    p.add_argument("--stepper", default="leapfrog_trapezoidal")
    p.add_argument("--days", type=float, default=0.01)
    a = p.parse_args()
    from swe_sphere import mpi
    from swe_sphere.config import load_scene
    from swe_sphere.simulation import Simulation

    comm = mpi.world()
    t0 = time.perf_counter()
    sim = Simulation(load_scene("tc5_mountain", ne=a.ne, days=a.days, stepper=a.stepper), "cpu", progress=False, comm=comm)
    setup = time.perf_counter() - t0
    sim.run(None)
    grid = sim.topology.grid
    row = (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
           sum(v.nbytes for v in vars(grid).values() if isinstance(v, np.ndarray)) / 2**20, sim.topology.N, setup)
    rows = comm.gather(row) if comm is not None else [row]
    if rows is not None:
        print(f"TC5 ne={a.ne} np=4 {a.stepper}, {a.days:g} day, {len(rows)} rank(s)")
        for rank, (rss, grid_mib, nodes, seconds) in enumerate(rows):
            print(f"  rank {rank}: peak RSS {rss:.0f} MiB, grid arrays {grid_mib:.0f} MiB, {nodes} element-local nodes, setup {seconds:.2f} s")


if __name__ == "__main__":
    main()
