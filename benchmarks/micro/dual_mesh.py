"""The run file's cells (GLL control volumes, ``swe_sphere.io.dual``): their first build and a
read from the grid cache (``swe_sphere.core.cache``), per ne, each in a fresh one-thread
process: CPU seconds (``time.process_time``) and the process's peak RSS; the cells' largest
relative area error and how many are not convex. The cells are fitted on the run's own grid
(radius a), built before the clock starts, as a run has it (``unit_dual_mesh(..., grid=)``); the
peak RSS holds that grid.

    python benchmarks/micro/dual_mesh.py --ne 30 60 120 [--np 4] [--rounds 3] [--source TREE ...] [--results STEM]

Each round builds into an empty cache folder (a temporary one; the user's is not touched),
then reads the entry back in another process; the medians over the rounds are printed
with the load average. ``--source`` trees (a clone, or ``git worktree add``) are timed in
turn within each round, each from its own folder. The whole-process comparison of
benchmarks/README.md is timed apart, with ``/usr/bin/time -v swe-sphere run ...``.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: results.py, the shared module
from results import recorded

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


def main(args: argparse.Namespace, figures: dict) -> None:
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


def parse() -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--ne", type=int, nargs="+", default=[30, 60, 120])
    p.add_argument("--np", type=int, default=4)
    p.add_argument("--rounds", type=int, default=1)
    p.add_argument(
        "--source", nargs="+", default=[None], help="swe_sphere trees, interleaved (default: the one Python finds)"
    )
    p.add_argument("--results", help="results/dual_mesh/<STEM>.json (default: the script's stem)")
    return p.parse_args()


if __name__ == "__main__":
    arguments = parse()
    with recorded(__file__, stem=arguments.results) as figures:
        main(arguments, figures)
