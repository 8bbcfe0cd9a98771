"""The DSS by element on GLL rows (``kernels.dss.dss_update_elements``, the CPU's
form since issue 99) against the node gather it replaced (``dss_rows``/``dss_update``): a step's
CPU cost, both in one process, interleaved.

For each ``--scene`` on its own grid (or ``--ne``/``--np``), at its own stepper and Δt, two models:
one as shipped and one built with the node gather (``Topology.element_rows`` False); each stepped
``--steps`` steps a round, ``--rounds`` rounds taken in turn so that a change of load hits both
alike; the median CPU ms a step (``time.process_time``, one thread) and the ratio. The two give
the same bits (tests/grid/test_dss_by_element.py); the run checks it on the states after the
rounds. Figures to ``benchmarks/results/dss_by_element/dss_by_element[_STEM].json``::

    SWE_SPHERE_THREADS=1 OMP_NUM_THREADS=1 python benchmarks/archive/dss_by_element.py --scene galewsky tc5_mountain
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path
from unittest import mock

os.environ.setdefault("SWE_SPHERE_THREADS", "1")

import numpy as np  # noqa: E402
import warp as wp  # noqa: E402
from threadpoolctl import threadpool_limits  # noqa: E402

wp.config.quiet = True

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: results.py, the shared module
from results import interleaved, positive, recorded  # noqa: E402  (after the path: benchmarks/ first)

from swe_sphere import Simulation  # noqa: E402
from swe_sphere.grid.topology import Topology  # noqa: E402


def arguments():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--scene", nargs="+", default=["galewsky", "tc5_mountain"])
    p.add_argument("--ne", type=positive(int), default=None)
    p.add_argument("--np", type=positive(int), default=None)
    p.add_argument("--steps", type=positive(int), default=48, help="steps a round")
    p.add_argument("--rounds", type=positive(int), default=9)
    p.add_argument("--results", default=None, help="results stem (default dss_by_element)")
    return p.parse_args()


def measure(scene: str, grid: dict, steps: int, rounds: int) -> dict:
    """CPU ms a step of ``scene`` with the DSS by element and by node, interleaved."""
    sims = {"element": Simulation(scene, "cpu", progress=False, days=1.0, graphs=False, **grid)}
    with mock.patch.object(Topology, "element_rows", False):
        sims["node"] = Simulation(scene, "cpu", progress=False, days=1.0, graphs=False, **grid)
    assert sims["element"].model.topology.edges is not None and sims["node"].model.topology.edges is None
    for sim in sims.values():  # recorded and compiled
        for _ in range(steps):
            sim.stepper.step(sim.x)
    med = interleaved({k: (lambda s=sim: s.stepper.step(s.x), steps) for k, sim in sims.items()}, rounds)
    same = bool(np.array_equal(sims["element"].x.numpy(), sims["node"].x.numpy()))
    s = sims["element"].scene
    return {
        "scene": scene,
        "grid": f"ne{s.ne} np{s.np}",
        "stepper": s.stepper,
        "node_ms": med["node"],
        "element_ms": med["element"],
        "ratio": med["element"] / med["node"],
        "bitwise": same,
        "steps": steps * (rounds + 1),
    }


def main() -> None:
    args = arguments()
    grid = {k: v for k, v in (("ne", args.ne), ("np", args.np)) if v}
    with recorded(__file__, args.results) as figures, threadpool_limits(limits=1):
        print(f"load average at the start: {os.getloadavg()}")
        rows = [measure(scene, grid, args.steps, args.rounds) for scene in args.scene]
        print(f"\nCPU ms a step, medians of {args.rounds} interleaved rounds of {args.steps} steps, one thread")
        print(f"{'scene':>22} {'grid':>9} {'stepper':>8} {'node':>8} {'element':>8} {'ratio':>6} {'bitwise':>8}")
        for r in rows:
            print(
                f"{r['scene']:>22} {r['grid']:>9} {r['stepper']:>8} {r['node_ms']:8.3f} {r['element_ms']:8.3f} "
                f"{r['ratio']:6.3f} {str(r['bitwise']):>8}"
            )
        figures["steps"] = rows
        print(f"load average at the end: {os.getloadavg()}")


if __name__ == "__main__":
    main()
