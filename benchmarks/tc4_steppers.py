"""TC4 (the forced translating low, exact solution) with every stepper at its documented Δt.

Explicit steppers at 80 % of their measured stability limit
(``Stepper.courant_limit``: (|v| + √(gh)) Δt/Δx at t = 0), rounded down to
a Δt that divides half a day; semi-implicit, implicit and IMEX at 4× and 10×
the explicit gravity-wave limit (the multiples their docstrings are measured
at), likewise rounded. Prints, per run: Δt, its multiple of the gravity-wave
limit, the normalized l2 errors of h and of the wind against the exact solution
at the last day, the temporal l2(h) error against RK4 at a tenth of the
smallest Δt on the same grid, RHS evaluations and wall time.

    python benchmarks/tc4_steppers.py --ne 16 --days 1
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import time

from swe_sphere.config import load_scene
from swe_sphere.constants import DAY
from swe_sphere.scoring import williamson_norms
from swe_sphere.simulation import BlowUp, Simulation
from swe_sphere.steppers import STEPPERS
from swe_sphere.sweep import dt_for_day, explicit_limits

RUNS = [  # (stepper, options, multiple of the gravity-wave limit or None: explicit at 0.8 × its limit)
    ("leapfrog", {}, None),
    ("leapfrog_trapezoidal", {}, None),
    ("ssprk3", {}, None),
    ("rk4", {}, None),
    ("semi_implicit", {}, 4),
    ("semi_implicit", {}, 10),
    ("imex", {}, 4),
    ("imex", {}, 10),
    ("imex", {"scheme": "ars232"}, 4),
    ("implicit", {}, 4),
    ("implicit", {}, 10),
    ("implicit", {"method": "bdf2"}, 4),
]


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--ne", type=int, default=16)
    p.add_argument("--np", type=int, default=4)
    p.add_argument("--days", type=float, default=1.0)
    args = p.parse_args()
    base = load_scene("tc4_forced_low", ne=args.ne, np=args.np, days=args.days)
    limits = explicit_limits(base, "cpu")
    half = min(0.5, args.days)
    sim0 = Simulation(dataclasses.replace(base, days=base.dt / DAY), "cpu", progress=False)
    c = sim0.courant()
    speed = (c["courant_advective"] + c["courant_gravity"]) / base.dt  # Courant number per second of Δt
    plan = []
    for stepper, options, multiple in RUNS:
        if multiple is None:
            dt = dt_for_day(0.8 * STEPPERS[stepper].courant_limit / speed, half)
        else:
            dt = dt_for_day(multiple * limits["dt_gravity"], half)
        plan.append((stepper, options, dt))
    ref_dt = dt_for_day(min(dt for _, _, dt in plan) / 10, half)

    def run(stepper, options, dt):
        scene = dataclasses.replace(base, stepper=stepper, stepper_options=options, dt=dt)
        sim = Simulation(scene, "cpu", progress=False)
        t0 = time.perf_counter()
        result = sim.run()
        return sim, result, time.perf_counter() - t0

    sim, _, _ = run("rk4", {}, ref_dt)
    ref = sim.x.numpy()[2].copy()
    print(f"TC4 ne{args.ne} np{args.np}, day {args.days:g}; gravity-wave limit {limits['dt_gravity']:.1f} s; "
          f"reference rk4 {ref_dt:.4g} s; load {os.getloadavg()[0]:.1f}")
    print(f"| stepper | options | Δt (s) | Δt / gw limit | l2(h) exact | l2(wind) exact | temporal l2(h) | RHS evals | wall (s) |")
    print("|---|---|---|---|---|---|---|---|---|")
    for stepper, options, dt in plan:
        opts = ", ".join(f"{k}={v}" for k, v in options.items()) or "defaults"
        try:
            sim, result, wall = run(stepper, options, dt)
        except BlowUp as err:
            print(f"| {stepper} | {opts} | {dt:.4g} | {dt / limits['dt_gravity']:.2f} | {err} | | | | |", flush=True)
            continue
        d = result.history[-1]
        temporal = williamson_norms(sim.grid, sim.x.numpy()[2], ref)["l2"]
        print(f"| {stepper} | {opts} | {dt:.4g} | {dt / limits['dt_gravity']:.2f} | {d['l2_h']:.3e} | {d['l2_wind']:.3e} | "
              f"{temporal:.3e} | {result.rhs_evals} | {wall:.1f} |", flush=True)


if __name__ == "__main__":
    main()
