"""N members of one scene (``swe_sphere.Simulation`` with ``members``) against one member, CPU clock
(issue 85's target: on one CPU thread, 8 members of `galewsky` ≤ 7× one member's run); with
``--device cuda`` the wall clock, the device synchronised (the target: 32 members on an H100 ≤ 4×
one).

Builds an ensemble of one member, ``--members`` N (seeded 1 m perturbations of h) in each layout
(``Simulation``'s ``layout``: "shared", the same launches; "in_turn", a model a member, a block of steps
each) and N ensembles of one member stepped in turn (what N runs in one process cost), times
their build (CPU s, compile included for the first) and their steps in ``--rounds`` interleaved
rounds of ``--steps`` steps (medians, CPU ms a step), and prints each against one member, a step
and the scene's whole run (its steps at those medians plus the build):

    SWE_SPHERE_THREADS=1 OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 \\
        python benchmarks/micro/ensemble_cost.py --scene galewsky --members 8
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

import warp as wp

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: results.py, the shared module
from results import positive, quiet_warp, recorded

from swe_sphere import Perturbation, Simulation


def clock(device: str) -> float:
    """The CPU clock on a CPU; on a card, the wall clock after the device's work has ended."""
    if device != "cpu":
        wp.synchronize()
        return time.perf_counter()
    return time.process_time()


def parse() -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scene", default="galewsky")
    parser.add_argument("--members", type=int, default=8)
    parser.add_argument("--steps", type=positive(int), default=20, help="steps a round")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--results", help="results/ensemble_cost/<STEM>.json (default: the script's stem)")
    return parser.parse_args()


def main(args: argparse.Namespace, figures: dict) -> None:
    quiet_warp()
    n = args.members
    kinds = {
        "1 member": [(1, None)],
        f"{n} members shared": [(n, "shared")],
        f"{n} members in_turn": [(n, "in_turn")],
        f"{n} x 1 member in turn": [(1, None)] * n,
    }
    runs, build = {}, {}
    for name, sizes in kinds.items():
        t = clock(args.device)
        runs[name] = [
            Simulation(
                args.scene,
                members=m,
                initial=Perturbation(1.0, seed=k),
                device=args.device,
                layout=layout,
                progress=False,
            )
            for k, (m, layout) in enumerate(sizes)
        ]
        for ens in runs[name]:
            ens.run(None, until_step=ens.step + 1)  # recorded: the rounds replay
        build[name] = clock(args.device) - t
    times: dict = {name: [] for name in runs}
    for _ in range(args.rounds):
        for name, ensembles in runs.items():
            t = clock(args.device)
            for ens in ensembles:
                ens.run(None, until_step=ens.step + args.steps)
            times[name].append((clock(args.device) - t) / args.steps)
    load = os.getloadavg()
    one = runs["1 member"][0]
    nsteps = one.scene.nsteps
    ms = {name: 1e3 * statistics.median(times[name]) for name in runs}
    whole = {name: build[name] + nsteps * ms[name] / 1e3 for name in runs}
    print(
        f"{args.scene} ne{one.grid.ne} np{one.grid.np} {one.scene.stepper} dt {one.scene.dt:.4g} s, {one.grid.nnodes} nodes a "
        f"member, {os.environ.get('SWE_SPHERE_THREADS', 'all')} thread(s), {'CPU' if args.device == 'cpu' else 'wall'} clock, median of {args.rounds} "
        f"interleaved rounds of {args.steps} steps"
    )
    print(f"load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}")
    for name in runs:
        print(
            f"{name:24s} build {build[name]:6.2f} s, {ms[name]:8.2f} ms a step ({ms[name] / ms['1 member']:5.2f}x), "
            f"whole run ({nsteps} steps) {whole[name]:7.1f} s ({whole[name] / whole['1 member']:5.2f}x)"
        )
    figures.update(
        members=n,
        ms_a_step=ms,
        build_s=build,
        step_ratio={layout: ms[f"{n} members {layout}"] / ms["1 member"] for layout in ("shared", "in_turn")},
        run_ratio={layout: whole[f"{n} members {layout}"] / whole["1 member"] for layout in ("shared", "in_turn")},
        in_turn_step_ratio=ms[f"{n} x 1 member in turn"] / ms["1 member"],
    )


if __name__ == "__main__":
    arguments = parse()
    with recorded(__file__, stem=arguments.results) as figures:
        main(arguments, figures)
