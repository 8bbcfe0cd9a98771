"""The CPU time of one ∇⁴ evaluation, constant ν against HOMME's tensor ∇⁴ (``hyperviscosity.scaling``).

One ``Hyperviscosity.operator`` (B x: two weak Laplacians and two DSS of the wind and h + hs,
recorded once, replayed) on the uniform cube of ``--ne``, np 4, one thread, in the CPU layout
(one thread per element) and the per-node layout (CUDA's, here on the CPU), constant ν and
s = 3.2: CPU time (``time.process_time``) per evaluation, medians of rounds interleaved so that
load changes hit all alike, and the setup of the tensor's metric (its eigen-decomposition, DSS
and bilinear interpolation) once. Quote with ``uptime``'s load.

    SWE_SPHERE_THREADS=1 OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 \\
        python benchmarks/tensor_hyperviscosity_cost.py --ne 16
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np
import warp as wp

from swe_sphere.core.runtime import init_warp
from swe_sphere.grid.cubed_sphere import CubedSphere
from swe_sphere.model.diagnostics import harmonic_state
from swe_sphere.model.shallow_water import ShallowWater


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ne", type=int, default=16)
    parser.add_argument("--rounds", type=int, default=7)
    parser.add_argument("--evaluations", type=int, default=50, help="∇⁴ evaluations a round")
    args = parser.parse_args()
    init_warp()
    grid = CubedSphere(args.ne, 4)
    z = np.zeros(grid.nnodes)
    state = np.stack([harmonic_state(grid, 9, "rotational")[0], z, 5000 + harmonic_state(grid, 9, "height")[2]])
    runs, setup = {}, {}
    for per_element in (True, False):
        for scaling in (None, 3.2):
            t0 = time.process_time()
            model = ShallowWater(
                grid, ["hyperviscosity"], z, z, nu=1e15, device="cpu", threads=1, per_element=per_element,
                hypervis_scaling=scaling,
            )  # fmt: skip
            name = f"{'per element' if per_element else 'per node'}, {'constant nu' if scaling is None else 's = 3.2'}"
            setup[name] = time.process_time() - t0
            x, out = model.new_state(*state), wp.zeros((3, grid.nnodes), dtype=wp.float64, device="cpu")
            model.hv.operator(x, out)  # compiled and recorded
            runs[name] = (model, x, out)
    times = {name: [] for name in runs}
    for _ in range(args.rounds):
        for name, (model, x, out) in runs.items():
            t0 = time.process_time()
            for _ in range(args.evaluations):
                model.hv.operator(x, out)
            times[name].append((time.process_time() - t0) / args.evaluations)
    print(f"ne{args.ne} np4 ({grid.nelem} elements), one thread, CPU time a ∇⁴ evaluation (median of {args.rounds})")
    for layout in ("per element", "per node"):
        base = statistics.median(times[f"{layout}, constant nu"])
        for name in (f"{layout}, constant nu", f"{layout}, s = 3.2"):
            t = statistics.median(times[name])
            print(f"  {name:28s} {t * 1e3:8.3f} ms  ({t / base:.3f}x)  model setup {setup[name]:.3f} s")


if __name__ == "__main__":
    main()
