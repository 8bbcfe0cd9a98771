"""A passive tracer's cost beside a dynamics step's (issue 125: one tracer ≤ 0.3× a step).

TC5 at ne NE np 4 on one CPU thread, the scene's stepper (rk4) and ∇⁴ (every k steps, and every
step: ``--every 1``): the CPU seconds (``time.process_time``, one thread: the clock this shared
machine can still compare) of a step with K tracers and without, in rounds that take the two in
turn, the median of each taken. Prints the ratio (step with K − step without) / (K · step
without); ``--limiter optimization``: the tracers limited (their limiter's cost counted with theirs).
A line before it gives the spread over the rounds: each step's quartiles, and the quartiles of each
round's own ratio (its step with K tracers against its step without). Each round's models are new
allocations, and a round's own ratio scatters widely (ne30, idle, one thread, rounds of 64 steps:
0.22–0.55 on 2026-11-30, with the medians 0.39–0.44): take 11 rounds or more and read the median
beside its quartiles.

Each round builds its model in a process of its own (this script, ``--round K``), takes one ∇⁴
cycle untimed, times ``--steps`` steps and exits, so that every model's arrays are laid out as a
user's run lays them out, in a fresh heap. Until 2026-11-30 the rounds' models were built in turn in
one process, each let go before the next: the later models' arrays then took the freed ones' memory
at another layout, and the ratio scattered with it (idle, ne30, 15 rounds of 32 steps, four runs:
0.284, 0.326, 0.362, 0.373; the step with a tracer 4.37–4.78 ms) where models built in fresh
processes gave 0.279 (eight of each, 64 steps: the step with a tracer 4.26–4.60 ms). Before that
the two models lived side by side and alternated every 16 steps, each round beginning with the
other model's arrays in the caches, which a user's run never does.

``--runs DAYS``: whole runs as a user makes them instead, ``swe-sphere run tc5_mountain`` in a
process of its own, with the K tracers (q = 1) named by ``-s tracers.…`` and without, of DAYS and
of 2·DAYS days, the rounds taking the four in turn: a step's CPU seconds (the child's user + system
time, ``resource.RUSAGE_CHILDREN``) as the longer run's less the shorter's over DAYS' steps (the
start-up, the compiles and the first output cancel; the later outputs stay in, as in a user's run).

``--kernels``: each launch of one RHS (the tendency and its DSS) alone instead, the two models'
launches taken in turn, each repeated 10 times a round in a row (in the caches as far as its own
arrays fit): what a tracer's row adds to each kernel's own work, without what the rest of a step
does to the caches; the CPU µs a call, medians over the rounds.

    SWE_SPHERE_THREADS=1 OMP_NUM_THREADS=1 python benchmarks/micro/tracer_cost.py --ne 16 --tracers 1 --rounds 5
    SWE_SPHERE_THREADS=1 OMP_NUM_THREADS=1 python benchmarks/micro/tracer_cost.py --ne 30 --runs 1
    SWE_SPHERE_THREADS=1 OMP_NUM_THREADS=1 python benchmarks/micro/tracer_cost.py --ne 30 --kernels --rounds 15
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import warp as wp

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: results.py
from results import DAY, positive, quiet_warp, recorded

from swe_sphere import CubedSphere, ShallowWater, load_scene, make_stepper


def quartiles(values: list) -> list[float]:
    """[first quartile, median, third quartile] of ``values`` (one value: itself three times)."""
    if len(values) < 2:
        return [float(values[0])] * 3
    q1, q2, q3 = statistics.quantiles(values, n=4, method="inclusive")
    return [q1, q2, q3]


def spread(seconds: dict, tracers: int, figures: dict) -> None:
    """Print and put in ``figures`` the quartiles over the rounds of the step's CPU ms without
    and with ``tracers`` (``seconds``: {0: [...], tracers: [...]}, a step's seconds a round) and
    of each round's own ratio (its step with the tracers less its step without, over
    ``tracers`` times the latter)."""
    ms = {k: quartiles([t * 1e3 for t in v]) for k, v in seconds.items()}
    ratio = quartiles([(c - b) / (tracers * b) for b, c in zip(seconds[0], seconds[tracers])])
    figures["step_ms_quartiles"] = {str(k): v for k, v in ms.items()}
    figures["tracer_over_step_by_round_quartiles"] = ratio
    print(
        f"quartiles over the rounds: a step {ms[0][0]:.2f}–{ms[0][2]:.2f} ms without tracers, "
        f"{ms[tracers][0]:.2f}–{ms[tracers][2]:.2f} with {tracers}; a round's own ratio "
        f"{ratio[0]:.3f} / {ratio[1]:.3f} / {ratio[2]:.3f} (first quartile / median / third)"
    )


def verdict(args, seconds: dict, figures: dict, head: str, rounds: str) -> None:
    """The ratio of the medians of ``seconds`` ({0: [...], K: [...]}, a step's CPU seconds a
    round) into ``figures`` with their spread (``spread``), and the figure line: ``head``, the
    steps, the ratio, and what a round is (``rounds``)."""
    bare, carried = (statistics.median(seconds[k]) for k in seconds)
    figures["tracer_over_step"] = (carried - bare) / (args.tracers * bare)
    spread(seconds, args.tracers, figures)
    limited = "" if args.limiter == "none" else f" limited ({args.limiter})"
    print(
        f"{head}a step {bare * 1e3:.2f} ms CPU without tracers, {carried * 1e3:.2f} ms with {args.tracers}{limited}; "
        f"a tracer {figures['tracer_over_step']:.3f} x a dynamics step (medians of {args.rounds} {rounds})"
    )


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
    how = parser.add_mutually_exclusive_group()
    how.add_argument("--runs", type=positive(float), default=None, metavar="DAYS", help="whole runs instead")
    how.add_argument("--kernels", action="store_true", help="an RHS's launches, each alone, instead")
    how.add_argument("--round", type=int, default=None, help=argparse.SUPPRESS)  # one_round's child
    args = parser.parse_args()
    if args.kernels and args.limiter != "none":
        parser.error("--kernels times an RHS, which holds no limiter: --limiter none")
    quiet_warp()
    if args.round is not None:
        return child_round(args)
    stem = "tracer_cost" + ("" if args.runs is None else "_runs") + ("_kernels" if args.kernels else "")
    stem += "" if args.every is None else f"_every{args.every}"
    stem += "" if args.limiter == "none" else f"_{args.limiter}"
    with recorded(__file__, None if stem == "tracer_cost" else stem) as figures:
        (whole_runs if args.runs is not None else kernels if args.kernels else measure)(args, figures)


def kernels(args, figures: dict) -> None:
    """``--kernels``: each launch of one RHS alone (the module's note), its CPU µs a call without
    and with the tracers; the sums' ratio into ``figures``."""
    scene = load_scene("tc5_mountain", ne=args.ne, np_=4)
    grid, case = CubedSphere(args.ne, 4), scene.make_case()
    launches = {}
    for k in (0, args.tracers):
        model = ShallowWater.from_case(grid, case, scene.terms, tracers=k, threads=1)
        u, v, h = case.initial(grid.lat, grid.lon)
        x = model.new_state(u, v, h, masses=np.repeat(h[None], k, axis=0))
        F = wp.zeros_like(x)
        model.rhs(x, F)  # records the launches (and compiles)
        launches[k] = [(a.kernel.key, a) for a in model.launches.recorded(model.rhs_key(x, F)) if hasattr(a, "kernel")]
    micro = {(k, i): [] for k, row in launches.items() for i in range(len(row))}
    for _ in range(args.rounds):
        for k, row in launches.items():  # interleaved: the machine's load falls on both alike
            for i, (_, launch) in enumerate(row):
                launch.launch()
                start = time.process_time()
                for _ in range(10):
                    launch.launch()
                micro[k, i].append((time.process_time() - start) / 10 * 1e6)
    total = {}
    for k, row in launches.items():
        total[k] = sum(statistics.median(micro[k, i]) for i in range(len(row)))
        for i, (key, _) in enumerate(row):
            print(f"{k} tracers: {key} {statistics.median(micro[k, i]):.1f} µs CPU a call")
    figures["rhs_ratio"] = total[args.tracers] / total[0]
    print(
        f"tc5 ne{args.ne} np4, an RHS's launches each alone: {total[0]:.1f} µs CPU without tracers, "
        f"{total[args.tracers]:.1f} µs with {args.tracers}; a tracer {(total[args.tracers] / total[0] - 1) / args.tracers:.3f} "
        f"x the RHS (medians of {args.rounds} rounds)"
    )


def run_seconds(args, tracers: int, days: float, output: Path) -> float:
    """The CPU seconds (user + system) of ``swe-sphere run tc5_mountain`` over ``days`` at ne, np 4,
    one thread, in a child process, with ``tracers`` q = 1 tracers named by ``-s``; its run file
    ``output`` (replaced)."""
    options = ["--ne", str(args.ne), "--np", "4", "--days", repr(days), "--device", "cpu", "--no-progress"]
    options += ["--overwrite", "--output", str(output)]
    if args.every is not None:
        options += ["-s", f"hyperviscosity.every={args.every}"]
    if tracers:  # TOML values: json's lists and strings are TOML's
        names = [f"q{k}" for k in range(tracers)]
        for key, value in (("names", names), ("initial", ["constant"] * tracers), ("limiter", args.limiter)):
            options += ["-s", f"tracers.{key}={json.dumps(value)}"]
    env = {**os.environ, "SWE_SPHERE_THREADS": "1", "OMP_NUM_THREADS": "1"}
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    command = [sys.executable, "-m", "swe_sphere", "run", "tc5_mountain", *options]
    done = subprocess.run(command, env=env, capture_output=True, text=True)
    if done.returncode:  # a refused option (a limiter's name): the run's own line, its exit code
        print(f"tracer_cost.py: {(done.stderr.strip().splitlines() or ['swe-sphere run failed'])[-1]}", file=sys.stderr)
        sys.exit(done.returncode)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime


def whole_runs(args, figures: dict) -> None:
    """``--runs``: ``main``'s line from whole runs (the module's note); the ratio into ``figures``."""
    scene = load_scene("tc5_mountain", ne=args.ne, np_=4)
    steps = args.runs * DAY / scene.dt
    seconds = {k: [] for k in (0, args.tracers)}
    with tempfile.TemporaryDirectory() as tmp:
        for _ in range(args.rounds):
            for k in seconds:  # interleaved: the machine's load falls on both alike
                short, long = (run_seconds(args, k, d, Path(tmp) / "run.nc") for d in (args.runs, 2 * args.runs))
                seconds[k].append((long - short) / steps)
    verdict(
        args,
        seconds,
        figures,
        f"swe-sphere run tc5_mountain --ne {args.ne}: ",
        f"rounds, runs of {args.runs:g} and {2 * args.runs:g} days",
    )


def one_round(args, tracers: int) -> float:
    """A step's CPU seconds with ``tracers`` q = 1 tracers, from a process of its own (``--round``)
    that builds the model, warms it (``stepping``) and times ``args.steps`` steps."""
    command = [sys.executable, __file__, "--round", str(tracers), "--ne", str(args.ne), "--steps", str(args.steps)]
    command += ["--limiter", args.limiter] + ([] if args.every is None else ["--every", str(args.every)])
    env = {**os.environ, "SWE_SPHERE_THREADS": "1", "OMP_NUM_THREADS": "1"}
    done = subprocess.run(command, env=env, capture_output=True, text=True)
    if done.returncode:  # a refused option (a limiter's name): the child's own line, its exit code
        print((done.stderr.strip().splitlines() or ["tracer_cost.py: a round failed"])[-1], file=sys.stderr)
        sys.exit(done.returncode)
    return float(done.stdout.split()[-1])


def child_round(args) -> None:
    """``--round K``: one round's model (``one_round``); prints a step's CPU seconds."""
    scene = load_scene("tc5_mountain", ne=args.ne, np_=4)
    step = stepping(scene, CubedSphere(args.ne, 4), args.round, args.every, args.limiter)
    print(repr(sum(step() for _ in range(args.steps)) / args.steps))


def measure(args, figures: dict) -> None:
    """``main``'s rounds and line; the ratio into ``figures``."""
    scene = load_scene("tc5_mountain", ne=args.ne, np_=4)
    seconds = {k: [] for k in (0, args.tracers)}
    for _ in range(args.rounds):
        for k in seconds:  # interleaved: the machine's load falls on both alike
            seconds[k].append(one_round(args, k))
    every = scene.hypervis_every if args.every is None else args.every
    head = f"tc5 ne{args.ne} np4 {scene.stepper} dt {scene.dt:.1f} s, ∇⁴ every {every}: "
    verdict(args, seconds, figures, head, f"rounds of {args.steps} steps, each model in a process of its own")


if __name__ == "__main__":
    main()
