"""What a step asks of the device: launches and bytes, counted, and with ``--rounds`` its time.

TC5 np 4 (topography, ∇⁴) at ``--ne``. First one RHS, one slow evaluation N(x) and one fast
evaluation L z + ρ of the multirate split (``GravitySplit``). Then a step of each stepper:
the Runge–Kutta engine's tables (ssprk3, rk4, kgu35 at the scene's Δt; IMEX ARS(2,3,2) and
ARS(3,4,3), ARS(3,4,3) as a ``tableau`` pair and the bundled example pairs at 4× it) and the
multirate ``split_explicit`` and ``mri`` at 6 and 8 Δt_g (substeps "auto"): RHS evaluations,
CG iterations, fast evaluations, launches and MB of the whole step (the solves' own graphs
off, so that their CG launches count), of its own work outside the solves and the ∇⁴, and GB
a simulated day. One step after two (recorded and compiled outside the count), by
``swe_sphere.core.tally`` (each distinct array's bytes once a launch, memsets and copies
included). ``--rounds`` > 0: also ms an evaluation and a step, round-robin over all of them
so that load changes hit them alike, median, CPU clock (run it single-threaded).

    SWE_SPHERE_THREADS=1 OMP_NUM_THREADS=1 python benchmarks/micro/step/step_cost.py --ne 8
    SWE_SPHERE_THREADS=1 OMP_NUM_THREADS=1 python benchmarks/micro/step/step_cost.py --ne 30 --rounds 5
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

import warp as wp

sys.path.insert(0, str(Path(__file__).resolve().parents[3] / "tests" / "steppers"))  # test_tableau and test_imex
sys.path.insert(0, str(Path(__file__).resolve().parents[3] / "tests"))

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # benchmarks/: results.py, the shared module
from results import quiet_warp, recorded  # noqa: E402  (after the path: benchmarks/ first)
from test_tableau import ars343_pair, example  # noqa: E402

from swe_sphere import (
    Simulation,  # noqa: E402
    load_scene,  # noqa: E402
)
from swe_sphere.core.tally import Tally, instrumented  # noqa: E402
from swe_sphere.steppers.multirate import GravitySplit  # noqa: E402
from swe_sphere.studies.sweep import explicit_limits  # noqa: E402

DAY = 86400.0
# (label, stepper, options, Δt: a multiple of the scene's Δt, or with "g" of the gravity-wave limit)
RUNS = [
    ("ssprk3", "ssprk3", {}, 1),
    ("rk4", "rk4", {}, 1),
    ("kgu35", "kgu35", {}, 1),
    ("kgu35 @ 1.5 dt_g", "kgu35", {}, "1.5g"),
    ("imex ARS(2,3,2)", "imex", {"scheme": "ars232"}, 4),
    ("imex ARS(3,4,3)", "imex", {"scheme": "ars343"}, 4),
    ("tableau ARS(3,4,3)", "tableau", ars343_pair(), 4),
    *((f"tableau {name}", "tableau", dict(example(name)), 4) for name in ("ark2_gkc", "ark324l2sa")),
    *((f"{stepper} @ {m} dt_g", stepper, {}, f"{m}g") for stepper in ("split_explicit", "mri") for m in (6, 8)),
    ("mri mis2 fbrk32 @ 6 dt_g", "mri", {"method": "mis2", "inner": "fbrk32"}, "6g"),
]


def count(tally: Tally, call, sim=None) -> tuple:
    """(launches, MB) of ``call()``; with ``sim``: of its step outside the solves and the ∇⁴."""
    gw = getattr(sim.stepper, "helmholtz", None) if sim is not None else None
    paused = [(o, n) for o, n in ((gw, "solve"), (sim and sim.model, "hyperviscosity")) if o is not None]
    for obj, name in paused:
        setattr(obj, name, tally.paused(getattr(obj, name)))
    with tally.counting():
        out = call()
    for obj, name in paused:
        vars(obj).pop(name)  # the class's method again
    return tally.total_launches, tally.total_bytes / 1e6, out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--ne", type=int, default=8)
    p.add_argument("--steps", type=int, default=10, help="evaluations or steps a configuration and round")
    p.add_argument("--rounds", type=int, default=0, help="timing rounds (0: counts only)")
    args = p.parse_args()
    quiet_warp()  # quietly
    base = load_scene("tc5_mountain", ne=args.ne, np_=4)
    dt_g = explicit_limits(base, "cpu")["dt_gravity"]
    tally = Tally()
    with instrumented(tally):
        sim = Simulation(base, "cpu", progress=False)
        split = GravitySplit(sim.model)
        split.set_depth(sim.x)
        out, rho = wp.zeros_like(sim.x), wp.zeros_like(sim.x)
        calls = {
            "RHS": lambda: sim.model.rhs(sim.x, out),
            "slow evaluation": lambda: split.slow(sim.x, out),
            "fast evaluation": lambda: split.fast(sim.x, out, rho),
        }
        sims = {}
        for label, stepper, options, rule in RUNS:
            dt = DAY / math.ceil(DAY / (float(rule[:-1]) * dt_g)) if isinstance(rule, str) else base.dt * rule
            s = sims[label] = Simulation(
                dataclasses.replace(base, stepper=stepper, stepper_options=options, dt=dt), "cpu", progress=False
            )
            if hasattr(s.stepper, "helmholtz"):
                s.stepper.helmholtz.graphable = False  # the solves' launches seen one by one
            calls[label] = lambda s=s: s.stepper.step(s.x)
        for call in calls.values():  # record and compile outside the clock and the counts
            call(), call()
        times = {label: [] for label in calls}
        for _ in range(args.rounds):
            for label, call in calls.items():
                t0 = time.process_time()
                for _ in range(args.steps):
                    call()
                times[label].append((time.process_time() - t0) / args.steps)
        ms = {label: 1e3 * statistics.median(t) if t else math.nan for label, t in times.items()}
        print(
            f"TC5 ne{args.ne} np4, dt_g = {dt_g:.1f} s, threads {os.environ.get('SWE_SPHERE_THREADS', 'default')}, "
            f"load average {os.getloadavg()[0]:.2f}"
        )
        rhs = None
        for label in ("RHS", "slow evaluation", "fast evaluation"):
            launches, mb, _ = count(tally, calls[label])
            rhs = rhs or (mb, ms[label])
            print(
                f"{label:16s} {launches:4d} launches {mb:8.2f} MB ({mb / rhs[0]:.2f} RHS)"
                + (f" {ms[label]:8.3f} ms ({ms[label] / rhs[1]:.2f} RHS)" if args.rounds else "")
            )
        print(
            f"{'stepper':26s} {'dt/dt_g':>7s} {'RHS':>4s} {'CG its':>6s} {'fast':>5s} {'launches':>8s} {'MB':>8s} "
            f"{'own launches':>12s} {'own MB':>7s} {'GB/day':>7s}"
            + (f" {'ms/step':>8s} {'s/day':>6s}" if args.rounds else "")
        )
        for label, s in sims.items():
            launches, mb, stats = count(tally, calls[label])
            own_launches, own_mb, _ = count(tally, calls[label], s)
            steps = DAY / s.scene.dt
            it = stats.iterations
            print(
                f"{label:26s} {s.scene.dt / dt_g:7.2f} {stats.rhs_evals:4d} {it.get('helmholtz', ''):>6} {it.get('fast', ''):>5} "
                f"{launches:8d} {mb:8.2f} {own_launches:12d} {own_mb:7.2f} {mb * steps / 1e3:7.2f}"
                + (f" {ms[label]:8.2f} {ms[label] * steps / 1e3:6.2f}" if args.rounds else "")
            )


if __name__ == "__main__":
    with recorded(__file__):
        main()
