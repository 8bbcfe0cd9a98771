"""Error control's accuracy and cost at small grids (``[time] control = "error"`` and ``"balanced"``): tolerance
proportionality, the cost against the best fixed step, the balanced controller, and starts far above
the stable step. One subcommand a study, each written to ``results/error_control/<study>/<stem>.json``::

    python benchmarks/studies/error_control.py STUDY [its options]   # STUDY --help: its options

``adaptive_proportionality``
~~~~~~~~~~~~~~~~~~~~~~~~~~~~
Error-controlled steps (``[time] control = "error"``) measured: tolerance proportionality,
the cost against the best fixed step, and a run started far above its stable step.

    SWE_SPHERE_THREADS=1 OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 \
        python benchmarks/studies/error_control.py adaptive_proportionality [--ne 8] [--tc2-days 5] [--tc5-days 5]

Every run is in this process, one thread, timed with its CPU clock (``time.process_time`` of
``Simulation.run``; each stepper warmed once first so that no kernel compiles inside a timing);
no run file is written. The temporal error of a run is the normalized l2 (Williamson et al. 1992,
eq. 83) of its final h + hs against a reference run of the same grid: ``dp54`` at rtol
``--rtol-ref`` (a fifth-order pair, so that the reference's own temporal error is far below
every run's). The parts:

(a) **Tolerance proportionality.** TC2 (``tc2_steady``) and TC5 (``tc5_mountain``) (``--cases``) at each rtol
    of ``--rtols`` (``--pair-rtols``: a pair's own) for each pair of ``--pairs`` (each pair's default controller; atol the default,
    rtol in each field's units): the temporal error, TC2's error against its exact solution
    (h l2, spatial and temporal together), accepted and rejected steps, CPU s; the slope q of
    log(temporal error) against log(rtol), least squares (issue 64's target: q in [0.7, 1.1]);
    ``--per-unit-step``: the pairs controlled per unit step (``time.per_unit_step``; the reference
    per step).
(b) **Cost against fixed steps** (TC5). The spatial error is the reference run's h + hs l2
    against the case's T213 run; a run qualifies when its temporal error is ≤ 10 % of it (the
    sweep's criterion, docs/explanation/methods.md "Sufficient accuracy"). For each pair the loosest
    qualifying rtol of ``--rtols`` and ``--loose``; against it the cheapest qualifying fixed-Δt
    run of ``--fixed`` (stepper@multiple of Δt_g, the gravity-wave limit of the initial state;
    each Δt cut to divide 3 h, as the sweep cuts its multiples): CPU s per simulated day, ratio.
(c) **A start far above the stable step** (TC5): each pair under control from ``--dt`` 5× the
    scene's Δt against the same from the scene's Δt, at rtol ``--hard-rtol``: blow-up or not,
    accepted and rejected steps, CPU s, ratio (issue 64's target ≤ 1.3×).
(d) **The control's own cost** (TC5): a pair's step at one Δt against a new Δt every step (the
    launch lists keyed by Δt recorded again), and one error norm; CPU ms.

``adaptive_balanced``
~~~~~~~~~~~~~~~~~~~~~
The balanced step control (``control = "balanced"``, issue 64's "a run that asks for an
accuracy") against the efficiency study's verdict: does one run at ``time.balance`` = f keep its
temporal error at about f of the spatial one, and what does it cost against the sweep's
cheapest qualifying fixed-Δt run?

    SWE_SPHERE_THREADS=1 OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 \
        python benchmarks/studies/error_control.py adaptive_balanced [--ne 16] [--cases tc5 tc6 galewsky] [--balances 0.1]

Every run in this process at ``--ne`` np4 over the sweep's lengths (TC5 15 days, TC6 14,
Galewsky 6; docs/explanation/efficiency/sweep.md), one thread, its CPU clock
(``time.process_time`` of ``Simulation.run``, each stepper warmed by a short run first); no run
file written; the helpers are ``adaptive_proportionality``'s. For each case:

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

Written to ``results/error_control/adaptive_balanced/adaptive_balanced.json`` (``--results``: another name).

``adaptive_hard_start``
~~~~~~~~~~~~~~~~~~~~~~~
The stability suite's hard cases started far above their stable step under error control
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

    SWE_SPHERE_THREADS=1 python benchmarks/studies/error_control.py adaptive_hard_start [--ne 8] [--rtol 1e-4] [--pairs ...] [--results STEM]
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from pathlib import Path

import numpy as np

from swe_sphere import STEPPERS, BlowUp, Simulation, load_scene
from swe_sphere.studies.sweep.runs import explicit_limits

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: results.py, the shared module
from results import DAY, quiet_warp, recorded, section, studies  # noqa: E402

STUDIES = (
    "adaptive_proportionality",
    "adaptive_balanced",
    "adaptive_hard_start",
)  # the subcommands, a section of this docstring each


SNAPSHOT = 10800.0  # s: the sweep's 3-hourly snapshots, which its fixed Δt divide


def build(case, ne, days, stepper, dt=None, control=None, overrides=None):
    """A ``Simulation`` of ``case`` at ``ne`` (np 4) over ``days`` with ``stepper`` at ``dt``
    (None: the scene's), under ``control`` (a dict of [time] keys, or None: fixed Δt), with the
    scene ``overrides`` ({"section.key": value}); one output, at the end."""
    overrides = {"output.every_days": days, **(overrides or {})}
    overrides |= {f"time.{k}": v for k, v in (control or {}).items()}
    scene = load_scene(case, ne=ne, np_=4, dt=dt, days=days, stepper=stepper, overrides=overrides)
    return Simulation(scene, "cpu", progress=False)


def run(case, ne, days, stepper, dt=None, control=None, overrides=None) -> dict:
    """One run (``build``'s arguments): its final h + hs, CPU s, steps (accepted, rejected), Δt
    (smallest, mean, largest), the final diagnostics; ``blowup`` the line of a run that did not
    finish."""
    sim = build(case, ne, days, stepper, dt, control, overrides)
    start = time.process_time()
    try:
        result = sim.run(None)
        blowup = result.blowup
    except BlowUp as err:
        result, blowup = None, str(err)
    cpu = time.process_time() - start
    out = {"cpu": cpu, "blowup": blowup, "sim": sim, "diagnostics": None if result is None else result.diagnostics}
    out["surface"] = sim.fields()[2] + sim.hs
    ctl = sim.control
    if ctl is None:
        out |= {"accepted": sim.step, "rejected": 0, "dt": (sim.scene.dt,) * 3}
    else:
        mean = ctl.dt_sum / max(ctl.accepted, 1)
        out |= {"accepted": ctl.accepted, "rejected": ctl.rejected, "dt": (ctl.dt_smallest, mean, ctl.dt_largest)}
    return out


def temporal(r, ref) -> float:
    """The normalized l2 of run r's final h + hs against ``ref``'s (Williamson et al. 1992, eq. 83:
    the grid's area integral, ``CubedSphere.integrate``; inf: blown up)."""
    if r["blowup"]:
        return math.inf
    integrate, e = ref["sim"].grid.integrate, r["surface"] - ref["surface"]
    return math.sqrt(integrate(e * e) / integrate(ref["surface"] ** 2))


def slope(rtols, errors) -> float:
    """q of error ∝ rtol^q, least squares in logs (NaN with fewer than two finite points)."""
    pts = [(math.log(r), math.log(e)) for r, e in zip(rtols, errors, strict=True) if 0 < e < math.inf]
    if len(pts) < 2:
        return math.nan
    x, y = np.array(pts).T
    return float(np.polyfit(x, y, 1)[0])


def warm(case, ne, steppers) -> None:
    """One short run of each stepper (fixed and under control), so that no timing compiles."""
    for stepper in steppers:
        run(case, ne, 0.25, stepper)
    for stepper in ("bs32", "dp54"):
        run(case, ne, 0.25, stepper, control={"control": "error", "rtol": 1e-4})


def proportionality(args, case, days, out: dict) -> dict:
    """(a) for one case: every pair at every rtol against the reference; the reference run.
    ``args.inviscid``: TC5 without its ∇⁴ (the split ∇⁴'s error, first order in Δt, is not in
    the pairs' estimates)."""
    over = None
    if args.inviscid and case == "tc5_mountain":
        over = {"terms": [t for t in load_scene(case).terms if t != "hyperviscosity"]}
    ref = run(case, args.ne, days, "dp54", control={"control": "error", "rtol": args.rtol_ref}, overrides=over)
    print(
        f"\n## {case} ne{args.ne}, {days:g} days{', no ∇⁴' if over else ''}"
        f"{', the pairs per unit step' if args.per_unit_step else ''}; reference dp54 rtol {args.rtol_ref:g}: "
        f"{ref['accepted']} steps, CPU {ref['cpu']:.1f} s"
    )
    exact = case == "tc2_steady"
    head = (
        f"{'pair':10s} {'rtol':>8s} {'temporal':>10s} "
        + ("exact h l2 " if exact else "")
        + "accepted rejected  dt min/mean/max (s)      CPU s"
    )
    print(head)
    rows = {}
    unit = {"per_unit_step": True} if args.per_unit_step else {}
    for pair in args.pairs:
        errs, rtols = [], args.pair_rtols.get(pair, args.rtols)
        for rtol in rtols:
            r = run(case, args.ne, days, pair, control={"control": "error", "rtol": rtol, **unit}, overrides=over)
            e = temporal(r, ref)
            errs.append(e)
            row = {"rtol": rtol, "temporal": e, "accepted": r["accepted"], "rejected": r["rejected"], "cpu": r["cpu"]}
            row["dt"] = r["dt"]
            line = f"{pair:10s} {rtol:8.0e} {e:10.3e} "
            if exact:
                row["exact_l2_h"] = math.inf if r["blowup"] else r["diagnostics"]["l2_h"]
                line += f"{row['exact_l2_h']:10.3e} "
            dt = "/".join(f"{x:.0f}" for x in r["dt"])
            print(line + f"{r['accepted']:8d} {r['rejected']:8d}  {dt:22s} {r['cpu']:7.2f}")
            rows.setdefault(pair, []).append(row)
        q = slope(rtols, errs)
        verdict = "in [0.7, 1.1]" if 0.7 <= q <= 1.1 else "OUTSIDE [0.7, 1.1]"
        print(f"{pair:10s} slope q = {q:.3f} ({verdict})")
        rows[pair] = {"runs": rows[pair], "q": q}
    out[case] = {"days": days, "reference_steps": ref["accepted"], "pairs": rows, "inviscid": over is not None}
    out[case]["per_unit_step"] = args.per_unit_step
    return ref


def fixed_dt(sim, multiple: float) -> tuple[float, float]:
    """(Δt, Δt_g): ``multiple`` Δt_g cut to divide 3 h, Δt_g the gravity-wave limit of ``sim``'s
    initial state (Courant number 1 on the smallest GLL spacing)."""
    dt_g = sim.scene.dt / sim.courant()["courant_gravity"]
    return SNAPSHOT / math.ceil(SNAPSHOT / (multiple * dt_g)), dt_g


def against_fixed(args, ref, days, out: dict) -> None:
    """(b): the loosest qualifying rtol of each pair against the cheapest qualifying fixed run."""
    spatial = ref["diagnostics"]["ref_l2_h_surface"]
    bound = 0.1 * spatial
    print(
        f"\n## TC5 ne{args.ne}: cost at the 10 % criterion; spatial error (h + hs against T213) {spatial:.3e}, bound {bound:.3e}"
    )
    print(f"{'run':22s} {'temporal':>10s} {'ok':>3s} accepted rejected  CPU s  CPU s/day")
    fixed = []
    probe = build("tc5_mountain", args.ne, days, "rk4")
    for spec in args.fixed:
        stepper, multiple = spec.split("@")
        dt, dt_g = fixed_dt(probe, float(multiple))
        r = run("tc5_mountain", args.ne, days, stepper, dt=dt)
        e = temporal(r, ref)
        fixed.append(
            {"run": f"{stepper}@{float(multiple):g} ({dt:.1f} s)", "temporal": e, "cpu": r["cpu"], "ok": e <= bound}
        )
        print(
            f"{fixed[-1]['run']:22s} {e:10.3e} {'yes' if e <= bound else 'no':>3s} {r['accepted']:8d} {0:8d} {r['cpu']:6.2f} {r['cpu'] / days:9.3f}"
        )
    print(f"(Δt_g = {dt_g:.1f} s at ne{args.ne})")
    qualified = [f for f in fixed if f["ok"]]
    best = min(qualified, key=lambda f: f["cpu"]) if qualified else None
    adaptive = {}
    for pair in args.pairs:
        tried = []
        for rtol in sorted({*args.rtols, *args.loose}, reverse=True):  # loosest first
            r = run("tc5_mountain", args.ne, days, pair, control={"control": "error", "rtol": rtol})
            e = temporal(r, ref)
            share = r["rejected"] / max(r["accepted"] + r["rejected"], 1)
            tried.append(
                {
                    "rtol": rtol,
                    "temporal": e,
                    "cpu": r["cpu"],
                    "accepted": r["accepted"],
                    "rejected": r["rejected"],
                    "ok": e <= bound,
                }
            )
            print(
                f"{pair + f'@rtol={rtol:g}':22s} {e:10.3e} {'yes' if e <= bound else 'no':>3s} {r['accepted']:8d} {r['rejected']:8d} "
                f"{r['cpu']:6.2f} {r['cpu'] / days:9.3f}  ({100 * share:.1f} % rejected)"
            )
            if e <= bound:
                break
        adaptive[pair] = tried
    verdicts(args, adaptive, best, days)
    out["cost"] = {"days": days, "spatial": spatial, "fixed": fixed, "adaptive": adaptive, "dt_g": dt_g}


def verdicts(args, adaptive: dict, best: dict | None, days: float) -> None:
    """(b)'s verdict: each pair's loosest qualifying rtol (``adaptive``: its tries, loosest first)
    against ``best``, the cheapest qualifying fixed run; and against the pair itself at a fixed Δt
    of as many steps (the control's own cost: the norm, the saved state, the launch lists)."""
    print("\nverdict (loosest qualifying rtol against the cheapest qualifying fixed run; the pair at a fixed")
    print("Δt of as many steps):")
    for pair, tried in adaptive.items():
        ok = [t for t in tried if t["ok"]]
        if not ok:
            print(f"  {pair}: no qualifying rtol")
            continue
        same = run("tc5_mountain", args.ne, days, pair, dt=days * DAY / ok[0]["accepted"])
        ok[0]["fixed_same_steps_cpu"] = same["cpu"]
        t = ok[0]
        against = (
            "no qualifying fixed run"
            if best is None
            else f"{best['run']} {best['cpu'] / days:.3f}: {t['cpu'] / best['cpu']:.2f}×"
        )
        print(
            f"  {pair}@rtol={t['rtol']:g}: {t['cpu'] / days:.3f} CPU s/day against {against}; {pair} fixed, "
            f"{t['accepted']} steps: {same['cpu'] / days:.3f} ({t['cpu'] / same['cpu']:.2f}× under control)"
        )


def hard_start(args, ref, days, out: dict) -> None:
    """(c): each pair from 5× the scene's Δt against the same from the scene's Δt."""
    scene_dt = build("tc5_mountain", args.ne, days, "bs32").scene.dt
    print(f"\n## TC5 ne{args.ne}: started at 5× the scene's Δt ({scene_dt:.1f} s), rtol {args.hard_rtol:g}")
    print(f"{'pair':10s} {'first dt':>9s} {'finished':>8s} accepted rejected  temporal    CPU s  ratio")
    rows = {}
    for pair in args.pairs:
        base = None
        for factor in (1, 5):
            r = run(
                "tc5_mountain",
                args.ne,
                days,
                pair,
                dt=factor * scene_dt,
                control={"control": "error", "rtol": args.hard_rtol},
            )
            e = temporal(r, ref)
            base = base or r["cpu"]
            ratio = r["cpu"] / base
            print(
                f"{pair:10s} {factor * scene_dt:9.1f} {'no' if r['blowup'] else 'yes':>8s} {r['accepted']:8d} {r['rejected']:8d} "
                f"{e:10.3e} {r['cpu']:7.2f} {ratio:6.2f}"
            )
            rows[f"{pair}@{factor}x"] = {
                "blowup": r["blowup"],
                "accepted": r["accepted"],
                "rejected": r["rejected"],
                "temporal": e,
                "cpu": r["cpu"],
                "ratio": ratio,
            }
    out["hard_start"] = {"scene_dt": scene_dt, "runs": rows}


def step_cost(args, out: dict) -> None:
    """(d): where a controlled step's own cost goes (TC5): each pair's step at one Δt (its launch
    lists replayed) against a new Δt every step (as under control: the lists keyed by Δt
    recorded again), and one error norm (``control.ErrorNorm``), ms of CPU each, over
    ``--step-repeat`` steps."""
    print(f"\n## TC5 ne{args.ne}: a step's CPU ms at one Δt, at a new Δt every step, and one error norm")
    rows = {}
    for pair in args.pairs:
        sim = run("tc5_mountain", args.ne, 0.25, pair, control={"control": "error", "rtol": 1e-3})["sim"]
        stepper, ctl, n = sim.stepper, sim.control, args.step_repeat

        def per_step(dts, stepper=stepper, sim=sim) -> float:
            start = time.process_time()
            for dt in dts:
                stepper.set_dt(dt)
                stepper.step(sim.x)
            return (time.process_time() - start) / len(dts) * 1e3

        same, new = per_step([500.0] * n), per_step([500.0 + 1e-3 * (i + 1) for i in range(n)])
        start = time.process_time()
        for _ in range(n):
            ctl.norm(stepper.error_estimate, ctl.x0, sim.x)
        norm = (time.process_time() - start) / n * 1e3
        rows[pair] = {"one_dt_ms": same, "new_dt_ms": new, "norm_ms": norm}
        print(
            f"{pair:10s} one Δt {same:.3f} ms, a new Δt every step {new:.3f} ms ({new / same:.2f}×), the norm {norm:.3f} ms"
        )
    out["step_cost"] = rows


def adaptive_proportionality(argv: list[str]) -> None:
    """``adaptive_proportionality``: its options parsed from ``argv``, its runs, its results file."""
    parser = argparse.ArgumentParser(
        prog="error_control.py adaptive_proportionality", description=section(__doc__, "adaptive_proportionality")
    )
    parser.add_argument("--ne", type=int, default=8)
    parser.add_argument("--tc2-days", type=float, default=5.0)
    parser.add_argument("--tc5-days", type=float, default=5.0)
    parser.add_argument("--pairs", nargs="+", default=["bs32", "rdpk3sp35", "ssprk43", "dp54"])
    parser.add_argument("--rtols", nargs="+", type=float, default=[1e-3, 1e-4, 1e-5, 1e-6])
    parser.add_argument(
        "--loose", nargs="+", type=float, default=[1e-2, 3e-3], help="rtols looser than --rtols tried in (b)"
    )
    parser.add_argument(
        "--pair-rtols",
        nargs="+",
        default=[],
        metavar="PAIR=R1,R2,...",
        help="(a): a pair's own rtols instead of --rtols (its decades below the Courant cap), one reference for all",
    )
    parser.add_argument("--rtol-ref", type=float, default=1e-9)
    parser.add_argument(
        "--fixed", nargs="+", default=["kgu35@1.78", "kgu35@0.89", "fbrk32@1.38", "fbrk32@0.69", "rk4@1.38", "rk4@0.69"]
    )
    parser.add_argument("--hard-rtol", type=float, default=1e-4)
    parser.add_argument("--step-repeat", type=int, default=100, help="steps timed in (d)")
    parser.add_argument("--parts", nargs="+", default=["a", "b", "c", "d"], choices=["a", "b", "c", "d"])
    parser.add_argument("--cases", nargs="+", default=["tc2", "tc5"], choices=["tc2", "tc5"], help="(a)'s cases")
    parser.add_argument("--inviscid", action="store_true", help="(a): TC5 without its ∇⁴")
    parser.add_argument(
        "--per-unit-step", action="store_true", help="(a): the pairs' error per unit step (time.per_unit_step)"
    )
    parser.add_argument(
        "--results",
        help="the results file's stem (default adaptive_proportionality; e.g. adaptive_proportionality_ne16)",
    )
    args = parser.parse_args(argv)
    args.pair_rtols = {k: [float(r) for r in v.split(",")] for k, v in (a.split("=") for a in args.pair_rtols)}
    quiet_warp()
    with recorded(__file__, args.results, study="adaptive_proportionality") as figures:
        print(f"load average at the start: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
        warm("tc5_mountain", args.ne, sorted({s.split("@")[0] for s in args.fixed} | set(args.pairs)))
        if "a" in args.parts and "tc2" in args.cases:
            proportionality(args, "tc2_steady", args.tc2_days, figures)
        ref = (
            proportionality(args, "tc5_mountain", args.tc5_days, figures)
            if "a" in args.parts and "tc5" in args.cases
            else None
        )
        if ref is None and {"b", "c"} & set(args.parts):
            ref = run(
                "tc5_mountain", args.ne, args.tc5_days, "dp54", control={"control": "error", "rtol": args.rtol_ref}
            )
        if "b" in args.parts:
            against_fixed(args, ref, args.tc5_days, figures)
        if "c" in args.parts:
            hard_start(args, ref, args.tc5_days, figures)
        if "d" in args.parts:
            step_cost(args, figures)
        print(f"load average at the end: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")


BALANCED_CASES = {  # label: (scene, days, the sweep's cheapest qualifying fixed run at ne16 on h + hs)
    "tc5": ("tc5_mountain", 15.0, "rk4@0.69"),
    "tc6": ("tc6_rossby_haurwitz", 14.0, "kgu35@1.6"),
    "galewsky": ("galewsky", 6.0, "fbrk32@1.3"),
}


def balanced_runs(args, label: str, out: dict) -> None:
    scene, days, fixed = BALANCED_CASES[label]
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
    rows = {fixed: _balanced_line(fixed, r, ref, spatial, base)}
    for pair in args.pairs:
        for f in args.balances:
            control = {"control": "balanced", "balance": f}
            r = run(scene, args.ne, days, pair, control=control, overrides=over)
            rows[f"{pair}@balance={f:g}"] = _balanced_line(f"{pair} balance {f:g}", r, ref, spatial, base)
    out[label] = {"days": days, "spatial": spatial, "reference_dt": dt_ref, "dt_g": dt_g, "runs": rows}


def _balanced_line(name, r, ref, spatial, base) -> dict:
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


def adaptive_balanced(argv: list[str]) -> None:
    """``adaptive_balanced``: its options parsed from ``argv``, its runs, its results file."""
    parser = argparse.ArgumentParser(
        prog="error_control.py adaptive_balanced", description=section(__doc__, "adaptive_balanced")
    )
    parser.add_argument("--ne", type=int, default=16)
    parser.add_argument("--cases", nargs="+", default=list(BALANCED_CASES), choices=list(BALANCED_CASES))
    parser.add_argument("--pairs", nargs="+", default=["rk43", "kgu352"])
    parser.add_argument("--balances", nargs="+", type=float, default=[0.1])
    parser.add_argument("--results", help="the results file's stem (default adaptive_balanced)")
    args = parser.parse_args(argv)
    quiet_warp()
    with recorded(__file__, args.results, study="adaptive_balanced") as figures:
        print(f"load average at the start: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
        for stepper in ("rk4", "kgu35", "fbrk32", *args.pairs):  # compiled before any timing
            run("tc5_mountain", args.ne, 0.25, stepper)
        for pair in args.pairs:
            run("tc5_mountain", args.ne, 0.25, pair, control={"control": "balanced"})
        for label in args.cases:
            balanced_runs(args, label, figures)
        print(f"load average at the end: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")


HARD_START_CASES = ("tc5_mountain", "tc6_rossby_haurwitz", "tc6_rossby_haurwitz_inviscid", "galewsky")


def stable_dt(case: str, ne: int, pair: str) -> float:
    """The pair's largest stable Δt (s) at the case's start on ne np4: its Courant limit over
    the initial state's largest signal rate; an IMEX pair's (gravity waves implicit) its
    advective limit over the largest |v|/Δx."""
    cls = STEPPERS[pair]
    if cls.courant_limit is None:
        sim = build(case, ne, 1.0, pair)
        rate = sim.courant()["courant_advective"] / sim.scene.dt  # max |v| / Δx at the start, s⁻¹
        return cls.advective_courant_limit / rate
    base = build(case, ne, 1.0, pair).scene
    limits = explicit_limits(base, "cpu")
    rate = STEPPERS["leapfrog"].courant_limit / limits["dt_leapfrog"]  # (|v| + sqrt(g h)) / Δx, s⁻¹
    return STEPPERS[pair].courant_limit / rate


def hard_start_case(case: str, args, out: dict) -> None:
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


def adaptive_hard_start(argv: list[str]) -> None:
    """``adaptive_hard_start``: its options parsed from ``argv``, its runs, its results file."""
    parser = argparse.ArgumentParser(
        prog="error_control.py adaptive_hard_start", description=section(__doc__, "adaptive_hard_start")
    )
    parser.add_argument("--ne", type=int, default=8)
    parser.add_argument("--cases", nargs="+", default=list(HARD_START_CASES))
    parser.add_argument("--pairs", nargs="+", default=["bs32", "rdpk3sp35", "ssprk43", "dp54"])
    parser.add_argument("--rtol", type=float, default=1e-4)
    parser.add_argument("--results", help="results/adaptive_hard_start/<STEM>.json (default: the script's stem)")
    args = parser.parse_args(argv)
    unknown = [pair for pair in args.pairs if pair not in STEPPERS]
    if unknown:
        parser.error(f"--pairs: unknown {', '.join(unknown)} (the steppers: swe-sphere list)")
    quiet_warp()
    with recorded(__file__, args.results, study="adaptive_hard_start") as figures:
        print(f"load average at the start: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
        figures["rtol"], figures["ne"] = args.rtol, args.ne
        for case in args.cases:
            hard_start_case(case, args, figures)
        print(f"load average at the end: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    studies(__doc__, {name: globals()[name] for name in STUDIES})
