"""Milliseconds a step of the implicit-type steppers, for comparing two checkouts (ISSUE 31).

Uses only what every version since the study has (``Simulation``, ``Stepper.step``), so the
same file runs against an older checkout's package: run it alternately with each
checkout's Python, e.g.

    for i in 1 2 3; do
      SWE_SPHERE_THREADS=1 OLD/venv/bin/python benchmarks/step_ab.py old
      SWE_SPHERE_THREADS=1 python benchmarks/step_ab.py new
    done

Per configuration (TC5 ne30 np4: IMEX ARS(3,4,3) @ 8 Δt_g, CN @ 4 and 10 Δt_g,
semi-implicit @ 2 Δt_g; kgu35 @ 415.4 s for scale): ``--spinup`` simulated hours
untimed (the CG iterations a step settle after TC5's first hours), then ``--steps``
steps, each timed (``--clock cpu``: process time, for one thread on a shared machine;
``wall`` for an idle one); prints the median ms a step and the CG iterations a step.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import os
import statistics
import time

import warp as wp

wp.config.quiet = True

from swe_sphere.config import load_scene  # noqa: E402
from swe_sphere.simulation import Simulation  # noqa: E402

# label → (stepper, Δt in multiples of Δt_g, or None for a Δt in s)
CONFIGS = {"kgu35": ("kgu35", None, 415.3846153846154), "imex@8": ("imex", 8.0, None), "CN@4": ("implicit", 4.0, None),
           "CN@10": ("implicit", 10.0, None), "semi_implicit@2": ("semi_implicit", 2.0, None)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("label", help="what this checkout is called in the output")
    ap.add_argument("--ne", type=int, default=30)
    ap.add_argument("--spinup", type=float, default=12.0, help="simulated hours untimed first")
    ap.add_argument("--steps", type=int, default=6)
    ap.add_argument("--clock", choices=("cpu", "wall"), default="cpu")
    ap.add_argument("--configs", nargs="+", default=list(CONFIGS), choices=list(CONFIGS))
    args = ap.parse_args()
    clock = time.process_time if args.clock == "cpu" else time.perf_counter
    base = load_scene("tc5_mountain", ne=args.ne, np=4, days=1.0)
    probe = Simulation(dataclasses.replace(base, stepper="ssprk3", dt=60.0), "cpu", progress=False)
    dt_g = 60.0 / probe.courant()["courant_gravity"]
    out = []
    for label in args.configs:
        stepper, f, seconds = CONFIGS[label]
        dt = seconds if f is None else f * dt_g
        sim = Simulation(dataclasses.replace(base, stepper=stepper, dt=dt, output_every_days=1.0), "cpu", progress=False)
        for _ in range(math.ceil(args.spinup * 3600.0 / dt - 1e-9)):
            sim.stepper.step(sim.x)
        times, its = [], []
        for _ in range(args.steps):
            t0 = clock()
            st = sim.stepper.step(sim.x)
            times.append((clock() - t0) * 1e3)
            its.append(st.iterations.get("helmholtz", 0))
        out.append(f"{label} {statistics.median(times):.1f} ms ({statistics.mean(its):.1f} CG)")
    print(f"{args.label}: ne{args.ne}, {args.clock} clock, SWE_SPHERE_THREADS={os.environ.get('SWE_SPHERE_THREADS', '-')}, "
          f"load {os.getloadavg()[0]:.2f}: " + "; ".join(out), flush=True)


if __name__ == "__main__":
    main()
