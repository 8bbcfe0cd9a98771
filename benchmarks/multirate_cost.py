"""What a multirate step asks of the device, counted: launches and the bytes they move
(``swe_sphere.tally.Tally``: each distinct array argument once a launch) per step and per
simulated day, for ``split_explicit`` and ``mri`` at slow steps of a few Δt_g beside the
explicit ``kgu35`` at 1.5 Δt_g, on TC5 np 4 (topography, ∇⁴); and one RHS, one slow
evaluation and one fast evaluation L z + ρ. Counts, not times: the same on any machine and,
every array scaling with N, at any ne (a fast evaluation's time at ne30 wants an idle machine).

    SWE_SPHERE_THREADS=1 python benchmarks/multirate_cost.py --ne 8
"""

from __future__ import annotations

import argparse
import dataclasses
import math

import warp as wp

from swe_sphere.config import load_scene
from swe_sphere.runtime import init_warp
from swe_sphere.simulation import Simulation
from swe_sphere.steppers.multirate import GravitySplit
from swe_sphere.sweep import explicit_limits
from swe_sphere.tally import Tally, instrumented

DAY = 86400.0
RUNS = [("kgu35", {}, 1.5), ("split_explicit", {}, 6.0), ("split_explicit", {}, 8.0), ("mri", {}, 6.0), ("mri", {}, 8.0),
        ("mri", {"method": "mis2", "inner": "fbrk32"}, 6.0)]


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--ne", type=int, default=8)
    args = p.parse_args()
    init_warp()  # quietly
    base = load_scene("tc5_mountain", ne=args.ne, np=4)
    dt_g = explicit_limits(base, "cpu")["dt_gravity"]
    tally = Tally()
    print(f"TC5 ne{args.ne} np4, dt_g = {dt_g:.1f} s")
    with instrumented(tally):
        sim = Simulation(base, "cpu", progress=False)
        split = GravitySplit(sim.model)
        split.set_depth(sim.x)
        out, rho = wp.zeros_like(sim.x), wp.zeros_like(sim.x)
        rhs_bytes = None
        for name, call in (("RHS", lambda: sim.model.rhs(sim.x, out)), ("slow evaluation", lambda: split.slow(sim.x, out)),
                           ("fast evaluation", lambda: split.fast(sim.x, out, rho))):
            call()  # recorded outside the count
            with tally.counting():
                call()
            rhs_bytes = rhs_bytes or tally.total_bytes
            print(f"{name:18s} {tally.total_launches:4d} launches {tally.total_bytes / 1e6:8.2f} MB ({tally.total_bytes / rhs_bytes:.2f} RHS)")
        print(f"{'stepper':48s} {'dt/dt_g':>7s} {'launches':>9s} {'MB/step':>8s} {'steps/day':>9s} {'GB/day':>7s}")
        for stepper, options, multiple in RUNS:
            dt = DAY / math.ceil(DAY / (multiple * dt_g))
            sim = Simulation(dataclasses.replace(base, stepper=stepper, stepper_options=options, dt=dt), "cpu", progress=False)
            sim.stepper.step(sim.x)  # the first step reads the mean depth and records
            with tally.counting():
                sim.stepper.step(sim.x)
            label = sim.stepper.label(options)
            steps = DAY / dt
            print(f"{label:48s} {dt / dt_g:7.2f} {tally.total_launches:9d} {tally.total_bytes / 1e6:8.1f} {steps:9.0f} "
                  f"{tally.total_bytes * steps / 1e9:7.2f}")


if __name__ == "__main__":
    main()
