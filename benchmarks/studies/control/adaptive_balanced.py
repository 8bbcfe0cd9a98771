"""The balanced step control (``control = "balanced"``, issue 64's "a run that asks for an
accuracy") against the efficiency study's verdict: does one run at ``time.balance`` = f keep its
temporal error at about f of the spatial one, and what does it cost against the sweep's
cheapest qualifying fixed-Δt run?

    SWE_SPHERE_THREADS=1 OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 \\
        python benchmarks/studies/control/adaptive_balanced.py [--ne 16] [--cases tc5 tc6 galewsky] [--balances 0.1]

Every run in this process at ``--ne`` np4 over the sweep's lengths (TC5 15 days, TC6 14,
Galewsky 6; docs/explanation/efficiency/sweep.md), one thread, its CPU clock
(``time.process_time`` of ``Simulation.run``, each stepper warmed by a short run first); no run
file written; the helpers are ``adaptive_proportionality.py``'s. For each case:

- the **reference**: rk4 at Δt_g/4 (the sweep's; Δt_g the gravity-wave limit of the initial
  state, cut to divide 3 h); its h + hs l2 (Williamson et al. 1992, eq. 83) against the case's
  T213 run is the spatial error, and a run's temporal error is its final h + hs against the
  reference's: it qualifies at ≤ 10 % of the spatial error (the sweep's criterion);
- the sweep's **cheapest qualifying fixed run** at ne16 on h + hs (``--fixed``: TC5 rk4 @ 0.69,
  TC6 kgu35 @ 1.6, Galewsky fbrk32 @ 1.3, multiples of Δt_g), rerun here;
- each pair of ``--pairs`` under ``control = "balanced"`` at each f of ``--balances`` (the
  default cap): its temporal error, the ratio to the spatial error (the mode's aim: f), the
  accepted and rejected steps, the smallest, mean and largest Δt, CPU s, and the CPU ratio to
  the fixed run.

Written to ``results/adaptive_balanced.json`` (``--results``: another name).
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from adaptive_proportionality import build, fixed_dt, run, temporal

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # benchmarks/: results.py, the shared module
from results import quiet_warp, recorded

CASES = {  # label: (scene, days, the sweep's cheapest qualifying fixed run at ne16 on h + hs)
    "tc5": ("tc5_mountain", 15.0, "rk4@0.69"),
    "tc6": ("tc6_rossby_haurwitz", 14.0, "kgu35@1.6"),
    "galewsky": ("galewsky", 6.0, "fbrk32@1.3"),
}


def case_runs(args, label: str, out: dict) -> None:
    scene, days, fixed = CASES[label]
    over = {"case.reference": "T213"}
    probe = build(scene, args.ne, days, "rk4", overrides=over)
    dt_ref, dt_g = fixed_dt(probe, 0.25)
    ref = run(scene, args.ne, days, "rk4", dt=dt_ref, overrides=over)
    spatial = ref["diagnostics"]["ref_l2_h_surface"]
    print(
        f"\n## {scene} ne{args.ne} np4, {days:g} days (Δt_g {dt_g:.1f} s): reference rk4 at {dt_ref:.1f} s, "
        f"{ref['accepted']} steps; spatial error (h + hs against T213) {spatial:.3e}, 10 % of it {0.1 * spatial:.3e}",
        flush=True,
    )
    print(f"{'run':22s} {'temporal':>10s} {'/spatial':>8s} ok accepted rejected  dt min/mean/max (s)   CPU s  ratio")
    stepper, multiple = fixed.split("@")
    dt, _ = fixed_dt(probe, float(multiple))
    r = run(scene, args.ne, days, stepper, dt=dt, overrides=over)
    base = r["cpu"]
    rows = {fixed: _line(fixed, r, ref, spatial, base)}
    for pair in args.pairs:
        for f in args.balances:
            control = {"control": "balanced", "balance": f}
            r = run(scene, args.ne, days, pair, control=control, overrides=over)
            rows[f"{pair}@balance={f:g}"] = _line(f"{pair} balance {f:g}", r, ref, spatial, base)
    out[label] = {"days": days, "spatial": spatial, "reference_dt": dt_ref, "dt_g": dt_g, "runs": rows}


def _line(name, r, ref, spatial, base) -> dict:
    e = temporal(r, ref)
    row = {"temporal": e, "ratio": e / spatial, "qualifies": e <= 0.1 * spatial, "accepted": r["accepted"]}
    row |= {"rejected": r["rejected"], "dt": r["dt"], "cpu": r["cpu"], "cpu_ratio": r["cpu"] / base}
    dt = "/".join(f"{x:.0f}" for x in r["dt"])
    ok = "yes" if row["qualifies"] else "no"
    print(
        f"{name:22s} {e:10.3e} {e / spatial:8.3f} {ok:>3s} {r['accepted']:8d} {r['rejected']:8d}  {dt:20s} "
        f"{r['cpu']:7.2f} {r['cpu'] / base:6.2f}",
        flush=True,
    )
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--ne", type=int, default=16)
    parser.add_argument("--cases", nargs="+", default=list(CASES), choices=list(CASES))
    parser.add_argument("--pairs", nargs="+", default=["rk43", "kgu352"])
    parser.add_argument("--balances", nargs="+", type=float, default=[0.1])
    parser.add_argument("--results", help="the results file's stem (default adaptive_balanced)")
    args = parser.parse_args()
    quiet_warp()
    with recorded(__file__, stem=args.results) as figures:
        print(f"load average at the start: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
        for stepper in ("rk4", "kgu35", "fbrk32", *args.pairs):  # compiled before any timing
            run("tc5_mountain", args.ne, 0.25, stepper)
        for pair in args.pairs:
            run("tc5_mountain", args.ne, 0.25, pair, control={"control": "balanced"})
        for label in args.cases:
            case_runs(args, label, figures)
        print(f"load average at the end: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    main()
