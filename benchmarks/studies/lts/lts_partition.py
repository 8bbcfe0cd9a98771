"""How evenly lts's work is spread over MPI ranks: the curve's chunks against each level cut
along the curve (``partition.level_chunks``, what a run of ``lts`` on several ranks uses).

For a mesh file and TC5's initial flow: the levels lts steps (from the flow) and those the
partition is made from (from the elements' sizes alone); for each rank count, the largest
rank's work over the mean (work: Σ 2^level over its elements, the evaluations of a coarse
step), each level's largest share over the mean, and the element pairs that share a node
across ranks (what the DSS exchanges grow with). No timing: the figures are the partition's.

    python benchmarks/studies/lts/lts_partition.py --mesh MESH.g [--ranks 2 3 4 8]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # benchmarks/: results.py, the shared module
from results import recorded

from swe_sphere import Simulation, load_scene
from swe_sphere.grid.levels import element_levels, element_neighbours, element_rates
from swe_sphere.grid.topology import rank_parts
from swe_sphere.steppers.local import size_levels


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--mesh", required=True)
    ap.add_argument("--ranks", type=int, nargs="+", default=[2, 3, 4, 8])
    ap.add_argument("--max-levels", type=int, default=3)
    ap.add_argument("--level-margin", type=float, default=1.3)
    args = ap.parse_args()
    options = {"method": "mrab3", "max_levels": args.max_levels, "level_margin": args.level_margin}
    scene = load_scene("tc5_mountain", mesh=args.mesh, days=0.01, stepper="lts")
    sim = Simulation(scene, "cpu", progress=False)
    grid = sim.grid
    flow = element_levels(grid, element_rates(grid, sim.x.numpy(), sim.model.g), args.max_levels, args.level_margin)
    sizes = size_levels(grid, options)
    print(
        f"{args.mesh}: levels from the flow {flow.elements_per_level()}, from the sizes "
        f"{np.bincount(sizes).tolist()} ({int(np.sum(sizes != flow.level))} elements differ)"
    )
    pairs = element_neighbours(grid).tocoo()
    print("| ranks | partition | work max/mean | each level's max/mean | element pairs across ranks |")
    print("|---:|---|---:|---|---:|")
    for size in args.ranks:
        for name, level in (("curve", None), ("each level", sizes)):
            parts = rank_parts(0, size, grid.mesh, level)
            owner = np.empty(grid.nelem, dtype=np.int64)
            for r, p in enumerate(parts):
                owner[p] = r
            per = np.array([np.bincount(flow.level[p], minlength=flow.count) for p in parts])
            work = per @ 2.0 ** np.arange(flow.count)
            shares = ", ".join(f"{c.max() / c.mean():.2f}" for c in per.T)
            cut = int(np.sum(owner[pairs.row] != owner[pairs.col]) // 2)
            print(f"| {size} | {name} | {work.max() / work.mean():.2f} | {shares} | {cut} |")


if __name__ == "__main__":
    with recorded(__file__):
        main()
