"""Local time stepping (``lts``, ``steppers.local``) on a refined mesh, TC5, np 4: what it saves,
what its parts cost and how its work spreads over ranks. One subcommand a study, each written to
``results/lts/<study>.json``::

    export SWE_SPHERE_THREADS=1 OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1
    python benchmarks/studies/lts.py study --mesh PATH/mountain_10_x2.g --days 3
    python benchmarks/studies/lts.py level_cost --mesh PATH/mountain_10_x2.g
    python benchmarks/studies/lts.py step_cost --mesh PATH/mountain_10_x2.g --dt 234.783 \\
        --options '{"method": "mrab3", "level_margin": 1.3}'
    python benchmarks/studies/lts.py partition --mesh MESH.g [--ranks 2 3 4 8]

``study``
~~~~~~~~~
``lts`` against the global explicit steppers, CPU clock, one thread: each stepper's largest
Δt within an accuracy, and its CPU seconds per simulated day there. First a reference: RK4 at
Δt = 86400/``--k-ref`` s over ``--days`` days of TC5 (the scene's ∇⁴). Then for each stepper the
largest Δt = 86400/k s (whole steps a day; k bisected over ``--k-range``) whose run does not blow
up and whose final depth is within ``--tol`` of the reference's (max-norm, relative: the temporal
error; at its stability limit a run that has not blown up yet can be far off), and at that Δt the
median CPU time (``time.process_time`` of ``Simulation.run``) of ``--rounds`` runs.

``level_cost``
~~~~~~~~~~~~~~
A level's tendency evaluation against its element count, CPU clock: does
``rhs_part`` cost in proportion to the elements it runs over? TC5's tendency terms (continuity,
momentum advection, Coriolis, pressure gradient, topography), one thread: the levels from the
initial flow (``grid.levels``, at most ``--max-levels``), then per level (and for the levels finer
than the coarsest together, the ``lts`` fast part) the CPU time of one ``ShallowWater.rhs_part``
(tendency kernels over the level's element ranges, merged over gaps of up to ``--gap`` other
elements, the DSS over the nodes it touches) and of the whole-grid ``rhs``; µs per element
evaluated and the ratio to the whole grid's, rounds interleaved, medians.

``step_cost``
~~~~~~~~~~~~~
Where a step goes, the ∇⁴ and the dynamics, and for ``method = "mrab3"`` its level
parts' evaluations and its sub-step sums; CPU clock, one thread. The scene's TC5 at ``--dt`` with
``--stepper`` and its options (``--options``, a JSON table), three steps taken first (past
MRAB3's start); then the median over ``--rounds`` of the mean CPU time of ``--calls`` calls: a
step, the ∇⁴ over dt (``ShallowWater.hyperviscosity``), the whole grid's RHS, and for MRAB3 each
level's ``rhs_part`` (times its 2^k evaluations a step) and each level's sums at each of the 2^K
finest sub-steps. A step's dynamics is the step less the ∇⁴.

``partition``
~~~~~~~~~~~~~
How evenly lts's work is spread over MPI ranks, the curve's chunks against each
level cut along the curve (``partition.level_chunks``, what a run of ``lts`` on several ranks
uses). The levels lts steps (from the flow) and those the partition is made from (from the
elements' sizes alone); for each rank count, the largest rank's work over the mean (work:
Σ 2^level over its elements, the evaluations of a coarse step), each level's largest share over
the mean, and the element pairs that share a node across ranks (what the DSS exchanges grow
with). No timing: the figures are the partition's.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np
import warp as wp

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tests"))  # meshes.case_model

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: results.py, the shared module
from results import DAY, positive, quiet_warp, recorded, section, studies, timed  # noqa: E402  (after the path: benchmarks/ first)

from swe_sphere import BlowUp, CubedSphere, Simulation, load_scene  # noqa: E402
from swe_sphere.grid.levels import element_levels, element_neighbours, element_rates  # noqa: E402
from swe_sphere.grid.topology import rank_parts  # noqa: E402
from swe_sphere.model.parts import ElementPart  # noqa: E402
from swe_sphere.steppers.local import size_levels  # noqa: E402

from meshes import case_model  # noqa: E402

TC5_TERMS = ["continuity", "momentum_advection", "coriolis", "pressure_gradient", "topography"]
STEPPERS = {  # study's label → (stepper, options)
    "rk4": ("rk4", {}),
    "kgu35": ("kgu35", {}),
    "ssprk3": ("ssprk3", {}),
    "lts MIS4a/rk4, 2 levels": ("lts", {"max_levels": 2}),
    "lts MIS4a/rk4, 3 levels": ("lts", {"max_levels": 3}),
    "lts MRI-GARK-ERK33a/rk4, 3 levels": ("lts", {"max_levels": 3, "method": "mri_gark_erk33a"}),
    "lts MIS4a/rk4, 3 levels, substeps 1": ("lts", {"max_levels": 3, "substeps": 1}),
    "lts MIS4a/rk4, 3 levels, substeps 2": ("lts", {"max_levels": 3, "substeps": 2}),
    "lts MRAB3, 1 level (AB3)": ("lts", {"method": "mrab3", "max_levels": 1}),
    "lts MRAB3, 2 levels": ("lts", {"method": "mrab3", "max_levels": 2}),
    "lts MRAB3, 3 levels": ("lts", {"method": "mrab3", "max_levels": 3}),
    "lts MRAB3, 2 levels, margin 1.3": ("lts", {"method": "mrab3", "max_levels": 2, "level_margin": 1.3}),
    "lts MRAB3, 3 levels, margin 1.3": ("lts", {"method": "mrab3", "max_levels": 3, "level_margin": 1.3}),
}


def tc5(mesh: str, days: float, stepper: str, options: dict, dt: float | None = None, **changes) -> Simulation:
    """The scene's TC5 on ``mesh`` for ``days`` with ``stepper`` and its ``options``, one output at
    the end, on the CPU; ``dt`` s (None: the scene's); ``changes`` other fields of its ``Scene``."""
    scene = load_scene("tc5_mountain", mesh=mesh, dt=dt, days=days, stepper=stepper)
    scene = dataclasses.replace(scene, stepper_options=options, output_every_days=days, **changes)
    return Simulation(scene, "cpu", progress=False)


def run(mesh, days, stepper, options, k):
    """(final depth, CPU s, the Simulation) of TC5 at Δt = DAY/k; None if it blows up."""
    sim = tc5(mesh, days, stepper, options, DAY / k)
    start = time.process_time()
    try:
        sim.run(None)
    except BlowUp:
        return None
    return sim.fields()[2], time.process_time() - start, sim


def error(result, ref) -> float:
    """The final depth's max-norm difference from the reference's, relative (inf: blown up)."""
    return math.inf if result is None else float(np.abs(result[0] - ref).max() / np.abs(ref).max())


def largest_accurate(args, stepper, options, ref):
    """The least k in ``args.k_range`` (Δt = DAY/k) whose run is within ``args.tol`` of
    ``ref``, bisected (taken as monotone in Δt); None if the largest k is not."""
    lo, hi = args.k_range

    def bad(k) -> bool:  # blown up, or (unless --tol inf: stability alone) too far off
        result = run(args.mesh, args.days, stepper, options, k)
        return result is None or error(result, ref) > args.tol

    if bad(hi):
        return None
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if bad(mid):
            lo = mid
        else:
            hi = mid
    return hi


def steppers_compared(args) -> None:
    """Each stepper's largest accurate Δt and its CPU seconds a simulated day there."""
    ref = run(args.mesh, args.days, "rk4", {}, args.k_ref)[0]
    rows = []
    for label, (stepper, options) in STEPPERS.items():
        if args.only and label != "rk4" and label not in args.only:
            continue
        k = largest_accurate(args, stepper, options, ref)
        if k is None:
            print(f"{label}: none within {args.tol:g}", flush=True)
            continue
        runs = [run(args.mesh, args.days, stepper, options, k) for _ in range(args.rounds)]
        cpu = statistics.median(r[1] for r in runs) / args.days
        levels = runs[0][2].stepper.describe()[0] if stepper == "lts" else ""
        rows.append((label, DAY / k, cpu, error(runs[0], ref), levels))
        print(f"{label}: dt {DAY / k:.1f} s, {cpu:.3f} CPU s/day", flush=True)
    print(
        f"\nTC5 {args.days:g} days on {os.path.basename(args.mesh)}, temporal error <= {args.tol:g} "
        f"(RK4 at {DAY / args.k_ref:g} s), load average {os.getloadavg()[0]:.2f}"
    )
    print(f"{'':36s} {'dt (s)':>8s} {'CPU s/day':>10s} {'/ rk4':>6s} {'error h':>10s}  levels")
    base = next(cpu for label, _, cpu, _, _ in rows if label == "rk4")
    for label, dt, cpu, err, levels in rows:
        print(f"{label:36s} {dt:8.1f} {cpu:10.3f} {cpu / base:6.2f} {err:10.2e}  {levels}")


def level_costs(args) -> None:
    """Each level's ``rhs_part`` against the whole grid's ``rhs``, µs an element."""
    grid = CubedSphere(0, 4, mesh=load_scene("tc5_mountain", mesh=args.mesh).make_mesh())
    case, model = case_model(grid, "tc5_mountain", TC5_TERMS, threads=1)
    x = model.new_state(*np.stack(case.initial(grid.lat, grid.lon)))
    levels = element_levels(grid, element_rates(grid, x.numpy(), model.g), args.max_levels)
    print(f"{Path(args.mesh).name}: {grid.nelem} elements; {levels.describe()}")
    out = wp.zeros_like(x)
    calls = {"whole grid": (grid.nelem, lambda: model.rhs(x, out))}
    sets = {f"level {k}": levels.level == k for k in range(levels.count)}
    if levels.count > 2:
        sets["levels >= 1 (lts's fast part)"] = levels.level >= 1
    for gap in args.gap:
        for name, chosen in sets.items():
            part = ElementPart.of(model, np.flatnonzero(chosen), gap)
            buf = wp.zeros_like(x)
            label = f"{name}, gap {gap}: {len(part.runs)} ranges"
            calls[label] = (part.nelem, lambda p=part, b=buf: model.rhs_part(x, b, p))
    for _, call in calls.values():
        call()  # compiled and recorded outside the clock
    times: dict = {name: [] for name in calls}
    for _ in range(args.rounds):
        for name, (_, call) in calls.items():
            start = time.process_time()
            for _ in range(args.calls):
                call()
            times[name].append((time.process_time() - start) / args.calls)
    whole = statistics.median(times["whole grid"]) / grid.nelem
    print(f"load average {os.getloadavg()[0]:.2f}; CPU time per evaluation, medians of {args.rounds} rounds")
    print(f"{'':44s} {'elements':>8s} {'ms':>8s} {'us/element':>11s} {'/ whole':>8s}")
    for name, (nelem, _) in calls.items():
        t = statistics.median(times[name])
        print(f"{name:44s} {nelem:8d} {t * 1e3:8.3f} {t / nelem * 1e6:11.2f} {t / nelem / whole:8.2f}")


def step_costs(args) -> None:
    """A step, its ∇⁴, the whole RHS and MRAB3's level parts and sums, CPU ms."""
    options = json.loads(args.options)
    changes = {} if args.hypervis_scaling is None else {"hypervis_scaling": args.hypervis_scaling}
    sim = tc5(args.mesh, 8 * args.dt / DAY, args.stepper, options, args.dt, **changes)  # whole steps
    stepper, model, x = sim.stepper, sim.model, sim.x
    for _ in range(3):
        stepper.step(x)
    out = model.new_state()
    ms = lambda f: timed(f, args.calls, args.rounds)  # noqa: E731
    step = ms(lambda: stepper.step(x))
    hv = ms(lambda: model.hyperviscosity(x, args.dt))
    rhs = ms(lambda: model.rhs(x, out))
    per_day = DAY / args.dt / 1e3
    print(
        f"TC5 on {os.path.basename(args.mesh)}, {args.stepper} {options}, dt {args.dt:g} s, load {os.getloadavg()[0]:.2f}"
    )
    print(f"  step {step:.3f} ms: the ∇⁴ {hv:.3f} ms (plan {model.hv.plan(args.dt)}), the dynamics {step - hv:.3f} ms")
    print(f"  the whole grid's RHS {rhs:.3f} ms; a simulated day {step * per_day:.3f} s, the ∇⁴ {hv * per_day:.3f} s")
    mrab = getattr(stepper, "mrab", None)
    if mrab is not None:
        parts = sum(ms(lambda k=k: mrab.evaluate(k, x, mrab.scratch[k])) * 2**k for k in range(mrab.levels))
        sums = sum(
            ms(lambda j=j, k=k: mrab.accumulate(x, j, k)) for j in range(mrab.substeps()) for k in range(mrab.levels)
        )
        print(f"  {stepper.levels.describe()}: level parts {parts:.3f} ms a step, sub-step sums {sums:.3f} ms a step")


def rank_balance(args) -> None:
    """The ranks' work over the mean, per level, and the element pairs across ranks."""
    options = {"method": "mrab3", "max_levels": args.max_levels, "level_margin": args.level_margin}
    sim = Simulation(load_scene("tc5_mountain", mesh=args.mesh, days=0.01, stepper="lts"), "cpu", progress=False)
    grid = sim.grid
    flow = element_levels(grid, element_rates(grid, sim.x.numpy(), sim.model.g), args.max_levels, args.level_margin)
    sizes = size_levels(grid, options)
    print(
        f"{args.mesh}: levels from the flow {flow.elements_per_level()}, from the sizes "
        f"{np.bincount(sizes).tolist()} ({int(np.sum(sizes != flow.level))} elements differ)"
    )
    pairs = element_neighbours(grid).tocoo()
    print("| ranks | partition | work max/mean | each level's max/mean | element pairs across ranks |")
    print("|---:|---|---:|---|---:|")
    for size in args.ranks:
        for name, level in (("curve", None), ("each level", sizes)):
            parts = rank_parts(0, size, grid.mesh, level)
            owner = np.empty(grid.nelem, dtype=np.int64)
            for r, p in enumerate(parts):
                owner[p] = r
            per = np.array([np.bincount(flow.level[p], minlength=flow.count) for p in parts])
            work = per @ 2.0 ** np.arange(flow.count)
            shares = ", ".join(f"{c.max() / c.mean():.2f}" for c in per.T)
            cut = int(np.sum(owner[pairs.row] != owner[pairs.col]) // 2)
            print(f"| {size} | {name} | {work.max() / work.mean():.2f} | {shares} | {cut} |")


def options(study: str) -> argparse.ArgumentParser:
    """The parser of ``study``'s options, the mesh among them (argparse's one line and exit 2 for a bad one)."""
    parser = argparse.ArgumentParser(prog=f"lts.py {study}", description=section(__doc__, study))
    parser.add_argument("--mesh", required=True, help="an Exodus .g file (a refined mesh)")
    return parser


def study(argv: list[str]) -> None:
    """``study``: its options from ``argv``, its runs, its results file."""
    p = options("study")
    # whole days: every dt searched is a day over a whole number of steps (DAY / k)
    p.add_argument("--days", type=positive(int), default=3)
    p.add_argument("--k-range", type=int, nargs=2, default=(24, 480), help="steps a day searched")
    p.add_argument("--k-ref", type=int, default=1920, help="the reference's steps a day")
    p.add_argument(
        "--tol", type=float, default=1e-4, help="temporal error allowed (max-norm of h, relative; inf: stability alone)"
    )
    p.add_argument("--rounds", type=positive(int), default=3)
    p.add_argument("--only", nargs="*", help="these steppers' labels alone (and rk4, the reference)")
    args = p.parse_args(argv)
    quiet_warp()
    with recorded(__file__, "study"):
        steppers_compared(args)


def level_cost(argv: list[str]) -> None:
    """``level_cost``: its options from ``argv``, its runs, its results file."""
    p = options("level_cost")
    p.add_argument("--max-levels", type=positive(int), default=3)
    p.add_argument("--rounds", type=positive(int), default=7)
    p.add_argument("--calls", type=positive(int), default=50, help="evaluations timed a round")
    p.add_argument("--gap", type=int, nargs="+", default=[0, 4, 16, 64], help="merge a level's ranges over gaps up to")
    args = p.parse_args(argv)
    quiet_warp()
    with recorded(__file__, "level_cost"):
        level_costs(args)


def step_cost(argv: list[str]) -> None:
    """``step_cost``: its options from ``argv``, its runs, its results file."""
    p = options("step_cost")
    p.add_argument("--dt", type=positive(float), required=True, help="s")
    p.add_argument("--stepper", default="lts")
    p.add_argument("--options", default="{}", help="the stepper's options, a JSON table")
    p.add_argument("--hypervis-scaling", type=float, help="the tensor ∇⁴'s s (default: the scene's constant ν)")
    p.add_argument("--calls", type=positive(int), default=20)
    p.add_argument("--rounds", type=positive(int), default=3)
    args = p.parse_args(argv)
    quiet_warp()
    with recorded(__file__, "step_cost"):
        step_costs(args)


def partition(argv: list[str]) -> None:
    """``partition``: its options from ``argv``, its figures, its results file."""
    p = options("partition")
    p.add_argument("--ranks", type=positive(int), nargs="+", default=[2, 3, 4, 8])
    p.add_argument("--max-levels", type=positive(int), default=3)
    p.add_argument("--level-margin", type=float, default=1.3)
    args = p.parse_args(argv)
    with recorded(__file__, "partition"):
        rank_balance(args)


if __name__ == "__main__":
    studies(__doc__, {name: globals()[name] for name in ("study", "level_cost", "step_cost", "partition")})
