"""Local time stepping (``lts``) against the global explicit steppers on a refined mesh, TC5,
CPU clock, one thread: each stepper's largest Δt within an accuracy, and its CPU seconds per
simulated day there.

First a reference: RK4 at Δt = 86400/``--k-ref`` s over ``--days`` days of TC5 (the scene's
∇⁴). Then for each stepper the largest Δt = 86400/k s (whole steps a day; k bisected over
``--k-range``) whose run does not blow up and whose final depth is within ``--tol`` of the
reference's (max-norm, relative: the temporal error; at its stability limit a run that has
not blown up yet can be far off), and at that Δt the median CPU time (``time.process_time``
of ``Simulation.run``, one thread) of ``--rounds`` runs. The load average is printed.

    SWE_SPHERE_THREADS=1 OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 \\
        python benchmarks/studies/lts/lts_study.py --mesh PATH/mountain_10_x2.g --days 3
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # benchmarks/: results.py, the shared module
from results import positive, quiet_warp, recorded

from swe_sphere import BlowUp, Simulation, load_scene

DAY = 86400.0
STEPPERS = {  # label → (stepper, options)
    "rk4": ("rk4", {}),
    "kgu35": ("kgu35", {}),
    "ssprk3": ("ssprk3", {}),
    "lts MIS4a/rk4, 2 levels": ("lts", {"max_levels": 2}),
    "lts MIS4a/rk4, 3 levels": ("lts", {"max_levels": 3}),
    "lts MRI-GARK-ERK33a/rk4, 3 levels": ("lts", {"max_levels": 3, "method": "mri_gark_erk33a"}),
    "lts MIS4a/rk4, 3 levels, substeps 1": ("lts", {"max_levels": 3, "substeps": 1}),
    "lts MIS4a/rk4, 3 levels, substeps 2": ("lts", {"max_levels": 3, "substeps": 2}),
    "lts MRAB3, 1 level (AB3)": ("lts", {"method": "mrab3", "max_levels": 1}),
    "lts MRAB3, 2 levels": ("lts", {"method": "mrab3", "max_levels": 2}),
    "lts MRAB3, 3 levels": ("lts", {"method": "mrab3", "max_levels": 3}),
    "lts MRAB3, 2 levels, margin 1.3": ("lts", {"method": "mrab3", "max_levels": 2, "level_margin": 1.3}),
    "lts MRAB3, 3 levels, margin 1.3": ("lts", {"method": "mrab3", "max_levels": 3, "level_margin": 1.3}),
}


def run(mesh, days, stepper, options, k):
    """(final depth, CPU s, the Simulation) of TC5 at Δt = DAY/k; None if it blows up."""
    scene = load_scene("tc5_mountain", mesh=mesh, dt=DAY / k, days=days, stepper=stepper)
    sim = Simulation(dataclasses.replace(scene, stepper_options=options, output_every_days=days), "cpu", progress=False)
    start = time.process_time()
    try:
        sim.run(None)
    except BlowUp:
        return None
    return sim.fields()[2], time.process_time() - start, sim


def error(result, ref) -> float:
    """The final depth's max-norm difference from the reference's, relative (inf: blown up)."""
    return math.inf if result is None else float(np.abs(result[0] - ref).max() / np.abs(ref).max())


def largest_accurate(args, stepper, options, ref):
    """The least k in ``args.k_range`` (Δt = DAY/k) whose run is within ``args.tol`` of
    ``ref``, bisected (taken as monotone in Δt); None if the largest k is not."""
    lo, hi = args.k_range

    def bad(k) -> bool:  # blown up, or (unless --tol inf: stability alone) too far off
        result = run(args.mesh, args.days, stepper, options, k)
        return result is None or error(result, ref) > args.tol

    if bad(hi):
        return None
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if bad(mid):
            lo = mid
        else:
            hi = mid
    return hi


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--mesh", required=True)
    # whole days: every dt searched is a day over a whole number of steps (DAY / k)
    parser.add_argument("--days", type=positive(int), default=3)
    parser.add_argument("--k-range", type=int, nargs=2, default=(24, 480), help="steps a day searched")
    parser.add_argument("--k-ref", type=int, default=1920, help="the reference's steps a day")
    parser.add_argument(
        "--tol", type=float, default=1e-4, help="temporal error allowed (max-norm of h, relative; inf: stability alone)"
    )
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--only", nargs="*", help="these steppers' labels alone (and rk4, the reference)")
    args = parser.parse_args()
    quiet_warp()
    ref = run(args.mesh, args.days, "rk4", {}, args.k_ref)[0]
    rows = []
    for label, (stepper, options) in STEPPERS.items():
        if args.only and label != "rk4" and label not in args.only:
            continue
        k = largest_accurate(args, stepper, options, ref)
        if k is None:
            print(f"{label}: none within {args.tol:g}", flush=True)
            continue
        runs = [run(args.mesh, args.days, stepper, options, k) for _ in range(args.rounds)]
        cpu = statistics.median(r[1] for r in runs) / args.days
        levels = runs[0][2].stepper.describe()[0] if stepper == "lts" else ""
        rows.append((label, DAY / k, cpu, error(runs[0], ref), levels))
        print(f"{label}: dt {DAY / k:.1f} s, {cpu:.3f} CPU s/day", flush=True)
    print(
        f"\nTC5 {args.days:g} days on {os.path.basename(args.mesh)}, temporal error <= {args.tol:g} "
        f"(RK4 at {DAY / args.k_ref:g} s), load average {os.getloadavg()[0]:.2f}"
    )
    print(f"{'':36s} {'dt (s)':>8s} {'CPU s/day':>10s} {'/ rk4':>6s} {'error h':>10s}  levels")
    base = next(cpu for label, _, cpu, _, _ in rows if label == "rk4")
    for label, dt, cpu, err, levels in rows:
        print(f"{label:36s} {dt:8.1f} {cpu:10.3f} {cpu / base:6.2f} {err:10.2e}  {levels}")


if __name__ == "__main__":
    with recorded(__file__):
        main()
