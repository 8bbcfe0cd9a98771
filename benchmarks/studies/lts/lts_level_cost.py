"""A level's tendency evaluation against its element count, CPU clock: does ``rhs_part`` cost in
proportion to the elements it runs over (local time stepping, ``steppers.local``)?

TC5 (its tendency terms: continuity, momentum advection, Coriolis, pressure gradient,
topography), np 4, one thread, on a refined mesh: the levels from the initial flow
(``grid.levels``, at most ``--max-levels``), then per level (and for the levels finer than the
coarsest together, the ``lts`` fast part) the CPU time of one ``ShallowWater.rhs_part``
(tendency kernels over the level's element ranges, merged over gaps of up to ``--gap`` other
elements, the DSS over the nodes it touches) and of
the whole-grid ``rhs``; µs per element evaluated and the ratio to the whole grid's. Rounds
interleaved so that load changes hit all alike; medians; the load average printed.

    SWE_SPHERE_THREADS=1 OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 \\
        python benchmarks/studies/lts/lts_level_cost.py --mesh PATH/mountain_10_x2.g
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np
import warp as wp

sys.path.insert(0, str(Path(__file__).resolve().parents[3] / "tests"))

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # benchmarks/: results.py, the shared module
from results import quiet_warp, recorded  # noqa: E402  (after the path: benchmarks/ first)

from swe_sphere import CubedSphere  # noqa: E402
from swe_sphere.grid.levels import element_levels, element_rates  # noqa: E402
from swe_sphere.mesh.mesh import read_exodus  # noqa: E402
from swe_sphere.model.shallow_water import ElementPart  # noqa: E402

from meshes import case_model  # noqa: E402

TC5_TERMS = ["continuity", "momentum_advection", "coriolis", "pressure_gradient", "topography"]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--mesh", required=True, help="an Exodus .g file (a refined mesh)")
    parser.add_argument("--max-levels", type=int, default=3)
    parser.add_argument("--rounds", type=int, default=7)
    parser.add_argument("--calls", type=int, default=50, help="evaluations timed a round")
    parser.add_argument(
        "--gap", type=int, nargs="+", default=[0, 4, 16, 64], help="merge a level's ranges over gaps up to"
    )
    args = parser.parse_args()
    quiet_warp()
    grid = CubedSphere(0, 4, mesh=read_exodus(args.mesh))
    case, model = case_model(grid, "tc5_mountain", TC5_TERMS, threads=1)
    x = model.new_state(*np.stack(case.initial(grid.lat, grid.lon)))
    levels = element_levels(grid, element_rates(grid, x.numpy(), model.g), args.max_levels)
    print(f"{Path(args.mesh).name}: {grid.nelem} elements; {levels.describe()}")
    out = wp.zeros_like(x)
    calls = {"whole grid": (grid.nelem, lambda: model.rhs(x, out))}
    sets = {f"level {k}": levels.level == k for k in range(levels.count)}
    if levels.count > 2:
        sets["levels >= 1 (lts's fast part)"] = levels.level >= 1
    for gap in args.gap:
        for name, chosen in sets.items():
            part = ElementPart.of(model, np.flatnonzero(chosen), gap)
            buf = wp.zeros_like(x)
            label = f"{name}, gap {gap}: {len(part.runs)} ranges"
            calls[label] = (part.nelem, lambda p=part, b=buf: model.rhs_part(x, b, p))
    for _, call in calls.values():
        call()  # compiled and recorded outside the clock
    times: dict = {name: [] for name in calls}
    for _ in range(args.rounds):
        for name, (_, call) in calls.items():
            start = time.process_time()
            for _ in range(args.calls):
                call()
            times[name].append((time.process_time() - start) / args.calls)
    whole = statistics.median(times["whole grid"]) / grid.nelem
    print(f"load average {os.getloadavg()[0]:.2f}; CPU time per evaluation, medians of {args.rounds} rounds")
    print(f"{'':44s} {'elements':>8s} {'ms':>8s} {'us/element':>11s} {'/ whole':>8s}")
    for name, (nelem, _) in calls.items():
        t = statistics.median(times[name])
        print(f"{name:44s} {nelem:8d} {t * 1e3:8.3f} {t / nelem * 1e6:11.2f} {t / nelem / whole:8.2f}")


if __name__ == "__main__":
    with recorded(__file__):
        main()
