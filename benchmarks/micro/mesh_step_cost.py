"""A step's cost per element on quadrilateral meshes against the uniform cube, CPU clock.

TC6 (every term and ∇⁴), np 4, SSP-RK3, one thread: ms a step and µs an element-step on the
equiangular cube, the same cube through the element-local map, and meshes whose nodes are
shared by up to 6 elements (their DSS tables have 6 columns, the cube's 4): the project's
icosahedral quadrilaterals (tests/meshes.py) and any ``.g`` given. Rounds interleaved, so that
load changes hit all alike; medians. Each element-step ratio is to the equiangular cube of
``--ne`` (the target: within 1.15).

    SWE_SPHERE_THREADS=1 OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 \\
        python benchmarks/micro/mesh_step_cost.py --ne 13 --mesh PATH/mountain_10_x2.g
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tests"))

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: results.py, the shared module
from results import quiet_warp, recorded  # noqa: E402  (after the path: benchmarks/ first)

from swe_sphere import (
    CubedSphere,  # noqa: E402
    load_scene,  # noqa: E402
    make_stepper,  # noqa: E402
)

from meshes import TC6_TERMS, case_model, icosahedral_mesh  # noqa: E402


def stepper_on(grid):
    """(stepper, state) of TC6 on ``grid``, one thread, two steps taken (compiled, recorded)."""
    case, model = case_model(grid, "tc6_rossby_haurwitz", TC6_TERMS, nu=1e15, nu_div=1e15, nu_s=1e15, threads=1)
    stepper = make_stepper("ssprk3", model, 60.0)
    x = model.new_state(*np.stack(case.initial(grid.lat, grid.lon)))
    for _ in range(2):
        stepper.step(x)
    return stepper, x


def mesh_of(mesh=None, **grid):
    """The mesh a scene's [grid] table makes (``Scene.make_mesh``): ``mesh`` an Exodus file, or ``grid``
    keys of a cube (``ne``, ``map``)."""
    return load_scene("tc6_rossby_haurwitz", mesh=mesh, overrides={"grid": grid}).make_mesh()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--ne", type=int, default=13, help="the uniform cube compared with (default 13: 1014 elements)")
    parser.add_argument("--mesh", nargs="*", default=[], help="Exodus .g files to time too")
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--steps", type=int, default=10, help="steps a round")
    args = parser.parse_args()
    quiet_warp()
    grids = {
        f"ne{args.ne} equiangular": CubedSphere(args.ne, 4),
        f"ne{args.ne} element-local": CubedSphere(args.ne, 4, mesh=mesh_of(ne=args.ne, map="element_local")),
        "icosahedral quads (2 subdivisions)": CubedSphere(0, 4, mesh=icosahedral_mesh(2)),
        **{Path(p).name: CubedSphere(0, 4, mesh=mesh_of(p)) for p in args.mesh},
    }
    runs = {name: stepper_on(g) for name, g in grids.items()}
    times: dict = {name: [] for name in grids}
    for _ in range(args.rounds):
        for name, (stepper, x) in runs.items():
            t = time.process_time()
            for _ in range(args.steps):
                stepper.step(x)
            times[name].append((time.process_time() - t) / args.steps)
    load = os.getloadavg()
    print(f"TC6 np4 ssprk3, one thread, CPU clock, median of {args.rounds} rounds of {args.steps} steps")
    print(f"load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}")
    base = None
    for name, g in grids.items():
        ms = 1e3 * statistics.median(times[name])
        per = 1e3 * ms / g.nelem
        base = per if base is None else base
        print(
            f"{name:38s} {g.nelem:6d} elements, DSS width {g.dss_table.shape[1]}: "
            f"{ms:8.2f} ms a step, {per:6.2f} us an element-step, {per / base:5.2f} x the cube's"
        )


if __name__ == "__main__":
    with recorded(__file__):
        main()
