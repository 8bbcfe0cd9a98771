"""The ∇⁴'s weak Laplacians with W elements a vector (``kernels.hyperviscosity_across.laplacian_across``,
the CPU's form at np ≥ 5 since issue 99) against one element a thread on GLL rows
(``laplacian_element``, ``Hyperviscosity.across_elements = 0``): a step's CPU cost, both in one
process, interleaved.

For each ``--case SCENE[:NE,NP]`` (the scene's own grid, or NE, NP), at the scene's own stepper and
Δt, two models: one as shipped and one built with the rows; each stepped ``--steps`` steps a round,
``--rounds`` rounds taken in turn so that a change of load hits both alike; the median CPU ms a
step (``time.process_time``, one thread) and the ratio, and the ∇⁴ evaluation alone (``operator``,
``--evals`` a round). The two give the same bits (tests/model/test_hyperviscosity_across.py); the
run checks it on the states after the rounds. Figures to
``benchmarks/results/hyperviscosity_across/hyperviscosity_across[_STEM].json``::

    SWE_SPHERE_THREADS=1 OMP_NUM_THREADS=1 taskset -c 0 python benchmarks/micro/step/hyperviscosity_across.py --case galewsky galewsky:25,6
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path
from unittest import mock

os.environ.setdefault("SWE_SPHERE_THREADS", "1")

import numpy as np  # noqa: E402
import warp as wp  # noqa: E402
from threadpoolctl import threadpool_limits  # noqa: E402

wp.config.quiet = True

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # benchmarks/: results.py, the shared module
from results import interleaved, positive, recorded  # noqa: E402  (after the path: benchmarks/ first)

from swe_sphere import Simulation  # noqa: E402
from swe_sphere.model.hyperviscosity import Hyperviscosity  # noqa: E402


def case(text: str) -> tuple[str, dict]:
    """``SCENE`` or ``SCENE:NE,NP`` → (scene, grid keywords)."""
    scene, _, grid = text.partition(":")
    if not grid:
        return scene, {}
    try:
        ne, np_ = (int(v) for v in grid.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"--case wants SCENE or SCENE:NE,NP (got {text!r})") from None
    if ne < 1 or not 2 <= np_ <= 8:
        raise argparse.ArgumentTypeError(f"--case {text}: ne >= 1 and np 2-8")
    return scene, {"ne": ne, "np": np_}


def arguments():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--case", type=case, nargs="+", default=[case("galewsky"), case("galewsky:25,6")])
    p.add_argument("--steps", type=positive(int), default=48, help="steps a round")
    p.add_argument("--evals", type=positive(int), default=8, help="∇⁴ evaluations a round")
    p.add_argument("--rounds", type=positive(int), default=9)
    p.add_argument("--results", default=None, help="results stem (default hyperviscosity_across)")
    return p.parse_args()


def measure(scene: str, grid: dict, steps: int, evals: int, rounds: int) -> dict:
    """CPU ms a step and a ∇⁴ evaluation of ``scene`` with W elements a vector and with rows,
    interleaved."""
    sims = {"across": Simulation(scene, "cpu", progress=False, days=1.0, graphs=False, **grid)}
    with mock.patch.object(Hyperviscosity, "across_elements", 0):
        sims["rows"] = Simulation(scene, "cpu", progress=False, days=1.0, graphs=False, **grid)
    assert sims["across"].model.hv.lanes > 1 and sims["rows"].model.hv.lanes == 0
    outs = {k: wp.zeros_like(sim.x) for k, sim in sims.items()}
    for k, sim in sims.items():  # recorded and compiled
        for _ in range(steps):
            sim.stepper.step(sim.x)
        sim.model.hv.operator(sim.x, outs[k])
    calls = {}
    for k, sim in sims.items():  # a round: each model's steps, then its ∇⁴ alone
        calls["step", k] = (lambda s=sim: s.stepper.step(s.x), steps)
        calls["hv", k] = (lambda s=sim, o=outs[k]: s.model.hv.operator(s.x, o), evals)
    ms = interleaved(calls, rounds)
    same = bool(np.array_equal(sims["across"].x.numpy(), sims["rows"].x.numpy()))
    same &= bool(np.array_equal(outs["across"].numpy(), outs["rows"].numpy()))
    s = sims["across"].scene
    med, hmed = ({k: ms[part, k] for k in sims} for part in ("step", "hv"))
    return {
        "scene": scene,
        "grid": f"ne{s.ne} np{s.np}",
        "stepper": s.stepper,
        "lanes": sims["across"].model.hv.lanes,
        "rows_ms": med["rows"],
        "across_ms": med["across"],
        "ratio": med["across"] / med["rows"],
        "hv_rows_ms": hmed["rows"],
        "hv_across_ms": hmed["across"],
        "hv_ratio": hmed["across"] / hmed["rows"],
        "bitwise": same,
        "steps": steps * (rounds + 1),
    }


def main() -> None:
    args = arguments()
    with recorded(__file__, args.results) as figures, threadpool_limits(limits=1):
        print(f"load average at the start: {os.getloadavg()}")
        rows = [measure(scene, grid, args.steps, args.evals, args.rounds) for scene, grid in args.case]
        print(
            f"\nCPU ms, medians of {args.rounds} interleaved rounds of {args.steps} steps (and {args.evals} ∇⁴), one thread"
        )
        print(
            f"{'scene':>10} {'grid':>9} {'W':>3} {'step rows':>10} {'across':>8} {'ratio':>6} "
            f"{'∇⁴ rows':>8} {'across':>8} {'ratio':>6} {'bitwise':>8}"
        )
        for r in rows:
            print(
                f"{r['scene']:>10} {r['grid']:>9} {r['lanes']:>3} {r['rows_ms']:10.3f} {r['across_ms']:8.3f} "
                f"{r['ratio']:6.3f} {r['hv_rows_ms']:8.3f} {r['hv_across_ms']:8.3f} {r['hv_ratio']:6.3f} "
                f"{str(r['bitwise']):>8}"
            )
        figures["steps"] = rows
        print(f"load average at the end: {os.getloadavg()}")


if __name__ == "__main__":
    main()
