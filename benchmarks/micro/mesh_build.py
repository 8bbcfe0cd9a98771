"""What a mesh costs before the first step: reading and checking a ``.g`` file, building
its grid (element-local metric, numbering, DSS table) and a one-process topology, and reading
its run file's cells from the grid cache (``io.dual.cached_cells``; their first build, once
per mesh, is timed apart), CPU clock, median of ``--rounds``, beside the equiangular cube of the
same size built in. The cache is a temporary folder (the user's is not touched).

The mesh is the project's own cube of ``--ne`` written as a ``.g`` (6·ne² elements; the
default ne = 41, 10 086 elements, is an E3SM production size), or the ``.g`` files given.

    OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 python benchmarks/micro/mesh_build.py --ne 41 --np 4
"""

from __future__ import annotations

import argparse
import functools
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: results.py, the shared module
from results import quiet_warp, recorded

from swe_sphere import CubedSphere
from swe_sphere.grid.topology import Topology
from swe_sphere.io.dual import cached_cells
from swe_sphere.mesh.cube import cube_mesh
from swe_sphere.mesh.mesh import read_exodus, write_exodus


def cpu(call, rounds: int):
    """(median CPU seconds, the last result) of ``call()`` over ``rounds``."""
    times, result = [], None
    for _ in range(rounds):
        t = time.process_time()
        result = call()
        times.append(time.process_time() - t)
    return statistics.median(times), result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--ne", type=int, default=41)
    parser.add_argument("--np", type=int, default=4)
    parser.add_argument("--mesh", nargs="*", default=[], help="Exodus .g files to time instead of the cube")
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args()
    quiet_warp()
    with tempfile.TemporaryDirectory() as tmp:
        os.environ["SWE_SPHERE_CACHE_DIR"] = str(Path(tmp) / "cache")
        files = [Path(p) for p in args.mesh] or [write_exodus(Path(tmp) / f"ne{args.ne}.g", cube_mesh(args.ne))]
        load = os.getloadavg()
        print(
            f"np {args.np}, CPU clock, median of {args.rounds}; load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}"
        )
        for path in files:
            read, mesh = cpu(lambda p=path: read_exodus(p), args.rounds)
            build, grid = cpu(lambda m=mesh: CubedSphere(0, args.np, mesh=m), args.rounds)
            topology, _ = cpu(lambda g=grid: Topology(g, "cpu", 1), args.rounds)
            cells = functools.partial(cached_cells, 0, args.np, mesh, grid=grid)  # past the process's memo
            first, _ = cpu(cells, 1)
            cached, _ = cpu(cells, args.rounds)
            total = read + build + topology + cached
            print(
                f"{path.name}: {mesh.nelem} elements; read and checked {read:.3f} s, grid built {build:.3f} s, "
                f"topology {topology:.3f} s, cells read from the cache {cached:.3f} s; total {total:.3f} s "
                f"(the cells' first build, once per mesh: {first:.2f} s)"
            )
    if not args.mesh:
        cube, _ = cpu(lambda: CubedSphere(args.ne, args.np), args.rounds)
        print(f"the equiangular ne{args.ne} cube built in: {cube:.3f} s")


if __name__ == "__main__":
    with recorded(__file__):
        main()
