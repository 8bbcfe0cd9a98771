"""A roofline of the Helmholtz product (M + cK) y and of the CG iteration, per launch.

For each grid (TC5 at np4) and thread count, in one interleaved run: every
launch of a CG iteration in float64 and in float32 (``HelmholtzCG``):
``helmholtz_gradient``, ``helmholtz_divergence`` (with the DSS of the gradient
inside), ``helmholtz_assemble``, the vector update ``cg_update`` and, for scale,
a launch over one node (the launch overhead). Per launch: the bytes it must move
(each array it reads or writes counted once: the compulsory traffic) and the flops
a node (an FMA is 2), both from the kernels' code; the median time; the bytes'
rate; and the same bytes at this machine's stream-triad rate measured alongside
(numpy, a working set inside the L3 cache and one far outside it).

Then a whole solve of the semi-implicit Schur complement (``HelmholtzSolver.solve``, as the
steppers call it: its right-hand side, the CG from zero, the mean's correction and the
back-substitution; a replayed graph on one thread) at five tolerances, and a
least-squares line through (CG iterations k, ms): its slope is an iteration's cost and
its intercept the solve's fixed cost, also given in iterations (the target: a solve of
k iterations costs ≤ k + 1 products).

What it says: a launch at the triad's rate is bound by bandwidth; one far below
it, whose float32 form (half the bytes) is no faster, by the instructions around
its gathers (``gid``, the DSS table) and its branches; one whose time stays as
the grid shrinks, by launch overhead.

    SWE_SPHERE_THREADS=1 python benchmarks/micro/step/helmholtz_roofline.py --clock cpu
    SWE_SPHERE_THREADS=2 python benchmarks/micro/step/helmholtz_roofline.py --clock wall --threads 2
    SWE_SPHERE_THREADS=1 python benchmarks/micro/step/helmholtz_roofline.py --clock cpu --ne 30 --solve-only
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np
import warp as wp

wp.config.quiet = True

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # benchmarks/: results.py, the shared module
from results import recorded  # noqa: E402  (after the path: benchmarks/ first)

from swe_sphere import (  # noqa: E402
    Simulation,  # noqa: E402
    load_scene,  # noqa: E402
)
from swe_sphere.model.helmholtz_cg import HelmholtzCG  # noqa: E402

TYPES = {"f64": wp.float64, "f32": wp.float32}


def traffic(np_: int, copies: int, N: int, nu: int, size: int) -> dict:
    """Launch → (bytes, flops) of one launch: every array read or written once (index
    arrays int32), flops counted from the kernels (an FMA as 2)."""
    i4 = 4
    return {
        # y through gid; Dinv (4), spheremp; wg (2) written
        "gradient": (nu * size + N * i4 + N * (4 + 1 + 2) * size, N * (4 * np_ + 8)),
        # wg (2) over the DSS table; rspheremp, y through gid, Dinv (4), metdet, spheremp; z written
        "divergence": (
            N * copies * i4 + N * i4 + nu * size + N * (2 + 1 + 4 + 1 + 1 + 1) * size,
            N * (4 * np_ + 2 * copies + 15),
        ),
        # wz through first and its table rows; y read, out written
        "assemble": (nu * (1 + copies) * i4 + N * size + 2 * nu * size, nu * (copies + 2)),
        # p, s, x, r, u, w, minv read; p, s, x, r, u written
        "cg_update": (12 * nu * size, 13 * nu),
    }


def triad(n: int, clock, repeat: int = 20) -> float:
    """GB/s of numpy's a = b + s·c over n float64 (3 arrays of n), median of ``repeat``."""
    a, b, c = np.zeros(n), np.ones(n), np.ones(n)
    times = []
    for _ in range(repeat):
        t0 = clock()
        np.multiply(c, 1.5, out=a)
        np.add(a, b, out=a)
        times.append(clock() - t0)
    return 4 * 8 * n / statistics.median(times) / 1e9  # c read, a written, a and b read


def launches(cg: HelmholtzCG, c: float) -> dict:
    """Name → the recorded launch of one CG iteration's product (u → w) and update."""
    cg.apply(cg.u, cg.w, c)  # records and sets c
    ops = [op for op in cg._operator(cg.u, cg.w) if hasattr(op, "kernel")]  # no exchanges on one rank
    return {"gradient": ops[0], "divergence": ops[1], "assemble": ops[2], "cg_update": cg._update}


def solve_cost(sim: Simulation, clock, repeat: int) -> tuple[list, float, float]:
    """[(k, ms)] of whole cold solves (IMEX ARS(3,4,3)'s at 8 Δt_g) at five tolerances (median of ``repeat`` rounds of 5),
    and the line ms = fixed + k·per_iteration through them: (rows, per_iteration, fixed)."""
    gw = sim.stepper.helmholtz
    sim.stepper.step(sim.x)  # H fixed, the step's graphs made
    gw.iterations()
    gw.warm = False
    r, z = wp.clone(sim.x), wp.zeros_like(sim.x)
    a = 0.4358665 * 8.0 * sim.scene.dt / sim.courant()["courant_gravity"]  # ARS(3,4,3)'s γΔt at 8 Δt_g
    rows = []
    for i, tol in enumerate((1e-1, 1e-3, 1e-5, 1e-7, 1e-9)):
        gw.tol, scale = tol, 1.0 + 1e-3 * i  # a graph of its own per tolerance (its key holds the scale)
        gw.solve(r, a, z, scale)
        k = gw.iterations()
        times = []
        for _ in range(repeat):
            t0 = clock()
            for _ in range(5):
                gw.solve(r, a, z, scale)
            wp.synchronize_device(sim.model.device)
            times.append((clock() - t0) / 5)
        gw.iterations()
        rows.append((k, statistics.median(times) * 1e3))
    k, ms = np.array(rows).T
    per_iteration, fixed = np.polyfit(k, ms, 1)
    return rows, per_iteration, fixed


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--ne", type=int, nargs="+", default=[16, 30, 60])
    ap.add_argument("--repeat", type=int, default=15, help="rounds (each times every launch --inner times)")
    ap.add_argument("--inner", type=int, default=20)
    ap.add_argument("--clock", choices=("cpu", "wall"), default="cpu")
    ap.add_argument("--threads", type=int, default=int(os.environ.get("SWE_SPHERE_THREADS", "1")))
    ap.add_argument("--solve-only", action="store_true", help="only the whole solve's cost (no launch table)")
    args = ap.parse_args()
    os.environ["SWE_SPHERE_THREADS"] = str(args.threads)
    clock = time.process_time if args.clock == "cpu" else time.perf_counter
    print(f"clock {args.clock}, {args.threads} thread(s), load average {os.getloadavg()[0]:.2f}")
    l3, dram = triad(500_000, clock), triad(40_000_000, clock, 5)
    print(f"stream triad (numpy): {l3:.1f} GB/s in cache (12 MB), {dram:.1f} GB/s from DRAM (960 MB)")
    for ne in args.ne:
        sim = Simulation(load_scene("tc5_mountain", ne=ne, stepper="imex"), "cpu", progress=False)
        m, topo = sim.model, sim.model.topology
        rows, per_iteration, fixed = solve_cost(sim, clock, args.repeat // 2 + 1)
        print(
            f"\nne {ne}: whole solves (CG iterations, ms): {', '.join(f'({k}, {ms:.2f})' for k, ms in rows)}; "
            f"an iteration {per_iteration:.3f} ms, fixed {fixed:.3f} ms = {fixed / per_iteration:.2f} iterations"
        )
        if args.solve_only:
            continue
        cgs = {name: (sim.stepper.helmholtz.cg if t is wp.float64 else HelmholtzCG(m, t)) for name, t in TYPES.items()}
        rng = np.random.default_rng(0)
        runs = {}
        for name, cg in cgs.items():
            cg.u.assign(rng.standard_normal(topo.nunique).astype(np.float32 if name == "f32" else np.float64))
            runs[name] = launches(cg, 1e9)
        tiny = wp.launch(_noop, 1, [wp.zeros(1, dtype=wp.float64)], device="cpu", record_cmd=True)
        times = {(name, k): [] for name in runs for k in runs[name]} | {("", "one-node launch"): []}
        for _ in range(args.repeat):
            for name, ls in runs.items():
                for k, launch in ls.items():
                    t0 = clock()
                    for _ in range(args.inner):
                        launch.launch()
                    times[(name, k)].append((clock() - t0) / args.inner)
            t0 = clock()
            for _ in range(args.inner):
                tiny.launch()
            times[("", "one-node launch")].append((clock() - t0) / args.inner)
        print(
            f"\nne {ne} np 4: N = {m.N} element-local nodes, {topo.nunique} unique, DSS table {topo.table.shape[1]} copies a node"
        )
        print(
            f"{'launch':<12} {'type':<4} {'ms':>7} {'MB':>6} {'GB/s':>6} {'B/node':>7} {'flop/node':>9} {'at L3 triad ms':>15} {'f32/f64':>8}"
        )
        for k in runs["f64"]:
            for name, t in TYPES.items():
                size = 8 if t is wp.float64 else 4
                nbytes, flops = traffic(4, topo.table.shape[1], m.N, topo.nunique, size)[k]
                ms = statistics.median(times[(name, k)]) * 1e3
                ratio = ms / (statistics.median(times[("f64", k)]) * 1e3)
                print(
                    f"{k:<12} {name:<4} {ms:7.3f} {nbytes / 1e6:6.2f} {nbytes / ms / 1e6:6.1f} {nbytes / m.N:7.1f} {flops / m.N:9.1f} "
                    f"{nbytes / l3 / 1e6:15.3f} {ratio:8.2f}"
                )
        print(f"one-node launch   {statistics.median(times[('', 'one-node launch')]) * 1e3:7.4f} ms")


@wp.kernel
def _noop(x: wp.array(dtype=wp.float64)):
    x[wp.tid()] = x[wp.tid()] + wp.float64(1.0)


if __name__ == "__main__":
    with recorded(__file__):
        main()
