"""Where a step of TC5 goes on a mesh: the ∇⁴ and the dynamics, and for ``lts`` with
``method = "mrab3"`` its level parts' evaluations and its sub-step sums; CPU clock, one thread.

The scene's TC5 on ``--mesh`` at ``--dt`` with ``--stepper`` and its options (``--options``, a
JSON table), three steps taken first (past MRAB3's start); then the median over ``--rounds`` of
the mean ``time.process_time`` of ``--calls`` calls: a step, the ∇⁴ over dt
(``ShallowWater.hyperviscosity``), the whole grid's RHS, and for MRAB3 each level's
``rhs_part`` (times its 2^k evaluations a step) and each level's sums at each of the 2^K
finest sub-steps. A step's dynamics is the step less the ∇⁴.

    SWE_SPHERE_THREADS=1 OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 python benchmarks/studies/lts/lts_step_cost.py \\
        --mesh PATH/mountain_10_x2.g --dt 234.783 --stepper lts --options '{"method": "mrab3", "level_margin": 1.3}'
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # benchmarks/: results.py, the shared module
from results import quiet_warp, recorded, timed

from swe_sphere import Simulation, load_scene

DAY = 86400.0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--mesh", required=True)
    parser.add_argument("--dt", type=float, required=True, help="s")
    parser.add_argument("--stepper", default="lts")
    parser.add_argument("--options", default="{}", help="the stepper's options, a JSON table")
    parser.add_argument("--hypervis-scaling", type=float, help="the tensor ∇⁴'s s (default: the scene's constant ν)")
    parser.add_argument("--calls", type=int, default=20)
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args()
    quiet_warp()
    days = 8 * args.dt / DAY  # whole steps
    scene = load_scene("tc5_mountain", mesh=args.mesh, dt=args.dt, days=days, stepper=args.stepper)
    if args.hypervis_scaling is not None:
        scene = dataclasses.replace(scene, hypervis_scaling=args.hypervis_scaling)
    options = json.loads(args.options)
    sim = Simulation(dataclasses.replace(scene, stepper_options=options, output_every_days=days), "cpu", progress=False)
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


if __name__ == "__main__":
    with recorded(__file__):
        main()
