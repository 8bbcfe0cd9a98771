"""The default path's whole process: ``swe-sphere run tc5_mountain`` (the scene's stepper, CPU, one
thread, a run file written) at ne30 for 0.25 day and ne120 for 0.01 day, as a user starts it: wall
seconds, CPU seconds and peak resident memory of the child process, the median of ``ROUNDS`` runs
after one untimed (Warp's kernels compiled into its cache; the quick form: one run of ne4). It
replaces ``default_path.sh`` (two trees by hand, last in d6c19d2): asv builds each commit, and
``asv continuous BASE HEAD`` compares them.

A setting against the default at one commit (default_path.sh's ``BASE_ARGS``, a flag against its
old value in one tree) is the benchmark's parameter ``setting``: ``SWE_SPHERE_ASV_SETTINGS``, a JSON
list of ``swe-sphere run`` flags, adds each beside the scene's own ("" in asv's tables), so that
asv times them in turn and prints them side by side::

    SWE_SPHERE_ASV_SETTINGS='["--stepper rk4"]' asv run --config benchmarks/asv.conf.json \\
        --python=same --bench DefaultPath --show-stderr
    python benchmarks/compare.py BASE HEAD --settings '--stepper rk4'   # both, at both commits"""

import json
import os
import shlex
import statistics
import subprocess
import sys
import tempfile
import time

from . import QUICK

RUNS = {4: 0.05} if QUICK else {30: 0.25, 120: 0.01}  # ne: days
ROUNDS = 1 if QUICK else int(os.environ.get("SWE_SPHERE_ASV_ROUNDS", 3))  # fewer on a loaded machine
SETTINGS = ["", *json.loads(os.environ.get("SWE_SPHERE_ASV_SETTINGS", "[]"))]  # swe-sphere run flags; "": the scene's
CHILD = """import resource, sys
from swe_sphere.cli import main
code = main(sys.argv[1:])
use = resource.getrusage(resource.RUSAGE_SELF)
print("usage", use.ru_utime + use.ru_stime, use.ru_maxrss, file=sys.stderr)
sys.exit(code)
"""


def whole_run(ne: int, days: float, setting: str = "") -> tuple[float, float, float]:
    """One run in a process of its own, in a fresh folder, with the flags ``setting`` besides:
    (wall s, CPU s, peak RSS MiB)."""
    args = ["run", "tc5_mountain", "--ne", str(ne), "--days", str(days), "--no-progress", "--device", "cpu"]
    args += shlex.split(setting)
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

    params = [list(RUNS), SETTINGS]
    param_names = ["ne", "setting"]
    timeout = 1800

    def setup_cache(self):
        runs = {}
        for ne, days in RUNS.items():
            for setting in SETTINGS:
                if not QUICK:
                    whole_run(ne, days, setting)  # untimed: compiles on a cold cache
            # the settings' runs taken in turn, so that a change of the machine's load hits each alike
            rounds = [[whole_run(ne, days, setting) for setting in SETTINGS] for _ in range(ROUNDS)]
            for k, setting in enumerate(SETTINGS):
                runs[ne, setting] = [statistics.median(r[k][i] for r in rounds) for i in range(3)]
        return runs

    def track_wall(self, runs, ne, setting):
        return runs[ne, setting][0]

    track_wall.unit = "seconds"

    def track_cpu(self, runs, ne, setting):
        return runs[ne, setting][1]

    track_cpu.unit = "seconds"

    def track_peak_memory(self, runs, ne, setting):
        return runs[ne, setting][2]

    track_peak_memory.unit = "MiB"
