#!/usr/bin/env python
"""Spatial convergence of Williamson et al. (1992) test case 2 (steady geostrophic flow).

Runs TC2 (alpha = 0 by default, ``--alpha pi4`` for the flow over the poles) for
``--days`` days (5) on a sequence of grids — np = 4 with ne = 4, 8, 16, 32 and
np = 8 with ne = 2, 4, 8 by default — and prints the normalized l1, l2 and l∞
errors of h at the end (Williamson eqs. 82–84), the observed rates between
successive grids (log2 of the error ratio per doubling of ne), the time step
and wall time of every run.

So that the time error does not spoil the high-order rates, the runs use rk4
with dt set from a target gravity-wave Courant number (``--courant``, 0.4):
dt = DAY / ceil(DAY / dt_max), dt_max = courant · min(Δx / sqrt(g h)) over the
initial state, Δx the distance to the nearest GLL node. (Scaling the scene's dt
by 1/(ne (np−1)) alone would give np = 8 a Courant number near 0.8.) Unless
``--no-check-dt``, the finest grid of each np is run again at dt/2 and the
relative change of its l2(h) and the size of the state change relative to the
error are printed.

    python benchmarks/tc2_convergence.py                 # alpha = 0, the full table
    python benchmarks/tc2_convergence.py --alpha pi4 --np4 4 8 16 --np8 2 4
"""

from __future__ import annotations

import argparse
import math
import sys
import time

import numpy as np
import warp as wp

wp.config.quiet = True  # before the package initializes Warp (older Warp)
if hasattr(wp, "LOG_WARNING"):
    wp.config.log_level = wp.LOG_WARNING  # newer Warp: no banner, no module-load messages

from swe_sphere.config import load_scene  # noqa: E402
from swe_sphere.constants import DAY  # noqa: E402
from swe_sphere.diagnostics import courant_numbers  # noqa: E402
from swe_sphere.grid import CubedSphere  # noqa: E402
from swe_sphere.runtime import default_device  # noqa: E402
from swe_sphere.simulation import Simulation  # noqa: E402

SCENES = {"0": "tc2_steady", "pi4": "tc2_steady_alpha_pi4"}
NORMS = ("l1", "l2", "linf")


def choose_dt(scene_name: str, ne: int, np_: int, courant: float) -> float:
    """The longest dt = DAY / k whose initial gravity-wave Courant number is <= ``courant``."""
    scene = load_scene(scene_name, ne=ne, np=np_, days=1.0)
    grid = CubedSphere(ne, np_)
    case = scene.make_case()
    u, v, h = case.initial(grid.lat, grid.lon)
    per_second = courant_numbers(grid, u, v, h, 1.0, case.planet.g)["courant_gravity"]
    return DAY / math.ceil(DAY / (courant / per_second) - 1e-9)


def run(scene_name: str, ne: int, np_: int, days: float, dt: float, stepper: str, device: str):
    scene = load_scene(scene_name, ne=ne, np=np_, days=days, dt=dt, stepper=stepper)
    t0 = time.perf_counter()
    sim = Simulation(scene, device, progress=False, log=lambda *a, **k: None)
    result = sim.run()
    total = time.perf_counter() - t0
    return scene, sim, result, total


def fmt_rate(r):
    return f"{r:6.2f}" if r is not None and math.isfinite(r) else "     -"


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--alpha", choices=sorted(SCENES), default="0", help="flow orientation: 0 (default) or pi4 (pi/4, over the poles)")
    p.add_argument("--days", type=float, default=5.0, help="run length in days (default 5)")
    p.add_argument("--np4", type=int, nargs="*", default=[4, 8, 16, 32], metavar="NE", help="ne values for np = 4 (default 4 8 16 32)")
    p.add_argument("--np8", type=int, nargs="*", default=[2, 4, 8], metavar="NE", help="ne values for np = 8 (default 2 4 8)")
    p.add_argument("--stepper", default="rk4", help="time stepper (default rk4)")
    p.add_argument("--courant", type=float, default=0.4, help="target gravity-wave Courant number that sets dt (default 0.4)")
    p.add_argument("--device", default=None, help="Warp device (default: cuda if available, else cpu)")
    p.add_argument("--no-check-dt", action="store_true", help="skip the dt/2 rerun of the finest grid of each np")
    args = p.parse_args(argv)

    device = args.device or default_device()
    scene_name = SCENES[args.alpha]
    print(f"TC2 convergence: scene {scene_name}, {args.days:g} days, stepper {args.stepper}, "
          f"gravity-wave Courant <= {args.courant:g}, device {device}, warp {wp.config.version}")
    print("errors: normalized l1, l2, linf of h at the end (Williamson et al. 1992, eqs. 82-84); "
          "rate = log2(e(ne/2) / e(ne)); wall = time-stepping only, total = incl. setup & diagnostics")
    header = (f"{'np':>3} {'ne':>3} {'dt [s]':>9} {'steps':>6} {'Cgrav':>5}  {'l1(h)':>10} {'l2(h)':>10} {'linf(h)':>10}"
              f"  {'r(l1)':>6} {'r(l2)':>6} {'r(inf)':>6}  {'mass chg':>9} {'wall [s]':>9} {'total [s]':>9}")
    summary = []
    for np_, nes in ((4, args.np4), (8, args.np8)):
        if not nes:
            continue
        print()
        print(header, flush=True)
        prev = None
        finest = None
        for ne in nes:
            dt = choose_dt(scene_name, ne, np_, args.courant)
            scene, sim, result, total = run(scene_name, ne, np_, args.days, dt, args.stepper, device)
            d = result.diagnostics
            err = [d[f"{k}_h"] for k in NORMS]
            rates = [None] * 3
            if prev is not None:
                pne, perr = prev
                rates = [math.log(a / b) / math.log(ne / pne) for a, b in zip(perr, err)]
            print(f"{np_:>3} {ne:>3} {scene.dt:>9.3f} {scene.nsteps:>6} {result.courant['courant_gravity']:>5.2f}  "
                  f"{err[0]:>10.3e} {err[1]:>10.3e} {err[2]:>10.3e}  {fmt_rate(rates[0])} {fmt_rate(rates[1])} {fmt_rate(rates[2])}  "
                  f"{d['mass_change']:>9.1e} {result.wall_time:>9.2f} {total:>9.2f}", flush=True)
            summary.append((np_, ne, err, rates))
            prev = (ne, err)
            finest = (ne, scene, sim, result)
        if finest is not None and not args.no_check_dt:
            ne, scene, sim, result = finest
            s2, sim2, r2, total2 = run(scene_name, ne, np_, args.days, scene.dt / 2, args.stepper, device)
            x, x2 = sim.x.numpy(), sim2.x.numpy()
            he = sim.case.exact(sim.grid.lat, sim.grid.lon, scene.days * DAY)[2]
            w = sim.grid.spheremp
            spatial = math.sqrt(w @ (x[2] - he) ** 2)
            temporal = math.sqrt(w @ (x[2] - x2[2]) ** 2)
            e1, e2 = result.diagnostics["l2_h"], r2.diagnostics["l2_h"]
            print(f"    dt check, np {np_} ne {ne}: dt/2 = {s2.dt:.3f} s gives l2(h) {e2:.4e} "
                  f"(relative change {abs(e1 - e2) / e2:.2e}); |h(dt) - h(dt/2)| / |h(dt) - h_exact| = {temporal / spatial:.2e}; "
                  f"wall {r2.wall_time:.2f} s", flush=True)
    if summary:
        print()
        for np_ in (4, 8):
            rows = [s for s in summary if s[0] == np_]
            if len(rows) >= 2:
                nes = np.array([r[1] for r in rows], dtype=float)
                slopes = [-np.polyfit(np.log(nes), np.log([r[2][i] for r in rows]), 1)[0] for i in range(3)]
                print(f"np = {np_}: least-squares rates over ne = {', '.join(str(r[1]) for r in rows)}: "
                      f"l1 {slopes[0]:.2f}, l2 {slopes[1]:.2f}, linf {slopes[2]:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
