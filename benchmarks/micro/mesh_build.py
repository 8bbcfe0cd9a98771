"""What a mesh and its run file's cells cost before the first step, CPU clock. One subcommand a study,
each written to ``results/mesh_build/<study>/<stem>.json``::

    python benchmarks/micro/mesh_build.py STUDY [its options]   # STUDY --help: its options

``mesh_build``
~~~~~~~~~~~~~~
What a mesh costs before the first step: reading and checking a ``.g`` file, building
its grid (element-local metric, numbering, DSS table) and a one-process topology, and reading
its run file's cells from the grid cache (``io.dual.cached_cells``; their first build, once
per mesh, is timed apart), CPU clock, median of ``--rounds``, beside the equiangular cube of the
same size built in. The cache is a temporary folder (the user's is not touched).

The mesh is the project's own cube of ``--ne`` written as a ``.g`` (6·ne² elements; the
default ne = 41, 10 086 elements, is an E3SM production size), or the ``.g`` files given.

    OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 python benchmarks/micro/mesh_build.py mesh_build --ne 41 --np 4

``dual_mesh``
~~~~~~~~~~~~~
The run file's cells (GLL control volumes, ``swe_sphere.io.dual``): their first build and a
read from the grid cache (``swe_sphere.core.cache``), per ne, each in a fresh one-thread
process: CPU seconds (``time.process_time``) and the process's peak RSS; the cells' largest
relative area error and how many are not convex. The cells are fitted on the run's own grid
(radius a), built before the clock starts, as a run has it (``unit_dual_mesh(..., grid=)``); the
peak RSS holds that grid.

    python benchmarks/micro/mesh_build.py dual_mesh --ne 30 60 120 [--np 4] [--rounds 3] [--source TREE ...] [--results STEM]

Each round builds into an empty cache folder (a temporary one; the user's is not touched),
then reads the entry back in another process; the medians over the rounds are printed
with the load average. ``--source`` trees (a clone, or ``git worktree add``) are timed in
turn within each round, each from its own folder. The whole-process comparison of
benchmarks/README.md is timed apart, with ``/usr/bin/time -v swe-sphere run ...``.
"""

from __future__ import annotations

import argparse
import functools
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: results.py, the shared module
from results import quiet_warp, recorded, section, studies  # noqa: E402  (after the path: benchmarks/ first)

from swe_sphere import CubedSphere  # noqa: E402
from swe_sphere.grid.topology import Topology  # noqa: E402
from swe_sphere.io.dual import cached_cells  # noqa: E402
from swe_sphere.mesh.cube import cube_mesh  # noqa: E402
from swe_sphere.mesh.mesh import read_exodus, write_exodus  # noqa: E402

STUDIES = (
    "mesh_build",
    "dual_mesh",
)  # the subcommands, a section of this docstring each


def cpu(call, rounds: int):
    """(median CPU seconds, the last result) of ``call()`` over ``rounds``."""
    times, result = [], None
    for _ in range(rounds):
        t = time.process_time()
        result = call()
        times.append(time.process_time() - t)
    return statistics.median(times), result


def build_costs(argv: list[str]) -> None:
    """Reading, checking and building each mesh (its grid, topology and cells), CPU s."""
    parser = argparse.ArgumentParser(prog="mesh_build.py mesh_build", description=section(__doc__, "mesh_build"))
    parser.add_argument("--ne", type=int, default=41)
    parser.add_argument("--np", type=int, default=4)
    parser.add_argument("--mesh", nargs="*", default=[], help="Exodus .g files to time instead of the cube")
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args(argv)
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


def mesh_build(argv: list[str]) -> None:
    """``mesh_build``: its options from ``argv``, its runs, its results file."""
    with recorded(__file__, "mesh_build/mesh_build"):
        build_costs(argv)


CHILD = """
import json, resource, sys, time
from swe_sphere import CubedSphere
from swe_sphere.io import dual
ne, np_, mode = int(sys.argv[1]), int(sys.argv[2]), sys.argv[3]
grid = CubedSphere(ne, np_)  # the run's own grid, built before its cells, outside the clock
start = time.process_time()
verts, corners, error, built = dual.unit_dual_mesh(ne, np_, grid=grid)
cpu = time.process_time() - start
assert (built is None) == (mode == "read"), (mode, built)
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
concave = int((~dual.convex(verts, corners)).sum())
print(json.dumps(dict(cpu=cpu, peak=peak, error=error, nodes=corners.shape[0], concave=concave)))
"""


def child(ne: int, np_: int, mode: str, cache: str, source: str | None) -> dict:
    """One build or read in a fresh one-thread process, of the swe_sphere in ``source`` (a tree,
    run from its folder: the folder Python starts in comes first on its path) or the one Python
    finds (None)."""
    env = {
        **os.environ,
        "SWE_SPHERE_CACHE_DIR": cache,
        "OMP_NUM_THREADS": "1",
        "OPENBLAS_NUM_THREADS": "1",
        "SWE_SPHERE_THREADS": "1",
    }
    if source is not None:
        env["PYTHONPATH"] = source
    out = subprocess.run(
        [sys.executable, "-c", CHILD, str(ne), str(np_), mode],
        env=env,
        cwd=source,
        capture_output=True,
        text=True,
        check=True,
    )
    return json.loads(out.stdout.splitlines()[-1])


def dual_costs(args: argparse.Namespace, figures: dict) -> None:
    print(f"load average {os.getloadavg()[0]:.2f} at the start; np {args.np}; one thread; medians of {args.rounds}")
    print(
        f"{'ne':>4} {'nodes':>8} {'build s':>8} {'build GB':>9} {'read s':>7} {'read GB':>8} {'area error':>10} "
        f"{'not convex':>10}  source"
    )
    for ne in args.ne:
        rows = {(source, mode): [] for source in args.source for mode in ("build", "read")}
        for _ in range(args.rounds):  # the sources interleaved, round by round
            for source in args.source:
                with tempfile.TemporaryDirectory(prefix="swe_sphere_cache_") as cache:
                    for mode in ("build", "read"):
                        rows[source, mode].append(child(ne, args.np, mode, cache, source))
        for source in args.source:
            b, r = (
                {k: statistics.median(x[k] for x in rows[source, m]) for k in ("cpu", "peak")}
                for m in ("build", "read")
            )
            last = rows[source, "build"][-1]
            figures[f"ne{ne} {source or 'default'}"] = dict(build_s=b["cpu"], build_peak=b["peak"], read_s=r["cpu"])
            print(
                f"{ne:>4} {last['nodes']:>8} {b['cpu']:>8.2f} {b['peak'] / 1e9:>9.2f} {r['cpu']:>7.3f} "
                f"{r['peak'] / 1e9:>8.2f} {last['error']:>10.1e} {last['concave']:>10}  {source or 'default'}",
                flush=True,
            )
    print(f"load average {os.getloadavg()[0]:.2f} at the end")


def parse_dual(argv: list[str]) -> argparse.Namespace:
    p = argparse.ArgumentParser(prog="mesh_build.py dual_mesh", description=section(__doc__, "dual_mesh"))
    p.add_argument("--ne", type=int, nargs="+", default=[30, 60, 120])
    p.add_argument("--np", type=int, default=4)
    p.add_argument("--rounds", type=int, default=1)
    p.add_argument(
        "--source", nargs="+", default=[None], help="swe_sphere trees, interleaved (default: the one Python finds)"
    )
    p.add_argument("--results", help="results/mesh_build/dual_mesh/<STEM>.json (default: dual_mesh)")
    return p.parse_args(argv)


def dual_mesh(argv: list[str]) -> None:
    """``dual_mesh``: its options from ``argv``, its runs, its results file."""
    arguments = parse_dual(argv)
    with recorded(__file__, arguments.results, study="dual_mesh") as figures:
        dual_costs(arguments, figures)


if __name__ == "__main__":
    studies(__doc__, {name: globals()[name] for name in STUDIES})
