"""RHS throughput and time per step, Warp against vectorised numpy, in one run.

Prints, per grid, the median time of one RHS evaluation (all TC5 terms + DSS)
with Warp and with the numpy reference of the same operators (tests/numpy_ops.py),
element-local points per second (nelem·np² per evaluation), their ratio, the
median time of one hyperviscosity application, and the median time per step of
each stepper; then a STREAM-like triad (numpy, a = b + s·c) for the machine's
memory bandwidth.

    python benchmarks/rhs_throughput.py [--ne 8 16 30] [--np 4 8] [--device cpu] [--repeat 10]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np
import warp as wp

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # tests.numpy_ops

from swe_sphere.cases import make_case  # noqa: E402
from swe_sphere.grid import CubedSphere  # noqa: E402
from swe_sphere.model import TERMS, ShallowWater, default_device  # noqa: E402
from swe_sphere.steppers import STEPPERS, make_stepper  # noqa: E402
from tests.numpy_ops import NumpyOps  # noqa: E402


def median_time(fn, repeat, sync_device=None):
    fn()  # warm-up (compiles, records launches)
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        if sync_device is not None:
            wp.synchronize_device(sync_device)
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def triad_bandwidth(n=20_000_000, repeat=5):
    """Bytes moved per second by a = b + s·c over float64 arrays (3 × 8 bytes per element)."""
    b, c = np.random.rand(n), np.random.rand(n)
    a = np.empty_like(b)

    def triad():
        np.multiply(c, 3.0, out=a)
        np.add(a, b, out=a)

    # the numpy triad reads c, writes a, reads a and b, writes a: 5 passes of 8 bytes
    t = median_time(triad, repeat)
    return 5 * 8 * n / t


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--ne", type=int, nargs="+", default=[8, 16, 30])
    p.add_argument("--np", type=int, nargs="+", default=[4, 8])
    p.add_argument("--device", default=default_device())
    p.add_argument("--repeat", type=int, default=10)
    args = p.parse_args(argv)
    wp.config.log_level = wp.LOG_ERROR
    case = make_case("tc5_mountain")
    terms = [t for t in TERMS]
    print(f"device {args.device}; terms: all six (TC5); medians of {args.repeat} repeats")
    header = f"{'ne':>4} {'np':>3} {'points':>9} | {'warp RHS ms':>11} {'Mpts/s':>7} | {'numpy RHS ms':>12} {'Mpts/s':>7} | {'speed-up':>8} | {'HV ms':>7} | " + " ".join(
        f"{name + ' ms/step':>26}" for name in STEPPERS
    )
    print(header)
    for np_ in args.np:
        for ne in args.ne:
            grid = CubedSphere(ne, np_)
            fcor, hs = case.fcor(grid.lat, grid.lon), case.hs(grid.lat, grid.lon)
            model = ShallowWater(grid, terms, fcor, hs, nu=1.5e15 * (30 * 3 / (ne * (np_ - 1))) ** 3.2, device=args.device)
            u, v, h = case.initial(grid.lat, grid.lon)
            x = model.new_state(u, v, h)
            out = wp.zeros_like(x)
            sync = args.device
            t_warp = median_time(lambda: model.rhs(x, out), args.repeat, sync)
            ops = NumpyOps(grid)
            state = np.stack([u, v, h])
            t_np = median_time(lambda: ops.sw_rhs(state, terms, fcor, hs, model.g), max(3, args.repeat // 3))
            t_hv = median_time(lambda: model.hyperviscosity(x, 1e-9), args.repeat, sync)
            steps = []
            for name in STEPPERS:
                xs = model.new_state(u, v, h)
                stepper = make_stepper(name, model, 1.0)
                stepper.step(xs)  # leapfrog family: the start step
                steps.append(median_time(lambda: stepper.step(xs), args.repeat, sync))
            pts = grid.npts
            print(
                f"{ne:>4} {np_:>3} {pts:>9} | {1e3 * t_warp:>11.3f} {pts / t_warp / 1e6:>7.2f} | {1e3 * t_np:>12.3f} {pts / t_np / 1e6:>7.2f} | "
                f"{t_np / t_warp:>7.1f}x | {1e3 * t_hv:>7.3f} | " + " ".join(f"{1e3 * t:>26.3f}" for t in steps)
            )
    bw = triad_bandwidth()
    print(f"memory bandwidth (numpy triad a = b + s*c, median): {bw / 1e9:.1f} GB/s")


if __name__ == "__main__":
    main()
