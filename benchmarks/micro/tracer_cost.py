"""A passive tracer's cost beside a dynamics step's (issue 125: one tracer ≤ 0.3× a step).

TC5 at ne NE np 4 on one CPU thread, the scene's stepper (rk4) and ∇⁴ (every k steps, and every
step: ``--every 1``): the CPU seconds (``time.process_time``, one thread: the clock this shared
machine can still compare) of a step with K tracers and without, in rounds that take the two in
turn, the median of each taken. Prints the ratio (step with K − step without) / (K · step
without); ``--limiter optimization``: the tracers limited (their limiter's cost counted with theirs).

Each round builds its model, takes one ∇⁴ cycle untimed, times ``--steps`` steps and lets the model
go, so that the process holds one model at a time, warm, as a user's run does. Until 2026-11-30 the
two models lived side by side and alternated every 16 steps (their Warp arrays 41 and 46 MB at
ne30, against this machine's 32 MB L3), so each round began with the other model's arrays in the
caches, which a user's run never does; a cold start adds about the same time to both steps, so it
pulled the ratio down.

    SWE_SPHERE_THREADS=1 OMP_NUM_THREADS=1 python benchmarks/micro/tracer_cost.py --ne 16 --tracers 1 --rounds 5
"""

from __future__ import annotations

import argparse
import gc
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: results.py
from results import positive, quiet_warp, recorded

from swe_sphere import CubedSphere, ShallowWater, load_scene, make_stepper


def stepping(scene, grid, tracers: int, every: int | None, limiter: str = "none"):
    """(a function taking one step and returning its CPU seconds) of ``scene`` on ``grid`` with
    ``tracers`` q = 1 tracers, its ∇⁴ every ``every`` steps (None: the scene's), the tracers'
    ``limiter`` (a scene's tracers.limiter; the model refuses another name)."""
    case = scene.make_case()
    hv = {"nu": scene.nu, "nu_div": scene.nu_div, "nu_s": scene.nu_s}
    hv["hypervis_every"] = scene.hypervis_every if every is None else every
    limited = {"limiter": limiter} if tracers else {}
    model = ShallowWater.from_case(grid, case, scene.terms, tracers=tracers, threads=1, **limited, **hv)
    u, v, h = case.initial(grid.lat, grid.lon)
    x = model.new_state(u, v, h, masses=np.repeat(h[None], tracers, axis=0))
    stepper = make_stepper(scene.stepper, model, scene.dt)
    for _ in range(1 + hv["hypervis_every"]):  # records the launches (and compiles), then a warm ∇⁴ cycle
        stepper.step(x)

    def step() -> float:
        t0 = time.process_time()
        stepper.step(x)
        return time.process_time() - t0

    return step


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ne", type=positive(int), default=16)
    parser.add_argument("--tracers", type=positive(int), default=1)
    parser.add_argument("--rounds", type=positive(int), default=5)
    parser.add_argument(
        "--steps", type=positive(int), default=16, help="steps timed a round (a multiple of the ∇⁴'s every)"
    )
    parser.add_argument("--every", type=positive(int), default=None, help="the ∇⁴ every k steps (default: the scene's)")
    parser.add_argument("--limiter", default="none", help="the tracers' limiter (a scene's tracers.limiter)")
    args = parser.parse_args()
    quiet_warp()
    stem = "tracer_cost" + ("" if args.every is None else f"_every{args.every}")
    stem += "" if args.limiter == "none" else f"_{args.limiter}"
    with recorded(__file__, None if stem == "tracer_cost" else stem) as figures:
        measure(args, figures)


def measure(args, figures: dict) -> None:
    """``main``'s rounds and line; the ratio into ``figures``."""
    scene = load_scene("tc5_mountain", ne=args.ne, np_=4)
    grid = CubedSphere(args.ne, 4)
    seconds = {k: [] for k in (0, args.tracers)}
    for _ in range(args.rounds):
        for k in seconds:  # interleaved: the machine's load falls on both alike
            step = stepping(scene, grid, k, args.every, args.limiter)
            seconds[k].append(sum(step() for _ in range(args.steps)) / args.steps)
            del step
            gc.collect()  # the model let go before the next is built: one model held at a time
    bare, carried = (statistics.median(seconds[k]) for k in seconds)
    every = scene.hypervis_every if args.every is None else args.every
    figures["tracer_over_step"] = (carried - bare) / (args.tracers * bare)
    print(
        f"tc5 ne{args.ne} np4 {scene.stepper} dt {scene.dt:.1f} s, ∇⁴ every {every}: a step "
        f"{bare * 1e3:.2f} ms CPU without tracers, {carried * 1e3:.2f} ms with {args.tracers}"
        f"{'' if args.limiter == 'none' else ' limited (' + args.limiter + ')'}; "
        f"a tracer {(carried - bare) / (args.tracers * bare):.3f} x a dynamics step "
        f"(medians of {args.rounds} rounds of {args.steps} steps)"
    )


if __name__ == "__main__":
    main()
