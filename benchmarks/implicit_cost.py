"""What the large-step steppers cost per simulated day, against ssprk3 (ISSUE 10).

TC5 (Williamson 1992 test case 5, all terms with hyperviscosity) at each
``--ne`` (np = 4), Δt = ``--factors`` × the gravity-wave limit dt_g (the
Courant-1 step min Δx / max sqrt(g h) of the initial state). One interleaved
run: every configuration is built and warmed up (``--warmup`` steps from the
initial state), then the timed steps go round-robin over the configurations,
so load changes hit them alike; medians are quoted.

Per configuration: Newton iterations per step, GMRES iterations per Newton,
preconditioner applications and Helmholtz iterations per step, RHS
evaluations per step, RHS-eq per step (ms per step / ms of one RHS, the RHS
timed in the same rounds), ms per step, and the cost per simulated day
relative to ssprk3 at its largest stable step (found by ``stable_ssprk3_dt``:
the largest of 1.0, 0.95, 0.9, ... × dt_g that runs ``--stable-days`` days).

    python benchmarks/implicit_cost.py --ne 16 30 --factors 1 4 10 30
"""

from __future__ import annotations

import argparse
import dataclasses
import platform
import statistics
import time

import numpy as np
import warp as wp
from threadpoolctl import threadpool_limits

wp.config.quiet = True

from swe_sphere.config import load_scene  # noqa: E402
from swe_sphere.constants import DAY  # noqa: E402
from swe_sphere.simulation import BlowUp, Simulation  # noqa: E402

# (label, stepper, options); a label's configuration runs at every factor
CONFIGS = [
    ("semi_implicit", "semi_implicit", {}),
    ("implicit cg 1e-2", "implicit", {}),
    ("implicit none", "implicit", {"preconditioner": "none"}),
    ("implicit vcycle", "implicit", {"helmholtz_solver": "vcycle"}),
    ("implicit amg 1e-2", "implicit", {"helmholtz_solver": "amg"}),
    ("implicit cheb8", "implicit", {"helmholtz_solver": "chebyshev"}),
    ("semi_implicit amg", "semi_implicit", {"helmholtz_solver": "amg"}),
    ("imex ars343", "imex", {"scheme": "ars343"}),
    ("imex ars232", "imex", {"scheme": "ars232"}),
    # the matrix-free Helmholtz CG that runs over MPI ranks, on one
    ("semi_implicit mf_cg", "semi_implicit", {"helmholtz_solver": "mf_cg"}),
    ("implicit mf_cg 1e-2", "implicit", {"helmholtz_solver": "mf_cg"}),
    ("imex ars343 mf_cg", "imex", {"scheme": "ars343", "helmholtz_solver": "mf_cg"}),
]


def scene(ne, stepper, dt, options, days=1.0):
    base = load_scene("tc5_mountain", ne=ne, np=4, days=days)
    return dataclasses.replace(base, stepper=stepper, dt=dt, stepper_options=options, output_every_days=days)


def gravity_limit(ne) -> float:
    base = load_scene("tc5_mountain", ne=ne, np=4, days=1.0)
    return base.dt / Simulation(base, "cpu", progress=False).courant()["courant_gravity"]


def stable_ssprk3_dt(ne, dt_g, days) -> float:
    for f in (1.0, 0.95, 0.9, 0.85, 0.8, 0.7, 0.6):
        n = int(np.ceil(days * DAY / (f * dt_g)))
        try:
            result = Simulation(scene(ne, "ssprk3", days * DAY / n, {}, days), "cpu", progress=False).run()
        except BlowUp:
            continue
        if result.blowup is None:
            return days * DAY / n
    raise RuntimeError("ssprk3 unstable at 0.6 dt_g")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--ne", type=int, nargs="+", default=[16, 30])
    ap.add_argument("--factors", type=float, nargs="+", default=[1, 4, 10, 30])
    ap.add_argument("--steps", type=int, default=3, help="timed steps per configuration")
    ap.add_argument("--warmup", type=int, default=2, help="untimed steps per configuration first")
    ap.add_argument("--stable-days", type=float, default=2.0)
    ap.add_argument("--only", nargs="*", default=None, help="labels to run (default all)")
    args = ap.parse_args()
    threadpool_limits(1)  # as Simulation.run: BLAS threads would fight the model's
    print(f"# {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, {platform.node()}, {platform.processor() or platform.machine()}")
    configs = [c for c in CONFIGS if args.only is None or c[0] in args.only]
    for ne in args.ne:
        dt_g = gravity_limit(ne)
        dt_ssp = stable_ssprk3_dt(ne, dt_g, args.stable_days)
        runs = [("ssprk3", dt_ssp / dt_g, Simulation(scene(ne, "ssprk3", dt_ssp, {}), "cpu", progress=False))]
        for label, stepper, options in configs:
            for f in args.factors:
                try:
                    runs.append((label, f, Simulation(scene(ne, stepper, f * dt_g, options), "cpu", progress=False)))
                except ValueError as err:
                    print(f"# {label} at {f:g}x: {err}")
        stats = {i: [] for i in range(len(runs))}
        failed = {}
        for i, (label, f, sim) in enumerate(runs):
            try:
                for _ in range(args.warmup):
                    sim.stepper.step(sim.x)
            except Exception as err:  # a failed configuration is reported, not fatal
                failed[i] = str(err).split("\n")[0]
        rhs_ms = []
        sim0 = runs[0][2]
        out = wp.zeros_like(sim0.x)
        for _ in range(args.steps):
            t0 = time.perf_counter()
            for _ in range(5):
                sim0.model.rhs(sim0.x, out)
            rhs_ms.append((time.perf_counter() - t0) / 5 * 1e3)
            for i, (label, f, sim) in enumerate(runs):
                if i in failed:
                    continue
                try:
                    t0 = time.perf_counter()
                    st = sim.stepper.step(sim.x)
                    stats[i].append(((time.perf_counter() - t0) * 1e3, st))
                except Exception as err:
                    failed[i] = str(err).split("\n")[0]
        rhs = statistics.median(rhs_ms)
        print(f"\nne={ne} np=4: dt_g = {dt_g:.1f} s, ssprk3 at {dt_ssp:.1f} s = {dt_ssp / dt_g:.2f} dt_g, "
              f"RHS {rhs:.3f} ms (median), {args.steps} timed steps after {args.warmup}")
        print("| stepper | Δt/dt_g | Newton/step | GMRES/Newton | precond/step | Helmholtz its/step | RHS/step | RHS-eq/step | ms/step | cost/day vs ssprk3 |")
        print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
        ref = None
        for i, (label, f, sim) in enumerate(runs):
            if i in failed:
                print(f"| {label} | {f:g} | failed: {failed[i]} |||||||||")
                continue
            ms = statistics.median(s[0] for s in stats[i])
            it = {k: statistics.mean(s[1].iterations.get(k, 0) for s in stats[i]) for k in ("newton", "gmres", "precond", "helmholtz")}
            nrhs = statistics.mean(s[1].rhs_evals for s in stats[i])
            per_day = ms / sim.scene.dt
            ref = per_day if ref is None else ref
            newton = it["newton"]
            gpn = it["gmres"] / newton if newton else float("nan")
            print(f"| {label} | {f:.2f} | {newton:.1f} | {gpn:.1f} | {it['precond']:.1f} | {it['helmholtz']:.1f} | {nrhs:.1f} | "
                  f"{ms / rhs:.0f} | {ms:.1f} | {per_day / ref:.2f} |")


if __name__ == "__main__":
    main()
