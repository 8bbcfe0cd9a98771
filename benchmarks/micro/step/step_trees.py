"""A step's CPU cost in several swe_sphere trees (an old commit against this one), one process
each, in turn: what a change to the step saved, whole, beside the in-process benchmarks that
isolate one part (``replaced_paths.py dss_by_element``, ``hyperviscosity_every.py``).

For each ``--scene`` at its own grid, stepper and Δt (or ``--ne``/``--np``), each ``--source``
tree (``git archive COMMIT | tar -x -C DIR``, with ``swe_sphere/testcases`` linked to
``../testcases`` for the bundled scenes) builds the scene in a one-thread child process
(``SWE_SPHERE_THREADS=1``), steps ``--steps`` steps to warm (kernels compiled, launches
recorded), then times ``--steps`` steps by the process's CPU clock; ``--rounds`` rounds take the
trees in turn, so that a change of load hits them alike. Medians, ms a step, and each tree's
ratio to the first. Between processes a step's time moves by up to ±25 % on a shared VM: quote
the medians of several rounds. Figures to ``benchmarks/results/step_trees/step_trees[_STEM].json``::

    python benchmarks/micro/step/step_trees.py --scene galewsky tc5_mountain --source OLD NEW --rounds 5
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # benchmarks/: results.py, the shared module
from results import check_sources, positive, recorded

CHILD = """
import json, sys, time
import warp as wp
wp.config.quiet = True
from swe_sphere import Simulation
scene, steps, grid = sys.argv[1], int(sys.argv[2]), json.loads(sys.argv[3])
sim = Simulation(scene, "cpu", progress=False, graphs=False, days=1.0, **grid)
for _ in range(steps):
    sim.stepper.step(sim.x)
start = time.process_time()
for _ in range(steps):
    sim.stepper.step(sim.x)
s = sim.scene
print(json.dumps({"ms": (time.process_time() - start) / steps * 1e3, "grid": f"ne{s.ne} np{s.np}",
                  "stepper": s.stepper, "dt": s.dt}))
"""


def child(source: str, scene: str, steps: int, grid: dict) -> dict:
    env = dict(os.environ, SWE_SPHERE_THREADS="1", OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1")
    env["PYTHONPATH"] = os.pathsep.join([source, *filter(None, [os.environ.get("PYTHONPATH")])])
    args = [sys.executable, "-c", CHILD, scene, str(steps), json.dumps(grid)]
    out = subprocess.run(args, env=env, cwd=source, capture_output=True, text=True)
    if out.returncode:
        raise SystemExit(f"{scene} ({source}): exit {out.returncode}\n{out.stderr[-2000:]}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--scene", nargs="+", default=["galewsky"])
    p.add_argument("--source", nargs="+", required=True, help="swe_sphere trees, the first the base")
    p.add_argument("--ne", type=positive(int), default=None)
    p.add_argument("--np", type=positive(int), default=None)
    p.add_argument("--steps", type=positive(int), default=48, help="steps to warm, then timed, a process")
    p.add_argument("--rounds", type=positive(int), default=5)
    p.add_argument("--results", default=None, help="results stem (default step_trees)")
    args = p.parse_args()
    check_sources(p, args.source)
    grid = {k: v for k, v in (("ne", args.ne), ("np", args.np)) if v}
    with recorded(__file__, args.results) as figures:
        print(f"load average at the start: {os.getloadavg()}")
        rows = []
        for scene in args.scene:
            runs = {s: [] for s in args.source}
            for _ in range(args.rounds):
                for source in args.source:
                    runs[source].append(child(source, scene, args.steps, grid))
            base = statistics.median(r["ms"] for r in runs[args.source[0]])
            for source, got in runs.items():
                ms = statistics.median(r["ms"] for r in got)
                rows.append(
                    {
                        "scene": scene,
                        "source": source,
                        **got[0],
                        "ms": ms,
                        "ratio": ms / base,
                        "each": [r["ms"] for r in got],
                    }
                )
                print(
                    f"{scene:>22} {got[0]['grid']:>9} {got[0]['stepper']:>8} {source:>24} "
                    f"{ms:8.3f} ms a step  {ms / base:6.3f}×"
                )
        figures["steps"] = rows
        print(f"load average at the end: {os.getloadavg()}")


if __name__ == "__main__":
    main()
