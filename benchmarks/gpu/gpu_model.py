"""The GPU performance model on paper: bytes per point of every
kernel, launches per step of every stepper, and the predicted times on an
H100 and an H200, from counts taken off the code on the CPU.

What is counted (TC5, all terms + ∇⁴, np = 4, the CUDA layout: per-node
kernels, ``per_element=False``, one thread, the steppers' CUDA solvers:
the Helmholtz ``pcg`` and the Krylov vector work of FGMRES and KIOPS in Warp kernels), by wrapping Warp's launch entry points (``swe_sphere.core.tally``)
while the model evaluates one RHS, one ∇⁴ and ``--steps`` steps of each
stepper after ``--warmup`` steps, on ``--ne`` (default 8):

* a launch's bytes: the capacity of each distinct array argument, once for a read and once
  for a write as the kernel's built code marks it (``core.tally.array_bytes``: an array
  updated in place, x += ..., both ways) (the compulsory HBM traffic when a kernel streams its
  arguments and the re-reads within an element hit L1/L2; the per-node layout re-reads 2·np
  nodes per point from cache). Kernels that touch some rows of an argument are overcounted
  (schur_height, the mass fixer's depth row), small beside the RHS and ∇⁴;
* launches: recorded (``wp.Launch.launch``) and direct (``wp.launch``)
  kernel launches, plus memsets and copies (``zero_``, ``fill_``,
  ``assign``, ``wp.copy``); host syncs: ``.numpy()`` read-backs, each of
  which ends a CUDA graph.

Predictions: GPU time = bytes / (0.7 × HBM bandwidth) + launches × 1 µs
(the GPU-side gap between consecutive kernels and memsets); launch floor = launches ×
4 µs of host time. Without graphs a step takes the larger of the two (the
host launches while the GPU runs); with one CUDA graph per sync-free segment
it takes GPU time + (syncs + 1) × 4 µs. A step is launch-bound when its
launch floor exceeds its GPU time. Bytes per point at ``--ne`` scale to other grids with the node count;
iteration counts at a fixed Courant number barely change with ne
(benchmarks/README.md: semi-implicit at 4× 25 / 24 CG iterations at ne16 / 30).

    python benchmarks/gpu/gpu_model.py                  # ne 8 counts, tables for ne 30 120 240
    python benchmarks/gpu/gpu_model.py --ne 16 --at 30 60 --implicit-dt-factor 10
    python benchmarks/gpu/gpu_model.py --precision float32_state    # issue 128: the float32 state's bytes

``--precision`` counts the model in "float32" (the mixed design: the tendency and the ∇⁴'s
Laplacians float32, the state and stages float64) or "float32_state" (the state and the stages
float32 too: the RHS on the float32 state, and only the steppers that carry it).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import warp as wp

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: results.py, the shared module
from results import recorded

# isort: split
from implicit_cost import use_krylov  # noqa: E402  (after the path: benchmarks/ first)
from precision_speed import float32_state  # noqa: E402
from rhs_throughput import build as tc5  # noqa: E402

from swe_sphere import STEPPERS, load_scene, make_stepper
from swe_sphere.core.tally import Tally, array_bytes, instrumented

HBM = {"H100": 3.35e12, "H200": 4.8e12}  # B/s: HBM3 (SXM) and HBM3e
EFFICIENCY = 0.7  # share of HBM bandwidth a streaming kernel reaches
LAUNCH_S = 4e-6  # host cost of one Warp kernel launch
KERNEL_GAP_S = 1e-6  # GPU-side gap between consecutive kernels
IMPLICIT = ("semi_implicit", "implicit", "imex")
CUDA_ON_CPU = {
    "np_": 4,
    "threads": 1,
    "device": "cpu",
    "per_element": False,
}  # TC5 (``tc5``) on np 4 in the CUDA layout, on the CPU

# Floating-point operations per point (np = 4, FMA = 2), counted by hand from
# kernels/: the ratio to the bytes shows every kernel far below an H100's
# FP64 ridge (≈ 34e12 / 3.35e12 ≈ 10 flop/B), i.e. bandwidth-bound.
FLOPS = {
    "tendency": 180,  # 4 × (14 continuity + 16 Bernoulli + 10 vorticity) + 20 pointwise finish
    "dss": 14,  # ≈ 2 · rows · copies (1.78 a node on average) + rows; 3 rows
    "dss_update": 26,  # the DSS's 14 and its combinations, ≈ 2 · rows · 2 terms (explicit stages)
    # 4 rows × (2 × 8 derivative + 6 gradient + 8 flux); the first pass forms the Cartesian wind
    # at the 2 np nodes it reads (10 a node)
    "laplacian_flux": 160,
    "laplacian_node": 92,  # 4 rows × (np × 4 + 1) of the weak divergence + 24 scaling (Y₁; Y₂'s shift: 9)
    "dss_apply": 27,  # 4 rows × 1.78 copies + 4 (unweighted DSS) + 16 (back to east/north, added)
    "axpby": 9,
    "axpbypcz": 15,
}


def count(args, tally):
    """{'rhs'|'hv'|stepper: (launches, bytes per point, syncs, kernels Counter, bytes Counter)} at args.ne,
    in ``args.precision`` (under "float32_state" the RHS of the float32 state, as its stages
    evaluate it, and the steppers that carry it)."""
    out = {}
    _, _, (_, _, x0), model = tc5(args.ne, precision=args.precision, **CUDA_ON_CPU)
    x, y = model.new_state(*x0), model.new_state()
    N = model.N
    state = (
        (float32_state(model, x), wp.zeros(x.shape, dtype=wp.float32)) if args.precision == "float32_state" else (x, y)
    )
    for name, fn in (("rhs", lambda: model.rhs(*state)), ("hv", lambda: model.hv.operator(x, y))):
        fn()  # records
        with tally.counting() as t:
            fn()
        out[name] = (t.total_launches, t.total_bytes / N, t.syncs, t.launches.copy(), t.bytes.copy())
    for name in steppers(args.precision):
        _, scene, (_, _, x0), model = tc5(
            args.ne,
            stepper=name,
            dt_factor=args.implicit_dt_factor if name in IMPLICIT else 1.0,
            precision=args.precision,
            **CUDA_ON_CPU,
        )
        stepper = make_stepper(name, model, scene.dt)
        use_krylov(stepper, "kernels")  # the Krylov vector work as on CUDA (on a CPU device it runs in numpy)
        out[name] = per_step(args, tally, stepper, model.new_state(*x0), N)
        if args.precision == "float32_state":  # and the float32 state kept between steps (``model.held``)
            _, _, (_, _, x0), model = tc5(
                args.ne, stepper=name, precision=args.precision, compensated=False, **CUDA_ON_CPU
            )
            out[f"{name}:kept"] = per_step(args, tally, make_stepper(name, model, scene.dt), model.held.new(x0), N)
    return out, N


def per_step(args, tally, stepper, x, N) -> tuple:
    """(launches, B/pt, syncs, launches by kernel, bytes by kernel) a step of ``stepper`` on the
    state x (N points), counted over ``args.steps`` steps after ``args.warmup``."""
    for _ in range(args.warmup):
        stepper.step(x)
    with tally.counting() as t:
        for _ in range(args.steps):
            stepper.step(x)
    s = args.steps
    return (t.total_launches / s, t.total_bytes / N / s, t.syncs / s, t.launches.copy(), t.bytes.copy())


def steppers(precision: str) -> list[str]:
    """The steppers counted in ``precision``: every one, but under "float32_state" those that carry it."""
    return [n for n, c in STEPPERS.items() if precision != "float32_state" or c.float32_state_refusal is None]


# the float32 state's conversions at a step's ends (``kernels.departure``)
CONVERSIONS = ("to_departure", "add_increment", "from_departure")


def kept_in_float32(counts, names, points_steps) -> None:
    """Print each stepper's B/pt a step under "float32_state" (compensated: the float64 state
    between steps), its two conversions (``CONVERSIONS``), and counted with the float32 state kept
    between steps (``numerics.compensated = false``, ``model.held``: no conversions at the step's
    ends; on TC5 HOMME's ∇⁴ every step through its float64 copy, whose two conversions are counted
    apart)."""
    print("\nThe float32 state kept between steps: B/pt a step, counted\n")
    print("| stepper | B/pt/step | conversions | kept in float32 | its ∇⁴ copy's conversions |")
    print("|---|---:|---:|---:|---:|")
    for name in names:
        bpp, by_kernel = counts[name][1], counts[name][4]
        kept, kept_by_kernel = counts[f"{name}:kept"][1], counts[f"{name}:kept"][4]
        conv, copy = (
            sum(b for key, b in k.items() if key.split("__")[0] in CONVERSIONS) / points_steps
            for k in (by_kernel, kept_by_kernel)
        )
        print(f"| {name} | {bpp:.0f} | {conv:.0f} | {kept:.0f} | {copy:.0f} |")


def cpu_check(ne, repeat):
    """Each launch of one RHS and one ∇⁴ in the CUDA layout on one CPU thread at ne:
    (kernel, CPU-clock µs median, B/pt counted, implied GB/s)."""
    _, _, (_, _, x0), model = tc5(ne, **CUDA_ON_CPU)
    x, y = model.new_state(*x0), model.new_state()
    model.rhs(x, y)
    model.hv.operator(x, y)
    rows = []
    for key in (k for k in model.launches.keys() if k[0] in ("rhs", "hvop")):
        for launch in model.launches.recorded(key):
            seen = array_bytes(launch.fwd_args, launch.kernel)
            times = []
            for _ in range(repeat):
                t0 = time.process_time()
                launch.launch()
                times.append(time.process_time() - t0)
            t = statistics.median(times)
            rows.append((launch.kernel.key, t * 1e6, sum(seen.values()) / model.N, sum(seen.values()) / t / 1e9))
    return rows


def points(ne):
    return 6 * ne * ne * 16


def predict(counts, name, ne, bw):
    """(GPU time, launch floor, step without graphs, step with graphs) in s of ``name`` (a key of
    ``counts``: the RHS, the ∇⁴ or a stepper) at ``ne`` np 4 on a card of ``bw`` B/s."""
    L, bpp, syncs, _, _ = counts[name]
    gpu = bpp * points(ne) / (EFFICIENCY * bw) + L * KERNEL_GAP_S
    floor = L * LAUNCH_S
    return gpu, floor, max(gpu, floor), gpu + (syncs + 1) * LAUNCH_S


def predictions(args, counts, names) -> None:
    """Print each card's predicted µs of ``names`` and TC5's simulated days a wall day."""
    print(
        f"\n## Predicted µs at {EFFICIENCY:.0%} of HBM: GPU time / launch floor ({LAUNCH_S * 1e6:g} µs a launch) / "
        "with one CUDA graph per sync-free segment; **bold**: launch-bound without graphs\n"
    )
    for gpu_name, bw in HBM.items():
        print(f"**{gpu_name} ({bw / 1e12:.2f} TB/s)**\n")
        print("| what | " + " | ".join(f"ne{ne} ({points(ne) / 1e6:.2f} M pts)" for ne in args.at) + " |")
        print("|---|" + "---:|" * len(args.at))
        for name in names:
            cells = []
            for ne in args.at:
                gpu, floor, _, graph = predict(counts, name, ne, bw)
                cell = f"{gpu * 1e6:.0f} / {floor * 1e6:.0f} / {graph * 1e6:.0f}"
                cells.append(f"**{cell}**" if floor > gpu else cell)
            print(f"| {name} | " + " | ".join(cells) + " |")
        print()
        print(
            "Simulated days per wall day for TC5 (the scene's Δt at each ne; semi_implicit, implicit, imex at "
            f"{args.implicit_dt_factor:g}× it), without / with graphs:\n"
        )
        dts = {ne: load_scene("tc5_mountain_homme", ne=ne, np_=4).dt for ne in args.at}
        print("| stepper | " + " | ".join(f"ne{ne} (Δt {dts[ne]:.1f} s)" for ne in args.at) + " |")
        print("|---|" + "---:|" * len(args.at))
        for name in names[2:]:
            cells = []
            for ne in args.at:
                dt = dts[ne] * (args.implicit_dt_factor if name in IMPLICIT else 1.0)
                _, _, plain, graph = predict(counts, name, ne, bw)
                cells.append(f"{dt / plain:,.0f} / {dt / graph:,.0f}")
            print(f"| {name} | " + " | ".join(cells) + " |")
        print()


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--ne", type=int, default=8, help="grid the counts are taken on (np 4)")
    p.add_argument("--at", type=int, nargs="+", default=[30, 120, 240], help="grids to predict (np 4)")
    p.add_argument("--steps", type=int, default=3)
    p.add_argument("--warmup", type=int, default=2)
    p.add_argument(
        "--check-ne", type=int, default=30, help="grid of the CPU check (each RHS and ∇⁴ launch timed alone); 0 to skip"
    )
    p.add_argument(
        "--implicit-dt-factor", type=float, default=4.0, help="Δt of semi_implicit, implicit, imex × TC5's explicit Δt"
    )
    p.add_argument(
        "--precision",
        choices=("float64", "float32", "float32_state"),
        default="float64",
        help="the model's (issue 128: each design's bytes; default %(default)s)",
    )
    args = p.parse_args(argv)
    # a precision's counts in a file of their own (results/gpu_model/gpu_model_<precision>.json)
    stem = None if args.precision == "float64" else f"gpu_model_{args.precision}"
    with recorded(__file__, stem):
        wp.config.quiet = True  # Warp < 1.10; newer Warp reads log_level (as tests/conftest.py)
        if hasattr(wp, "LOG_WARNING"):
            wp.config.log_level = wp.LOG_WARNING
        tally = Tally()
        with instrumented(tally):
            counts, N = count(args, tally)

        print(
            f"## Per kernel (counted at ne={args.ne} np=4, N={N}; bytes of each distinct array argument per point per launch)\n"
        )
        print("| kernel | B/pt per launch | flop/pt | flop/B | launches in one RHS | in one ∇⁴ |")
        print("|---|---:|---:|---:|---:|---:|")
        keys = sorted(set(counts["rhs"][3]) | set(counts["hv"][3]))
        for key in keys:
            n = counts["rhs"][3][key] + counts["hv"][3][key]
            bpp = (counts["rhs"][4][key] + counts["hv"][4][key]) / n / N
            fl = FLOPS.get(key.split("__")[0])
            print(
                f"| {key} | {bpp:.0f} | {fl if fl is not None else '–'} | {fl / bpp if fl else float('nan'):.2f} | "
                f"{counts['rhs'][3][key]} | {counts['hv'][3][key]} |"
            )
        if args.check_ne:
            print(
                f"\nCPU check: each launch alone at ne={args.check_ne} np=4, CUDA layout, one thread, CPU clock, median of 20\n"
            )
            print("| kernel | µs | B/pt | implied GB/s |")
            print("|---|---:|---:|---:|")
            for key, us, bpp, gbs in cpu_check(args.check_ne, 20):
                print(f"| {key.split('__')[0]} | {us:.0f} | {bpp:.0f} | {gbs:.1f} |")
        print(
            f"\nRHS: {counts['rhs'][1]:.0f} B/pt, {counts['rhs'][0]:.0f} launches; ∇⁴ (hv.operator, with its memset): "
            f"{counts['hv'][1]:.0f} B/pt, {counts['hv'][0]:.0f} launches; ∇⁴/RHS bytes {counts['hv'][1] / counts['rhs'][1]:.2f}\n"
        )

        print(
            f"## Per step (semi_implicit, implicit, imex at {args.implicit_dt_factor:g}× TC5's Δt; {args.steps} steps after {args.warmup})\n"
        )
        print("| stepper | launches/step | host syncs/step | B/pt/step | RHS-eq (bytes) |")
        print("|---|---:|---:|---:|---:|")
        names = ["rhs", "hv", *steppers(args.precision)]
        for name in names:
            L, bpp, syncs, _, _ = counts[name]
            print(f"| {name} | {L:.0f} | {syncs:.1f} | {bpp:.0f} | {bpp / counts['rhs'][1]:.1f} |")
        if args.precision == "float32_state":
            kept_in_float32(counts, names[2:], N * args.steps)

        predictions(args, counts, names)


if __name__ == "__main__":
    main()
