"""RHS throughput and time per step beside their limits, in one run.

Prints, in this order (all float64, TC5 terms, medians of ``--repeat`` timings):

1. The machine's memory bandwidth: a STREAM-like triad ``a = b + s·c`` in numpy
   on 1 thread and on ``--threads`` threads (each on its own slice; numpy
   releases the GIL), 5 passes of 8 bytes per element counted.
2. RHS throughput per grid: one RHS evaluation (all TC5 terms + DSS) with Warp
   on 1 thread and on ``--threads`` threads (the two models timed alternately in
   this process), and with the vectorised numpy reference of the same operators
   (tests/numpy_ops.py); element-local points per second (nelem·np² per
   evaluation), the ratio to numpy, the compulsory bytes per point (state in,
   tendency out, and every metric/index array the RHS reads, each once) and the
   bandwidth that implies, as a share of the triad's.
3. A full step of each stepper per grid (``--step-ne``, np = 4) with its
   breakdown: time inside ``model.rhs`` (of which the DSS, estimated from the
   DSS launch timed alone), inside ``model.hyperviscosity``, and the rest
   (solver, linear combinations, norms, host round trips). Explicit steppers at
   the scene's Δt, semi_implicit and implicit at ``--implicit-dt-factor``× it.
   The implicit (JFNK) row's RHS share is the figure to watch. BLAS is limited to
   one thread here, as in ``Simulation.run``. RHS-eq = the step over one plain
   ``model.rhs`` timed in the same rounds (alternately with the steps); "HV eq"
   the hyperviscosity likewise. ``--steppers`` picks the rows.

``--clock cpu`` times with ``time.process_time`` (the process's CPU seconds,
all threads), which a loaded machine does not inflate; use it with one thread
(``SWE_SPHERE_THREADS=1``) on a shared machine, where wall times mean little.
The RHS table's flop/pt is counted by hand (``rhs_flops``), GFLOP/s uses the
faster of the two Warp columns.

    python benchmarks/micro/step/rhs_throughput.py                     # ne 8 16 30, np 4 8; steps at ne 16 30
    python benchmarks/micro/step/rhs_throughput.py --ne 60 --np 4 --step-ne 60
    SWE_SPHERE_THREADS=1 python benchmarks/micro/step/rhs_throughput.py   # pins "threads" to 1
    SWE_SPHERE_THREADS=1 OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 python benchmarks/micro/step/rhs_throughput.py \
        --clock cpu --ne 30 --np 4 --step-ne 30 --steppers rk4 ssprk3 kgu35 fbrk32 leapfrog leapfrog_trapezoidal
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import threading
import time
from pathlib import Path

import numpy as np
import warp as wp
from threadpoolctl import threadpool_limits

sys.path.insert(
    0, str(Path(__file__).resolve().parents[3] / "tests")
)  # numpy_ops; not the repo root, which would shadow the installed package

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # benchmarks/: results.py, the shared module
from results import positive, quiet_warp, recorded  # noqa: E402  (after the path: benchmarks/ first)

from swe_sphere import (  # noqa: E402
    STEPPERS,
    CubedSphere,  # noqa: E402
    ShallowWater,  # noqa: E402
    load_scene,  # noqa: E402
    make_stepper,
)
from swe_sphere.core.backend import Backend, default_device  # noqa: E402
from swe_sphere.core.parallel import SplitLaunch  # noqa: E402
from swe_sphere.core.tally import array_bytes  # noqa: E402

from numpy_ops import NumpyOps  # noqa: E402

CLOCKS = {"wall": time.perf_counter, "cpu": time.process_time}
clock = CLOCKS["wall"]  # set by --clock


def interleaved_times(fns, repeat, sync_device=None):
    """Median time of each of ``fns``, timed alternately (one call of each per round)
    after one untimed call of each (compiles, records launches)."""
    for fn in fns:
        fn()
    if sync_device is not None:
        wp.synchronize_device(sync_device)
    times = [[] for _ in fns]
    for _ in range(repeat):
        for k, fn in enumerate(fns):
            t0 = clock()
            fn()
            if sync_device is not None:
                wp.synchronize_device(sync_device)
            times[k].append(clock() - t0)
    return [statistics.median(t) for t in times]


def median_time(fn, repeat, sync_device=None):
    """Median time of fn() (synchronised on ``sync_device``), after one untimed call."""
    return interleaved_times([fn], repeat, sync_device)[0]


def triad_bandwidth(threads=1, n=20_000_000, repeat=5):
    """Bytes per second moved by a = b + s·c over float64 arrays on ``threads`` threads
    (the numpy triad reads c, writes a, reads a and b, writes a: 5 passes of 8 bytes)."""
    b, c = np.random.rand(n), np.random.rand(n)
    a = np.empty_like(b)
    cuts = [round(k * n / threads) for k in range(threads + 1)]
    parts = [(a[i:j], b[i:j], c[i:j]) for i, j in zip(cuts[:-1], cuts[1:])]

    def triad_part(a_, b_, c_):
        np.multiply(c_, 3.0, out=a_)
        np.add(a_, b_, out=a_)

    def triad():
        workers = [threading.Thread(target=triad_part, args=p) for p in parts[1:]]
        for w in workers:
            w.start()
        triad_part(*parts[0])
        for w in workers:
            w.join()

    return 5 * 8 * n / median_time(triad, repeat)


def build(
    ne, np_, threads, device, stepper=None, dt_factor=1.0, per_element=None, precision="float64", compensated=True
):
    """TC5 scene on (ne, np): grid, scene, case fields and initial state, model (``per_element``: its
    layout; ``precision``: its ``model.precision``; ``compensated`` False: a float32 state kept
    between steps, ``model.held``)."""
    scene = load_scene("tc5_mountain_homme", ne=ne, np_=np_)
    if stepper is not None:
        scene = load_scene("tc5_mountain_homme", ne=ne, np_=np_, stepper=stepper, dt=scene.dt * dt_factor)
    grid = CubedSphere(ne, np_)
    case = scene.make_case()
    model = ShallowWater.from_scene(
        scene, grid, case, device=device, threads=threads, per_element=per_element, precision=precision,
        compensated=compensated,
    )  # fmt: skip
    fcor, hs = model.operators.fcor.numpy(), model.operators.hs.numpy()
    u, v, h = case.initial(grid.lat, grid.lon)
    return grid, scene, (fcor, hs, np.stack([u, v, h])), model


def rhs_compulsory_bytes(model) -> int:
    """Bytes an RHS evaluation must move at least: the state read and the tendency
    written once, and each array the recorded RHS launches read (metric terms,
    Coriolis, forcing, DSS indices and masses), once. The tendency work array
    (written and re-read between the term kernels) is not compulsory."""
    x = model.new_state()
    out = wp.zeros_like(x)
    model.rhs(x, out)
    arrays = {}
    for launch in model.launches.recorded(model.rhs_key(x, out)):
        launch = launch.whole if isinstance(launch, SplitLaunch) else launch
        arrays.update(array_bytes(launch.fwd_args or []))
    for a in (x, out, model.tend):
        arrays.pop(a.ptr, None)
    return sum(arrays.values()) + x.capacity + out.capacity


def rhs_flops(model) -> float:
    """Floating-point operations per point of one TC5 RHS (all five terms; FMA
    counted as 2), by hand from kernels/tendencies.py and kernels/dss.py: per
    node 21 to form the fluxes, the Bernoulli function and the covariant wind,
    12 per GLL index of the derivative sums (continuity 4, Bernoulli gradient 4,
    vorticity 4) and 20 to finish, in the per-element layout; the per-node
    layout recomputes the fluxes at every index, 40 an index. The DSS: per row
    2 a copy (weighted) and 1 for the inverse mass, with the table's mean copy
    count (1.78 at np 4, ne 30)."""
    np_ = model.grid.np
    tendency = (21 + 12 * np_ if model.operators.per_element else 40 * np_) + 20
    copies = float((model.topology.table.numpy() >= 0).sum()) / model.N
    return tendency + 3 * (2 * copies + 1)


def dss_launch(model, x, out):
    """The recorded DSS launch of ``model.rhs(x, out)`` (its last launch)."""
    return model.launches.recorded(model.rhs_key(x, out))[-1]


class Timers:
    """Time inside model.rhs and model.rhs_update (the explicit stages, their
    combinations included) and model.hyperviscosity (instance-level wrappers)."""

    def __init__(self, model, device):
        self.t = {"rhs": 0.0, "hv": 0.0}
        self.n = {"rhs": 0, "hv": 0}
        for name, attr in (("rhs", "rhs"), ("rhs", "rhs_update"), ("hv", "hyperviscosity")):
            setattr(model, attr, self._wrap(name, getattr(model, attr), device))

    def _wrap(self, name, fn, device):
        def timed(*args):
            t0 = clock()
            fn(*args)
            wp.synchronize_device(device)
            self.t[name] += clock() - t0
            self.n[name] += 1

        return timed

    def reset(self):
        for k in self.t:
            self.t[k], self.n[k] = 0.0, 0


def rhs_table(args, threads, triad):
    print(
        f"\nRHS throughput (all TC5 terms + DSS), medians of {args.repeat}, {args.clock} clock; Warp 1 thread and {threads} threads timed alternately"
    )
    head = (
        f"{'ne':>4} {'np':>3} {'points':>9} | {'1-thr ms':>8} {'Mpts/s':>7} | {f'{threads}-thr ms':>8} {'Mpts/s':>7} | "
        f"{'numpy ms':>9} {'Mpts/s':>7} | {'warp/numpy':>10} | {'B/pt':>5} {'GB/s':>6} {'% triad':>7} | {'flop/pt':>7} {'GFLOP/s':>7}"
    )
    print(head)
    print("-" * len(head))
    for np_ in args.np:
        for ne in args.ne:
            grid, scene, (fcor, hs, state), m1 = build(ne, np_, 1, args.device)
            mt = build(ne, np_, threads, args.device)[3] if threads > 1 else m1
            xs = [m.new_state(*state) for m in (m1, mt)]
            outs = [wp.zeros_like(x) for x in xs]
            t1, tt = interleaved_times(
                [lambda: m1.rhs(xs[0], outs[0]), lambda: mt.rhs(xs[1], outs[1])], args.repeat, args.device
            )
            ops = NumpyOps(grid)
            rhs_terms = [t for t in scene.terms if t != "hyperviscosity"]
            t_np = median_time(lambda: ops.sw_rhs(state, rhs_terms, fcor, hs, m1.g), max(3, args.repeat // 3))
            pts = grid.nnodes
            bpp = rhs_compulsory_bytes(m1) / pts
            best = min(t1, tt)
            gbs = bpp * pts / best / 1e9
            flops = rhs_flops(m1)
            print(
                f"{ne:>4} {np_:>3} {pts:>9} | {1e3 * t1:>8.3f} {pts / t1 / 1e6:>7.2f} | {1e3 * tt:>8.3f} {pts / tt / 1e6:>7.2f} | "
                f"{1e3 * t_np:>9.3f} {pts / t_np / 1e6:>7.2f} | {t_np / best:>9.1f}x | {bpp:>5.0f} {gbs:>6.2f} {100 * gbs * 1e9 / triad:>6.1f}% | "
                f"{flops:>7.0f} {flops * pts / best / 1e9:>7.2f}"
            )


@threadpool_limits.wrap(limits=1, user_api="blas")  # as Simulation.run: single-threaded BLAS for the Krylov solvers
def step_table(args, threads):
    print(
        f"\nOne step per stepper, TC5, np=4, {threads} thread(s), {args.clock} clock; ms per step (median of {args.step_repeat}, "
        f"each after a plain RHS timed alone: RHS-eq = step / RHS) and its breakdown; semi_implicit/implicit at {args.implicit_dt_factor:g}x the scene dt"
    )
    head = (
        f"{'ne':>4} {'stepper':<21} {'dt s':>6} | {'step ms':>9} {'ns/pt':>7} {'RHS-eq':>6} | {'RHS ms':>8} {'evals':>5} {'(DSS)':>7} | "
        f"{'HV ms':>7} {'HV eq':>5} | {'other ms':>9} | {'RHS %':>5} | iterations"
    )
    print(head)
    print("-" * len(head))
    for ne in args.step_ne:
        for name in args.steppers or STEPPERS:
            implicit = not STEPPERS[name].explicit
            grid, scene, (_, _, state), model = build(
                ne, 4, threads, args.device, name, args.implicit_dt_factor if implicit else 1.0
            )
            x = model.new_state(*state)
            stepper = make_stepper(name, model, scene.dt, **scene.stepper_options)
            stepper.step(x)  # leapfrog family: the start step; compiles and records
            y, k = model.new_state(*state), wp.zeros_like(x)
            model.rhs(y, k)
            t_dss = median_time(dss_launch(model, y, k).launch, 20, args.device)
            timers = Timers(model, args.device)
            steps, rhs = [], []
            for _ in range(args.step_repeat):
                t0 = clock()
                model.rhs(y, k)
                wp.synchronize_device(args.device)
                rhs.append(clock() - t0)
                timers.reset()
                t0 = clock()
                stats = stepper.step(x)
                wp.synchronize_device(args.device)
                steps.append((clock() - t0, dict(timers.t), dict(timers.n), stats))
            steps.sort(key=lambda s: s[0])
            t, tt, nn, stats = steps[len(steps) // 2]
            t_rhs = statistics.median(rhs)
            other = t - tt["rhs"] - tt["hv"]
            its = ", ".join(f"{k} {v}" for k, v in stats.iterations.items())
            print(
                f"{ne:>4} {name:<21} {scene.dt:>6.0f} | {1e3 * t:>9.2f} {1e9 * t / grid.nnodes:>7.0f} {t / t_rhs:>6.2f} | {1e3 * tt['rhs']:>8.2f} {nn['rhs']:>5} "
                f"{1e3 * t_dss * nn['rhs']:>7.2f} | {1e3 * tt['hv']:>7.2f} {tt['hv'] / t_rhs:>5.2f} | {1e3 * other:>9.2f} | {100 * tt['rhs'] / t:>4.0f}% | {its}"
            )


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--ne", type=int, nargs="+", default=[8, 16, 30])
    p.add_argument("--np", type=int, nargs="+", default=[4, 8])
    p.add_argument(
        "--step-ne", type=int, nargs="*", default=[16, 30], help="grids (np=4) of the step table; none to skip it"
    )
    p.add_argument("--device", default=default_device())
    p.add_argument(
        "--threads",
        type=int,
        default=None,
        help="CPU threads of the multi-threaded column (default: the model's default)",
    )
    p.add_argument("--repeat", type=positive(int), default=20)
    p.add_argument("--step-repeat", type=int, default=5)
    p.add_argument("--implicit-dt-factor", type=float, default=4.0)
    p.add_argument(
        "--steppers", nargs="+", choices=sorted(STEPPERS), help="rows of the step table (default: every stepper)"
    )
    p.add_argument(
        "--clock", choices=sorted(CLOCKS), default="wall", help="wall (time.perf_counter) or cpu (time.process_time)"
    )
    args = p.parse_args(argv)
    global clock
    clock = CLOCKS[args.clock]
    quiet_warp()  # quietly
    threads = args.threads or Backend.of(args.device).threads()
    print(
        f"Warp {wp.__version__}, device {args.device}, threads {threads}, {args.clock} clock, load average {os.getloadavg()[0]:.2f}"
    )
    triad1 = triad_bandwidth(1)
    triad = triad_bandwidth(threads) if threads > 1 else triad1
    print(
        f"memory bandwidth (numpy triad a = b + s*c, median): 1 thread {triad1 / 1e9:.1f} GB/s, {threads} threads {triad / 1e9:.1f} GB/s"
    )
    rhs_table(args, threads, max(triad, triad1))
    if args.step_ne:
        step_table(args, threads)
    print(f"load average at the end {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    with recorded(__file__):
        main()
