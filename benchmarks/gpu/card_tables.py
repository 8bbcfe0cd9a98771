"""The tables of ``gpu_session.py``'s figures: a markdown table's head, a ``precision`` row, and
``card``: the summary of ``gpu_session.sh card``'s items in one folder (their results files,
``mpi.xml``, ``exchange.txt``, ``session.log``), printed as markdown tables and kept as figures.
Reads files only: no device."""

from __future__ import annotations

import json
from pathlib import Path


def header(title, columns, right):
    """Print a table's title, its header and the alignment row (the last ``right`` columns right-aligned)."""
    print(title)
    print("| " + " | ".join(columns) + " |")
    print("|" + "---|" * (len(columns) - right) + "---:|" * right)


PRECISION_COLUMNS = [
    "scene",
    "ne np",
    "stepper",
    "members",
    "precision",
    "graphs kept",
    "Δt s",
    "build s",
    "ms a step",
    "ms a member",
    "days a wall day",
    "× float64",
    "graph a step µs",
    "chained µs",
    "max|Δh| / max h",
    "target",
]


def precision_row(r: dict) -> str:
    """A ``precision`` row (its figures' dict) as a markdown row of ``PRECISION_COLUMNS``."""
    chained = ", ".join(f"{k}: {us:.1f}" for k, us in r["chained_us"].items()) or "–"
    graph = "–" if r["graph_step_us"] is None else f"{r['graph_step_us']:.1f}"
    met = "" if r["target"] is None else f"{r['target']}: {'met' if r['met'] else 'NOT met'}"
    return (
        f"| {r['scene']} | {r['ne']} {r['np']} | {r['stepper']} | {r['members']} | {r['precision']} | {r['graphs_kept']} | "
        f"{r['dt']:.4g} | {r['build_s']:.1f} | {r['ms_a_step']:.4f} | {r['ms_a_member']:.4f} | {r['days_a_wall_day']:,.0f} | "
        f"{r['speedup']:.2f} | {graph} | {chained} | {r['h_rel_diff']:.2e} | {met} |"
    )


def _log_items(text: str) -> dict:
    """``gpu_session.sh``'s session.log: each part's exit status and seconds (the last of a name)."""
    items = {}
    for line in text.splitlines():
        words = line.split()
        if len(words) == 7 and words[0] == "==" and words[2] == "exit" and words[4] == "after":  # run()'s line
            items[words[1].rstrip(":")] = {"exit": int(words[3]), "s": int(words[5])}
    return items


def _junit(path: Path) -> dict | None:
    """pytest's junit file: the counts and each test's outcome (None: no file, the part not run or stopped)."""
    import xml.etree.ElementTree as ET

    if not path.is_file():
        return None
    suite = ET.parse(path).getroot()
    suite = suite if suite.tag == "testsuite" else suite.find("testsuite")
    tests = {}
    for case in suite.iter("testcase"):
        outcome = next((c.tag for c in case if c.tag in ("failure", "error", "skipped")), "passed")
        tests[case.get("name")] = outcome
    counts = {k: int(suite.get(k, 0)) for k in ("tests", "failures", "errors", "skipped")}
    return {**counts, "outcomes": tests}


def _exchange_tables(text: str) -> list[str]:
    """``scaling.py``'s time tables (ms a step, the exchange's share, the bare exchange µs) from its output."""
    lines, keep = [], False
    for line in text.splitlines():
        keep = keep and bool(line.strip()) and not line.startswith("figures written") or "RK4 TC5 on" in line
        if keep:
            lines.append(line)
    return lines


def card(args, figures):
    folder = Path(args.folder)
    items = _log_items((folder / "session.log").read_text()) if (folder / "session.log").is_file() else {}
    rows, devices = [], set()  # in the order the items ran
    for path in sorted(folder.glob("precision_*.json"), key=lambda p: [*items, p.stem].index(p.stem)):
        record = json.loads(path.read_text())
        rows += [{"item": path.stem, **r} for r in record["figures"]["rows"]]
        devices.add(f"{record['figures']['device']} (Warp {record['figures']['warp']}, {record['commit']})")
    mpi = _junit(folder / "mpi.xml")
    exchange = _exchange_tables((folder / "exchange.txt").read_text()) if (folder / "exchange.txt").is_file() else []
    figures.update(items=items, precision=rows, mpi=mpi, exchange=exchange, devices=sorted(devices))
    print(f"On {', '.join(sorted(devices)) or 'no device (no precision item ended)'}\n")
    header("The card's items (session.log): exit status and seconds", ["item", "exit", "s"], 2)
    for name, item in items.items():
        print(f"| {name} | {item['exit']} | {item['s']} |")
    print()
    header(
        "float32 against float64 (gpu_session.py precision)", ["item", *PRECISION_COLUMNS], len(PRECISION_COLUMNS) - 5
    )
    for r in rows:
        print(f"| {r['item']} {precision_row(r)}")
    print()
    if mpi is None:
        print(
            "2 ranks on one card against 1 (tests/test_mpi_devices.py): no results (not run, or stopped by its time box)"
        )
    else:
        print(
            f"2 ranks on one card against 1 (tests/test_mpi_devices.py): {mpi['tests']} tests, {mpi['failures']} failed, "
            f"{mpi['errors']} errors, {mpi['skipped']} skipped (a skip on the card is a failure)"
        )
        for name, outcome in mpi["outcomes"].items():
            print(f"- {name}: {outcome}")
    print()
    print("The staged exchange (benchmarks/studies/scaling.py; bare exch us: docs/explanation/scaling.md's S)")
    print("\n".join(exchange) if exchange else "no time table (not run, or stopped by its time box)")
