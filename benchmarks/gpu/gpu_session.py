"""The GPU measurements (agreement with the CPU, throughput, graphs, host reads, iterations), one subcommand each (driven by
``gpu_session.sh``, which time-boxes them and keeps their output under $OUT):

* ``agreement``: TC5 for ``--days`` on ``--ne``, every stepper (semi_implicit,
  implicit, imex at ``--dt-factor`` × Δt), on ``--device`` and on the CPU:
  max |h_dev − h_cpu| / max |h_cpu|, and of the tendency after one RHS.
* ``throughput``: a device copy (``wp.copy``, read + write counted) as the
  bandwidth reference, then one RHS (TC5, all terms + DSS, CUDA layout) per
  ``--ne``: µs, M points/s, GB/s of compulsory bytes (``rhs_throughput``'s
  count) and of bytes as launched (``gpu_model``'s), each as % of the copy.
* ``graphs``: µs a step of ``Simulation.run`` (TC5 from ``tc5_mountain_homme``,
  Δt 90 s at ne30, every explicit stepper), its steps launched one by one
  (``sim.graphs = False``) and replayed as CUDA graphs (the default on a GPU),
  the bad-state check read every ``check_every`` steps either way: the time
  loop's wall time over ``--graph-steps`` steps after 100, median of ``--runs``.
* ``bits``: TC5 for ``--steps`` steps (default 10) on ``--ne``, every stepper but
  ``tableau`` (semi_implicit, implicit, imex at ``--dt-factor`` × Δt) and ``dp54``
  under error control and ``ssprk3`` under CFL control, its steps launched one by
  one and replayed as graphs: the step graphs kept, and whether u, v, h have the
  same bits (issue 67 item 2).
* ``reads``: host reads (``.numpy()`` read-backs, ``swe_sphere.core.tally``) and
  launches a step of every stepper (semi_implicit, implicit, imex at
  ``--dt-factor`` × Δt; ``--steps`` steps after 2) on ``--device``, and
  whether ``Simulation`` replays its steps as graphs; ``--krylov kernels`` gives the
  Krylov steppers CUDA's backends of their vector work on a CPU (``host``: numpy's).
* ``floor``: where a small grid's step goes (issue 83 item 5): the default scenes (``galewsky``,
  ``tc5_mountain`` at ``--ne``, default 8 and 30), µs a step of ``Simulation.run``'s time loop, of
  one step's graph replayed in a bare Python loop, and of ``--chain`` steps captured as one graph
  (the host's share: the first against the second; the launches' own: the last), ``--graph-steps``
  steps each, median of ``--runs``. Timing only: a chained graph's bits are not checked.
* ``kernels``: where a step's GPU time goes: Warp's CUDA activity timing (``wp.timing_begin``,
  kernels, memsets and copies) over ``--steps`` plain-launched steps of the default scenes
  (``galewsky``, ``tc5_mountain`` at ``--ne``), µs a step and launches a step of each kernel.
* ``iterations``: the semi_implicit, imex and implicit steppers at
  ``--dt-factor`` × TC5's Δt: solver iterations per step on ``--device``
  (their device solvers) against the CPU (its defaults).
* ``precision``: float32 (or the float32 state, issue 128) and float64 side by side (issue 114 item 7; ``--precisions``): ``--scene`` at
  each ``--ne`` (default the scene's grid), one run a precision built at once, ``--warmup`` steps
  (compiles, records, captures), then ``--runs`` rounds of ``--graph-steps`` steps, the
  precisions in turn and their order swapped each round: ms a step (medians of the run's time
  loop, graphs on as a user's run on the card; with ``--members`` N > 1 N members of one
  Simulation in the same launches, 1 m perturbations of h) and simulated days a
  wall day; then max |h − h_float64| / max |h_float64| after the same steps, and (one member)
  ``floor``'s bare replays of one step's graph and of ``--chain`` steps a graph.
* ``card``: the summary of ``gpu_session.sh card``'s items in ``--folder`` (their results files,
  ``mpi.xml``, ``exchange.txt``, ``session.log``): one markdown table against issue 99's and 114's
  targets, the figures as ``--results``.

Medians of ``--repeat`` timings after a warm-up, synchronised; wall clock.
Runs on the CPU too (``--device cpu``, small ``--ne``) to check the script.

    python benchmarks/gpu/gpu_session.py throughput --ne 30 60 120 240
    python benchmarks/gpu/gpu_session.py agreement --ne 4 --days 0.2 --device cpu
    python benchmarks/gpu/gpu_session.py graphs --ne 30
    python benchmarks/gpu/gpu_session.py precision --scene tc5_mountain --ne 120 --graph-steps 1000 --chain
"""

from __future__ import annotations

import argparse
import dataclasses
import statistics
import sys
import time
from pathlib import Path

import numpy as np
import warp as wp

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: results.py, the shared module
from results import DAY, positive, recorded  # noqa: E402  (after the path: benchmarks/ first)

# isort: split
from card_tables import PRECISION_COLUMNS, card, header, precision_row  # noqa: E402
from gpu_model import IMPLICIT  # noqa: E402
from implicit_cost import use_krylov  # noqa: E402
from rhs_throughput import build, median_time, rhs_compulsory_bytes  # noqa: E402

from swe_sphere import (
    STEPPERS,  # noqa: E402
    Perturbation,  # noqa: E402
    Simulation,  # noqa: E402
    load_scene,  # noqa: E402
)
from swe_sphere.core.tally import Tally, instrumented  # noqa: E402


def _scene(name, ne, dt_factor, **kw):
    """TC5 on ne, np 4 with stepper ``name``; semi_implicit, implicit, imex at dt_factor × the scene's Δt."""
    scene = load_scene("tc5_mountain", ne=ne, np_=4, stepper=name, **kw)
    if name in IMPLICIT:  # the run rounded to whole steps of the longer Δt (one output, at its end)
        dt = scene.dt * dt_factor
        days = max(1, round(scene.days * DAY / dt)) * dt / DAY
        scene = dataclasses.replace(scene, dt=dt, days=days, output_every_days=days)
    return scene


def agreement(args):
    header(
        f"TC5 ne{args.ne[0]} np4, {args.days:g} days (semi_implicit, implicit, imex at {args.dt_factor:g}× Δt): "
        f"max|h_{args.device} − h_cpu| / max|h_cpu|",
        ["stepper", "after one RHS", "after the run", "steps", "wall s device", "wall s cpu"],
        5,
    )
    for name in args.steppers or STEPPERS:
        scene = _scene(name, args.ne[0], args.dt_factor, days=args.days)
        scene = dataclasses.replace(scene, output_every_days=args.days)
        h, rhs, wall, steps = {}, {}, {}, 0
        for device in (args.device, "cpu"):
            sim = Simulation(scene, device, progress=False)
            out = sim.model.new_state()
            sim.model.rhs(sim.x, out)
            rhs[device] = out.numpy()
            t0 = time.perf_counter()
            result = sim.run()
            wall[device], steps = time.perf_counter() - t0, result.steps
            h[device] = sim.fields()[2]
        d_rhs = np.max(np.abs(rhs[args.device] - rhs["cpu"])) / np.max(np.abs(rhs["cpu"]))
        d_h = np.max(np.abs(h[args.device] - h["cpu"])) / np.max(np.abs(h["cpu"]))
        print(
            f"| {name} | {d_rhs:.2e} | {d_h:.2e} | {steps} | {wall[args.device]:.1f} | {wall['cpu']:.1f} |", flush=True
        )


def copy_bandwidth(device, nbytes=2**30, repeat=10):
    """B/s of a device-to-device copy of nbytes (read + write counted)."""
    a = wp.zeros(nbytes // 8, dtype=wp.float64, device=device)
    b = wp.zeros_like(a)
    return 2 * nbytes / median_time(lambda: wp.copy(b, a), repeat, device)


def throughput(args):
    bw = copy_bandwidth(args.device, args.copy_mib * 2**20)
    header(
        f"device copy ({args.copy_mib} MiB, read + write): {bw / 1e9:.0f} GB/s",
        [
            "ne",
            "points",
            "RHS µs",
            "M pts/s",
            "compulsory B/pt",
            "GB/s",
            "% of copy",
            "launched B/pt",
            "GB/s",
            "% of copy",
        ],
        10,
    )
    runs = []
    for ne in args.ne:
        _, _, (_, _, state), model = build(ne, 4, 1, args.device)
        x, out = model.new_state(*state), model.new_state()
        runs.append((ne, model, x, out, median_time(lambda: model.rhs(x, out), args.repeat, args.device)))
    tally = Tally()
    for ne, model, x, out, t in runs:
        with instrumented(tally), tally.counting():  # after the timings: its wrappers cost host time per launch
            model.rhs(x, out)
        pts = model.N
        compulsory, launched = rhs_compulsory_bytes(model) / pts, tally.total_bytes / pts
        print(
            f"| {ne} | {pts} | {t * 1e6:.1f} | {pts / t / 1e6:.0f} | {compulsory:.0f} | {compulsory * pts / t / 1e9:.0f} | "
            f"{100 * compulsory * pts / t / bw:.0f} % | {launched:.0f} | {launched * pts / t / 1e9:.0f} | {100 * launched * pts / t / bw:.0f} % |",
            flush=True,
        )


def _stepper(name, ne, device, dt_factor):
    sim = Simulation(_scene(name, ne, dt_factor), device, progress=False)
    return sim, sim.stepper


def graphs(args):
    ne = args.ne[0]
    names = args.steppers or [n for n, cls in STEPPERS.items() if cls.capturable]
    header(
        f"TC5 ne{ne} np4 (tc5_mountain_homme's Δt): µs a step of Simulation.run, {args.graph_steps} steps after 100, "
        f"median of {args.runs}, plain launches and graphs ({args.device})",
        ["stepper", "Δt s", "plain µs", "graphs µs", "speed-up"],
        4,
    )
    for name in names:
        us = {}
        for graphed in (False, True):
            scene = load_scene("tc5_mountain_homme", ne=ne, np_=4, stepper=name)
            days = (100 + args.runs * args.graph_steps) * scene.dt / DAY
            sim = Simulation(dataclasses.replace(scene, days=days, output_every_days=days), args.device, progress=False)
            sim.graphs = graphed
            sim.run(None, until_step=100)  # compiles, records and captures
            times = []
            for k in range(args.runs):
                result = sim.run(None, until_step=100 + (k + 1) * args.graph_steps)
                times.append(result.loop_time / args.graph_steps)
            us[graphed] = statistics.median(times) * 1e6
        print(f"| {name} | {scene.dt:g} | {us[False]:.0f} | {us[True]:.0f} | {us[False] / us[True]:.2f} |", flush=True)


BITS_CONTROLLED = {
    "dp54+error": ("dp54", {"time.control": "error", "time.rtol": 1e-5}),
    "ssprk3+cfl": ("ssprk3", {"time.control": "cfl"}),
}


def bits(args):
    ne, steps = args.ne[0], args.steps
    header(
        f"TC5 ne{ne} np4, {steps} steps (semi_implicit, implicit, imex at {args.dt_factor:g}× Δt; {args.device}): "
        "plain launches against graphs",
        ["stepper", "Δt s", "graphs kept", "same bits", "max |Δh| m", "wall s plain", "wall s graphs"],
        5,
    )
    names = [n for n in STEPPERS if n != "tableau"]  # tableau reads a user's table file: its engine is rk4's
    for label in names + list(BITS_CONTROLLED):
        name, over = BITS_CONTROLLED.get(label, (label, {}))
        fields, kept, wall = {}, {}, {}
        for mode in ("off", "on"):
            scene = _scene(name, ne, args.dt_factor, overrides=over or None)
            days = steps * scene.dt / DAY
            scene = dataclasses.replace(scene, days=days, output_every_days=days)
            sim = Simulation(scene, args.device, progress=False, graphs=mode)
            t0 = time.perf_counter()
            sim.run(None)
            wall[mode] = time.perf_counter() - t0
            fields[mode] = sim.fields()
            kept[mode] = sim.graphs_kept
        same = all(
            np.array_equal(a.view(np.uint64), b.view(np.uint64))
            for a, b in zip(fields["off"], fields["on"], strict=True)
        )
        dh = float(np.max(np.abs(fields["off"][2] - fields["on"][2])))
        print(
            f"| {label} | {scene.dt:g} | {kept['on']} | {'yes' if same else 'NO'} | {dh:.1e} | {wall['off']:.2f} | {wall['on']:.2f} |",
            flush=True,
        )


def reads(args):
    ne = args.ne[0]
    krylov = f", Krylov work: {args.krylov}" if args.krylov else ""
    header(
        f"TC5 ne{ne} np4 (semi_implicit, implicit, imex at {args.dt_factor:g}× Δt; {args.steps} steps after 2, {args.device}{krylov}): "
        "host reads and launches a step",
        ["stepper", "graphs", "host reads a step", "launches a step"],
        3,
    )
    tally = Tally()
    for name in args.steppers or STEPPERS:
        sim, stepper = _stepper(name, ne, args.device, args.dt_factor)
        use_krylov(stepper, args.krylov)
        stepper.deferred = True  # as ``Simulation.run`` steps it: solvers' device counters read once a block, not here
        for _ in range(2):
            stepper.step(sim.x)
        with instrumented(tally), tally.counting():
            for _ in range(args.steps):
                stepper.step(sim.x)
        graphed = "yes" if stepper.capturable and stepper.graph_key() is not None else "no"
        print(
            f"| {name} | {graphed} | {tally.syncs / args.steps:.1f} | {tally.total_launches / args.steps:.1f} |",
            flush=True,
        )


def iterations(args):
    ne = args.ne[0]
    header(
        f"TC5 ne{ne} np4 at {args.dt_factor:g}× Δt: solver iterations per step ({args.steps} steps after 1), {args.device} vs cpu",
        ["stepper", "device", "iterations per step", "RHS per step", "ms per step"],
        2,
    )
    for name in args.steppers or IMPLICIT:
        for device in dict.fromkeys((args.device, "cpu")):
            sim, stepper = _stepper(name, ne, device, args.dt_factor)
            stepper.step(sim.x)
            total, rhs = {}, 0
            wp.synchronize_device(device)
            t0 = time.perf_counter()
            for _ in range(args.steps):
                stats = stepper.step(sim.x)
                rhs += stats.rhs_evals
                for k, v in stats.iterations.items():
                    total[k] = total.get(k, 0) + v
            wp.synchronize_device(device)
            ms = (time.perf_counter() - t0) / args.steps * 1e3
            its = ", ".join(f"{k} {v / args.steps:.1f}" for k, v in total.items())
            print(f"| {name} | {device} | {its} | {rhs / args.steps:.1f} | {ms:.1f} |", flush=True)


def _captured(stepper, x, dev, chain=1):
    """``chain`` steps of ``stepper`` on x captured as one CUDA graph."""
    with wp.ScopedCapture(device=dev, force_module_load=False) as capture:
        for _ in range(chain):
            stepper.step(x)
    return capture.graph


def _replayed(graph, dev, replays, chain=1) -> float:
    """Seconds a step of ``replays`` launches of a graph of ``chain`` steps from a bare loop, synchronised."""
    wp.synchronize_device(dev)
    t0 = time.perf_counter()
    for _ in range(replays):
        wp.capture_launch(graph)
    wp.synchronize_device(dev)
    return (time.perf_counter() - t0) / (replays * chain)


def floor(args):
    header(
        f"µs a step ({args.device}; {args.graph_steps} steps, median of {args.runs}): the run's loop, a graph a step "
        f"from a bare loop, {' and '.join(map(str, args.chain))} steps a graph",
        [
            "scene",
            "ne np",
            "stepper",
            "launches a step",
            "run loop",
            "graph a step",
            *(f"{k} a graph" for k in args.chain),
        ],
        3 + len(args.chain),
    )
    dev, n = wp.get_device(args.device), args.graph_steps
    for name, ne in [("galewsky", None), *(("tc5_mountain", ne) for ne in args.ne)]:
        scene = load_scene(name, ne=ne)
        days = (100 + (args.runs + 1) * n) * scene.dt / DAY
        sim = Simulation(dataclasses.replace(scene, days=days, output_every_days=days), args.device, progress=False)
        sim.run(None, until_step=100)  # compiles, records and captures
        loop = []
        for k in range(args.runs):
            loop.append(sim.run(None, until_step=100 + (k + 1) * n).loop_time / n)
        stepper, x = sim.stepper, sim.x
        tally = Tally()
        with instrumented(tally), tally.counting():
            stepper.step(x)
        row = [statistics.median(loop)]
        for chain in (1, *args.chain):
            graph = _captured(stepper, x, dev, chain)
            row.append(statistics.median(_replayed(graph, dev, max(1, n // chain), chain) for _ in range(args.runs)))
        cells = " | ".join(f"{t * 1e6:.1f}" for t in row)
        print(f"| {name} | {scene.ne} {scene.np} | {scene.stepper} | {tally.total_launches} | {cells} |", flush=True)


def kernels(args):
    for name, ne in [("galewsky", None), *(("tc5_mountain", ne) for ne in args.ne)]:
        scene = load_scene(name, ne=ne)
        sim = Simulation(scene, args.device, progress=False, graphs=False)
        for _ in range(3):  # compiles and records
            sim.stepper.step(sim.x)
        wp.synchronize_device(args.device)
        wp.timing_begin(cuda_filter=wp.TIMING_KERNEL | wp.TIMING_MEMCPY | wp.TIMING_MEMSET)
        t0 = time.perf_counter()
        for _ in range(args.steps):
            sim.stepper.step(sim.x)
        wp.synchronize_device(args.device)
        wall = (time.perf_counter() - t0) / args.steps
        results = wp.timing_end()
        spent, count = {}, {}
        for r in results:
            spent[r.name] = spent.get(r.name, 0.0) + r.elapsed * 1e3 / args.steps
            count[r.name] = count.get(r.name, 0) + 1
        total = sum(spent.values())
        header(
            f"{name} ne{scene.ne} np{scene.np} {scene.stepper} ("
            f"{sim.model.N} nodes): µs a step on the device, {args.steps} plain-launched steps; wall {wall * 1e6:.1f} µs a "
            f"step, the activities' sum {total:.1f} µs",
            ["kernel", "a step", "µs a step", "share"],
            3,
        )
        for k in sorted(spent, key=spent.get, reverse=True):
            print(f"| {k} | {count[k] / args.steps:g} | {spent[k]:.1f} | {spent[k] / (total or 1):.0%} |", flush=True)


def _precision_run(args, ne, precision, steps):
    """``args.scene`` at ``ne`` (None: the scene's) and ``precision`` with room for ``steps`` steps: the
    scene, the Simulation (with ``--members`` N > 1, N members in the same launches, 1 m
    perturbations of h seeded alike) and a call that steps it n steps and returns the seconds a step.
    Graphs "on": the card's default, and on a CPU (one thread) the same path."""
    scene = load_scene(args.scene, ne=ne, precision=precision)
    days = steps * scene.dt / DAY
    scene = dataclasses.replace(scene, days=days, output_every_days=days)
    many = (
        {"members": args.members, "initial": Perturbation(1.0, seed=1), "layout": "shared"} if args.members > 1 else {}
    )
    run, done = Simulation(scene, args.device, progress=False, graphs="on", **many), [0]

    def advance(n):  # the run's time loop, as ``graphs`` and ``floor`` time it
        done[0] += n
        return run.run(None, until_step=done[0]).loop_time / n

    return scene, run, advance


def precision(args, figures):
    dev, n, names = wp.get_device(args.device), args.graph_steps, args.precisions
    steps = args.warmup + args.runs * n
    figures.update(device=dev.name, warp=wp.config.version, rows=[])
    kind = f"{args.members} members in the same launches" if args.members > 1 else "one run"
    header(
        f"{args.scene}, {kind}, {' and '.join(names)} ({args.device}: {dev.name}): {args.warmup} steps, then "
        f"{args.runs} rounds of {n} steps, the precisions in turn (order swapped each round), medians",
        PRECISION_COLUMNS,
        len(PRECISION_COLUMNS) - 5,
    )
    for ne in args.ne or [None]:
        runs, build = {}, {}
        for name in names:
            t0 = time.perf_counter()
            runs[name] = _precision_run(args, ne, name, steps)
            runs[name][2](args.warmup)  # compiles, records and captures
            build[name] = time.perf_counter() - t0
        per_step = {name: [] for name in names}
        for k in range(args.runs):
            for name in names if k % 2 == 0 else names[::-1]:
                per_step[name].append(runs[name][2](n))
        h = {name: run.states()[0, 2] for name, (_, run, _) in runs.items()}  # member 0's h
        base = names[0]
        for name in names:
            scene, run, _ = runs[name]
            t = statistics.median(per_step[name])
            chained = {}  # floor's bare replays, after h: they step the state further
            for chain in (1, *args.chain) if args.members == 1 and args.chain else ():
                g = _captured(run.stepper, run.x, dev, chain)
                replays = [_replayed(g, dev, max(1, n // chain), chain) for _ in range(args.runs)]
                chained[chain] = 1e6 * statistics.median(replays)
            graph = chained.pop(1, None)
            row = {
                "scene": args.scene,
                "ne": scene.ne,
                "np": scene.np,
                "stepper": scene.stepper,
                "members": args.members,
                "precision": name,
                "graphs_kept": run.graphs_kept,  # 0: its steps launched plainly (a capture or check failed: stderr says)
                "dt": scene.dt,
                "build_s": build[name],
                "ms_a_step": 1e3 * t,
                "ms_a_member": 1e3 * t / args.members,
                "days_a_wall_day": scene.dt / t,
                "speedup": statistics.median(per_step[base]) / t,
                "graph_step_us": graph,
                "chained_us": chained,
                "h_rel_diff": float(np.max(np.abs(h[name] - h[base])) / np.max(np.abs(h[base]))),
                "rounds_ms": [1e3 * x for x in per_step[name]],
                "target": None,
                "met": None,
            }
            if args.target_ms is not None:
                row.update(target=f"≤ {args.target_ms:g} ms a step", met=row["ms_a_step"] <= args.target_ms)
            if args.target_days is not None:
                row.update(
                    target=f"≥ {args.target_days:,.0f} days a wall day", met=row["days_a_wall_day"] >= args.target_days
                )
            figures["rows"].append(row)
            print(precision_row(row), flush=True)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("part", choices=(*PARTS, "precision", "card"))
    p.add_argument("--device", default="cuda")
    p.add_argument(
        "--ne",
        type=int,
        nargs="+",
        default=None,
        help="grid(s), np 4 (default per part: 16 / 30 60 120 240 / 30 / 30; precision: the scene's)",
    )
    p.add_argument("--days", type=float, default=5.0)
    p.add_argument("--steppers", nargs="*", default=None)
    p.add_argument("--dt-factor", type=float, default=4.0, help="Δt of semi_implicit, implicit, imex × TC5's")
    p.add_argument(
        "--steps", type=int, default=None, help="reads, iterations: steps timed (default 3); bits: steps run (10)"
    )
    p.add_argument("--repeat", type=int, default=20)
    p.add_argument(
        "--graph-steps", type=positive(int), default=2000, help="graphs, floor, precision: steps a timed run"
    )
    p.add_argument("--runs", type=positive(int), default=5, help="graphs, floor: timed runs; precision: rounds")
    p.add_argument("--copy-mib", type=int, default=1024)
    p.add_argument(
        "--chain",
        type=int,
        nargs="*",
        default=[10, 50],
        help="floor, precision: steps captured as one graph (none: no replays)",
    )
    p.add_argument(
        "--krylov",
        choices=("host", "kernels"),
        default=None,
        help="reads: the Krylov vector work's backend (default: the device's)",
    )
    p.add_argument("--scene", default="tc5_mountain", help="precision: the scene")
    p.add_argument("--members", type=positive(int), default=1, help="precision: an ensemble of so many (1: a run)")
    p.add_argument("--warmup", type=positive(int), default=100, help="precision: steps before the rounds")
    p.add_argument(
        "--precisions",
        nargs="+",
        choices=("float64", "float32", "float32_state"),
        default=["float64", "float32"],
        help="precision: the first the baseline",
    )
    p.add_argument("--target-ms", type=float, default=None, help="precision: a target, ms a step at most")
    p.add_argument("--target-days", type=float, default=None, help="precision: a target, simulated days a wall day")
    p.add_argument("--folder", default=".", help="card: the folder of the card's items")
    p.add_argument("--results", help="results/gpu_session/<STEM>.json (default: the script's stem; a path: there)")
    args = p.parse_args(argv)
    args.steps = args.steps or {"bits": 10, "kernels": 20}.get(args.part, 3)
    if args.part != "precision":
        args.ne = args.ne or {
            "agreement": [16],
            "throughput": [30, 60, 120, 240],
            "floor": [8, 30],
            "kernels": [30, 120],
        }.get(args.part, [30])
    wp.config.quiet = True  # Warp < 1.10; newer Warp reads log_level (as tests/conftest.py)
    if hasattr(wp, "LOG_WARNING"):
        wp.config.log_level = wp.LOG_WARNING
    with recorded(__file__, stem=args.results) as figures:
        if args.part == "card":  # reads files: no device
            card(args, figures)
            return
        wp.init()
        if args.part == "precision":
            precision(args, figures)
        else:
            PARTS[args.part](args)


PARTS = {
    "agreement": agreement,
    "throughput": throughput,
    "graphs": graphs,
    "bits": bits,
    "reads": reads,
    "iterations": iterations,
    "floor": floor,
    "kernels": kernels,
}

if __name__ == "__main__":
    main()
