"""What step control (``[time] control = "error"`` or ``"cfl"``) costs a step beyond the step
itself, at ne30.

    SWE_SPHERE_THREADS=1 OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 \\
        python benchmarks/studies/control/control_overhead.py [--ne 30] [--control error cfl] [--pair bs32] [--rtol 1e-5]
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
import os
import pstats
import sys
import tempfile
import time
from pathlib import Path

import warp as wp

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # benchmarks/: results.py, the shared module
from results import quiet_warp, recorded

from swe_sphere import Simulation, load_scene
from swe_sphere.integrator.control import on_grid
from swe_sphere.simulation import checkpoint


def build(args, days, dt=None, control=True) -> Simulation:
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
    sim = build(args, args.days)
    controlled = cpu(lambda: sim.run(None))
    ctl = sim.control
    behind = None
    if ctl.lookahead:
        unlooked = build(args, args.days)
        unlooked.control.lookahead = False
        behind = cpu(lambda: unlooked.run(None)) / unlooked.control.accepted
    steps, dts = ctl.accepted, [dt for _, dt, _ in ctl.history]
    mean = ctl.dt_sum / steps
    fixed = build(args, steps * mean / 86400.0, dt=mean, control=False)
    fixed.stepper.carry_last_stage()  # an FSAL pair's last stage carried, as under control: s − 1 RHS a step
    fixed_cpu = cpu(lambda: fixed.run(None))
    bare = build(args, args.days)

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
    sim = build(args, 0.25)
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
    sim = build(args, args.days)
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
    fixed = build(args, steps * mean / 86400.0, dt=mean, control=False)
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
    sim = build(args, args.days)
    sim.run(None)
    ctl = sim.control
    steps, mean = ctl.accepted, ctl.dt_sum / ctl.accepted
    for name, make in (
        ("controlled", lambda: build(args, args.days)),
        ("fixed", lambda: build(args, steps * mean / 86400.0, dt=mean, control=False)),
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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
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
    args = parser.parse_args()
    global DEVICE
    DEVICE = args.device
    quiet_warp()
    with recorded(__file__, stem=args.results) as figures:
        print(f"load average at the start: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
        figures["args"] = vars(args)
        for control in args.control:
            pair = args.pair if control == "error" else args.cfl_stepper
            one = argparse.Namespace(**{**vars(args), "control": control, "pair": pair})
            build(one, 0.125).run(None)  # warm-ups: every kernel compiled
            build(one, 0.125, control=False).run(None)
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
    main()
