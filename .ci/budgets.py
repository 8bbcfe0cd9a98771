"""Each test folder's summed test time beside its budget, from pytest's JUnit XML.

Usage: ``python .ci/budgets.py REPORT.xml`` (``python -m pytest --junitxml=REPORT.xml``).
A test's time is its setup, call and teardown (pytest's JUnit ``time``); a folder's sum
is its tests' times added, whichever worker ran them, so it does not depend on how many
workers share the run. Budgets are in ``.ci/budgets.toml`` (seconds, from measured sums
with room); a folder without one gets ``default``'s. Exit 1 when a folder's sum is over
its budget by more than ``margin`` (a clock shared with other work is noisy: a wide
margin fails only on a real change), else 0; over the budget alone is a warning line.
"""

from __future__ import annotations

import sys
import tomllib
import xml.etree.ElementTree as ET
from collections import defaultdict
from pathlib import Path

BUDGETS = Path(__file__).with_name("budgets.toml")


def folder_of(case: ET.Element) -> str:
    """The test's folder, from its JUnit ``classname`` (``tests.core.test_backend`` or
    ``tests.core.test_backend.TestClass`` → ``tests/core``)."""
    parts = case.get("classname", "").split(".")
    modules = [i for i, p in enumerate(parts) if p.startswith("test_")]
    return "/".join(parts[: modules[0]] if modules else parts[:-1]) or "."


def folder_sums(report: Path) -> tuple[dict[str, float], dict[str, int], float]:
    """(summed seconds by folder, tests by folder, the run's wall seconds) of a JUnit XML report."""
    root = ET.parse(report).getroot()
    sums: dict[str, float] = defaultdict(float)
    counts: dict[str, int] = defaultdict(int)
    for case in root.iter("testcase"):
        folder = folder_of(case)
        sums[folder] += float(case.get("time", 0.0))
        counts[folder] += 1
    suites = [root] if root.tag == "testsuite" else list(root.iter("testsuite"))
    return dict(sums), dict(counts), sum(float(s.get("time", 0.0)) for s in suites)


def main(argv: list[str]) -> int:
    if len(argv) != 1:
        print("usage: python .ci/budgets.py REPORT.xml", file=sys.stderr)
        return 2
    config = tomllib.loads(BUDGETS.read_text())
    margin, default, budgets = config["margin"], config["default"], config["folders"]
    sums, counts, wall = folder_sums(Path(argv[0]))
    print(f"test time by folder (s; summed over tests, fails at {margin:g}x the budget):")
    failed = []
    for folder in sorted(sums, key=sums.get, reverse=True):
        budget = budgets.get(folder, default)
        verdict = "ok" if sums[folder] <= budget else "over"
        if sums[folder] > margin * budget:
            verdict = "FAIL"
            failed.append(folder)
        own = "" if folder in budgets else " (default budget)"
        print(f"  {folder:<20} {counts[folder]:5d} tests {sums[folder]:8.1f} / {budget:6.0f}  {verdict}{own}")
    print(f"  {'all':<20} {sum(counts.values()):5d} tests {sum(sums.values()):8.1f}   (wall {wall:.0f} s)")
    if failed:
        print(f"over {margin:g}x their budget: {', '.join(failed)} (.ci/budgets.toml)", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
