"""The default path's whole process: ``swe-sphere run tc5_mountain`` (the scene's stepper, CPU, one
thread, a run file written) at ne30 for 0.25 day and ne120 for 0.01 day, as a user starts it: wall
seconds, CPU seconds and peak resident memory of the child process, the median of ``ROUNDS`` runs
after one untimed (Warp's kernels compiled into its cache; the quick form: one run of ne4). It
replaces ``default_path.sh`` (two trees by hand, last in d6c19d2): asv builds each commit, and
``asv continuous BASE HEAD`` compares them."""

import os
import statistics
import subprocess
import sys
import tempfile
import time

from . import QUICK

RUNS = {4: 0.05} if QUICK else {30: 0.25, 120: 0.01}  # ne: days
ROUNDS = 1 if QUICK else int(os.environ.get("SWE_SPHERE_ASV_ROUNDS", 3))  # fewer on a loaded machine
CHILD = """import resource, sys
from swe_sphere.cli import main
code = main(sys.argv[1:])
use = resource.getrusage(resource.RUSAGE_SELF)
print("usage", use.ru_utime + use.ru_stime, use.ru_maxrss, file=sys.stderr)
sys.exit(code)
"""


def whole_run(ne: int, days: float) -> tuple[float, float, float]:
    """One run in a process of its own, in a fresh folder: (wall s, CPU s, peak RSS MiB)."""
    args = ["run", "tc5_mountain", "--ne", str(ne), "--days", str(days), "--no-progress", "--device", "cpu"]
    env = {**os.environ, "SWE_SPHERE_THREADS": "1", "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}
    with tempfile.TemporaryDirectory() as folder:
        start = time.perf_counter()
        done = subprocess.run(
            [sys.executable, "-c", CHILD, *args, "--output", "run.nc"],
            cwd=folder,
            env=env,
            capture_output=True,
            text=True,
        )
        wall = time.perf_counter() - start
    if done.returncode != 0:
        raise RuntimeError(f"swe-sphere {' '.join(args)} failed:\n{done.stderr[-2000:]}")
    _, cpu, rss = done.stderr.strip().splitlines()[-1].split()
    return wall, float(cpu), round(int(rss) / 1024, 1)  # Linux's ru_maxrss: KiB


class DefaultPath:
    """Wall, CPU and peak memory of the default run at each grid (``RUNS``)."""

    params = [list(RUNS)]
    param_names = ["ne"]
    timeout = 1800

    def setup_cache(self):
        runs = {}
        for ne, days in RUNS.items():
            if not QUICK:
                whole_run(ne, days)  # untimed: compiles on a cold cache
            runs[ne] = [whole_run(ne, days) for _ in range(ROUNDS)]
        return {ne: [statistics.median(r[k] for r in rows) for k in range(3)] for ne, rows in runs.items()}

    def track_wall(self, runs, ne):
        return runs[ne][0]

    track_wall.unit = "seconds"

    def track_cpu(self, runs, ne):
        return runs[ne][1]

    track_cpu.unit = "seconds"

    def track_peak_memory(self, runs, ne):
        return runs[ne][2]

    track_peak_memory.unit = "MiB"
