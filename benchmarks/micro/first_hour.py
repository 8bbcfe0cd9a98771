"""What a run costs outside its step loop: ``swe-sphere run SCENE --days D`` as a whole
process on one thread, its CPU seconds (user + sys, ``RUSAGE_CHILDREN``) less the CPU seconds of
its step loop (the run's own ledger, ``simulation.summary.Ledger``): the imports, the
set-up, the diagnostics, scoring and writing at output times, the summary.

    python benchmarks/micro/first_hour.py [--scene tc5_mountain_homme] [--days 1] [--rounds 5]
                                    [--source DIR ...]

Each ``--source`` is a tree of swe_sphere (a clone, or ``git archive COMMIT | tar -x``)
put first on ``PYTHONPATH``; several are run interleaved, round by round, so that a
before/after comparison meets the same load. Before the rounds each source runs once to
warm Warp's kernel cache and the grid cache (the user's own, as a user's second run
finds them). Also timed, in a fresh process each round: ``import
swe_sphere.config.scene`` alone (what every command imports first). Prints each
round, the medians and the load average at the start and the end.
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: results.py, the shared module
from results import check_sources, recorded

# The run as the console script runs it (``cli.main()`` with the process's own argv: it
# ends in ``os._exit`` after the atexit callbacks), with the step loop's CPU seconds
# written to the file $FIRST_HOUR_LOOP from an atexit callback.
RUN = """
import atexit, os, sys
from swe_sphere.simulation import summary
loop = [0.0]
account = summary.Ledger.account
def counted(self, n, t0, cpu0):
    before = self.c["cpu_time"]
    account(self, n, t0, cpu0)
    loop[0] += self.c["cpu_time"] - before
summary.Ledger.account = counted
atexit.register(lambda: open(os.environ["FIRST_HOUR_LOOP"], "w").write(repr(loop[0])))
from swe_sphere import cli
sys.argv = ["swe-sphere", *sys.argv[1:]]
cli.main()
"""

IMPORT = """
import time
t = time.process_time()
import swe_sphere.config.scene
print(time.process_time() - t)
"""

ENV = {"SWE_SPHERE_THREADS": "1", "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}


def child(code: str, args: list[str], source: str | None, loop_file: Path) -> tuple[float, str]:
    """Run ``code`` in a fresh interpreter; returns its CPU seconds (user + sys, all its
    threads) and its last line of output."""
    env = {**os.environ, **ENV, "FIRST_HOUR_LOOP": str(loop_file)}
    if source is not None:
        env["PYTHONPATH"] = os.pathsep.join([source, *filter(None, [os.environ.get("PYTHONPATH")])])
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    out = subprocess.run([sys.executable, "-c", code, *args], env=env, capture_output=True, text=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)  # one child at a time: the difference is this one
    if out.returncode != 0:
        raise SystemExit(f"{' '.join(args)} ({source or 'default'}): exit {out.returncode}\n{out.stderr[-2000:]}")
    cpu = after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime
    return cpu, (out.stdout.splitlines() or [""])[-1]


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--scene", default="tc5_mountain_homme")
    p.add_argument("--days", default="1")
    p.add_argument("--rounds", type=int, default=5)
    p.add_argument(
        "--source", nargs="+", default=[None], help="swe_sphere trees, interleaved (default: the one Python finds)"
    )
    args = p.parse_args()
    check_sources(p, args.source)
    print(
        f"load average {os.getloadavg()[0]:.2f} at the start; {args.scene} --days {args.days}; one thread", flush=True
    )
    with tempfile.TemporaryDirectory(prefix="first_hour_") as tmp:
        output, loop_file = Path(tmp) / "run.nc", Path(tmp) / "loop"
        cmd = ["run", args.scene, "--days", args.days, "--output", str(output)]

        def run(source):
            output.unlink(missing_ok=True)  # a fresh file each run: nothing to replace
            cpu, _ = child(RUN, cmd, source, loop_file)
            return cpu, float(loop_file.read_text())

        for source in args.source:  # warm the kernel and grid caches
            run(source)
        rows: dict = {s: [] for s in args.source}
        for r in range(args.rounds):
            for source in args.source:
                cpu, loop = run(source)
                _, imp = child(IMPORT, [], source, loop_file)
                row = dict(total=cpu, loop=loop, outside=cpu - loop, imp=float(imp))
                rows[source].append(row)
                print(
                    f"round {r + 1} {source or 'default'}: process {row['total']:.2f} s, step loop {row['loop']:.2f} s, "
                    f"outside {row['outside']:.2f} s; import swe_sphere.config.scene {row['imp']:.2f} s",
                    flush=True,
                )
    print(f"medians of {args.rounds} (CPU s)")
    for source, rs in rows.items():
        med = {k: statistics.median(x[k] for x in rs) for k in rs[0]}
        print(
            f"  {source or 'default'}: outside the step loop {med['outside']:.2f}, process {med['total']:.2f}, "
            f"step loop {med['loop']:.2f}, import swe_sphere.config.scene {med['imp']:.2f}"
        )
    print(f"load average {os.getloadavg()[0]:.2f} at the end")


if __name__ == "__main__":
    with recorded(__file__):
        main()
