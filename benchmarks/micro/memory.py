"""Peak resident memory of a run against the bytes of its state and metric arrays.

Runs ``swe-sphere run tc5_mountain_homme --ne NE --days DAYS`` (np = 4, the scene's
stepper leapfrog_trapezoidal unless ``--stepper``) in a child process and reads
its peak RSS (``resource.getrusage(RUSAGE_CHILDREN).ru_maxrss``), next to the
peak RSS of a child that only imports swe_sphere and initialises Warp (the
interpreter, numpy/scipy/xarray and Warp's libraries), and to the bytes of the
arrays the run must hold: the state and the metric/index arrays on the device,
the model's and the stepper's work arrays, and the grid's host (numpy) arrays.

    python benchmarks/micro/memory.py              # ne = 30
    python benchmarks/micro/memory.py --ne 60      # benchmarks/README.md's figure
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import warp as wp

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: results.py, the shared module
from results import recorded

BASELINE = "import warp as wp; wp.config.quiet = True; wp.config.log_level = wp.LOG_ERROR; wp.init(); from swe_sphere import Simulation"


def child_peak_rss(cmd) -> float:
    """Peak RSS (bytes) of one child process running ``cmd``."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    p = subprocess.run(cmd, capture_output=True, text=True)
    if p.returncode != 0:
        raise RuntimeError(f"{cmd} failed ({p.returncode}):\n{p.stdout}\n{p.stderr}")
    peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss  # max over all children so far, KiB
    if peak <= before:
        print("  (note: this child's peak is not above an earlier child's; the figure is an upper bound)")
    return peak * 1024.0


def array_bytes(ne, stepper):
    """Bytes of the run's arrays, by group, from a model built like the run's."""
    from swe_sphere import CubedSphere, ShallowWater, load_scene, make_stepper

    scene = load_scene("tc5_mountain_homme", ne=ne, np_=4, stepper=stepper)
    grid = CubedSphere(ne, 4)
    m = ShallowWater.from_scene(scene, grid, device="cpu", threads=1)
    st = make_stepper(scene.stepper, m, scene.dt, **scene.stepper_options)
    metric = (
        "D",
        "Dinv",
        "metdet",
        "spheremp",
        "rspheremp",
        "dvv",
        "gid",
        "offsets",
        "copies",
        "xyz",
        "east",
        "north",
        "fcor",
        "hs",
        "topo_forcing",
    )
    metric_bytes = sum(getattr(m, k).capacity for k in metric if getattr(m, k, None) is not None)
    work_bytes = sum(
        v.capacity for k, v in vars(m).items() if isinstance(v, wp.array) and k not in metric and v.shape[-1] == m.N
    )
    stepper_bytes = sum(v.capacity for v in vars(st).values() if isinstance(v, wp.array))
    host_bytes = sum(v.nbytes for v in vars(grid).values() if isinstance(v, np.ndarray))
    state_bytes = 3 * m.N * 8
    return grid, dict(
        state=state_bytes, metric=metric_bytes, model_work=work_bytes, stepper=stepper_bytes, grid_host=host_bytes
    )


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--ne", type=int, default=30)
    ap.add_argument("--days", type=float, default=0.05)
    ap.add_argument("--stepper", default="leapfrog_trapezoidal")
    args = ap.parse_args(argv)
    wp.config.quiet = True
    wp.config.log_level = wp.LOG_ERROR
    with tempfile.TemporaryDirectory() as tmp:
        base = child_peak_rss([sys.executable, "-c", BASELINE])
        run = [
            sys.executable,
            "-m",
            "swe_sphere.cli",
            "run",
            "tc5_mountain_homme",
            "--ne",
            str(args.ne),
            "--days",
            str(args.days),
            "--stepper",
            args.stepper,
            "--device",
            "cpu",
            "--no-progress",
            "--output",
            os.path.join(tmp, "run.nc"),
        ]
        peak = child_peak_rss(run)
    grid, b = array_bytes(args.ne, args.stepper)
    mib = 2.0**20
    need = b["state"] + b["metric"]
    print(
        f"tc5_mountain_homme ne={args.ne} np=4 ({grid.nnodes} element-local points), {args.stepper}, {args.days:g} days, CPU"
    )
    print(f"  peak RSS of the run                 {peak / mib:8.1f} MiB")
    print(f"  peak RSS of import + wp.init()      {base / mib:8.1f} MiB")
    print(f"  run minus baseline                  {(peak - base) / mib:8.1f} MiB")
    for k, v in b.items():
        print(f"  {k + ' arrays':<35} {v / mib:8.1f} MiB  ({v / grid.nnodes:.0f} B/pt)")
    print(f"  (run - baseline) / (state + metric) {(peak - base) / need:8.1f}x")
    print(f"  (run - baseline) / all arrays above {(peak - base) / sum(b.values()):8.1f}x")


if __name__ == "__main__":
    with recorded(__file__):
        main()
