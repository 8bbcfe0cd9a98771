"""What a step of the Runge–Kutta engine's steppers asks of the device: launches and bytes.

The named tables (ssprk3, rk4, kgu35, imex ARS(2,3,2) / ARS(3,4,3)), ARS(3,4,3) written as a
``tableau`` pair and the bundled example pairs, TC5 np 4, IMEX at 4× the explicit step. Per
stepper, one step after two (``swe_sphere.tally``: each distinct array's bytes once a launch,
memsets and copies included): RHS evaluations, CG iterations, launches and MB of the whole
step (the solves' own graphs off) and of its own work outside the solves and the ∇⁴.
``--rounds`` > 0: also ms a step, interleaved, median, CPU clock (run it single-threaded).
    SWE_SPHERE_THREADS=1 OMP_NUM_THREADS=1 python benchmarks/tableau_cost.py --ne 8
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from swe_sphere.config import load_scene  # noqa: E402
from swe_sphere.simulation import Simulation  # noqa: E402
from swe_sphere.tally import Tally, instrumented  # noqa: E402
from test_tableau import ars343_pair, example  # noqa: E402

STEPPERS = [
    ("ssprk3", "ssprk3", {}), ("rk4", "rk4", {}), ("kgu35", "kgu35", {}),
    ("imex ARS(2,3,2)", "imex", {"scheme": "ars232"}), ("imex ARS(3,4,3)", "imex", {"scheme": "ars343"}),
    ("tableau ARS(3,4,3)", "tableau", ars343_pair()),
    *((f"tableau {name}", "tableau", dict(example(name))) for name in ("ark2_gkc", "ark324l2sa")),
]


def counts(sim: Simulation, own: bool) -> tuple:
    """(launches, MB, RHS evaluations, Helmholtz iterations) of one step; ``own``: the solves and ∇⁴ apart."""
    tally = Tally()
    gw = getattr(sim.stepper, "gw", None)
    if own:
        if gw is not None:
            gw.solve = tally.paused(gw.solve)
        sim.model.hyperviscosity = tally.paused(sim.model.hyperviscosity)
    with instrumented(tally), tally.counting():
        stats = sim.stepper.step(sim.x)
    for obj, name in ((gw, "solve"), (sim.model, "hyperviscosity")):
        if obj is not None:
            vars(obj).pop(name, None)  # the class's method again
    return tally.total_launches, tally.total_bytes / 1e6, stats.rhs_evals, stats.iterations.get("helmholtz", 0)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--ne", type=int, default=8)
    p.add_argument("--steps", type=int, default=20, help="steps per stepper and round")
    p.add_argument("--rounds", type=int, default=0, help="timing rounds (0: counts only)")
    args = p.parse_args()
    base = load_scene("tc5_mountain", ne=args.ne, np=4)
    sims = {}
    for label, stepper, options in STEPPERS:
        dt = base.dt * (1 if stepper in ("ssprk3", "rk4", "kgu35") else 4)
        sim = Simulation(dataclasses.replace(base, stepper=stepper, stepper_options=options, dt=dt), "cpu", progress=False)
        if hasattr(sim.stepper, "gw"):
            sim.stepper.gw.graphable = False  # the solves' launches seen one by one
        for _ in range(2):  # record and compile outside the clock and the counts
            sim.stepper.step(sim.x)
        sims[label] = sim
    times = {label: [] for label in sims}
    for _ in range(args.rounds):
        for label, sim in sims.items():
            t0 = time.process_time()
            for _ in range(args.steps):
                sim.stepper.step(sim.x)
            times[label].append((time.process_time() - t0) / args.steps)
    print(f"TC5 ne{args.ne} np4, threads {os.environ.get('SWE_SPHERE_THREADS', 'default')}, load average {os.getloadavg()[0]:.2f}")
    print(f"{'stepper':24s} {'RHS':>4s} {'CG its':>7s} {'launches':>9s} {'MB':>8s} {'own launches':>13s} {'own MB':>8s}"
          + (f" {'ms/step':>8s}" if args.rounds else ""))
    for label, sim in sims.items():
        launches, mb, evals, its = counts(sim, own=False)
        own_launches, own_mb, _, _ = counts(sim, own=True)
        ms = f" {1e3 * statistics.median(times[label]):8.2f}" if args.rounds else ""
        print(f"{label:24s} {evals:4d} {its:7d} {launches:9d} {mb:8.2f} {own_launches:13d} {own_mb:8.2f}{ms}")


if __name__ == "__main__":
    main()
