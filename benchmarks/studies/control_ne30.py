"""Step control at ne30 (issue 64's target): error-controlled runs against the cheapest qualifying
fixed step, and what the control itself costs. One subcommand a study, each written to
``results/control_ne30/<study>/<stem>.json``::

    python benchmarks/studies/control_ne30.py STUDY [its options]   # STUDY --help: its options

``adaptive_ne30``
~~~~~~~~~~~~~~~~~
Error-controlled steps at ne30 (issue 64's target): at the loosest tolerance whose temporal
error meets the sweep's 10 % criterion, CPU time per simulated day against the cheapest
qualifying fixed-Δt run, on TC5 and Galewsky, and the share of steps rejected; Galewsky's Δt
over time from the same runs.

    SWE_SPHERE_THREADS=1 OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 \
        python benchmarks/studies/control_ne30.py adaptive_ne30 [--cases tc5 galewsky] [--tc5-days 5] [--galewsky-days 6]

Every run in this process at ne30 np4 (given, not the scenes' grids), one thread, its CPU clock
(``time.process_time`` of ``Simulation.run``; each stepper warmed first by a short run); no run
file written; the runs and helpers are ``error_control.py adaptive_proportionality``'s. For each case:

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
day and Δt a day; written to ``results/control_ne30/adaptive_ne30/adaptive_ne30_dt.json`` (``--results``: another name).

``control_overhead``
~~~~~~~~~~~~~~~~~~~~
What step control (``[time] control = "error"`` or ``"cfl"``) costs a step beyond the step
itself, at ne30.

    SWE_SPHERE_THREADS=1 OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 \
        python benchmarks/studies/control_ne30.py control_overhead [--ne 30] [--control error cfl] [--pair bs32] [--rtol 1e-5]
            [--cfl-stepper ssprk3] [--cfl 1.0] [--days 0.5]

TC5 (``tc5_mountain``), np4, one thread, CPU clock (``time.process_time``), every run in this
process after a warm-up run of each kind (no kernel compiles inside a timing); no run file.
``--device cuda``: on the card, wall clock (``time.perf_counter``, the device synchronised at
each end), steps replayed as CUDA graphs by default (``SWE_SPHERE_GRAPHS=off``: plain launches),
the controlled run's a graph a Δt of the controller's grid (``Simulation.try_step``).
Issue 64's target: the controller costs ≤ 2 % of a step at ne30. For each of ``--control``, error
control (``--pair`` at ``--rtol``) and CFL control (``--cfl-stepper`` at ``--cfl``), the parts:

(a) **Whole runs.** The stepper under its control over ``--days`` (``Simulation.run``:
    the steps it chose, their error norms, rejections, the landing on the end): CPU s per accepted
    step. Against it the same stepper at a fixed Δt (an FSAL pair with its last stage carried over,
    as under control), the controlled run's mean Δt, over as many steps
    (``Simulation.run`` of a fixed-Δt scene: its guard's blocks), and the controlled run's own Δt
    sequence stepped bare (``set_dt`` and ``step``, nothing else: what the steps alone cost). On
    CUDA the controlled run again without its tries launched ahead (``StepControl.lookahead``).
    The overhead: controlled against each, %.
(b) **Its parts**, ms of CPU each over ``--repeat`` calls: the stepper's step at one Δt; at a Δt
    never taken before every step (the recorded launches take the new coefficients as arguments
    in place, nothing recorded; before that change, each such step recorded its lists again);
    at three Δt of the controller's grid in turn (``integrator.control.on_grid``: fewer than
    ``LAUNCH_VARIANTS``, so each replays its own lists as recorded); one error norm
    (``control.ErrorNorm``) or, under "cfl", one pass of the Courant numbers (``control.CourantMax``);
    and one controlled step (``StepControl.step``: the state kept, the
    step, the norm, the controller) at one Δt.
(g) **What its graphs cost it** (``--parts g``): the controlled run of (a), then twice more on
    the same ``Simulation`` restored to its start (its restart file at t = 0). The runs take the
    same steps to the same bits; the third captures no graph (each Δt's was made by the first two),
    so the first less the third is what capturing a graph for each new Δt (and the plain steps
    before it) costs the run, and the third against the fixed-Δt run what the control costs a step.
(p) **Where the host's time goes** (``--parts p``): the controlled run and the fixed-Δt run of
    (a) again under cProfile, the host's CPU seconds a step (``time.process_time``) beside the wall
    seconds, and the functions that take most of the host's time. On a card the host must issue a
    step faster than the card runs it, or the card waits on Python.
"""

from __future__ import annotations

import argparse
import cProfile
import math
import os
import pstats
import statistics
import sys
import tempfile
import time
from pathlib import Path

import warp as wp

from swe_sphere import Simulation, load_scene
from swe_sphere.integrator.control import on_grid
from swe_sphere.simulation import checkpoint

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: results.py, the shared module
from error_control import build, fixed_dt, run, temporal  # noqa: E402
from results import DAY, quiet_warp, recorded, section, studies  # noqa: E402

STUDIES = ("adaptive_ne30", "control_overhead")  # the subcommands, a section of this docstring each


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


def adaptive_ne30(argv: list[str]) -> None:
    """``adaptive_ne30``: its options parsed from ``argv``, its runs, its results file."""
    parser = argparse.ArgumentParser(
        prog="control_ne30.py adaptive_ne30", description=section(__doc__, "adaptive_ne30")
    )
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
    args = parser.parse_args(argv)
    quiet_warp()
    stem = args.results or ("adaptive_ne30_dt" if args.dt_runs else None)
    with recorded(__file__, stem, study="adaptive_ne30") as figures:
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


def build_run(args, days, dt=None, control=True) -> Simulation:
    """TC5 at ``args.ne`` (np 4) over ``days`` with ``args.pair`` at ``dt`` (None: the scene's),
    under ``args.control`` (error control at ``args.rtol``, or CFL control at ``args.cfl``) or at a
    fixed Δt; one output, at the end."""
    overrides = {"output.every_days": days}
    if control:
        keys = {"rtol": args.rtol} if args.control == "error" else {"cfl": args.cfl}
        overrides |= {"time.control": args.control, **{f"time.{k}": v for k, v in keys.items()}}
    scene = load_scene("tc5_mountain", ne=args.ne, np_=4, dt=dt, days=days, stepper=args.pair, overrides=overrides)
    return Simulation(scene, args.device, progress=False)


def what(args) -> str:
    """The control, as the headings name it."""
    return f"rtol {args.rtol:g}" if args.control == "error" else f"cfl {args.cfl:g}"


DEVICE = "cpu"  # ``--device``: the clock's (CPU time on a CPU, wall time with a device synchronised)


def cpu(call) -> float:
    """CPU s of ``call()`` on a CPU; on CUDA wall s, the device idle at both ends."""
    if DEVICE == "cpu":
        start = time.process_time()
        call()
        return time.process_time() - start
    wp.synchronize_device(DEVICE)
    start = time.perf_counter()
    call()
    wp.synchronize_device(DEVICE)
    return time.perf_counter() - start


def whole_runs(args, out: dict) -> None:
    """(a): the controlled run, the fixed-Δt run of as many steps at its mean Δt, its Δt stepped bare;
    where the control launches tries ahead (``StepControl.lookahead``: CUDA), the controlled run
    without that too."""
    sim = build_run(args, args.days)
    controlled = cpu(lambda: sim.run(None))
    ctl = sim.control
    behind = None
    if ctl.lookahead:
        unlooked = build_run(args, args.days)
        unlooked.control.lookahead = False
        behind = cpu(lambda: unlooked.run(None)) / unlooked.control.accepted
    steps, dts = ctl.accepted, [dt for _, dt, _ in ctl.history]
    mean = ctl.dt_sum / steps
    fixed = build_run(args, steps * mean / 86400.0, dt=mean, control=False)
    fixed.stepper.carry_last_stage()  # an FSAL pair's last stage carried, as under control: s − 1 RHS a step
    fixed_cpu = cpu(lambda: fixed.run(None))
    bare = build_run(args, args.days)

    def stepped():
        for dt in dts:
            bare.stepper.set_dt(dt)
            bare.stepper.step(bare.x)

    bare_cpu = cpu(stepped)
    per = {
        "controlled": controlled / steps,
        "fixed": fixed_cpu / fixed.step,
        "bare": bare_cpu / len(dts),
    }
    row = {"accepted": steps, "rejected": ctl.rejected, "fixed_steps": fixed.step, "dt_mean": mean}
    row |= {"ahead_taken": ctl.ahead_taken, "ahead_dropped": ctl.ahead_dropped}
    row |= {"graphs_kept": sim.graphs_kept, "fixed_graphs_kept": fixed.graphs_kept}
    row |= {"courant_passes": ctl.courant_passes, "courant_queued": ctl.courant_queued}
    if behind is not None:
        per["no_lookahead"] = behind
    row |= {f"{k}_ms": v * 1e3 for k, v in per.items()}
    row |= {f"overhead_vs_{k}_pct": (per["controlled"] / per[k] - 1) * 100 for k in ("fixed", "bare")}
    out["whole_runs"] = row
    print(
        f"\n## TC5 ne{args.ne} {args.pair} {what(args)}, {args.days:g} days: {steps} steps accepted, "
        f"{ctl.rejected} rejected, dt {ctl.dt_smallest:.1f}/{mean:.1f}/{ctl.dt_largest:.1f} s"
    )
    print(
        f"controlled     {per['controlled'] * 1e3:8.3f} ms a step ({ctl.ahead_taken} tries launched ahead taken, {ctl.ahead_dropped} undone)"
    )
    if behind is not None:
        print(f"  no lookahead {behind * 1e3:8.3f} ms a step ({(behind / per['controlled'] - 1) * 100:+.1f} %)")
    print(f"fixed dt {mean:7.1f} s {per['fixed'] * 1e3:8.3f} ms a step ({fixed.step} steps)")
    print(f"step graphs kept: {sim.graphs_kept} controlled, {fixed.graphs_kept} fixed (each captured once)")
    if ctl.courant is not None:
        print(f"Courant cap passes: {ctl.courant_passes}, {ctl.courant_queued} queued before the try launched ahead")
    print(f"its dt, bare   {per['bare'] * 1e3:8.3f} ms a step")
    print(
        f"overhead: {row['overhead_vs_fixed_pct']:+.2f} % against the fixed dt, "
        f"{row['overhead_vs_bare_pct']:+.2f} % against its own steps bare"
    )


def parts(args, out: dict) -> None:
    """(b): a step at one Δt, at a new Δt every step, one error norm, one controlled step."""
    sim = build_run(args, 0.25)
    sim.run(None)  # records the launches, sets the control's proposal
    stepper, ctl, n = sim.stepper, sim.control, args.repeat
    dt = on_grid(ctl.dt)

    def steps(dts) -> float:
        def call():
            for d in dts:
                stepper.set_dt(d)
                stepper.step(sim.x)

        return cpu(call) / len(dts) * 1e3

    grid = [on_grid(dt * 2.0 ** (k / 16)) for k in range(-1, 2)]  # three neighbours on the controller's grid
    steps(grid)  # each recorded once
    one = steps([dt] * n)
    new = steps([dt * (1 - 1e-4 * (k + 1)) for k in range(n)])
    turn = steps([grid[k % len(grid)] for k in range(n)])
    if ctl.error:
        norm = cpu(lambda: [ctl.norm(stepper.error_estimate, ctl.x0, sim.x) for _ in range(n)]) / n * 1e3
    else:
        norm = cpu(lambda: [ctl.courant(sim.x, dt) for _ in range(n)]) / n * 1e3
    ctl.dt, t = dt, ctl.t

    def controlled():
        nonlocal t
        for _ in range(n):
            ctl.dt = dt
            t, _ = ctl.step(sim.x, t, t + 100 * dt)

    step = cpu(controlled) / n * 1e3
    row = {"one_dt_ms": one, "new_dt_ms": new, "grid_dt_ms": turn, "norm_ms": norm, "controlled_step_ms": step}
    row["dt"] = dt
    out["parts"] = row
    print(f"\n## TC5 ne{args.ne} {args.pair} {what(args)}: CPU ms of each part, {n} calls")
    print(f"a step at one dt ({dt:.1f} s)    {one:8.3f}")
    print(f"a new dt every step            {new:8.3f} ({(new / one - 1) * 100:+.2f} %)")
    print(f"three grid dt in turn          {turn:8.3f} ({(turn / one - 1) * 100:+.2f} %)")
    name = "one error norm" if ctl.error else "one Courant pass"
    print(f"{name:30s} {norm:8.3f} ({norm / one * 100:.2f} % of a step)")
    print(f"one controlled step (one dt)   {step:8.3f} ({(step / one - 1) * 100:+.2f} %)")


def graph_cost(args, out: dict) -> None:
    """(g): the controlled run, then the same run twice more from its start, its graphs kept."""
    sim = build_run(args, args.days)
    with tempfile.TemporaryDirectory() as tmp:
        start = checkpoint.read(sim.write_checkpoint(Path(tmp) / "start.nc"))
    first = cpu(lambda: sim.run(None))
    steps, end = sim.control.accepted, sim.x.numpy().copy()
    sim.restore(start)
    sim.run(None)  # captures the Δt the first run took once (a key's graph is made at its second step)
    kept = sim.graphs_kept
    sim.restore(start)
    again = cpu(lambda: sim.run(None))
    if sim.control.accepted != steps or (sim.x.numpy() != end).any() or sim.graphs_kept != kept:
        raise SystemExit("(g): a run again took other steps, reached other bits or captured a graph")
    mean = sim.control.dt_sum / steps
    fixed = build_run(args, steps * mean / 86400.0, dt=mean, control=False)
    fixed.stepper.carry_last_stage()
    fixed_s = cpu(lambda: fixed.run(None))
    row = {"accepted": steps, "graphs": kept}
    row |= {"first_ms": first / steps * 1e3, "kept_ms": again / steps * 1e3, "fixed_ms": fixed_s / fixed.step * 1e3}
    row["a_graph_ms"] = (first - again) / kept * 1e3
    out["graph_cost"] = row
    print(f"\n## TC5 ne{args.ne} {args.pair} {what(args)}, {args.days:g} days: {steps} steps, {kept} step graphs")
    print(f"controlled, first run    {row['first_ms']:8.3f} ms a step ({first / fixed_s:.3f}x the fixed dt)")
    print(f"the same, graphs kept    {row['kept_ms']:8.3f} ms a step ({again / fixed_s:.3f}x)")
    print(f"fixed dt {mean:7.1f} s      {row['fixed_ms']:8.3f} ms a step")
    print(f"each step graph costs the first run {row['a_graph_ms']:.3f} ms")


def profiled(args, out: dict) -> None:
    """(p): the controlled run and the fixed-Δt run of as many steps under cProfile."""
    sim = build_run(args, args.days)
    sim.run(None)
    ctl = sim.control
    steps, mean = ctl.accepted, ctl.dt_sum / ctl.accepted
    for name, make in (
        ("controlled", lambda: build_run(args, args.days)),
        ("fixed", lambda: build_run(args, steps * mean / 86400.0, dt=mean, control=False)),
    ):
        run = make()
        if name == "fixed":
            run.stepper.carry_last_stage()
        profile = cProfile.Profile()
        wp.synchronize_device(DEVICE)
        wall, host = time.perf_counter(), time.process_time()
        profile.enable()
        run.run(None)
        wp.synchronize_device(DEVICE)
        profile.disable()
        wall, host = time.perf_counter() - wall, time.process_time() - host
        out[f"profile_{name}"] = {"steps": steps, "wall_ms": wall / steps * 1e3, "host_cpu_ms": host / steps * 1e3}
        print(
            f"\n## {name}, {steps} steps under cProfile: wall {wall / steps * 1e3:.3f} ms a step, host CPU {host / steps * 1e3:.3f}"
        )
        stats = pstats.Stats(profile)
        stats.sort_stats("tottime").print_stats(args.profile_rows)
        # the control's own parts and the graphs' captures, with what they call
        stats.sort_stats("cumulative").print_stats(r"graphs\.py|adaptive\.py|control\.py|capture", args.profile_rows)


def control_overhead(argv: list[str]) -> None:
    """``control_overhead``: its options parsed from ``argv``, its runs, its results file."""
    parser = argparse.ArgumentParser(
        prog="control_ne30.py control_overhead", description=section(__doc__, "control_overhead")
    )
    parser.add_argument("--ne", type=int, default=30)
    parser.add_argument("--control", nargs="+", default=["error", "cfl"], choices=["error", "cfl"])
    parser.add_argument("--pair", default="bs32", help="the stepper under error control")
    parser.add_argument("--rtol", type=float, default=1e-5)
    parser.add_argument("--cfl-stepper", default="ssprk3", help="the stepper under CFL control")
    parser.add_argument("--cfl", type=float, default=1.0, help="the target Courant number under CFL control")
    parser.add_argument("--days", type=float, default=0.5)
    parser.add_argument("--repeat", type=int, default=40, help="calls timed in (b)")
    parser.add_argument("--parts", nargs="+", default=["a", "b"], choices=["a", "b", "g", "p"])
    parser.add_argument("--profile-rows", type=int, default=25, help="functions (p) prints a run")
    parser.add_argument("--results", help="results/control_overhead/<STEM>.json (default: the script's stem)")
    parser.add_argument("--device", default="cpu", help="cpu (CPU clock) or cuda (wall clock)")
    args = parser.parse_args(argv)
    global DEVICE
    DEVICE = args.device
    quiet_warp()
    with recorded(__file__, args.results, study="control_overhead") as figures:
        print(f"load average at the start: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
        figures["args"] = vars(args)
        for control in args.control:
            pair = args.pair if control == "error" else args.cfl_stepper
            one = argparse.Namespace(**{**vars(args), "control": control, "pair": pair})
            build_run(one, 0.125).run(None)  # warm-ups: every kernel compiled
            build_run(one, 0.125, control=False).run(None)
            figures[control] = {}
            if "a" in args.parts:
                whole_runs(one, figures[control])
            if "b" in args.parts:
                parts(one, figures[control])
            if "g" in args.parts:
                graph_cost(one, figures[control])
            if "p" in args.parts:
                profiled(one, figures[control])
        print(f"load average at the end: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    studies(__doc__, {name: globals()[name] for name in STUDIES})
