"""Two commits compared on the regression suite (``benchmarks/regressions``, asv): ``asv continuous``
builds both, times each benchmark on both with their rounds interleaved (a change of the machine's
load hits both alike), and flags a ratio beyond ``--factor`` that its statistics call real; its
table, with the date, machine, load and commits, becomes ``results/compare/<stem>.json``::

    python benchmarks/compare.py d6c19d2 HEAD [--factor 1.1] [--bench REGEX] [--rounds N] [--results STEM]
        [--settings FLAGS ...]   # the whole run also with these swe-sphere run flags (whole_run.py)

The exit status is asv's: 0 when nothing got slower beyond the factor, 1 when something did (the
record is written either way: a slower figure is a figure)."""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

from results import positive, recorded

CONFIG = Path(__file__).resolve().parent / "asv.conf.json"


def table(out: str) -> str:
    """asv's comparison at the end of its output (from its "All benchmarks:" head on, asv 0.6; else
    its "before after ratio" head), without the progress lines before it."""
    lines = out.splitlines()
    heads = [
        i
        for i, line in enumerate(lines)
        if line.startswith("All benchmarks") or line.split()[:3] == ["before", "after", "ratio"]
    ]
    return "\n".join(lines[heads[-1] :] if heads else lines)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("base", help="the earlier commit (a hash, tag or branch)")
    parser.add_argument("head", nargs="?", default="HEAD", help="the later one (default HEAD)")
    parser.add_argument("--factor", type=positive(float, 1.0), default=1.1, help="a ratio beyond it is flagged")
    parser.add_argument("--bench", help="only the benchmarks matching this regular expression")
    parser.add_argument("--rounds", type=positive(int), help="asv's rounds a benchmark (default its 2), taken in turn")
    parser.add_argument("--results", help="results/compare/<STEM>.json (default: compare)")
    parser.add_argument(
        "--settings",
        nargs="+",
        default=[],
        metavar="FLAGS",
        help="swe-sphere run flags the whole run is also timed with, each beside the scene's own (regressions/whole_run.py)",
    )
    args = parser.parse_args()
    for rev in (args.base, args.head):
        git = ["git", "rev-parse", "--verify", "-q", f"{rev}^{{commit}}"]  # in the suite's repository, as asv
        if subprocess.run(git, cwd=CONFIG.parent, capture_output=True).returncode:
            parser.error(f"no commit {rev!r} in this repository")
    command = ["asv", "continuous", "--config", str(CONFIG), "--factor", str(args.factor), "--interleave-rounds"]
    command += ["--no-only-changed", *(["--bench", args.bench] if args.bench else [])]
    command += ["--attribute", f"rounds={args.rounds}"] if args.rounds else []
    with recorded(__file__, args.results) as figures:
        figures.update(base=args.base, head=args.head, factor=args.factor, rounds=args.rounds, settings=args.settings)
        print(" ".join([*command, args.base, args.head]))
        env = {**os.environ, "SWE_SPHERE_ASV_SETTINGS": json.dumps(args.settings)}  # asv passes it on
        done = subprocess.run([*command, args.base, args.head], capture_output=True, text=True, env=env)
        print(table(done.stdout))
        figures["exit"] = done.returncode
        if done.returncode not in (0, 1):  # asv's own failure (a build, a benchmark): no comparison
            print(done.stderr[-3000:], file=sys.stderr)
            raise SystemExit(done.returncode)
    return done.returncode


if __name__ == "__main__":
    sys.exit(main())
