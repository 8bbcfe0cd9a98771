"""A float32 model against float64 on the CPU: the RHS, a step, the device arrays, peak memory.

For each grid, the same scene's model is built twice in this process, ``precision`` float64
and float32 (``swe_sphere.model.precision``: the tendency and the ∇⁴ in float32 from the float64
state, the DSS's sums, the state and its updates float64), one thread each, and timed in
alternating rounds (the two never apart by more than one round's drift):

1. the RHS (``model.rhs``: the tendency and its DSS) in element-local points a second;
2. a step of the scene's stepper (its stages' ``rhs_update``, the ∇⁴ every k steps as the scene
   says), ms;
3. the bytes of the device arrays the run holds (the model's, its operators', topology's, ∇⁴'s
   and tendency's arrays and the stepper's, each array once);

then, with ``--peak-ne``, the peak resident memory of a short ``swe-sphere run`` of TC5 in a
child process in each precision. Medians of ``--rounds``; ``--clock cpu`` (the default) times
with ``time.process_time``, which another process's load does not inflate (one thread here).

    SWE_SPHERE_THREADS=1 python benchmarks/micro/precision_speed.py                      # ne30 np4, ne120 np4 (TC5), ne12 np8 (galewsky)
    SWE_SPHERE_THREADS=1 python benchmarks/micro/precision_speed.py --peak-ne 120 240
"""

from __future__ import annotations

import argparse
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
PRECISIONS = ("float64", "float32")


def device_bytes(*owners) -> int:
    """Bytes of the distinct Warp arrays held by ``owners`` and their attributes one level down
    (a model's operators, topology, ∇⁴ and tendency arrays; a stepper's buffers)."""
    seen: dict[int, int] = {}

    def note(value):
        if isinstance(value, wp.array) and value.ptr and value.capacity:
            seen.setdefault(value.ptr, value.capacity)

    def walk(obj, depth):
        values = (
            obj._asdict().values()
            if hasattr(obj, "_asdict")
            else vars(obj).values()
            if hasattr(obj, "__dict__")
            else []
        )
        for value in values:
            note(value)
            if isinstance(value, (list, tuple)):
                for v in value:
                    note(v)
            elif (
                depth
                and not isinstance(value, (wp.array, np.ndarray, str, int, float))
                and (type(value).__module__.startswith("swe_sphere") or hasattr(value, "_asdict"))
            ):
                walk(value, depth - 1)

    for owner in owners:
        walk(owner, 2)
    return sum(seen.values())


def build(name: str, ne: int, np_: int, precision: str):
    """(model, stepper, state) of scene ``name`` at ne, np in ``precision``, one thread, CPU."""
    from swe_sphere import CubedSphere, ShallowWater, load_scene, make_stepper

    scene = load_scene(name, ne=ne, np_=np_)
    case = scene.make_case()
    grid = CubedSphere(ne, np_, radius=case.planet.a)
    model = ShallowWater.from_scene(scene, grid, case, device="cpu", threads=1, precision=precision)
    stepper = make_stepper(scene.stepper, model, scene.dt, **scene.stepper_options)
    x = model.new_state(*np.stack(case.initial(grid.lat, grid.lon)))
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
    ap.add_argument("--results", default="precision_speed", help="results/STEM.json (default %(default)s)")
    args = ap.parse_args(argv)
    quiet_warp()  # quietly
    clock = time.process_time if args.clock == "cpu" else time.perf_counter
    with recorded("precision_speed", args.results) as figures:
        print(f"clock {args.clock}, one thread, medians of {args.rounds} rounds of {args.repeat} calls")
        print(
            "| grid | nodes | RHS float64 Mpt/s | RHS float32 Mpt/s | ratio | step float64 ms | step float32 ms | ratio | device MiB float64 | float32 | ratio |"
        )
        print("|---|---|---|---|---|---|---|---|---|---|---|")
        for key in args.grids:
            name, ne, np_ = GRIDS[key]
            built = {p: build(name, ne, np_, p) for p in PRECISIONS}
            out = {p: wp.zeros_like(built[p][2]) for p in PRECISIONS}
            rhs, step = {p: [] for p in PRECISIONS}, {p: [] for p in PRECISIONS}
            for _ in range(args.rounds):
                for p in PRECISIONS:
                    model, stepper, x = built[p]
                    rhs[p].append(timed(clock, lambda m=model, x=x, o=out[p]: m.rhs(x, o), args.repeat))
                    step[p].append(timed(clock, lambda s=stepper, x=x: s.step(x), args.repeat))
            n = built["float64"][0].N
            rate = {p: n / statistics.median(rhs[p]) / 1e6 for p in PRECISIONS}
            ms = {p: 1e3 * statistics.median(step[p]) for p in PRECISIONS}
            mib = {p: device_bytes(built[p][0], built[p][1]) / 2.0**20 for p in PRECISIONS}
            row = dict(nodes=n, rhs_mpts=rate, step_ms=ms, device_mib=mib)
            figures[key] = row
            print(
                f"| {key} | {n} | {rate['float64']:.1f} | {rate['float32']:.1f} | {rate['float32'] / rate['float64']:.2f} "
                f"| {ms['float64']:.2f} | {ms['float32']:.2f} | {ms['float32'] / ms['float64']:.2f} "
                f"| {mib['float64']:.1f} | {mib['float32']:.1f} | {mib['float32'] / mib['float64']:.2f} |"
            )
            del built, out
        for ne in args.peak_ne:
            peaks = {p: child_peak_rss(ne, p) for p in PRECISIONS}
            figures[f"peak_rss_tc5_ne{ne}"] = peaks
            print(
                f"peak RSS, TC5 ne{ne} np4 run: float64 {peaks['float64']:.0f} MiB, float32 {peaks['float32']:.0f} MiB"
            )


if __name__ == "__main__":
    main()
