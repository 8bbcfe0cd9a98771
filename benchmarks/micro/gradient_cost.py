"""The CPU cost of a gradient (``swe_sphere.gradient``) against the forward run it differentiates.

    python benchmarks/micro/gradient_cost.py [--scene tc5_mountain] [--stepper rk4] [--ne 4 8]
        [--steps 48 | --days D] [--dt DT] [--snapshots S] [--disk [FOLDER]] [--disk-interval K]
        [-s time.control=error -s time.rtol=5e-6] [--repeat 3] [--source DIR ...]

A scene of testcases/ (default TC5; np 4, the stepper at the scene's Δt rescaled to the grid or
``--dt`` s, its ∇⁴), a height misfit
of the final state, ``--snapshots`` states held in the reverse sweep (default every state;
fewer: binomial checkpointing, its forward steps printed); ``--days`` sets the steps to the
scene's Δt's count in that many days (issue 66's target: ``--scene galewsky --stepper kgu35
--ne 16 --days 6 --dt 403.7383177570093 --snapshots 30``, the Δt of the scene's former default
at ne16 np4, 86400/214 s). ``--disk`` times, in the same runs, the two-level gradient
besides (``gradient(..., disk=FOLDER or True, disk_interval=K)``: states every K steps, default
``--snapshots``, in a temporary file, each segment reversed with ``--snapshots`` in memory): its
CPU s, forward steps, the file's bytes, its ratios to the forward steps and to the gradient in
memory alone, and whether the two gradients are the same bits. Each ``--source`` (a tree of swe_sphere: a clone, or
``git archive COMMIT | tar -x -C DIR``) runs in a one-thread child process
(``SWE_SPHERE_THREADS=1``), which times with the process's CPU clock, medians of ``--repeat``:
the forward run (``steps`` steps of the stepper, its model built), the same with the model
built (a whole run, as the gradient builds its own), the whole ``gradient`` call
(the model and the adjoint built, the forward sweep, the reverse sweep), and the model's
construction alone. The ratios are gradient / forward and gradient / run; the target of issue 66 is ≤ 4.

``-s KEY=VALUE`` overrides the scene as ``swe-sphere run -s`` does; under ``time.control`` the
"run" is the controlled run itself (a ``Simulation`` over the span: its steps, rejected tries and
control), "forward" its accepted steps replayed by the stepper alone at their Δt (``StepTimes``), and
the gradient follows that run's history (``gradient(..., history=)``): "steps" its accepted steps.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: results.py, the shared module
from results import check_sources, recorded

from swe_sphere.cli.values import overrides

ROOT = Path(__file__).resolve().parents[2]

CHILD = """
import dataclasses, json, statistics, sys, time
import numpy as np
import warp as wp
wp.config.quiet = True
from swe_sphere import HeightMisfit, Simulation, gradient, load_scene
from swe_sphere.adjoint.gradient import scene_model
from swe_sphere.core.clock import StepTimes

ne, steps, repeat, path, stepper_name = int(sys.argv[1]), float(sys.argv[2]), int(sys.argv[3]), sys.argv[4], sys.argv[5]
snapshots = None if sys.argv[6] == "all" else int(sys.argv[6])
disk = {"none": None, "temp": True}.get(sys.argv[7], sys.argv[7])
interval = None if sys.argv[8] == "none" else int(sys.argv[8])
dt = None if sys.argv[9] == "scene" else float(sys.argv[9])
scene = load_scene(path, ne=ne, np_=4, stepper=stepper_name, dt=dt, overrides=json.loads(sys.argv[10]))
steps = int(steps) if steps > 0 else round(-steps * 86400.0 / scene.dt)  # negative: days
span = dataclasses.replace(scene, days=steps * scene.dt / 86400.0)  # a controlled run's: its time span
model, stepper, x0 = scene_model(scene)
cost = HeightMisfit(x0[2] + 10.0)
clock = time.process_time


def controlled_run():
    sim = Simulation(span, "cpu", progress=False)
    sim.run(None)
    return sim.control.history


history = controlled_run() if scene.control else None  # compiled too
steps, every = (steps, StepTimes(0.0, scene.dt)) if history is None else (len(history), StepTimes(0.0, scene.dt, history))
gradient(scene, 2, cost, snapshots=min(2, snapshots or 2), history=history)  # compile and warm the caches
rows = {"forward": [], "run": [], "gradient": [], "model": []} | ({"two_level": []} if disk else {})


def replay(st):
    x = wp.array(x0, dtype=wp.float64, device=st.model.device)
    st.prepare(x)
    for k in range(steps):
        every.set(st, k)
        st.advance(x)


for _ in range(repeat):
    t = clock()
    scene_model(scene)
    rows["model"].append(clock() - t)
    t = clock()
    replay(stepper)
    rows["forward"].append(clock() - t)
    t = clock()  # a whole run as ``gradient`` makes one (a new model, its ∇⁴ plan, the steps), or the controlled run
    if history is None:
        replay(scene_model(scene)[1])
    else:
        controlled_run()
    rows["run"].append(clock() - t)
    t = clock()
    g = gradient(scene, steps, cost, snapshots=snapshots, history=history)
    rows["gradient"].append(clock() - t)
    if disk:
        t = clock()
        d = gradient(scene, steps, cost, snapshots=snapshots, disk=disk, disk_interval=interval, history=history)
        rows["two_level"].append(clock() - t)
taken = {"steps": steps, "forward_steps": g.forward_steps, "dt": scene.dt}
if history is not None:
    taken |= {"distinct_dt": len({dt for _, dt, _ in history}), "dt_mean": span.days * 86400.0 / steps}
if disk:
    same = bool(np.array_equal(d.grad, g.grad) and d.cost == g.cost)
    taken |= {"two_level_forward_steps": d.forward_steps, "disk_bytes": d.disk_bytes, "same_bits": same}
print(json.dumps({k: statistics.median(v) for k, v in rows.items()} | taken))
"""


def measure(
    source: str | None, ne: int, steps: float, repeat: int, scene: str, stepper: str, snapshots, disk, dt=None, sets=()
) -> dict:
    """The child's medians (CPU s) for one tree and grid; steps < 0: that many days; ``disk``
    (folder or True, interval or None) or None: the two-level gradient besides; ``dt`` s or None
    (the scene's, rescaled); ``sets`` the ``-s`` pairs."""
    env = dict(os.environ, SWE_SPHERE_THREADS="1", OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1")
    if source is not None:
        env["PYTHONPATH"] = os.pathsep.join([source, *filter(None, [os.environ.get("PYTHONPATH")])])
    path = str(ROOT / "testcases" / f"{scene}.toml")
    folder, interval = disk or (None, None)
    folder = {None: "none", True: "temp"}.get(folder, folder)
    args = [sys.executable, "-c", CHILD, str(ne), str(steps), str(repeat), path, stepper, str(snapshots or "all")]
    args += [
        str(folder),
        str(interval or "none"),
        "scene" if dt is None else repr(float(dt)),
        json.dumps(overrides(sets)),
    ]
    out = subprocess.run(args, env=env, cwd=source or ROOT, capture_output=True, text=True)  # -c puts the cwd first
    if out.returncode:
        raise SystemExit(f"ne{ne} ({source or 'default'}): exit {out.returncode}\n{out.stderr[-2000:]}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scene", default="tc5_mountain", help="a scene of testcases/ (its file's stem)")
    parser.add_argument("--stepper", default="rk4", help="an explicit Runge–Kutta table, or fbrk32")
    parser.add_argument("--ne", type=int, nargs="+", default=[4, 8])
    parser.add_argument("--steps", type=int, default=48)
    parser.add_argument("--days", type=float, help="the steps in this many days instead of --steps")
    parser.add_argument("--dt", type=float, help="the step, s (default: the scene's, rescaled to the grid)")
    parser.add_argument("--snapshots", type=int, help="states held in the reverse sweep (default: every state)")
    parser.add_argument(
        "--disk",
        nargs="?",
        const=True,
        help="also the two-level gradient, its states in FOLDER (default: a temporary folder)",
    )
    parser.add_argument(
        "--disk-interval", type=int, help="K, the steps between the states on the disk (default --snapshots)"
    )
    parser.add_argument("-s", dest="sets", action="append", default=[], help="KEY=VALUE: the scene overridden")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--source", nargs="+", default=[None], help="swe_sphere trees (default: the one Python finds)")
    parser.add_argument("--results", help="results/gradient_cost/<STEM>.json (default: the script's stem)")
    args = parser.parse_args()
    check_sources(parser, args.source)
    if args.steps < 1 or (args.days is not None and not args.days > 0):
        parser.error(f"--steps must be >= 1 and --days > 0 (got {args.steps}, {args.days})")
    if args.disk not in (None, True) and not Path(args.disk).is_dir():
        parser.error(f"--disk {args.disk}: not an existing folder")
    steps = -args.days if args.days else args.steps
    held = f"{args.snapshots} states held" if args.snapshots else "every state held"
    with recorded(__file__, args.results) as figures:
        span = f"{args.days} days" if args.days else f"{args.steps} steps"
        print(
            f"{args.scene} {args.stepper} np4, {span}, {held}, one thread, CPU s (medians of {args.repeat}); "
            f"load {os.getloadavg()}"
        )
        for ne in args.ne:
            for source in args.source:
                disk = (args.disk, args.disk_interval) if args.disk else None
                r = measure(
                    source, ne, steps, args.repeat, args.scene, args.stepper, args.snapshots, disk, args.dt, args.sets
                )
                ratio, whole = r["gradient"] / r["forward"], r["gradient"] / r["run"]
                figures[f"ne{ne} {source or 'default'}"] = r | {"ratio": ratio, "ratio_run": whole}
                if args.disk:
                    two = {
                        k: r["two_level"] / r[d]
                        for k, d in [("forward", "forward"), ("run", "run"), ("memory", "gradient")]
                    }
                    figures[f"ne{ne} {source or 'default'}"] |= {f"two_level_ratio_{k}": v for k, v in two.items()}
                print(
                    f"ne{ne} dt {r['dt']:.1f} s, {r['steps']} steps ({r['forward_steps']} taken forward by the gradient)"
                    f"  {source or 'default'}: forward {r['forward']:.4f}, "
                    f"run {r['run']:.4f}, gradient {r['gradient']:.4f} ({ratio:.2f}× the forward, {whole:.2f}× the run; "
                    f"the model's construction {r['model']:.4f})"
                )
                if "distinct_dt" in r:
                    print(f"  under control: mean dt {r['dt_mean']:.1f} s, {r['distinct_dt']} distinct dt")
                if args.disk:
                    print(
                        f"  two-level: {r['two_level']:.4f} ({two['forward']:.2f}× the forward, {two['run']:.2f}× the run, "
                        f"{two['memory']:.3f}× the gradient in memory), {r['two_level_forward_steps']} steps taken forward, "
                        f"{r['disk_bytes']} bytes on the disk, the same bits as in memory: {r['same_bits']}"
                    )


if __name__ == "__main__":
    main()
