"""Error-controlled steps at ne30 (issue 64's target): at the loosest tolerance whose temporal
error meets the sweep's 10 % criterion, CPU time per simulated day against the cheapest
qualifying fixed-Δt run, on TC5 and Galewsky, and the share of steps rejected; Galewsky's Δt
over time from the same runs.

    SWE_SPHERE_THREADS=1 OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 \\
        python benchmarks/studies/control/adaptive_ne30.py [--cases tc5 galewsky] [--tc5-days 5] [--galewsky-days 6]

Every run in this process at ne30 np4 (given, not the scenes' grids), one thread, its CPU clock
(``time.process_time`` of ``Simulation.run``; each stepper warmed first by a short run); no run
file written; the runs and helpers are ``adaptive_proportionality.py``'s. For each case:

- the **reference**: ``dp54`` at rtol ``--rtol-ref``; its h + hs l2 (Williamson et al. 1992,
  eq. 83) against the case's T213 run (Galewsky's at ne30 in docs/explanation/efficiency/sweep.md; TC5's there
  was T341, which stores days 1 and 15 only) is the spatial error, and a run qualifies when its
  temporal error (its final h + hs against the reference's) is ≤ 10 % of it (the sweep's
  criterion, docs/explanation/methods.md "Sufficient accuracy");
- the **fixed** runs ``--tc5-fixed`` / ``--galewsky-fixed`` (stepper@multiple of Δt_g, the
  gravity-wave limit of the initial state, cut to divide 3 h as the sweep cuts them): the
  sweep's cheapest qualifying run on h + hs (TC5 ``rk4`` @ 0.79, Galewsky ``fbrk32`` @ 1.24)
  and its neighbours;
- each pair of ``--pairs`` under ``control = "error"`` (its default controller and atol, the
  default Courant cap) at the rtols of ``--rtols`` (with ``--balances``: under ``control =
  "balanced"`` at those fractions), loosest first, until one qualifies: its
  temporal error, accepted and rejected steps, how many steps the Courant cap set, CPU s a
  simulated day, against the cheapest qualifying fixed run;
- Galewsky only: each pair's qualifying run's Δt over time (smallest, mean and largest
  accepted Δt a day) from its ``StepControl.history``.

With ``--rounds R`` the cheapest qualifying fixed run and each pair at its qualifying rtol run
again, in turn, R times: the medians of their CPU s and the pairs' ratios (the verdict's figures
where the machine's load moves a single run's clock by 20 %).

With ``--dt-runs PAIR@RTOL[@CFL] ...`` only Galewsky's Δt over time at those tolerances instead
(tighter ones, where the error controller and not the Courant cap sets the step; CFL a
``time.cfl``, ``false``: no cap): the reference, then each run's temporal error, steps, CPU s a
day and Δt a day; written to ``results/adaptive_ne30_dt.json`` (``--results``: another name).
"""

from __future__ import annotations

import argparse
import math
import os
import statistics
import sys
from pathlib import Path

from adaptive_proportionality import build, fixed_dt, run, temporal

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # benchmarks/: results.py, the shared module
from results import DAY, quiet_warp, recorded

NE = 30
CASES = {  # label: (scene, its spectral reference: T213, the one that stores TC5's day 5; T341 has days 1 and 15)
    "tc5": ("tc5_mountain", "T213"),
    "galewsky": ("galewsky", "T213"),
}


def case_runs(args, label: str, days: float, fixed_specs, out: dict) -> None:
    """One case: the reference, the fixed runs, each pair's loosest qualifying rtol."""
    ne = args.ne
    scene, reference = CASES[label]
    reference = args.tc5_reference if label == "tc5" else reference
    over = {"case.reference": reference}
    error = {"control": "error", "rtol": args.rtol_ref}
    ref = run(scene, ne, days, "dp54", control=error, overrides=over)
    spatial = ref["diagnostics"]["ref_l2_h_surface"]
    bound = 0.1 * spatial
    print(
        f"\n## {scene} ne{ne} np4, {days:g} days: reference dp54 rtol {args.rtol_ref:g}, {ref['accepted']} steps "
        f"({ref['rejected']} rejected), CPU {ref['cpu']:.1f} s; spatial error (h + hs against {reference}) "
        f"{spatial:.3e}, bound {bound:.3e}",
        flush=True,
    )
    print(f"{'run':26s} {'temporal':>10s} {'ok':>3s} accepted rejected capped  CPU s  CPU s/day  dt min/mean/max (s)")
    probe = build(scene, ne, days, "rk4", overrides=over)
    fixed = []
    for spec in fixed_specs:
        stepper, multiple = spec.split("@")
        dt, dt_g = fixed_dt(probe, float(multiple))
        r = run(scene, ne, days, stepper, dt=dt, overrides=over)
        e = temporal(r, ref)
        row = {"run": f"{stepper}@{float(multiple):g} ({dt:.1f} s)", "temporal": e, "cpu": r["cpu"], "ok": e <= bound}
        row |= {"steps": r["accepted"], "blowup": r["blowup"]}
        fixed.append(row)
        _line(row["run"], e, bound, r, days)
    print(f"(Δt_g = {dt_g:.1f} s)", flush=True)
    qualified = [f for f in fixed if f["ok"]]
    best = min(qualified, key=lambda f: f["cpu"]) if qualified else None
    pairs = {}
    for pair in args.pairs:
        tried = []
        for name, control in controls(args):  # loosest first
            r = run(scene, ne, days, pair, control=control, overrides=over)
            e = temporal(r, ref)
            ctl = r["sim"].control
            row = {"try": name, "control": control, "temporal": e, "cpu": r["cpu"], "accepted": r["accepted"]}
            row["rejected"] = r["rejected"]
            row |= {"capped": ctl.capped, "dt": r["dt"], "ok": e <= bound, "blowup": r["blowup"]}
            if label == "galewsky":
                row["dt_by_day"] = by_day(ctl.history, days)
            tried.append(row)
            _line(f"{pair}@{name}", e, bound, r, days, ctl.capped)
            if row["ok"]:
                break
        pairs[pair] = tried
    print(f"\nverdict ({scene}; the loosest qualifying rtol against the cheapest qualifying fixed run):")
    for pair, tried in pairs.items():
        t = tried[-1]
        if not t["ok"]:
            print(f"  {pair}: none of those tried qualifies")
            continue
        share = t["rejected"] / max(t["accepted"] + t["rejected"], 1)
        against = "no qualifying fixed run" if best is None else f"{best['run']}: {t['cpu'] / best['cpu']:.2f}×"
        print(f"  {pair}@{t['try']}: {t['cpu'] / days:.3f} CPU s a day against {against}; {100 * share:.1f} % rejected")
    if label == "galewsky":
        print(f"\n{scene}: each pair's qualifying run's accepted Δt a day, smallest/mean/largest (s)")
        for pair, tried in pairs.items():
            cells = "  ".join(f"d{i + 1} {a:.0f}/{m:.0f}/{b:.0f}" for i, (a, m, b) in enumerate(tried[-1]["dt_by_day"]))
            print(f"  {pair}@{tried[-1]['try']}: {cells}")
    out[label] = {"scene": scene, "reference": reference, "days": days, "spatial": spatial, "dt_g": dt_g}
    out[label] |= {"reference_steps": ref["accepted"], "fixed": fixed, "pairs": pairs}
    if args.rounds and best is not None:
        out[label]["rounds"] = rounds(args, scene, days, over, best, probe, pairs)


def controls(args) -> list:
    """Each pair's tries, loosest first: (a name, its [time] keys): ``--balances`` under
    control = "balanced" where given, else ``--rtols`` under "error"."""
    if args.balances:
        return [(f"balance={f:g}", {"control": "balanced", "balance": f}) for f in sorted(args.balances, reverse=True)]
    return [(f"rtol={r:g}", {"control": "error", "rtol": r}) for r in sorted(args.rtols, reverse=True)]


def rounds(args, scene, days, over, best, probe, pairs) -> dict:
    """``--rounds``: the cheapest qualifying fixed run and each pair at its qualifying rtol run
    again in turn, ``args.rounds`` times: each one's CPU s a round, the medians and the ratio."""
    stepper, multiple = best["run"].split(" ")[0].split("@")
    runs = {best["run"]: dict(stepper=stepper, dt=fixed_dt(probe, float(multiple))[0])}
    for pair, tried in pairs.items():
        if tried[-1]["ok"]:
            runs[f"{pair}@{tried[-1]['try']}"] = dict(stepper=pair, control=tried[-1]["control"])
    cpu = {name: [] for name in runs}
    for i in range(args.rounds):
        for name, spec in runs.items():
            cpu[name].append(run(scene, args.ne, days, overrides=over, **spec)["cpu"])
        print(f"round {i + 1}: " + ", ".join(f"{n} {c[-1]:.1f} s" for n, c in cpu.items()), flush=True)
    base = statistics.median(cpu[best["run"]])
    print(f"medians of {args.rounds} interleaved rounds (CPU s a day; against {best['run']}):")
    for name, values in cpu.items():
        print(f"  {name}: {statistics.median(values) / days:.3f}, {statistics.median(values) / base:.2f}×")
    return {name: {"cpu": values, "ratio": statistics.median(values) / base} for name, values in cpu.items()}


def dt_runs(args, days: float, out: dict) -> None:
    """``--dt-runs``: Galewsky's Δt over time at each PAIR@RTOL, with its temporal error."""
    scene, reference = CASES["galewsky"]
    over = {"case.reference": reference}
    ref = run(scene, args.ne, days, "dp54", control={"control": "error", "rtol": args.rtol_ref}, overrides=over)
    print(
        f"\n## {scene} ne{args.ne} np4, {days:g} days: reference dp54 rtol {args.rtol_ref:g}, {ref['accepted']} steps"
    )
    rows = {}
    for spec in args.dt_runs:
        pair, rtol, *cfl = spec.split("@")
        control = {"control": "error", "rtol": float(rtol)}
        control |= {"cfl": False if cfl[0] == "false" else float(cfl[0])} if cfl else {}
        r = run(scene, args.ne, days, pair, control=control, overrides=over)
        ctl, e = r["sim"].control, temporal(r, ref)
        daily = by_day(ctl.history, days)
        rows[spec] = {"temporal": e, "accepted": r["accepted"], "rejected": r["rejected"], "capped": ctl.capped}
        rows[spec] |= {"cpu": r["cpu"], "dt_by_day": daily}
        print(
            f"{spec}: temporal {e:.3e}, {r['accepted']} steps ({r['rejected']} rejected, the cap set {ctl.capped}), "
            f"{r['cpu'] / days:.3f} CPU s a day",
            flush=True,
        )
        print("  " + "  ".join(f"d{i + 1} {a:.0f}/{m:.0f}/{b:.0f}" for i, (a, m, b) in enumerate(daily)), flush=True)
    out["galewsky_dt"] = {"days": days, "reference_steps": ref["accepted"], "runs": rows}


def by_day(history, days: float) -> list:
    """(smallest, mean, largest) accepted Δt (s) of each day, from (time reached (s), Δt, error)
    rows; a step counts for the day it ends in, the last one landed on a day's end in that day."""
    rows = []
    for d in range(math.ceil(days)):
        dts = [dt for t, dt, _ in history if d * DAY < t <= (d + 1) * DAY]
        rows.append((min(dts), sum(dts) / len(dts), max(dts)) if dts else (math.nan,) * 3)
    return rows


def _line(name, e, bound, r, days, capped=0) -> None:
    dt = "/".join(f"{x:.0f}" for x in r["dt"])
    ok = "yes" if e <= bound else "no"
    print(
        f"{name:26s} {e:10.3e} {ok:>3s} {r['accepted']:8d} {r['rejected']:8d} {capped:6d} {r['cpu']:6.1f} "
        f"{r['cpu'] / days:9.3f}  {dt}" + (f"  BLOW-UP {r['blowup']}" if r["blowup"] else ""),
        flush=True,
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--ne", type=int, default=NE, help="the grid (np 4); 30 is the target's")
    parser.add_argument("--cases", nargs="+", default=list(CASES), choices=list(CASES))
    parser.add_argument("--tc5-days", type=float, default=5.0)
    parser.add_argument("--galewsky-days", type=float, default=6.0)
    parser.add_argument("--pairs", nargs="+", default=["dp54", "ssprk43", "rdpk3sp35"])
    parser.add_argument("--rtols", nargs="+", type=float, default=[1e-2, 1e-4, 1e-5, 1e-6])
    parser.add_argument(
        "--balances", nargs="+", type=float, help='fractions f under control = "balanced" instead of --rtols'
    )
    parser.add_argument("--rtol-ref", type=float, default=1e-8)
    parser.add_argument("--tc5-fixed", nargs="+", default=["rk4@0.79", "rk4@1.24", "kgu35@0.8"])
    parser.add_argument("--galewsky-fixed", nargs="+", default=["fbrk32@1.24", "fbrk32@1.05", "kgu35@1.63"])
    parser.add_argument(
        "--rounds", type=int, default=0, help="the cheapest fixed run and each qualifying pair again, interleaved"
    )
    parser.add_argument("--dt-runs", nargs="+", help="PAIR@RTOL[@CFL]: Galewsky's Δt over time at these instead")
    parser.add_argument(
        "--tc5-reference", default="T213", help="TC5's spectral reference (T341 stores days 1 and 15 only)"
    )
    parser.add_argument(
        "--results", help="the results file's name (default adaptive_ne30; with --dt-runs adaptive_ne30_dt)"
    )
    args = parser.parse_args()
    quiet_warp()
    stem = args.results or ("adaptive_ne30_dt" if args.dt_runs else None)
    with recorded(__file__, stem) as figures:
        print(f"load average at the start: {' '.join(f'{x:.2f}' for x in os.getloadavg())}", flush=True)
        fixed = {"tc5": args.tc5_fixed, "galewsky": args.galewsky_fixed}
        days = {"tc5": args.tc5_days, "galewsky": args.galewsky_days}
        steppers = sorted({s.split("@")[0] for c in args.cases for s in fixed[c]} | {*args.pairs, "dp54"})
        if args.dt_runs:
            args.cases, args.pairs = ["galewsky"], sorted({s.split("@")[0] for s in args.dt_runs} | {"dp54"})
            steppers = args.pairs
        for stepper in steppers:  # compile every kernel before any timing
            run(
                CASES[args.cases[0]][0],
                args.ne,
                0.125,
                stepper,
                control={"control": "error"} if stepper in args.pairs else None,
            )
        for label in [] if args.dt_runs else args.cases:
            case_runs(args, label, days[label], fixed[label], figures)
        if args.dt_runs:
            dt_runs(args, args.galewsky_days, figures)
            print(f"load average: {' '.join(f'{x:.2f}' for x in os.getloadavg())}", flush=True)
        print(f"load average at the end: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    main()
