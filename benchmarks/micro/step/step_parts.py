"""A step's CPU time kernel by kernel, inside the step (issue 99): where a scene's step goes.

For ``--scene`` on its own grid (or ``--ne``/``--np``) at its own stepper, Δt and ∇⁴ schedule
(``--every`` to change it), ``--steps`` steps after a whole ∇⁴ cycle to record and compile; every
recorded launch (``wp.Launch.launch``, and the ``launch`` of the model's one-range CPU launches,
which call Warp's entry point directly), ``wp.copy``, ``zero_`` and ``assign`` timed by the CPU
clock around it and summed by kernel key: calls a step, ms a step and ms a call, and what the
step spends outside them (Python, the stepper's bookkeeping). A kernel here reads what the
passes before it left in the caches, which is why its figure differs from
``roofline.py kernel_roofline``'s (each kernel alone, repeated): e.g. Galewsky's DSS update 0.66 ms a call
in the step against 0.40 alone. One thread: run it with ``SWE_SPHERE_THREADS=1``. Figures to
``benchmarks/results/step_parts/step_parts[_STEM].json``::

    SWE_SPHERE_THREADS=1 OMP_NUM_THREADS=1 python benchmarks/micro/step/step_parts.py --scene galewsky
"""

from __future__ import annotations

import argparse
import collections
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("SWE_SPHERE_THREADS", "1")

import warp as wp  # noqa: E402
from threadpoolctl import threadpool_limits  # noqa: E402

wp.config.quiet = True

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # benchmarks/: results.py, the shared module
from results import positive, recorded  # noqa: E402  (after the path: benchmarks/ first)

from swe_sphere import Simulation  # noqa: E402


def arguments():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--scene", default="galewsky")
    p.add_argument("--ne", type=positive(int), default=None)
    p.add_argument("--np", type=positive(int), default=None)
    p.add_argument("--every", type=positive(int), default=None, help="the ∇⁴ every k steps (default: the scene's)")
    p.add_argument("--steps", type=positive(int), default=96)
    p.add_argument("--precision", default=None, help="numerics.precision (default: the scene's)")
    p.add_argument("--kept", action="store_true", help="numerics.compensated = false: the float32 state kept")
    p.add_argument("--results", default=None, help="results stem (default step_parts)")
    return p.parse_args()


def timed(tally, call, key):
    """``call`` with its CPU time added to tally[key(args)] (calls, seconds)."""

    def run(*args, **kwargs):
        start = time.process_time()
        out = call(*args, **kwargs)
        entry = tally[key(args)]
        entry[0] += 1
        entry[1] += time.process_time() - start
        return out

    return run


def main() -> None:
    args = arguments()
    options = {k: v for k, v in (("ne", args.ne), ("np", args.np)) if v}
    if args.every:
        options["hyperviscosity"] = {"every": args.every}
    if args.precision:
        options["precision"] = args.precision
    if args.kept:
        options["numerics.compensated"] = False
    tally = collections.defaultdict(lambda: [0, 0.0])
    wrapped = (
        (wp.Launch, "launch", lambda a: a[0].kernel.key),
        (wp, "copy", lambda a: "wp.copy"),
        (wp.array, "zero_", lambda a: "zero_"),
        (wp.array, "assign", lambda a: "assign"),
    )
    with recorded(__file__, args.results) as figures, threadpool_limits(limits=1):
        print(f"load average at the start: {os.getloadavg()}")
        sim = Simulation(args.scene, "cpu", progress=False, graphs=False, **options)  # its days: "auto" reads them
        every = sim.scene.hypervis_every
        for _ in range(2 * every):  # recorded and compiled: whole cycles of the ∇⁴
            sim.stepper.step(sim.x)
        launches = sim.model.launches  # one thread: its recorded launches call Warp's entry point directly
        kinds = {type(one) for key in launches.keys() for one in launches.recorded(key)} - {wp.Launch}
        wrapped += tuple((kind, "launch", lambda a: a[0].kernel.key) for kind in kinds)
        originals = [(owner, name, getattr(owner, name)) for owner, name, _ in wrapped]
        for (owner, name, key), (_, _, call) in zip(wrapped, originals):
            setattr(owner, name, timed(tally, call, key))
        try:
            start = time.process_time()
            for _ in range(args.steps):
                sim.stepper.step(sim.x)
            step = (time.process_time() - start) / args.steps * 1e3
        finally:
            for owner, name, call in originals:
                setattr(owner, name, call)
        scene = sim.scene
        print(
            f"\n## {args.scene} ne{scene.ne} np{scene.np} {scene.stepper} at {scene.dt:.1f} s, ∇⁴ every {every}: "
            f"{step:.3f} CPU ms a step ({args.steps} steps, one thread)"
        )
        print(f"{'kernel':<72} {'calls/step':>10} {'ms/step':>8} {'share':>6} {'ms/call':>8}")
        rows = []
        for key, (calls, seconds) in sorted(tally.items(), key=lambda kv: -kv[1][1]):
            ms = seconds / args.steps * 1e3
            rows.append({"kernel": key, "calls": calls / args.steps, "ms": ms, "ms_per_call": seconds / calls * 1e3})
            print(f"{key[:72]:<72} {calls / args.steps:10.3f} {ms:8.3f} {ms / step:6.1%} {seconds / calls * 1e3:8.3f}")
        rest = step - sum(r["ms"] for r in rows)
        print(f"{'(outside the kernels and copies)':<72} {'':>10} {rest:8.3f} {rest / step:6.1%}")
        figures.update(ms_per_step=step, parts=rows, outside=rest)
        print(f"load average at the end: {os.getloadavg()}")


if __name__ == "__main__":
    main()
