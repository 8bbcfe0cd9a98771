"""What ``swe-sphere plot`` costs: each of the README's plot commands (a map, the default map and
series, ``--diff T213``, ``--spectrum``, ``--zonal-mean``, ``--animate``) run in-process
(``swe_sphere.cli.main``) in a fresh interpreter, once as a user's command line meets it (the
imports and the first call: ``first``) and then ``--repeat`` times more in the same process, as a
test suite meets it (grids and remappers built once a process: ``again``, the median).

    python benchmarks/micro/plot_cost.py [--ne 2 16] [--np 8 4] [--commands map default ...]
                                   [--rounds 3] [--repeat 3] [--source DIR ...]

Each ``--source`` is a tree of swe_sphere (a worktree, or ``git archive COMMIT | tar -x``) put
first on ``PYTHONPATH``; several are run interleaved, command by command and round by round, so
that a before/after comparison meets the same load. The run files (``tc5_mountain``, 5 days, one
for each ``--ne``/``--np`` pair) are made once, by the first source, in a temporary folder. Wall
and CPU seconds (``time.process_time``, which a loaded machine disturbs less) of each; prints each
round, then the medians side by side, and the load average at the start and the end.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: results.py, the shared module
from results import check_sources, positive, recorded

# the plot commands of the README, on a run file RUN (tc5_mountain, days 0..5) into a folder OUT
COMMANDS = {
    "map": ["--field", "vorticity", "--day", "5", "--lat-range", "0", "90", "--width", "720"],
    "default": [],  # h + hs at the last day, and the series figure
    "diff": ["--day", "5", "--diff", "T213"],
    "spectrum": ["--spectrum", "--day", "0", "5"],
    "zonal": ["--zonal-mean", "--field", "h", "u", "--lat-range", "0", "90"],
    "animate": ["--animate", "gif", "--field", "vorticity"],
}

# one command in a fresh interpreter: the import of the command line, then the command repeated;
# prints one JSON line of wall and CPU seconds
CHILD = """
import json, sys, time
w, c = time.perf_counter(), time.process_time()
from swe_sphere.cli import main
times = {"import": (time.perf_counter() - w, time.process_time() - c), "calls": []}
repeat, argv = int(sys.argv[1]), sys.argv[2:]
for _ in range(1 + repeat):
    w, c = time.perf_counter(), time.process_time()
    rc = main(argv)
    if rc:
        raise SystemExit(f"exit {rc}")
    times["calls"].append((time.perf_counter() - w, time.process_time() - c))
print(json.dumps(times))
"""

ENV = {"SWE_SPHERE_THREADS": "1", "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MPLBACKEND": "Agg"}


def child(code: str, args: list[str], source: str | None, cwd: Path) -> str:
    """Run ``code`` with ``args`` in a fresh interpreter in ``cwd`` (``source`` first on the path);
    returns its last line of output."""
    env = {**os.environ, **ENV}
    if source is not None:
        env["PYTHONPATH"] = os.pathsep.join([source, *filter(None, [os.environ.get("PYTHONPATH")])])
    out = subprocess.run([sys.executable, "-c", code, *args], env=env, cwd=cwd, capture_output=True, text=True)
    if out.returncode != 0:
        raise SystemExit(f"{' '.join(args)} ({source or 'default'}): exit {out.returncode}\n{out.stderr[-2000:]}")
    return (out.stdout.splitlines() or [""])[-1]


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--ne", type=positive(int), nargs="+", default=[2, 16], help="the run files' grids (with --np)")
    p.add_argument("--np", type=positive(int), nargs="+", default=[8, 4], help="GLL points, one per --ne")
    p.add_argument("--commands", nargs="+", choices=list(COMMANDS), default=list(COMMANDS))
    p.add_argument("--rounds", type=positive(int), default=3)
    p.add_argument("--repeat", type=positive(int), default=3, help="calls after the first, in the same process")
    p.add_argument(
        "--source", nargs="+", default=[None], help="swe_sphere trees, interleaved (default: the one Python finds)"
    )
    args = p.parse_args()
    check_sources(p, args.source)
    if len(args.ne) != len(args.np):
        p.error(f"--ne and --np pair up: {len(args.ne)} against {len(args.np)}")
    print(f"load average {os.getloadavg()[0]:.2f} at the start; one thread; tc5_mountain 5 days", flush=True)
    rows: dict = {}
    with tempfile.TemporaryDirectory(prefix="plot_cost_") as tmp:
        tmp = Path(tmp)
        runs = {}
        for ne, np_ in zip(args.ne, args.np):
            runs[f"ne{ne}np{np_}"] = run = f"tc5_ne{ne}np{np_}.nc"
            made = ["run", "tc5_mountain", "--ne", str(ne), "--np", str(np_), "--days", "5", "--output", run]
            child(CHILD, ["0", *made, "--no-progress"], args.source[0], tmp)
        for r in range(args.rounds):
            for grid, run in runs.items():
                for name in args.commands:
                    for k, source in enumerate(args.source):
                        cmd = ["plot", run, *COMMANDS[name], "--output", f"out{k}", "--overwrite"]
                        t = json.loads(child(CHILD, [str(args.repeat), *cmd], source, tmp))
                        (w0, c0), again = t["calls"][0], t["calls"][1:]
                        row = dict(
                            imp_wall=t["import"][0],
                            imp_cpu=t["import"][1],
                            first_wall=t["import"][0] + w0,
                            first_cpu=t["import"][1] + c0,
                            again_wall=statistics.median(w for w, _ in again),
                            again_cpu=statistics.median(c for _, c in again),
                        )
                        rows.setdefault((grid, name, source), []).append(row)
                        print(
                            f"round {r + 1} {grid} {name} {source or 'default'}: first (import and call) "
                            f"{row['first_wall']:.2f} s wall {row['first_cpu']:.2f} CPU, again {row['again_wall']:.2f} "
                            f"wall {row['again_cpu']:.2f} CPU; import {row['imp_cpu']:.2f} CPU; "
                            f"load {os.getloadavg()[0]:.2f}",
                            flush=True,
                        )
    print(f"medians of {args.rounds} rounds (s; first: a fresh process's import and call, again: a call after it)")
    header = "  ".join(f"{s or 'default':>28}" for s in args.source)
    print(f"{'grid':>9} {'command':>8}  {'':>14}{header}")
    for grid in runs:
        for name in args.commands:
            for key, what in (("first", "first"), ("again", "again")):
                cells = []
                for source in args.source:
                    rs = rows[(grid, name, source)]
                    wall = statistics.median(x[f"{key}_wall"] for x in rs)
                    cpu = statistics.median(x[f"{key}_cpu"] for x in rs)
                    cells.append(f"{wall:6.2f} wall {cpu:6.2f} CPU")
                print(f"{grid:>9} {name:>8}  {what:>14}" + "  ".join(f"{c:>28}" for c in cells))
    print(f"load average {os.getloadavg()[0]:.2f} at the end")


if __name__ == "__main__":
    with recorded(__file__):
        main()
