"""A float32 model against float64 on the CPU: the RHS, a step, the device arrays, peak memory.

For each grid, the same scene's model is built twice in this process, ``precision`` float64
and float32 (``swe_sphere.model.precision``: the tendency and the ∇⁴ in float32 from the float64
state, the DSS's sums, the state and its updates float64), one thread each, and timed in
alternating rounds (the two never apart by more than one round's drift):

1. the RHS (``model.rhs``: the tendency and its DSS) in element-local points a second;
2. a step of the scene's stepper (its stages' ``rhs_update``, the ∇⁴ every k steps as the scene
   says), ms;
3. the bytes of the device arrays a run holds (``run_arrays``): of the Warp allocations alive
   after the scene's ``Simulation`` (as ``swe-sphere run`` builds it: its members, model, stepper,
   scorer) has taken a step and written its run file at t = 0 and at the step (the diagnostics'
   vorticity and divergence), those the run made, each allocation once (a view not counted
   again); ``--arrays`` lists them by owner, float type, shape and bytes;

then, with ``--peak-ne``, the peak resident memory of a short ``swe-sphere run`` of TC5 in a
child process in each precision. Medians of ``--rounds``; ``--clock cpu`` (the default) times
with ``time.process_time``, which another process's load does not inflate (one thread here).

    SWE_SPHERE_THREADS=1 python benchmarks/micro/precision_speed.py                      # ne30 np4, ne120 np4 (TC5), ne12 np8 (galewsky)
    SWE_SPHERE_THREADS=1 python benchmarks/micro/precision_speed.py --peak-ne 120 240

``--precisions float64 float32 float32_state`` adds the float32 state (issue 128: a step's
state and stages in float32 too), its RHS on the float32 state as a stage reads it
(``rhs_call``), each timed against float64 in the same rounds. A precision with ``:rows``
(``float32:rows``, ``float32_state:rows``) is that precision's model with its tendency on GLL
rows (``ShallowWater``'s ``lanes=0``), the layout before its vector lanes (``model.lanes``: W
elements a vector at np 4), timed in the same rounds. ``float32_state`` keeps the float32 state
between steps (its default: ``model.held``, its stepper stepping the float32 state with no
conversion); ``float32_state:compensated`` holds the float64 state between steps
(``numerics.compensated = true``: converted at each step's two ends)::

    SWE_SPHERE_THREADS=1 python benchmarks/micro/precision_speed.py --grids tc5_ne120_np4 \
        --precisions float64 float32:rows float32 float32_state:rows float32_state
"""

from __future__ import annotations

import argparse
import collections
import gc
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import warp as wp

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: results.py, the shared module
from results import quiet_warp, recorded

GRIDS = {
    "tc5_ne30_np4": ("tc5_mountain", 30, 4),
    "tc5_ne120_np4": ("tc5_mountain", 120, 4),
    "galewsky_ne12_np8": ("galewsky", 12, 8),
}
PRECISIONS = ("float64", "float32")  # the default; ``--precisions`` adds "float32_state" (issue 128)


def allocations() -> dict:
    """The Warp arrays alive that own their memory (not views), by address."""
    return {a.ptr: a for a in gc.get_objects() if type(a) is wp.array and a.ptr and a.deleter is not None}


def owners(root, name: str) -> dict:
    """Address -> the first attribute path from ``root`` (called ``name``) to a Warp array there,
    breadth first through swe_sphere's objects, named tuples, lists, tuples and dicts."""
    found, seen, queue = {}, set(), collections.deque([(name, root)])
    while queue:
        path, obj = queue.popleft()
        if id(obj) in seen:
            continue
        seen.add(id(obj))
        if isinstance(obj, wp.array):
            found.setdefault(obj.ptr, path)
        elif isinstance(obj, dict):
            queue.extend((f"{path}[{k!r}]", v) for k, v in obj.items())
        elif isinstance(obj, (list, tuple)) and not hasattr(obj, "_asdict"):
            queue.extend((f"{path}[{k}]", v) for k, v in enumerate(obj))
        elif hasattr(obj, "_asdict"):
            queue.extend((f"{path}.{k}", v) for k, v in obj._asdict().items())
        elif type(obj).__module__.startswith("swe_sphere") and hasattr(obj, "__dict__"):
            queue.extend((f"{path}.{k}", v) for k, v in vars(obj).items())
    return found


def run_arrays(name: str, ne: int, np_: int, precision: str) -> list[tuple]:
    """(bytes, float type, shape, owner) of each Warp array a run of scene ``name`` at ne, np in
    ``precision`` (``:compensated``: ``numerics.compensated = true``) holds, largest first: those alive
    after its ``Simulation`` has taken a step and written its run file (t = 0 and the step) that
    it made (``allocations``), an owner the attribute path from the simulation (``owners``; "?"
    for one only a recorded launch holds)."""
    from swe_sphere import Simulation

    precision, _, layout = precision.partition(":")
    before = set(allocations())
    options = {"numerics.compensated": True} if layout == "compensated" else {}
    sim = Simulation(name, device="cpu", progress=False, threads=1, ne=ne, np=np_, precision=precision, **options)
    with tempfile.TemporaryDirectory() as tmp:
        sim.run(Path(tmp) / "run.nc", until_step=1)
    gc.collect()
    where = owners(sim, "sim")
    held = [(a.capacity, getattr(a.dtype, "__name__", str(a.dtype)), a.shape, where.get(ptr, "?"))
            for ptr, a in allocations().items() if ptr not in before]  # fmt: skip
    return sorted(held, key=lambda row: -row[0])


def float32_state(model, x):
    """x as a float32 state's stages hold it (u, v, h − H₀ in float32: ``model.precision``);
    x itself where it is one (a kept state's)."""
    if x.dtype is wp.float32:
        return x
    departure = x.numpy() - np.array([0.0, 0.0, model.tendency_arrays.depth])[:, None]
    return wp.array(departure.astype(np.float32), dtype=wp.float32, device=x.device)


def rhs_call(model, x):
    """The RHS a call: ``model.rhs`` (the tendency and its DSS) into an array of x's type; under
    "float32_state" on the float32 state (``float32_state``) into a float32 array."""
    if model.state_dtype is not wp.float64:
        x = float32_state(model, x)
    out = wp.zeros_like(x)
    return lambda: model.rhs(x, out)


def build(name: str, ne: int, np_: int, precision: str):
    """(model, stepper, state) of scene ``name`` at ne, np in ``precision`` (``:rows``: its tendency
    on rows, ``lanes=0``; ``:compensated``: the float64 state held between steps, each step's
    float32 increment added to it), one thread, CPU."""
    from swe_sphere import CubedSphere, ShallowWater, load_scene, make_stepper

    precision, _, layout = precision.partition(":")
    scene = load_scene(name, ne=ne, np_=np_)
    case = scene.make_case()
    grid = CubedSphere(ne, np_, radius=case.planet.a)
    lanes = 0 if layout == "rows" else None
    options = {"compensated": True} if layout == "compensated" else {}
    model = ShallowWater.from_scene(
        scene, grid, case, device="cpu", threads=1, precision=precision, lanes=lanes, **options
    )
    stepper = make_stepper(scene.stepper, model, scene.dt, **scene.stepper_options)
    x = model.held.new(np.stack(case.initial(grid.lat, grid.lon)))  # the state a run holds
    return model, stepper, x


def timed(clock, fn, repeat: int) -> float:
    """Seconds of one ``fn()``, the mean of ``repeat`` calls after one untimed."""
    fn()
    t0 = clock()
    for _ in range(repeat):
        fn()
    return (clock() - t0) / repeat


# run in a process of its own, so that RUSAGE_CHILDREN is this run's peak alone (a parent's own
# RUSAGE_CHILDREN is the largest of all its children so far)
PEAK = (
    "import resource, subprocess, sys; r = subprocess.run(sys.argv[1:], capture_output=True, text=True); "
    "sys.stderr.write(r.stderr[-2000:]); print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss); "
    "sys.exit(r.returncode)"
)


def child_peak_rss(ne: int, precision: str) -> float:
    """Peak RSS (MiB) of a child running TC5 at ne np4 for a few steps in ``precision``."""
    with tempfile.TemporaryDirectory() as tmp:
        cmd = [sys.executable, "-m", "swe_sphere.cli", "run", "tc5_mountain", "--ne", str(ne), "--days", "0.01"]
        cmd += ["--precision", precision, "--no-progress", "--output", os.path.join(tmp, "run.nc")]
        env = {**os.environ, "SWE_SPHERE_THREADS": "1"}
        p = subprocess.run([sys.executable, "-c", PEAK, *cmd], capture_output=True, text=True, env=env)
        if p.returncode != 0:
            raise RuntimeError(f"{' '.join(cmd)} failed ({p.returncode}):\n{p.stderr[-2000:]}")
        return int(p.stdout.split()[-1]) / 1024.0  # KiB on Linux


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--grids", nargs="*", default=list(GRIDS), choices=list(GRIDS))
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--repeat", type=int, default=10, help="calls a timing (the mean)")
    ap.add_argument("--clock", choices=("cpu", "wall"), default="cpu")
    ap.add_argument("--peak-ne", type=int, nargs="*", default=[], help="TC5 grids for the peak-memory rows")
    ap.add_argument(
        "--precisions",
        nargs="+",
        default=list(PRECISIONS),
        choices=(
            "float64",
            "float32",
            "float32_state",
            "float32:rows",
            "float32_state:rows",
            "float32_state:compensated",
        ),
        help="float64 first, each timed against it (default %(default)s)",
    )
    ap.add_argument("--results", default="precision_speed", help="results/STEM.json (default %(default)s)")
    ap.add_argument("--arrays", action="store_true", help="list each array a run holds (``run_arrays``)")
    args = ap.parse_args(argv)
    quiet_warp()  # quietly
    clock = time.process_time if args.clock == "cpu" else time.perf_counter
    with recorded("precision_speed", args.results) as figures:
        print(f"clock {args.clock}, one thread, medians of {args.rounds} rounds of {args.repeat} calls")
        precisions = args.precisions
        if precisions[0] != "float64":
            ap.error("--precisions: float64 first (the others are timed against it)")
        lower = precisions[1:]
        head = ["grid", "nodes", "RHS float64 Mpt/s", *(f"{p} (ratio)" for p in lower), "step float64 ms"]
        head += [*(f"{p} (ratio)" for p in lower), "device MiB float64", *(f"{p} (ratio)" for p in lower)]
        print("| " + " | ".join(head) + " |")
        print("|" + "---|" * len(head))
        for key in args.grids:
            name, ne, np_ = GRIDS[key]
            built = {p: build(name, ne, np_, p) for p in precisions}
            calls = {p: rhs_call(built[p][0], built[p][2]) for p in precisions}
            rhs, step = {p: [] for p in precisions}, {p: [] for p in precisions}
            for _ in range(args.rounds):
                for p in precisions:
                    model, stepper, x = built[p]
                    rhs[p].append(timed(clock, calls[p], args.repeat))
                    step[p].append(timed(clock, lambda s=stepper, x=x: s.step(x), args.repeat))
            n = built["float64"][0].N
            rate = {p: n / statistics.median(rhs[p]) / 1e6 for p in precisions}
            ms = {p: 1e3 * statistics.median(step[p]) for p in precisions}
            del built, calls
            # a run's arrays: the rows layout is no scene's (the CLI runs the shipped lanes)
            held = {p: run_arrays(name, ne, np_, p) for p in precisions if not p.endswith(":rows")}
            mib = {p: sum(row[0] for row in held.get(p, [])) / 2.0**20 or float("nan") for p in precisions}
            row = dict(nodes=n, rhs_mpts=rate, step_ms=ms, device_mib=mib)
            figures[key] = row
            cells = [key, str(n)]
            for figure, fmt in ((rate, ".1f"), (ms, ".2f"), (mib, ".1f")):
                cells.append(f"{figure['float64']:{fmt}}")
                cells += [f"{figure[p]:{fmt}} ({figure[p] / figure['float64']:.2f})" for p in lower]
            print("| " + " | ".join(cells) + " |")
            if args.arrays:
                for p, rows in held.items():
                    print(f"{key} {p}: {len(rows)} arrays, {mib[p]:.2f} MiB")
                    for size, dtype, shape, owner in rows:
                        print(f"  {size / 2.0**20:9.3f} MiB  {dtype:>8}  {str(shape):>16}  {owner}")
        for ne in args.peak_ne:
            peaks = {p: child_peak_rss(ne, p) for p in precisions if ":" not in p}  # the CLI runs the shipped lanes
            figures[f"peak_rss_tc5_ne{ne}"] = peaks
            print(f"peak RSS, TC5 ne{ne} np4 run: " + ", ".join(f"{p} {v:.0f} MiB" for p, v in peaks.items()))


if __name__ == "__main__":
    main()
