"""Start-up time: from `swe-sphere run` to the end of its first step, cold and warm kernel cache.

Each measurement is a new process running ``swe-sphere run SCENE --ne 4 --days 1``
(the CLI's ``main``; a wrapper around the stepper reports the end of the first step
and exits). Cold: ``WARP_CACHE_PATH`` is an empty directory, so every Warp module
is compiled; warm: the same directory again, so every module is loaded from the
cache. Also prints the cold time with Warp's CPU precompiled header disabled
(``wp.config.use_precompiled_headers = False``), which Warp otherwise builds in a
per-process temporary directory before the first compile.

    python benchmarks/startup.py [--scene tc2_steady] [--repeat 3]
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time

CHILD = r"""
import os, sys, time
import warp as wp
if os.environ.get("SWE_BENCH_NO_PCH"):
    wp.config.use_precompiled_headers = False
from swe_sphere import simulation
make = simulation.make_stepper
def wrapped(*args, **kwargs):
    stepper = make(*args, **kwargs)
    step = stepper.step
    def first(x):
        step(x)
        wp.synchronize()
        print("FIRST_STEP_DONE", time.time(), flush=True)
        os._exit(0)
    stepper.step = first
    return stepper
simulation.make_stepper = wrapped
from swe_sphere.cli import main
sys.exit(main(sys.argv[1:]))
"""


def time_to_first_step(scene, cache, out, pch=True) -> float:
    env = dict(os.environ, WARP_CACHE_PATH=cache)
    if not pch:
        env["SWE_BENCH_NO_PCH"] = "1"
    cmd = [sys.executable, "-c", CHILD, "run", scene, "--ne", "4", "--days", "1", "--output", out, "--no-progress"]
    t0 = time.time()
    p = subprocess.run(cmd, env=env, capture_output=True, text=True)
    for line in p.stdout.splitlines():
        if line.startswith("FIRST_STEP_DONE"):
            return float(line.split()[1]) - t0
    raise RuntimeError(f"no first step (rc {p.returncode}):\n{p.stdout}\n{p.stderr}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--scene", default="tc2_steady")
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args(argv)
    rows = {"cold (empty kernel cache)": [], "warm (cache filled)": [], "cold, no precompiled header": []}
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "run.nc")
        for k in range(args.repeat):
            cache = os.path.join(tmp, f"cache{k}")
            rows["cold (empty kernel cache)"].append(time_to_first_step(args.scene, cache, out))
            rows["warm (cache filled)"].append(time_to_first_step(args.scene, cache, out))
            rows["cold, no precompiled header"].append(time_to_first_step(args.scene, os.path.join(tmp, f"nopch{k}"), out, pch=False))
    print(f"swe-sphere run {args.scene} --ne 4 --days 1: seconds from process start to the end of the first step "
          f"(median of {args.repeat}; targets: cold <= 20 s, warm <= 2 s)")
    for name, ts in rows.items():
        print(f"  {name:<30} {statistics.median(ts):6.2f} s   (runs: {', '.join(f'{t:.2f}' for t in ts)})")


if __name__ == "__main__":
    main()
