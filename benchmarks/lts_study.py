"""Local time stepping (``lts``) against the global explicit steppers on a refined mesh, TC5,
CPU clock, one thread: each stepper's largest stable Δt, its CPU seconds per simulated day
there, and its temporal error.

For each stepper the largest stable Δt = 86400/k s (whole steps a day; k bisected over
``--k-range``) over ``--days`` days of TC5 (the scene's ∇⁴), then at that Δt the median CPU
time (``time.process_time`` of ``Simulation.run``, one thread) of ``--rounds`` runs, and the
final depth's max-norm difference from RK4 at a quarter of RK4's largest stable Δt (the
temporal error; nodes matched by position, as lts numbers a mesh's elements by level). The
load average is printed.

    SWE_SPHERE_THREADS=1 OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 \\
        python benchmarks/lts_study.py --mesh ../shared/meshes/mountain_10_x2.g --days 3
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import statistics
import time

import numpy as np

from swe_sphere.config.scene import load_scene
from swe_sphere.core.errors import BlowUp
from swe_sphere.core.runtime import init_warp
from swe_sphere.simulation.simulation import Simulation

DAY = 86400.0
STEPPERS = {  # label → (stepper, options)
    "rk4": ("rk4", {}),
    "kgu35": ("kgu35", {}),
    "ssprk3": ("ssprk3", {}),
    "lts MIS4a/rk4, 2 levels": ("lts", {"max_levels": 2}),
    "lts MIS4a/rk4, 3 levels": ("lts", {"max_levels": 3}),
    "lts MRI-GARK-ERK33a/rk4, 3 levels": ("lts", {"max_levels": 3, "method": "mri_gark_erk33a"}),
}


def run(mesh, days, stepper, options, k):
    """(final depth sorted by node position, CPU s, the Simulation) of TC5 at Δt = DAY/k; None if it blows up."""
    scene = load_scene("tc5_mountain", mesh=mesh, dt=DAY / k, days=days, stepper=stepper)
    sim = Simulation(dataclasses.replace(scene, stepper_options=options, output_every_days=days), "cpu", progress=False)
    start = time.process_time()
    try:
        sim.run(None)
    except BlowUp:
        return None
    cpu = time.process_time() - start
    g = sim.grid
    return sim.fields()[2][np.lexsort((np.round(g.lon, 9), np.round(g.lat, 9)))], cpu, sim


def largest_stable(mesh, days, stepper, options, lo, hi):
    """The least k in [lo, hi] (Δt = DAY/k) that runs ``days`` without blowing up, bisected
    (stability taken as monotone in Δt); None if hi does not."""
    if run(mesh, days, stepper, options, hi) is None:
        return None
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if run(mesh, days, stepper, options, mid) is None:
            lo = mid
        else:
            hi = mid
    return hi


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--mesh", required=True)
    parser.add_argument("--days", type=float, default=3.0)
    parser.add_argument("--k-range", type=int, nargs=2, default=(24, 480), help="steps a day searched")
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args()
    init_warp()
    found = {}
    for label, (stepper, options) in STEPPERS.items():
        found[label] = largest_stable(args.mesh, args.days, stepper, options, *args.k_range)
        print(
            f"{label}: largest stable dt {DAY / found[label]:.1f} s" if found[label] else f"{label}: none", flush=True
        )
    ref = run(args.mesh, args.days, "rk4", {}, 4 * found["rk4"])[0]
    print(f"\nTC5 {args.days:g} days on {os.path.basename(args.mesh)}, load average {os.getloadavg()[0]:.2f}")
    print(f"{'':36s} {'dt (s)':>8s} {'CPU s/day':>10s} {'/ rk4':>6s} {'temporal err h':>15s}  levels")
    base = None
    for label, (stepper, options) in STEPPERS.items():
        k = found[label]
        if k is None:
            continue
        runs = [run(args.mesh, args.days, stepper, options, k) for _ in range(args.rounds)]
        cpu = statistics.median(r[1] for r in runs) / args.days
        base = cpu if label == "rk4" else base
        err = np.abs(runs[0][0] - ref).max() / np.abs(ref).max()
        levels = runs[0][2].stepper.describe()[0] if stepper == "lts" else ""
        print(f"{label:36s} {DAY / k:8.1f} {cpu:10.3f} {cpu / base:6.2f} {err:15.3e}  {levels}")


if __name__ == "__main__":
    main()
