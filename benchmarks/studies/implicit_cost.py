"""What an implicit-type or exponential step costs, broken down, against the best explicit stepper.

Per configuration (case, stepper, Δt as a multiple of the gravity-wave limit
Δt_g = min Δx / max sqrt(g h) of the initial state), one interleaved run:
every configuration is built, spun up (``--spinup`` simulated hours, untimed:
TC5's first hours take more CG iterations a step, 53 at IMEX @ 8 Δt_g ne30 in
hours 0–6 against a steady 40–41 from hour 12 to day 3, so early steps overstate
a day's cost) and warmed up (``--warmup`` steps), then the
timed steps go round-robin over the configurations and the explicit
references (ssprk3, rk4, leapfrog_trapezoidal at their largest stable steps,
``EXPLICIT``), so load changes hit them alike. Each step's time is split by
timers around the model's and the solver's calls (exclusive, nested calls
subtracted):

* RHS: ``model.rhs`` (including JFNK's Jacobian-vector products);
* ∇⁴: ``model.hyperviscosity`` (split after the step);
* Helmholtz op: the operator M + cK of the compiled CG (``HelmholtzCG.apply``, both
  precisions);
* Helmholtz rest: the rest of ``HelmholtzSolver.solve`` (the CG's vector updates
  and inner products, the preconditioner fused into them, the Schur pieces);
  where a solve is a replayed graph (one CPU thread, CUDA; ``HelmholtzSolver``) the
  whole solve, its operator included (Helmholtz op then 0);
* Krylov vectors: the Krylov basis's Gram–Schmidt and combinations
  (the backend's ``dots``/``combine``: FGMRES's, KIOPS's; FGMRES's one-thread kernels
  of its small dense work fall in "other");
* J·v passes: the finite-difference J·v's pointwise passes around its RHS
  (``FiniteDifferenceJacobian``: x + εw, the difference, ε and its norms, gathers and scatters);
* other: the rest of the step (stage combinations; Newton, KIOPS's host work, norms).

``--krylov host kernels`` builds each configuration with a Krylov basis in both
backends of that vector work (``KrylovBasis``'s ``HostVectors``/``KernelVectors``,
the J·v's ``HostPasses``/``KernelPasses``: numpy on the CPU against Warp's
kernels, the CUDA path), interleaved; the exponential rows also give the Krylov
vectors a step and the step's RHS-eq per Krylov vector.

Medians over the timed steps, in ms and in RHS-equivalents (one RHS timed in
the same rounds); the last column is the cost per simulated day relative to
the cheapest explicit reference of the same case. ``--clock cpu``
(``time.process_time``) is for one thread on a shared machine; ``--clock wall``
for the targets' idle machine with several threads (process time sums them).
``--device cuda`` times on the GPU by the wall clock, the device synchronised
around every timed call (so the parts add up; the syncs cost a few µs each).

    SWE_SPHERE_THREADS=1 python benchmarks/studies/implicit_cost.py --clock cpu
    SWE_SPHERE_THREADS=1 python benchmarks/studies/implicit_cost.py --clock cpu --precision float64 float32
    SWE_SPHERE_THREADS=1 python benchmarks/studies/implicit_cost.py --ne 16 --cases tc5_mountain --steppers epi2 epi3 CN \
        --krylov host kernels --explicit kgu35@900 rk4@350
    SWE_SPHERE_THREADS=2 python benchmarks/studies/implicit_cost.py --clock wall
    python benchmarks/studies/implicit_cost.py --device cuda
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import os
import platform
import statistics
import sys
import time
from pathlib import Path

import warp as wp
from threadpoolctl import threadpool_limits

wp.config.quiet = True

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: results.py, the shared module
from results import recorded  # noqa: E402  (after the path: benchmarks/ first)

from swe_sphere import (  # noqa: E402
    Simulation,  # noqa: E402
    load_scene,  # noqa: E402
)
from swe_sphere.solvers import jacobian, krylov  # noqa: E402

# case → (label, stepper, Δt/Δt_g, options)
CONFIGS = {
    "tc5_mountain": [
        ("imex", "imex", 8.0, {}),
        ("CN", "implicit", 4.0, {}),
        ("CN", "implicit", 10.0, {}),
        ("semi_implicit", "semi_implicit", 2.0, {}),
        ("epi2", "epi2", 5.0, {}),
        ("epi3", "epi3", 5.0, {}),
    ],
    "tc6_rossby_haurwitz": [("imex", "imex", 4.7, {}), ("CN", "implicit", 4.7, {})],
}
# case → explicit references (stepper, Δt in s): the largest stable steps measured at ne30 np4 on
# an idle machine (TC5 ssprk3 216 s, the cheapest there; TC6 ssprk3 160 s, rk4 200 s,
# leapfrog_trapezoidal 90 s). Other ne: --explicit.
EXPLICIT = {
    "tc5_mountain": [("ssprk3", 216.0)],
    "tc6_rossby_haurwitz": [("ssprk3", 160.0), ("rk4", 200.0), ("leapfrog_trapezoidal", 90.0)],
}
PARTS = ("RHS", "∇⁴", "Helmholtz op", "Helmholtz rest", "Krylov vectors", "J·v passes", "other")
KRYLOV = {"host": (krylov.HostVectors, jacobian.HostPasses), "kernels": (krylov.KernelVectors, jacobian.KernelPasses)}


class Timers:
    """Exclusive time per part: a wrapped call's time less that of the wrapped calls inside it."""

    def __init__(self, clock, sync):
        self.clock, self.sync, self.total, self.stack = clock, sync, dict.fromkeys(PARTS, 0.0), []

    def wrap(self, obj, name, part):
        inner = getattr(obj, name)

        def timed(*args, **kwargs):
            self.stack.append(0.0)
            self.sync()
            t0 = self.clock()
            try:
                return inner(*args, **kwargs)
            finally:
                self.sync()
                dt = self.clock() - t0
                children = self.stack.pop()
                self.total[part] += dt - children
                if self.stack:
                    self.stack[-1] += dt

        timed.__wrapped__ = inner
        setattr(obj, name, timed)

    def reset(self):
        self.total = dict.fromkeys(PARTS, 0.0)


def scene(case, ne, stepper, dt, options):
    base = load_scene(case, ne=ne, np_=4, days=1.0)
    return dataclasses.replace(base, stepper=stepper, dt=dt, stepper_options=options, output_every_days=1.0)


def use_krylov(stepper, backend=None):
    """Give a JFNK (FGMRES) or exponential (KIOPS) stepper's Krylov vector work the
    ``backend`` (a key of KRYLOV; None: the device's own, as built); returns
    (basis, jacobian), or None for a stepper without a Krylov basis."""
    kiops = getattr(stepper, "kiops", None)
    basis = kiops.basis if kiops is not None else getattr(stepper, "fgmres", None)
    if basis is None:
        return None
    if backend is not None:
        vectors, passes = KRYLOV[backend]
        basis.vectors, stepper.jacobian.passes = vectors(basis), passes(stepper.model)
    return basis, stepper.jacobian


def build(case, ne, stepper, dt, options, clock, device, backend=None):
    """A Simulation with its parts timed; ``backend`` (a key of KRYLOV): the Krylov vector work's."""
    sim = Simulation(scene(case, ne, stepper, dt, options), device, progress=False)
    timers = Timers(clock, lambda: wp.synchronize_device(device))
    krylov_work = use_krylov(sim.stepper, backend)
    if krylov_work is not None:
        basis, jac = krylov_work
        for name in ("dots", "combine"):
            timers.wrap(basis.vectors, name, "Krylov vectors")
        for name in ("gather", "scatter", "point_norm", "epsilon", "perturb", "difference", "norm"):
            timers.wrap(jac.passes, name, "J·v passes")
    timers.wrap(sim.model, "rhs", "RHS")
    timers.wrap(sim.model, "rhs_update", "RHS")  # the explicit steppers' stages, combinations included
    timers.wrap(sim.model, "hyperviscosity", "∇⁴")
    gw = getattr(sim.stepper, "helmholtz", None)
    if gw is not None:
        timers.wrap(gw, "solve", "Helmholtz rest")
        for cg in (gw.cg, gw.low) if not gw.graphable else ():  # the float64 CG's operator, and the float32 one's
            if cg is not None:
                timers.wrap(cg, "apply", "Helmholtz op")
    return sim, timers


def arguments() -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--ne", type=int, default=30)
    ap.add_argument("--cases", nargs="+", default=list(CONFIGS), choices=list(CONFIGS))
    ap.add_argument("--steps", type=int, default=5, help="timed steps per configuration")
    ap.add_argument("--spinup", type=float, default=12.0, help="simulated hours each configuration runs untimed first")
    ap.add_argument("--warmup", type=int, default=3, help="untimed steps per configuration after the spin-up")
    ap.add_argument("--clock", choices=("cpu", "wall"), default="cpu")
    ap.add_argument("--device", choices=("cpu", "cuda"), default="cpu", help="cuda: wall clock, synchronised")
    ap.add_argument(
        "--precision",
        nargs="+",
        default=["float64"],
        choices=("float64", "float32"),
        help="the Helmholtz solves' precision; several: each configuration in each, interleaved",
    )
    ap.add_argument(
        "--steppers",
        nargs="+",
        default=None,
        metavar="LABEL",
        help="only these configurations (labels: imex, CN, semi_implicit, epi2, epi3)",
    )
    ap.add_argument(
        "--krylov",
        nargs="+",
        default=[None],
        choices=list(KRYLOV),
        help="the Krylov vector work's backend (default: the device's); several: each Krylov configuration in each, interleaved",
    )
    ap.add_argument(
        "--explicit",
        nargs="*",
        default=None,
        metavar="STEPPER@DT",
        help="the explicit references of every case, e.g. ssprk3@216 (default: EXPLICIT, measured at ne30)",
    )
    args = ap.parse_args()
    return args


def case_runs(args, case: str, dt_g: float, clock) -> list:
    """The runs of ``case``: each explicit reference, then each configuration in each precision and
    Krylov backend asked for: (name, Δt/Δt_g, explicit, Simulation, timers)."""
    runs = []
    explicit = (
        EXPLICIT[case] if args.explicit is None else [(e.split("@")[0], float(e.split("@")[1])) for e in args.explicit]
    )
    for name, dt in explicit:
        runs.append((name, dt / dt_g, True, *build(case, args.ne, name, dt, {}, clock, args.device)))
    for label, stepper, f, options in CONFIGS[case]:
        if args.steppers and label not in args.steppers:
            continue
        krylov_stepper = stepper in ("implicit", "epi2", "epi3")
        for precision in args.precision if stepper not in ("epi2", "epi3") else [None]:
            for backend in args.krylov if krylov_stepper else [None]:
                name = " ".join(
                    [
                        label,
                        *([precision] if precision and len(args.precision) > 1 else []),
                        *([backend] if backend and len(args.krylov) > 1 else []),
                    ]
                )
                opts = {**options, **({"precision": precision} if precision else {})}
                runs.append(
                    (name, f, False, *build(case, args.ne, stepper, f * dt_g, opts, clock, args.device, backend))
                )
    return runs


def timed_steps(args, runs: list, clock, sync) -> tuple[list, dict]:
    """Spin every run up, then ``--steps`` rounds: five RHS evaluations (ms each) and one step of
    each run with its parts (ms): (the RHS's ms per round, each run's (ms, parts, stats) per round)."""
    for _, _, _, sim, _timers in runs:
        for _ in range(math.ceil(args.spinup * 3600.0 / sim.scene.dt - 1e-9) + args.warmup):
            sim.stepper.step(sim.x)
    rhs_sim, out = runs[0][3], wp.zeros_like(runs[0][3].x)
    rhs_ms, per_step = [], {i: [] for i in range(len(runs))}
    for _ in range(args.steps):
        sync()
        t0 = clock()
        for _ in range(5):
            rhs_sim.model.rhs.__wrapped__(rhs_sim.x, out)  # untimed by the parts
        sync()
        rhs_ms.append((clock() - t0) / 5 * 1e3)
        for i, (_, _, _, sim, timers) in enumerate(runs):
            timers.reset()
            sync()
            t0 = clock()
            st = sim.stepper.step(sim.x)
            sync()
            total = (clock() - t0) * 1e3
            parts = {k: v * 1e3 for k, v in timers.total.items()}
            parts["other"] = total - sum(v for k, v in parts.items() if k != "other")
            per_step[i].append((total, parts, st))
    return rhs_ms, per_step


def report(args, case: str, dt_g: float, runs: list, rhs_ms: list, per_step: dict) -> None:
    """Print ``case``'s table: each run's step, its parts in RHS-equivalents, its cost a day."""
    rhs = statistics.median(rhs_ms)
    cost = {i: statistics.median(s[0] for s in per_step[i]) / runs[i][3].scene.dt for i in per_step}
    best = min((i for i in cost if runs[i][2]), key=cost.get)
    print(
        f"\n{case} ne{args.ne} np4: Δt_g = {dt_g:.1f} s, RHS {rhs:.2f} ms (median); {args.steps} timed steps after {args.spinup:g} h and {args.warmup} more; "
        f"best explicit {runs[best][0]} @ {runs[best][3].scene.dt:.0f} s"
    )
    print(
        "| stepper | Δt/Δt_g | Δt (s) | its/step | ms/step | "
        + " | ".join(f"{p} ms (RHS-eq)" for p in PARTS)
        + " | RHS-eq/step | RHS-eq per Krylov vector | cost/day vs best explicit |"
    )
    print("|---|---:|---:|---|---:|" + "---:|" * len(PARTS) + "---:|---:|---:|")
    for i, (label, f, _, sim, _) in enumerate(runs):
        steps = per_step[i]
        ms = statistics.median(s[0] for s in steps)
        parts = {p: statistics.median(s[1][p] for s in steps) for p in PARTS}
        its = {
            k: statistics.mean(s[2].iterations.get(k, 0) for s in steps)
            for k in ("newton", "gmres", "helmholtz", "krylov")
        }
        per_vector = f"{ms / rhs / its['krylov']:.2f}" if its["krylov"] else "-"
        its_text = ", ".join(f"{k} {v:.1f}" for k, v in its.items() if v) or "-"
        print(
            f"| {label} | {f:.2f} | {sim.scene.dt:.0f} | {its_text} | {ms:.1f} | "
            + " | ".join(f"{parts[p]:.1f} ({parts[p] / rhs:.1f})" for p in PARTS)
            + f" | {ms / rhs:.1f} | {per_vector} | {cost[i] / cost[best]:.2f} |"
        )


def main():
    args = arguments()
    clock = time.process_time if args.clock == "cpu" and args.device == "cpu" else time.perf_counter
    sync = lambda: wp.synchronize_device(args.device)  # noqa: E731
    threadpool_limits(1)  # as Simulation.run: BLAS threads would fight the model's
    print(
        f"# {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, {platform.node()}, {platform.processor() or platform.machine()}, "
        f"device {args.device}, clock {'wall' if args.device == 'cuda' else args.clock}, SWE_SPHERE_THREADS={os.environ.get('SWE_SPHERE_THREADS', '(all CPUs)')}, load {os.getloadavg()[0]:.2f}"
    )
    for case in args.cases:
        probe = Simulation(scene(case, args.ne, "ssprk3", 60.0, {}), args.device, progress=False)
        dt_g = 60.0 / probe.courant()["courant_gravity"]
        runs = case_runs(args, case, dt_g, clock)
        rhs_ms, per_step = timed_steps(args, runs, clock, sync)
        report(args, case, dt_g, runs, rhs_ms, per_step)


if __name__ == "__main__":
    with recorded(__file__):
        main()
