"""Cost per RHS of a Butcher-table stepper against the built-in stepper of the same table.

ssprk3, rk4 and kgu35 written as tables (``stepper = "tableau"``, the tables of
tests/test_tableau.py) against the built-ins, and ARS(3,4,3) written as a pair
against ``imex``: TC5 np 4 (topography, ∇⁴), each stepper's step timed over
``--steps`` steps, the steppers interleaved round by round; per stepper the
median over rounds of the time a step and a RHS evaluation, and the ratio
table / built-in. CPU clock of this process (``time.process_time``); run it
single-threaded for figures that repeat on a shared machine. Then, per step, the
launches and the bytes they move (``swe_sphere.tally.Tally``: each distinct array argument
once): a table with the built-in's updates moves the same bytes in the same launches,
so a ratio away from 1 is the clock's noise, not the table.

    SWE_SPHERE_THREADS=1 OMP_NUM_THREADS=1 python benchmarks/tableau_cost.py --ne 16
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
from test_tableau import BUILT_IN, ars343_pair  # noqa: E402

from swe_sphere.tally import Tally, instrumented  # noqa: E402

PAIRS = [(name, {}, {"name": name, **BUILT_IN[name]}) for name in BUILT_IN] + [("imex", {"scheme": "ars343"}, ars343_pair())]


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--ne", type=int, default=16)
    p.add_argument("--steps", type=int, default=20, help="steps per stepper and round")
    p.add_argument("--rounds", type=int, default=5)
    args = p.parse_args()
    base = load_scene("tc5_mountain", ne=args.ne, np=4)
    sims = {}
    for name, builtin, table in PAIRS:
        dt = base.dt * (4 if name == "imex" else 1)  # IMEX at 4x the explicit step
        for label, stepper, options in ((name, name, builtin), (f"tableau({name})", "tableau", table)):
            scene = dataclasses.replace(base, stepper=stepper, stepper_options=options, dt=dt)
            sim = Simulation(scene, "cpu", progress=False)
            sim.stepper.step(sim.x)  # record and compile outside the clock
            sims[label] = sim
    times = {label: [] for label in sims}
    evals = {}
    for _ in range(args.rounds):
        for label, sim in sims.items():
            t0 = time.process_time()
            n = sum(sim.stepper.step(sim.x).rhs_evals for _ in range(args.steps))
            times[label].append((time.process_time() - t0) / args.steps)
            evals[label] = n / args.steps
    print(f"TC5 ne{args.ne} np4, {args.steps} steps x {args.rounds} rounds, CPU clock, threads "
          f"{os.environ.get('SWE_SPHERE_THREADS', 'default')}, load average {os.getloadavg()[0]:.2f}")
    tally, counts = Tally(), {}
    with instrumented(tally):  # after the timing: the wrappers cost host time
        for label, sim in sims.items():
            with tally.counting() as t:
                sim.stepper.step(sim.x)
            counts[label] = (t.total_launches, t.total_bytes / 1e6)
    print(f"{'stepper':22s} {'ms/step':>9s} {'RHS/step':>9s} {'ms/RHS':>8s} {'table/built-in':>15s} {'launches':>9s} {'MB/step':>8s}")
    for name, _, _ in PAIRS:
        ref = statistics.median(times[name]) / evals[name]
        for label in (name, f"tableau({name})"):
            step = statistics.median(times[label])
            per = step / evals[label]
            ratio = f"{per / ref:.3f}" if label != name else ""
            print(f"{label:22s} {1e3 * step:9.2f} {evals[label]:9.1f} {1e3 * per:8.2f} {ratio:>15s} {counts[label][0]:9d} {counts[label][1]:8.1f}")


if __name__ == "__main__":
    main()
