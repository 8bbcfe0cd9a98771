"""The CPU time of one ∇⁴ evaluation, constant ν against HOMME's tensor ∇⁴ (``hyperviscosity.scaling``).

One ``Hyperviscosity.operator`` (B x: two weak Laplacians and two DSS of the wind and h + hs,
recorded once, replayed) on the uniform cube of ``--ne``, np 4, one thread, in the CPU layout
(one thread per element) and the per-node layout (CUDA's, here on the CPU), constant ν and
s = 3.2: CPU time (``time.process_time``) per evaluation, medians of rounds interleaved so that
load changes hit all alike, and the setup of the tensor's metric (its eigen-decomposition, DSS
and bilinear interpolation) once. Quote with ``uptime``'s load.

With ``--mesh FILE.g``, instead a whole step of a scene (``--scene``, TC5 by default; ``--stepper``,
``kgu35``) on that mesh at multiples of its gravity-wave limit Δt_g (``sweep.explicit_limits``:
the worst element's), with constant ν against ``hyperviscosity.scaling`` s = 3.2 and 4 (ν from the
scene's e-fold rule in every case, so that it keeps its meaning at the mean spacing): the ∇⁴
evaluations a step (``Hyperviscosity.plan``: forward-Euler substeps, or RKL1 stages) and the CPU
time a step, medians of interleaved rounds.

    SWE_SPHERE_THREADS=1 OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 \\
        python benchmarks/micro/step/tensor_hyperviscosity_cost.py --ne 16
    SWE_SPHERE_THREADS=1 OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 \\
        python benchmarks/micro/step/tensor_hyperviscosity_cost.py --mesh PATH/mountain_10_x2.g --multiples 1 1.66
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np
import warp as wp

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # benchmarks/: results.py, the shared module
from results import quiet_warp, recorded

from swe_sphere import CubedSphere, ShallowWater, Simulation, load_scene
from swe_sphere.model.diagnostics import harmonic_state
from swe_sphere.studies.sweep import explicit_limits

SCALINGS = (None, 3.2, 4.0)  # constant ν, E3SM's production s, the e-fold rule element by element


def mesh_steps(args) -> None:
    """A step of ``args.scene`` on ``args.mesh`` per ∇⁴ setting and Δt multiple: ∇⁴ evaluations and CPU time."""
    scene = load_scene(args.scene, mesh=args.mesh, stepper=args.stepper)
    dt_g = explicit_limits(scene, "cpu")["dt_gravity"]
    runs = {}
    for s in SCALINGS:
        for m in args.multiples:
            overrides = {} if s is None else {"hyperviscosity.scaling": s}
            sc = load_scene(args.scene, mesh=args.mesh, stepper=args.stepper, overrides=overrides)
            sim = Simulation(dataclasses.replace(sc, dt=m * dt_g), "cpu", progress=False)
            for _ in range(2):  # compiled and recorded
                sim.stepper.step(sim.x)
            runs[s, m] = sim
    times: dict = {key: [] for key in runs}
    for _ in range(args.rounds):
        for key, sim in runs.items():
            t0 = time.process_time()
            for _ in range(args.steps):
                sim.stepper.step(sim.x)
            times[key].append((time.process_time() - t0) / args.steps)
    load = os.getloadavg()
    grid = next(iter(runs.values())).grid
    print(
        f"{args.scene} on {os.path.basename(args.mesh)} ({grid.nelem} elements) np{grid.np}, {args.stepper}, "
        f"dt_g = {dt_g:.1f} s, one thread, CPU time a step (median of {args.rounds} rounds of {args.steps} steps); "
        f"load {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}"
    )
    for m in args.multiples:
        base = statistics.median(times[None, m])
        for s in SCALINGS:
            hv = runs[s, m].model.hv
            evals, rkl = hv.plan(m * dt_g)
            t = statistics.median(times[s, m])
            what = "constant nu" if s is None else f"s = {s:g}"
            print(
                f"  {m:5.2f} dt_g  {what:12s} nu = {hv.nu_max:.3g} m^4/s: {evals:3d} ∇⁴ evaluations a step "
                f"({'RKL1 stages' if rkl else 'forward Euler'}), {t * 1e3:7.2f} ms a step ({t / base:.2f}x)"
            )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--ne", type=int, default=16)
    parser.add_argument("--rounds", type=int, default=7)
    parser.add_argument("--evaluations", type=int, default=50, help="∇⁴ evaluations a round")
    parser.add_argument("--mesh", help="Exodus .g file: time whole steps of --scene on it instead")
    parser.add_argument("--scene", default="tc5_mountain")
    parser.add_argument("--stepper", default="kgu35")
    parser.add_argument("--multiples", type=float, nargs="+", default=[1.0], help="steps in dt_g")
    parser.add_argument("--steps", type=int, default=10, help="steps a round (--mesh)")
    args = parser.parse_args()
    quiet_warp()
    if args.mesh:
        mesh_steps(args)
        return
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
    with recorded(__file__):
        main()
