"""What the ∇⁴ every k steps saves (``[hyperviscosity] every``, issue 99): a step's CPU cost at
each k, interleaved, beside the step with the ∇⁴ every step.

For ``--scene`` on its own grid (or ``--ne``/``--np``) at its own stepper and Δt, one model a k
of ``--every``, each stepped ``--steps`` steps a round (rounded up to a multiple of every k, so a
round holds whole cycles of the ∇⁴), ``--rounds`` rounds taken in turn so that a change of load
hits every k alike; the median CPU ms a step (``time.process_time``, one thread: run it with
``SWE_SPHERE_THREADS=1``), its ratio to k = 1 and the ∇⁴'s plan over kΔt (evaluations, RKL1 or
forward Euler; ``Hyperviscosity.plan``). The accuracy at each k is ``long_step.py``'s
(``--runs STEPPER@DT:hyperviscosity.every=K``). ``--filter MU ...``: beside them, the scene without
its ∇⁴ and with the element filter ([filter] mu = MU) after every step instead (its accuracy:
``long_step.py --runs STEPPER@DT:terms=...:filter.mu=MU``). Figures to
``benchmarks/results/hyperviscosity_every/hyperviscosity_every[_STEM].json``::

    SWE_SPHERE_THREADS=1 OMP_NUM_THREADS=1 python benchmarks/micro/step/hyperviscosity_every.py --scene galewsky --every 1 6 12
"""

from __future__ import annotations

import argparse
import math
import os
import statistics
import sys
import time
from pathlib import Path

os.environ.setdefault("SWE_SPHERE_THREADS", "1")

import warp as wp  # noqa: E402
from threadpoolctl import threadpool_limits  # noqa: E402

wp.config.quiet = True

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # benchmarks/: results.py, the shared module
from results import positive, recorded  # noqa: E402  (after the path: benchmarks/ first)

from swe_sphere import (  # noqa: E402
    ArgumentError,  # noqa: E402
    Simulation,  # noqa: E402
    load_scene,  # noqa: E402
)


def arguments():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--scene", default="galewsky")
    p.add_argument("--ne", type=positive(int), default=None)
    p.add_argument("--np", type=positive(int), default=None)
    p.add_argument("--every", type=positive(int), nargs="+", default=[1, 6, 12])
    p.add_argument("--filter", type=positive(float), nargs="*", default=[], help="the element filter's mu instead")
    p.add_argument("--steps", type=positive(int), default=48, help="steps a round (a multiple of every k)")
    p.add_argument("--rounds", type=positive(int), default=5)
    p.add_argument("--results", default=None, help="results stem (default hyperviscosity_every)")
    return p.parse_args()


def main() -> None:
    args = arguments()
    ks = sorted(set([1, *args.every]))
    cycle = math.lcm(*ks)
    steps = cycle * math.ceil(args.steps / cycle)
    grid = {k: v for k, v in (("ne", args.ne), ("np", args.np)) if v}
    with recorded(__file__, args.results) as figures, threadpool_limits(limits=1):
        print(f"load average at the start: {os.getloadavg()}")
        inviscid = [t for t in load_scene(args.scene).terms if t != "hyperviscosity"]
        runs = {k: {"hyperviscosity": {"every": k}} for k in ks}
        runs |= {f"filter {mu:g}": {"terms": inviscid, "filter": {"mu": mu}} for mu in args.filter}
        sims = {
            k: Simulation(args.scene, "cpu", progress=False, days=1.0, graphs=False, **over, **grid)
            for k, over in runs.items()
        }
        if sims[1].model.hv is None:
            raise ArgumentError(f"--scene {args.scene}: its terms have no hyperviscosity")
        for sim in sims.values():  # recorded and compiled: one whole cycle
            for _ in range(cycle):
                sim.stepper.step(sim.x)
        ms = {k: [] for k in sims}
        for _ in range(args.rounds):
            for k, sim in sims.items():
                start = time.process_time()
                for _ in range(steps):
                    sim.stepper.step(sim.x)
                ms[k].append((time.process_time() - start) / steps * 1e3)
        sim = sims[1]
        scene, hv = sim.scene, sim.model.hv
        print(
            f"\n## {args.scene} ne{scene.ne} np{scene.np} {scene.stepper} at {scene.dt:.1f} s, "
            f"CPU ms a step (medians of {args.rounds} interleaved rounds of {steps} steps), one thread"
        )
        print(f"{'every':>6} {'ms/step':>9} {'ratio':>6} {'∇⁴ plan over kΔt':>20} {'∇⁴ evals/step':>14}")
        med = {k: statistics.median(v) for k, v in ms.items()}
        rows = []
        for k in ks:
            evals, rkl = hv.plan(k * scene.dt)
            rows.append({"every": k, "ms": med[k], "ratio": med[k] / med[1], "evaluations": evals, "rkl1": rkl})
            plan = f"{evals} {'RKL1 stages' if rkl else 'Euler substeps'}"
            print(f"{k:>6} {med[k]:9.3f} {med[k] / med[1]:6.3f} {plan:>20} {evals / k:14.3f}")
        for k in [k for k in runs if k not in ks]:
            rows.append({"run": k, "ms": med[k], "ratio": med[k] / med[1]})
            print(f"{k:>6} {med[k]:9.3f} {med[k] / med[1]:6.3f} {'no ∇⁴':>20}")
        figures["steps"] = rows
        print(f"load average at the end: {os.getloadavg()}")


if __name__ == "__main__":
    main()
