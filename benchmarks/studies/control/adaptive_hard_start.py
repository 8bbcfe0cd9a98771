"""The stability suite's hard cases started far above their stable step under error control
(issue 64's target: finish without a blow-up, at ≤ 1.3× the cost of a run started at the right step).

For each case (``--cases``: TC5, TC6, inviscid TC6 and Galewsky, each over its scene's length,
ne ``--ne`` np 4) and each embedded pair (``--pairs``), three runs under ``time.control =
"error"`` at rtol ``--rtol``:

- from the pair's largest stable step (its measured Courant limit ``Stepper.courant_limit`` over
  the initial state's largest signal rate (|v| + sqrt(g h))/Δx, ``sweep.runs.explicit_limits``;
  an IMEX pair's ``advective_courant_limit`` over the largest |v|/Δx);
- from 5× that step with the default Courant cap (0.9 × the limit: the first step is cut to it);
- from 5× that step with the cap off (``time.cfl = false``): the error controller alone.

Printed per run: finished or the blow-up's line, accepted and rejected steps, CPU s (one
thread, ``time.process_time``), the ratio to the run from the stable step.

    SWE_SPHERE_THREADS=1 python benchmarks/studies/control/adaptive_hard_start.py [--ne 8] [--rtol 1e-4] [--pairs ...] [--results STEM]
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from adaptive_proportionality import build, run

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # benchmarks/: results.py, the shared module
from results import quiet_warp, recorded

from swe_sphere import STEPPERS, load_scene
from swe_sphere.model.diagnostics import courant_numbers
from swe_sphere.studies.sweep.runs import explicit_limits

CASES = ("tc5_mountain", "tc6_rossby_haurwitz", "tc6_rossby_haurwitz_inviscid", "galewsky")


def stable_dt(case: str, ne: int, pair: str) -> float:
    """The pair's largest stable Δt (s) at the case's start on ne np4: its Courant limit over
    the initial state's largest signal rate; an IMEX pair's (gravity waves implicit) its
    advective limit over the largest |v|/Δx."""
    cls = STEPPERS[pair]
    if cls.courant_limit is None:
        sim = build(case, ne, 1.0, pair)
        u, v, h = sim.x.numpy()
        return cls.advective_courant_limit / courant_numbers(sim.grid, u, v, h, 1.0, sim.g)["courant_advective"]
    base = build(case, ne, 1.0, pair).scene
    limits = explicit_limits(base, "cpu")
    rate = STEPPERS["leapfrog"].courant_limit / limits["dt_leapfrog"]  # (|v| + sqrt(g h)) / Δx, s⁻¹
    return STEPPERS[pair].courant_limit / rate


def one_case(case: str, args, out: dict) -> None:
    days = load_scene(case).days
    print(f"\n## {case} ne{args.ne} np4, {days:g} days, rtol {args.rtol:g}", flush=True)
    print(f"{'pair':10s} {'start':22s} {'first dt':>9s} {'finished':>8s} accepted rejected   CPU s  ratio")
    rows = {}
    for pair in args.pairs:
        dt = stable_dt(case, args.ne, pair)
        base = None
        for label, factor, cap in (("stable step", 1, None), ("5x, default cap", 5, None), ("5x, no cap", 5, False)):
            control = {"control": "error", "rtol": args.rtol} | ({} if cap is None else {"cfl": cap})
            r = run(case, args.ne, days, pair, dt=factor * dt, control=control)
            base = base or r["cpu"]
            done = "no" if r["blowup"] else "yes"
            print(
                f"{pair:10s} {label:22s} {factor * dt:9.1f} {done:>8s} {r['accepted']:8d} {r['rejected']:8d} "
                f"{r['cpu']:7.2f} {r['cpu'] / base:6.2f}",
                flush=True,
            )
            rows[f"{pair} {label}"] = {
                "first_dt": factor * dt,
                "blowup": r["blowup"],
                "accepted": r["accepted"],
                "rejected": r["rejected"],
                "cpu": r["cpu"],
                "ratio": r["cpu"] / base,
            }
    out[case] = {"days": days, "runs": rows}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--ne", type=int, default=8)
    parser.add_argument("--cases", nargs="+", default=list(CASES))
    parser.add_argument("--pairs", nargs="+", default=["bs32", "rdpk3sp35", "ssprk43", "dp54"])
    parser.add_argument("--rtol", type=float, default=1e-4)
    parser.add_argument("--results", help="results/adaptive_hard_start/<STEM>.json (default: the script's stem)")
    args = parser.parse_args()
    unknown = [pair for pair in args.pairs if pair not in STEPPERS]
    if unknown:
        parser.error(f"--pairs: unknown {', '.join(unknown)} (the steppers: swe-sphere list)")
    quiet_warp()
    with recorded(__file__, stem=args.results) as figures:
        print(f"load average at the start: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
        figures["rtol"], figures["ne"] = args.rtol, args.ne
        for case in args.cases:
            one_case(case, args, figures)
        print(f"load average at the end: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    main()
